//! docs/QUICKSTART.md, run as written: every `./target/release/lavatube` command of its `sh`
//! blocks, in order, and the `lavatube` commands it names inline, so that a quickstart
//! command that stops working fails CI instead of the first reader.
//!
//! Run as written, with these substitutions only (each again where it is made):
//! - the binary is this build's launcher, `CARGO_BIN_EXE_lavatube` (its process binaries are
//!   found beside it, so the workspace must be built, as for every end-to-end test);
//! - the working directory is a fresh temp dir holding `configs/default.toml`, a stand-in that
//!   extends the repository's configs/smoke.toml (`[run] out-dir = "runs"` as the real
//!   default, and enough steps to still be training when the learner is swapped),
//!   `configs/bench.toml`, the repository's own (its runtime, `default.toml` beside it, is
//!   then the stand-in), and `my-ppo.toml`, the stand-in with other `[ppo]` values;
//! - the run id `demo` is `qs-<pid>`: shared-memory names are machine-wide;
//! - `bench` gets `--quick`: the full matrix takes many minutes in a release build;
//! - `lavatube clean [--run-id R]` runs as `lavatube clean --run-id qs-<pid>`.
//!
//! Every command has a watchdog; nothing is timed. A failing test still stops what it
//! started (guards below) and removes its run's shared memory.

use common::ipc;
use common::run_dir;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

#[allow(dead_code)] // this test uses only some of the shared helpers
mod support;

/// The subcommands of the quickstart's `sh` blocks, in order, that this test knows how to
/// run (the first `run` in the background, swapped and killed; the second resumes it).
const FENCED: [&str; 4] = ["run", "swap-learner", "run", "bench"];
/// The `lavatube …` commands the quickstart names inline, in order, as this test runs them.
const INLINE: [&str; 3] = [
    "lavatube map --run-id demo",
    "lavatube status",
    "lavatube clean [--run-id R]",
];
/// The stand-in's step budget, in the smoke config's updates of 1024 steps: a run still going
/// when the swap is done (it waits for the first update; in a debug build on 2 shared cores
/// the launcher was killed about 1 s in, at update 1 or 2, of some 15 s of training), and a
/// resume that finishes seconds later.
const TOTAL_STEPS: u64 = 64 * 1024;
/// The swapped-in learner's config differs from the run's in these `[ppo]` values only.
const OTHER_PPO: &str = "\n[ppo]\nlearning-rate = 1e-4\nepochs = 3\n";

/// Watchdogs: a run (and its resume), the swap (its own answer timeout is 120 s), the quick
/// bench (as tests/bench.rs), a command that only reads or removes files.
const RUN_WATCHDOG: Duration = Duration::from_secs(900);
const SWAP_WATCHDOG: Duration = Duration::from_secs(300);
const BENCH_WATCHDOG: Duration = Duration::from_secs(900);
const SHORT_WATCHDOG: Duration = Duration::from_secs(120);
/// How long a debug-build run may take to publish its first policy, and its processes to
/// stop after their launcher's death (a watchdog, not an assertion about speed).
const PATIENCE: Duration = Duration::from_secs(300);

/// A command of the quickstart: its line in the file and its words after the program.
#[derive(Debug)]
struct DocCommand {
    line: usize,
    text: String,
    args: Vec<String>,
}

impl DocCommand {
    fn subcommand(&self) -> &str {
        self.args.first().map_or("", String::as_str)
    }
}

/// `text` split into words as a shell would split it: refused when it needs more than
/// whitespace (quotes, variables, pipes), which this test does not emulate.
fn words(text: &str, line: usize) -> Vec<String> {
    assert!(
        !text.contains(['\'', '"', '$', '|', '&', ';', '<', '>', '`', '\\', '*']),
        "docs/QUICKSTART.md:{line}: `{text}` needs a shell; tests/quickstart.rs splits \
         commands on whitespace only: teach it, or keep the command plain"
    );
    text.split_whitespace().map(str::to_owned).collect()
}

/// Every line of a ```sh block that starts with `./target/release/lavatube`.
fn fenced_commands(doc: &str) -> Vec<DocCommand> {
    const PROGRAM: &str = "./target/release/lavatube";
    let mut fence: Option<&str> = None;
    let mut out = Vec::new();
    for (i, line) in doc.lines().enumerate() {
        let trimmed = line.trim();
        if let Some(info) = trimmed.strip_prefix("```") {
            fence = match fence {
                None => Some(info.trim()),
                Some(_) => None,
            };
            continue;
        }
        if fence == Some("sh")
            && let Some(rest) = trimmed.strip_prefix(PROGRAM)
        {
            out.push(DocCommand {
                line: i + 1,
                text: trimmed.to_owned(),
                args: words(rest, i + 1),
            });
        }
    }
    out
}

/// Every inline code span outside code blocks that starts with `lavatube `.
fn inline_commands(doc: &str) -> Vec<DocCommand> {
    let mut in_fence = false;
    let mut out = Vec::new();
    for (i, line) in doc.lines().enumerate() {
        if line.trim().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        if in_fence {
            continue;
        }
        // Odd pieces between backticks are code spans.
        for span in line.split('`').skip(1).step_by(2) {
            if let Some(rest) = span.strip_prefix("lavatube ") {
                out.push(DocCommand {
                    line: i + 1,
                    text: span.to_owned(),
                    args: words(rest, i + 1),
                });
            }
        }
    }
    out
}

/// The quickstart's words, here: `demo` (alone or as a path component, `runs/demo`) and the
/// inline placeholder `R` name this test's run; optional `[…]` arguments are given.
fn as_here(args: &[String], run: &str) -> Vec<String> {
    args.iter()
        .map(|a| {
            let a = a.trim_matches(['[', ']']);
            if a == "R" {
                return run.to_owned();
            }
            a.split('/')
                .map(|part| if part == "demo" { run } else { part })
                .collect::<Vec<_>>()
                .join("/")
        })
        .collect()
}

/// A launcher command started by this test, its stdout and stderr in one file (a chatty
/// command cannot block on a full pipe). Dropped while it runs (a failing test), it is
/// stopped as Ctrl-C would, then killed if that is not enough.
struct Started {
    child: Child,
    shown: String,
    log: PathBuf,
    at: Instant,
}

impl Started {
    fn spawn(cwd: &Path, args: &[String], log: PathBuf) -> Self {
        let file = std::fs::File::create(&log).expect("log file");
        // Substitution: the binary is this build's launcher, not ./target/release/lavatube.
        let child = Command::new(env!("CARGO_BIN_EXE_lavatube"))
            .args(args)
            .current_dir(cwd)
            .stdin(Stdio::null())
            .stdout(Stdio::from(file.try_clone().expect("log file")))
            .stderr(Stdio::from(file))
            .spawn()
            .expect("the launcher starts");
        let shown = format!("lavatube {}", args.join(" "));
        eprintln!("quickstart: $ {shown}");
        Self {
            child,
            shown,
            log,
            at: Instant::now(),
        }
    }

    fn output(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    fn running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Waits for the command under `watchdog`; its exit status and everything it printed.
    fn finish(mut self, watchdog: Duration) -> (ExitStatus, String) {
        let status = loop {
            if let Some(status) = self.child.try_wait().expect("poll") {
                break status;
            }
            assert!(
                self.at.elapsed() < watchdog,
                "`{}` did not finish within {watchdog:?}; so far it printed:\n{}",
                self.shown,
                self.output()
            );
            std::thread::sleep(Duration::from_millis(100));
        };
        eprintln!(
            "quickstart: `{}` → {status} after {:.1} s",
            self.shown,
            self.at.elapsed().as_secs_f64()
        );
        (status, self.output())
    }

    /// Runs the command to the end and asserts that it succeeded; what it printed.
    fn succeeds(self, watchdog: Duration) -> String {
        let shown = self.shown.clone();
        let (status, said) = self.finish(watchdog);
        assert!(status.success(), "`{shown}` failed ({status}):\n{said}");
        said
    }
}

impl Drop for Started {
    fn drop(&mut self) {
        if !self.running() {
            return;
        }
        let pid = self.child.id() as i32;
        // SAFETY: kill(2) on our own child, not yet reaped.
        unsafe {
            libc::kill(pid, libc::SIGINT);
        }
        let until = Instant::now() + Duration::from_secs(60);
        while self.running() && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(100));
        }
        if self.running() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// On a failure, removes what the test's run left in shared memory (after every `Started`
/// declared later has been stopped).
struct Cleanup(String);

impl Drop for Cleanup {
    fn drop(&mut self) {
        if std::thread::panicking() {
            let _ = Command::new(env!("CARGO_BIN_EXE_lavatube"))
                .args(["clean", "--run-id", &self.0])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status();
        }
    }
}

/// Waits for a telemetry tick and a policy of at least version 1 (the run is going), while
/// the launcher still runs.
fn until_going(watch: &support::Watch, launcher: &mut Started) {
    let (mut ticked, mut newest) = (false, 0);
    while newest < 1 || !ticked {
        assert!(
            launcher.running(),
            "the run ended before it published a policy:\n{}",
            launcher.output()
        );
        assert!(
            launcher.at.elapsed() < PATIENCE,
            "the run did not get going within {PATIENCE:?}:\n{}",
            launcher.output()
        );
        watch.ticks.wait(Duration::from_millis(10)).expect("wait");
        ticked |= watch.ticks.try_recv().expect("telemetry").is_some();
        while let Some(p) = watch.policies.try_recv().expect("policy") {
            newest = newest.max(p.user_header().version);
        }
    }
}

/// The run's live processes other than the launcher and this test's monitor: name and pid.
fn children(run: &str) -> Vec<(String, i32)> {
    ipc::list_nodes(run)
        .expect("nodes")
        .into_iter()
        .filter(|n| {
            n.alive && !["launcher", "quickstart", "swap-learner"].contains(&n.name.as_str())
        })
        .map(|n| (n.name, n.pid))
        .collect()
}

/// Everything a log directory holds, its last lines each, for a failure message.
fn logs_tail(dir: &Path) -> String {
    let mut out = String::new();
    for e in std::fs::read_dir(dir.join(run_dir::LOGS))
        .into_iter()
        .flatten()
        .flatten()
    {
        let text = std::fs::read_to_string(e.path()).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        let tail = lines[lines.len().saturating_sub(15)..].join("\n");
        out += &format!("--- {}\n{tail}\n", e.path().display());
    }
    out
}

#[test]
fn the_quickstart_commands_work_as_written() {
    let started = Instant::now();
    let root = support::root();
    let doc = std::fs::read_to_string(root.join("docs/QUICKSTART.md")).expect("QUICKSTART");
    let fenced = fenced_commands(&doc);
    let found: Vec<&str> = fenced.iter().map(DocCommand::subcommand).collect();
    assert_eq!(
        found, FENCED,
        "docs/QUICKSTART.md's `./target/release/lavatube` commands changed ({fenced:#?}): \
         tests/quickstart.rs runs them in order and must learn the new ones"
    );
    let inline = inline_commands(&doc);
    let named: Vec<&str> = inline.iter().map(|c| c.text.as_str()).collect();
    assert_eq!(
        named, INLINE,
        "docs/QUICKSTART.md's inline `lavatube …` commands changed: tests/quickstart.rs runs \
         them and must learn the new ones"
    );
    let [run_cmd, swap_cmd, resume_cmd, bench_cmd] = &fenced[..] else {
        unreachable!("checked above")
    };
    let [map_cmd, status_cmd, clean_cmd] = &inline[..] else {
        unreachable!("checked above")
    };

    // Substitution: a fresh working directory, with stand-ins for the files the quickstart
    // reads from a checkout (see the module's documentation).
    let tmp = tempfile::tempdir().expect("temp dir");
    let cwd = tmp.path();
    std::fs::create_dir_all(cwd.join("configs")).expect("configs dir");
    std::fs::create_dir_all(cwd.join("out")).expect("output dir");
    let smoke = root.join("configs/smoke.toml");
    let stand_in = format!(
        "# configs/default.toml for tests/quickstart.rs: the smoke run, long enough to swap.\n\
         extends = {:?}\n\n[run]\nout-dir = \"runs\"\ntotal-steps = {TOTAL_STEPS}\n",
        smoke.display().to_string()
    );
    std::fs::write(cwd.join("configs/default.toml"), &stand_in).expect("default.toml");
    std::fs::copy(
        root.join("configs/bench.toml"),
        cwd.join("configs/bench.toml"),
    )
    .expect("bench.toml");
    // "a copy of configs/default.toml with other [ppo] values"
    std::fs::write(cwd.join("my-ppo.toml"), stand_in + OTHER_PPO).expect("my-ppo.toml");

    // Substitution: the run id `demo` is this test's own.
    let run = format!("qs-{}", std::process::id());
    let dir = cwd.join("runs").join(&run);
    let here = |c: &DocCommand| as_here(&c.args, &run);
    let mut n = 0;
    let mut log = |c: &DocCommand| {
        n += 1;
        eprintln!("quickstart: docs/QUICKSTART.md:{}: {}", c.line, c.text);
        cwd.join("out").join(format!("{n}-{}.log", c.subcommand()))
    };
    let _cleanup = Cleanup(run.clone());

    // `lavatube run --config configs/default.toml --run-id demo`, in the background.
    let mut launcher = Started::spawn(cwd, &here(run_cmd), log(run_cmd));
    let watch = support::Watch::connect(&run, "quickstart");
    until_going(&watch, &mut launcher);

    // "From another terminal": `lavatube status` lists the run and its processes.
    let said = Started::spawn(cwd, &here(status_cmd), log(status_cmd)).succeeds(SHORT_WATCHDOG);
    let listed = |name: &str| {
        said.lines().any(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            w.first() == Some(&name) && w.last() == Some(&"alive")
        })
    };
    assert!(
        said.contains(&format!("run {run}: ")) && listed("launcher") && listed("learner"),
        "`lavatube status` lists run {run}, its launcher and its learner:\n{said}"
    );

    // `lavatube swap-learner --run-id demo --config my-ppo.toml` while the run trains.
    let learner = |nodes: Vec<(String, i32)>| {
        nodes
            .into_iter()
            .find(|(name, _)| name == "learner")
            .map(|(_, pid)| pid)
    };
    let old = learner(children(&run));
    let said = Started::spawn(cwd, &here(swap_cmd), log(swap_cmd)).succeeds(SWAP_WATCHDOG);
    assert!(
        launcher.running(),
        "the run ended during the swap: raise TOTAL_STEPS in tests/quickstart.rs\n{}",
        launcher.output()
    );
    // The swap answers once the new learner is started; its node comes up a moment later.
    let swapped = Instant::now();
    while learner(children(&run)).is_none_or(|pid| Some(pid) == old) {
        assert!(
            swapped.elapsed() < PATIENCE,
            "no new learner after the swap ({said}); the run's processes: {:?}\n{}",
            children(&run),
            launcher.output()
        );
        std::thread::sleep(Duration::from_millis(50));
    }

    // The launcher dies (the quickstart's dropped SSH connection): its processes stop.
    let left = children(&run);
    assert!(
        launcher.running(),
        "the run ended before the launcher could be killed: raise TOTAL_STEPS in \
         tests/quickstart.rs\n{}",
        launcher.output()
    );
    // SAFETY: kill(2) on the launcher this test started; it is reaped right after.
    assert_eq!(
        unsafe { libc::kill(launcher.child.id() as i32, libc::SIGKILL) },
        0
    );
    launcher.child.wait().expect("reap the launcher");
    let killed = Instant::now();
    let saved = std::fs::read_dir(dir.join(run_dir::CHECKPOINTS))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| run_dir::parse_checkpoint_file(&e.file_name().to_string_lossy()))
        .max();
    eprintln!(
        "quickstart: launcher killed {:.1} s after it started, newest checkpoint {saved:?} of {} updates",
        launcher.at.elapsed().as_secs_f64(),
        TOTAL_STEPS / 1024
    );
    support::until_gone(&left, killed, PATIENCE);
    drop(watch);

    // `lavatube run --resume runs/demo`: goes on to the end of the run.
    let said = Started::spawn(cwd, &here(resume_cmd), log(resume_cmd)).succeeds(RUN_WATCHDOG);
    assert!(said.contains("(resumed)"), "{said}");
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join(run_dir::SUMMARY_JSON))
            .unwrap_or_else(|e| panic!("summary.json of the resumed run: {e}\n{said}")),
    )
    .expect("summary.json");
    let whole = format!("{summary:#}\n{said}\n{}", logs_tail(&dir));
    assert!(
        summary["env_steps"].as_u64() >= Some(TOTAL_STEPS),
        "the resumed run ran to its {TOTAL_STEPS} steps:\n{whole}"
    );
    for p in ["sim", "learner", "estimator"] {
        assert_eq!(summary["exit"][p], "exit status: 0", "{p}:\n{whole}");
    }
    // What a finished run leaves, as the quickstart names it (CONCEPTS.md lists it).
    for f in [
        run_dir::CONFIG_TOML,
        run_dir::METRICS_CSV,
        run_dir::CURVES_PNG,
        run_dir::TRACK_CSV,
        run_dir::MAP_PNG,
        run_dir::CHECKPOINTS,
        run_dir::LOGS,
        "launcher",
    ] {
        assert!(dir.join(f).exists(), "the finished run has {f}:\n{whole}");
    }
    assert!(
        std::fs::read_dir(&dir)
            .expect("run dir")
            .flatten()
            .any(|e| e
                .file_name()
                .to_string_lossy()
                .starts_with("events.out.tfevents.")),
        "the learner's TensorBoard events are beside metrics.csv:\n{whole}"
    );
    let updates = support::update_numbers(&dir);
    assert!(
        updates.len() >= 2 && updates.windows(2).all(|w| w[1] > w[0]),
        "one update sequence across the swap and the resume: {updates:?}"
    );
    assert!(
        ipc::run_files(&run).is_empty(),
        "the finished run left shared memory: {:?}",
        ipc::run_files(&run)
    );

    // `lavatube map --run-id demo` draws the finished run's map again.
    std::fs::remove_file(dir.join(run_dir::MAP_PNG)).expect("remove map.png");
    let said = Started::spawn(cwd, &here(map_cmd), log(map_cmd)).succeeds(SHORT_WATCHDOG);
    assert!(
        dir.join(run_dir::MAP_PNG).is_file(),
        "`lavatube map` drew runs/{run}/map.png:\n{said}"
    );

    // `lavatube bench --config configs/bench.toml`, plus `--quick`.
    let mut bench = here(bench_cmd);
    bench.push("--quick".into());
    let said = Started::spawn(cwd, &bench, log(bench_cmd)).succeeds(BENCH_WATCHDOG);
    let written = std::fs::read_dir(cwd.join("runs/bench"))
        .into_iter()
        .flatten()
        .flatten()
        .any(|e| e.path().join("bench.json").is_file());
    assert!(
        written,
        "the bench wrote runs/bench/<id>/bench.json:\n{said}"
    );

    // `lavatube clean [--run-id R]`.
    Started::spawn(cwd, &here(clean_cmd), log(clean_cmd)).succeeds(SHORT_WATCHDOG);
    assert!(
        ipc::run_files(&run).is_empty(),
        "{:?}",
        ipc::run_files(&run)
    );
    eprintln!(
        "quickstart: every command worked, {:.1} s in all",
        started.elapsed().as_secs_f64()
    );
}
