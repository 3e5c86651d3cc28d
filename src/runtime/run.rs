//! [`Run`]: one run of the system, from a resolved config to its summary. It creates the run
//! directory, starts every process of the run under its restart policy, shows progress from
//! the run's own telemetry, answers learner swaps, and ends with the stop ladder, the run's
//! shared memory removed and `summary.json` written.

use super::board::Board;
use super::console::{self, Rate, Summaries};
use super::swap::{SwapContext, learner_args, swap_learner};
use super::{
    Binaries, Event, Host, Lines, Progress, Role, Spec, Summary, Supervised, coverage_line, ladder,
    say,
};
use crate::error::UserError;
use anyhow::Context;
use common::config::{Acting, AreaKind, PolicySlot, RestartPolicy};
use common::coverage::Coverage;
use common::ipc::{self, Bus, Receiver, SwapServer};
use common::wire::{EnvTick, PolicyHeader, SwapReply, TerrainEstimate, TerrainHeader, TickHeader};
use common::{Config, run_dir};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The launcher's node name on a run's bus: a live one means the run id is taken.
pub const LAUNCHER_NODE: &str = "launcher";

/// A run, prepared: its id checked, its directory made, its resolved config written.
pub struct Run<'a> {
    cfg: &'a Config,
    id: String,
    dir: PathBuf,
    logs: PathBuf,
    cfg_path: PathBuf,
    bins: Binaries,
    bar: ProgressBar,
    /// Going on from the run directory's checkpoints (`lavatube run --resume`).
    resume: bool,
    /// This host's part of the run.
    host: Host,
    /// Which of the children's log lines reach the terminal.
    lines: Lines,
}

/// A run directory to resume: its resolved config, and its run id (the directory's name).
#[derive(Debug)]
pub struct ResumedConfig {
    pub cfg: Config,
    pub run_id: String,
    pub dir: PathBuf,
}

impl ResumedConfig {
    /// Reads `dir/config.toml`. Fails in one line when `dir` is no run directory.
    pub fn load(dir: &Path) -> anyhow::Result<Self> {
        let dir = std::path::absolute(dir)
            .with_context(|| format!("cannot resolve {}", dir.display()))?;
        let cfg_path = dir.join(run_dir::CONFIG_TOML);
        if !cfg_path.is_file() {
            return Err(UserError(format!(
                "--resume {}: not a run directory (no config.toml)",
                dir.display()
            ))
            .into());
        }
        let run_id = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        ipc::validate_run_id(&run_id)
            .map_err(|e| UserError(format!("--resume {}: {e}", dir.display())))?;
        Ok(Self {
            cfg: Config::load(&cfg_path)?,
            run_id,
            dir,
        })
    }
}

/// How a run ended.
#[derive(Debug)]
pub struct Finished {
    pub summary: Summary,
    /// Stopped by Ctrl-C (or SIGTERM) before it finished.
    pub interrupted: bool,
}

impl<'a> Run<'a> {
    /// Prepares `cfg` in `<run.out-dir>/<dir_name>/`, its processes to meet in the shared
    /// memory of run `run_id`. Fails before anything starts when a live run already uses
    /// `run_id`, the directory exists, or a binary is missing.
    pub fn prepare(
        cfg: &'a Config,
        dir_name: &str,
        run_id: &str,
        quiet: bool,
    ) -> anyhow::Result<Self> {
        // Absolute, so logs and the children's arguments name it unambiguously.
        let dir = std::path::absolute(cfg.run.out_dir.join(dir_name))
            .with_context(|| format!("cannot resolve {}", cfg.run.out_dir.display()))?;
        if dir.exists() {
            return Err(UserError(format!(
                "run directory {} already exists: pick another --run-id",
                dir.display()
            ))
            .into());
        }
        let run = Self::open(cfg, run_id, dir, quiet)?;
        std::fs::create_dir_all(&run.logs)
            .with_context(|| format!("cannot create {}", run.logs.display()))?;
        std::fs::write(&run.cfg_path, cfg.to_toml())
            .with_context(|| format!("cannot write {}", run.cfg_path.display()))?;
        Ok(run)
    }

    /// Prepares the run in `dir` to go on where it stopped (see [`ResumedConfig`]): same
    /// config and run id, each learner from its newest checkpoint, the sim counting on from
    /// the steps that checkpoint had learned from.
    pub fn resume(resumed: &'a ResumedConfig, quiet: bool) -> anyhow::Result<Self> {
        let mut run = Self::open(&resumed.cfg, &resumed.run_id, resumed.dir.clone(), quiet)?;
        run.resume = true;
        std::fs::create_dir_all(&run.logs)
            .with_context(|| format!("cannot create {}", run.logs.display()))?;
        Ok(run)
    }

    fn open(cfg: &'a Config, run_id: &str, dir: PathBuf, quiet: bool) -> anyhow::Result<Self> {
        let bins = Binaries::locate()?;
        // Two runs on one id would read each other's messages and remove each other's shared
        // memory at the end. Other nodes (monitors, tests watching the run) may come first.
        let live: Vec<String> = ipc::list_nodes(run_id)
            .unwrap_or_default()
            .into_iter()
            .filter(|n| n.alive && n.name == LAUNCHER_NODE)
            .map(|n| format!("{} (pid {})", n.name, n.pid))
            .collect();
        if !live.is_empty() {
            return Err(UserError(format!(
                "run id `{run_id}` is in use by a live run ({}): pick another --run-id",
                live.join(", ")
            ))
            .into());
        }
        let bar = if quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::new(cfg.run.total_steps)
        };
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} {elapsed_precise} [{bar:30}] {human_pos}/{human_len} steps · {msg} · ETA {eta}",
            )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Ok(Self {
            cfg,
            id: run_id.to_string(),
            logs: dir.join(run_dir::LOGS),
            cfg_path: dir.join(run_dir::CONFIG_TOML),
            dir,
            bins,
            bar,
            resume: false,
            host: Host::Whole,
            lines: Lines::Notices,
        })
    }

    /// Runs only this host's part of the run (DESIGN §9).
    pub fn on_host(mut self, host: Host) -> Self {
        self.host = host;
        self
    }

    /// Shows every log line of the children, not only their warnings and errors.
    pub fn verbose(mut self, verbose: bool) -> Self {
        if verbose {
            self.lines = Lines::All;
        }
        self
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Every process of this host's part of the run: learners (then frozen ones),
    /// estimator, bridge, sim last, so the sim's first chunk finds its readers.
    fn specs(&self) -> Vec<Spec> {
        let (cfg, sup) = (self.cfg, &self.cfg.supervise);
        let join = |extra: &[&str]| -> Vec<String> {
            let mut v: Vec<String> = extra.iter().map(std::string::ToString::to_string).collect();
            v.extend([
                "--config".into(),
                self.cfg_path.display().to_string(),
                "--run-id".into(),
                self.id.clone(),
            ]);
            v
        };
        let spec = |role: Role, args: Vec<String>, policy| Spec {
            role,
            bin: self.bins.of(role).clone(),
            args,
            policy,
        };
        let mut specs: Vec<Spec> = cfg
            .run
            .learners
            .iter()
            .map(|&slot| {
                let mut join = join(&["serve", "--slot", slot.name()]);
                if let Host::Learner { .. } = self.host {
                    join.extend(["--sources".into(), cfg.net.sim_hosts.to_string()]);
                }
                if let Some(init) = cfg.run.warm_start(slot) {
                    join.extend(["--init-from".into(), init.display().to_string()]);
                }
                let args = learner_args(&join, &run_dir::learner_dir(&self.dir, slot), None);
                spec(Role::Learner(slot), args, sup.learner)
            })
            .collect();
        specs.extend(cfg.run.frozen.iter().map(|(&slot, ckpt)| {
            let join = join(&["serve", "--slot", slot.name(), "--frozen"]);
            let args = learner_args(&join, &run_dir::learner_dir(&self.dir, slot), Some(ckpt));
            spec(Role::Learner(slot), args, sup.learner)
        }));
        if cfg.run.estimator {
            specs.push(spec(Role::Estimator, join(&["serve"]), sup.estimator));
        }
        if let Some(file) = &cfg.run.record {
            let mut args = join(&["serve"]);
            args.extend(["--out".into(), self.dir.join(file).display().to_string()]);
            // Never restarted: a new recorder would start the file over.
            specs.push(spec(Role::Recorder, args, RestartPolicy::NEVER));
        }
        if let Some(args) = self.host.bridge_args() {
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            // The bridge restarts like a learner: its peers on the other hosts wait for it.
            specs.push(spec(Role::Bridge, join(&args), sup.learner));
        }
        let mut sim_args = join(&[]);
        if self.resume {
            sim_args.push("--resume".into());
        }
        if self.host.source() != 0 {
            sim_args.extend(["--source".into(), self.host.source().to_string()]);
        }
        sim_args.extend([
            "--track".into(),
            self.dir.join(run_dir::TRACK_CSV).display().to_string(),
        ]);
        if cfg.sim.randomize.is_active() {
            sim_args.extend([
                "--worlds".into(),
                self.dir.join(run_dir::WORLDS_CSV).display().to_string(),
            ]);
        }
        if cfg.run.telemetry_csv {
            sim_args.extend([
                "--telemetry".into(),
                self.dir.join(run_dir::TELEMETRY_CSV).display().to_string(),
            ]);
        }
        specs.push(spec(Role::Sim, sim_args, sup.sim));
        specs.retain(|s| self.host.starts(s.role));
        specs
    }

    /// Runs to the end: until the sim has finished and the learners have learned from its
    /// last chunk, a process fails for good, or Ctrl-C. Fails when a process failed for good.
    pub fn execute(self) -> anyhow::Result<Finished> {
        self.announce();
        let bus = Bus::connect(&self.id, LAUNCHER_NODE)?;
        let control = bus.control_notifier()?;
        let ports = Ports::open(&bus, &self.cfg.run.learners)?;
        let grace = Duration::from_millis(self.cfg.supervise.grace_ms);
        let members = self.start_members(grace)?;

        let started = Instant::now();
        let mut loop_ = Supervision::new(&self, &bus, members, grace);
        let interrupted = loop_.until_done(&ports)?;
        loop_.show_progress(&ports)?;
        let Supervision {
            mut members,
            progress,
            failed,
            swaps,
            rate_now,
            mut board,
            ..
        } = loop_;
        let steps = progress.tick.env_steps.max(progress.learned_steps);
        if let Some(e) = board.write(&progress, steps, rate_now, true) {
            eprintln!("lavatube: {e}");
        }
        stop_all(
            &mut members,
            &|| {
                if let Err(e) = ipc::request_shutdown(&control) {
                    eprintln!("lavatube: {e}");
                }
            },
            grace,
        );
        self.bar.finish_and_clear();
        drop((ports, control, bus));
        if let Err(e) = ipc::remove_run(&self.id) {
            eprintln!("lavatube: {e}");
        }

        let summary = Summary::of(
            &self.id,
            &progress,
            self.cfg.sim.decision_dt(),
            started.elapsed().as_secs_f64(),
            swaps,
        );
        let summary = self.report(summary, &members)?;
        if let Some(f) = failed {
            anyhow::bail!("{f}; logs in {}", self.logs.display());
        }
        Ok(Finished {
            summary,
            interrupted,
        })
    }

    /// Says which run starts, how, and where its directory is.
    fn announce(&self) {
        say(
            &self.bar,
            format!(
                "run {}{}: {}, {:?} mode → {}",
                self.id,
                if self.resume { " (resumed)" } else { "" },
                self.cfg.sim.describe_envs(),
                self.cfg.run.mode,
                self.dir.display()
            ),
        );
    }

    /// Starts every process of this host's part of the run in [`Self::specs`]'s order; when
    /// one cannot start, stops those already started.
    fn start_members(&self, grace: Duration) -> anyhow::Result<Vec<Supervised>> {
        let mut members: Vec<Supervised> = Vec::new();
        for spec in self.specs() {
            match Supervised::start(spec, &self.logs, &self.bar, self.lines) {
                Ok(s) => members.push(s),
                Err(e) => {
                    stop_all(&mut members, &|| {}, grace);
                    return Err(e);
                }
            }
        }
        if self.lines == Lines::All {
            let pids: Vec<String> = members
                .iter()
                .map(|s| format!("{} {}", s.role().name(), s.child.pid()))
                .collect();
            say(&self.bar, format!("pids: {}", pids.join(", ")));
        }
        Ok(members)
    }

    /// Completes `summary` with each member's pid, exit and restarts and writes it to
    /// `summary.json`, draws the run's map, and prints the summary line and any learner's
    /// failed writes.
    fn report(&self, mut summary: Summary, members: &[Supervised]) -> anyhow::Result<Summary> {
        for m in members {
            let name = m.role().name().to_string();
            summary.pids.insert(name.clone(), m.child.pid());
            summary
                .exit
                .insert(name.clone(), m.child.status().map(|s| s.to_string()));
            summary.restarts.insert(name, m.restarts);
        }
        let telemetry = self.dir.join(run_dir::TELEMETRY_CSV);
        if self.cfg.sim.acting == Acting::Switch
            && self.host.starts(Role::Sim)
            && telemetry.is_file()
        {
            match Coverage::of_files(&[telemetry], &self.cfg.sim) {
                Ok(c) => {
                    println!("{}", coverage_line(&c, self.cfg.sim.decision_dt()));
                    summary.switching = Some(c);
                }
                Err(e) => eprintln!("lavatube: no switching coverage: {e}"),
            }
        }
        let path = self.dir.join(run_dir::SUMMARY_JSON);
        std::fs::write(&path, serde_json::to_string_pretty(&summary)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
        // After the summary: on a full disk the summary matters more than the picture.
        if self.host.starts(Role::Sim)
            && let Err(e) = super::map::draw_run(&self.cfg.sim, &self.dir)
        {
            eprintln!("lavatube: no map: {e:#}");
        }
        println!("{}", summary.line(&self.dir));
        for (learner, n) in summary.write_failures.iter().filter(|(_, n)| **n > 0) {
            eprintln!(
                "lavatube: {learner}: {n} checkpoint or metrics write(s) failed (disk full?); see {}",
                run_dir::log_file(&self.dir, learner).display()
            );
        }
        Ok(summary)
    }
}

/// The launcher's ports on the run's bus.
struct Ports {
    telemetry: Receiver<EnvTick, TickHeader>,
    terrain: Receiver<TerrainEstimate, TerrainHeader>,
    /// Each training learner's policies, for the writes it could not make.
    policies: Vec<(PolicySlot, Receiver<f32, PolicyHeader>)>,
    swap: SwapServer,
}

impl Ports {
    /// Subscribes to the run's telemetry, terrain estimates and the policies of `learners`,
    /// and serves swap requests.
    fn open(bus: &Bus, learners: &[PolicySlot]) -> anyhow::Result<Self> {
        Ok(Self {
            telemetry: bus.receiver(&ipc::TELEMETRY, None)?,
            terrain: bus.receiver(&ipc::TERRAIN, None)?,
            policies: learners
                .iter()
                .map(|&slot| Ok((slot, bus.receiver(&ipc::POLICY, Some(slot.name()))?)))
                .collect::<anyhow::Result<_>>()?,
            swap: bus.swap_server()?,
        })
    }
}

/// The run while it runs: its processes and what they have said.
struct Supervision<'r, 'a> {
    run: &'r Run<'a>,
    bus: &'r Bus,
    members: Vec<Supervised>,
    progress: Progress,
    /// Why the run failed, once a process failed for good.
    failed: Option<String>,
    swaps: u32,
    sim_finished: Option<Instant>,
    grace: Duration,
    rate: Rate,
    /// The newest steps/s, for the launcher's last scalars.
    rate_now: Option<f64>,
    board: Board,
    summaries: Summaries,
}

impl<'r, 'a> Supervision<'r, 'a> {
    /// The run's `members` just started, nothing heard from them yet.
    fn new(run: &'r Run<'a>, bus: &'r Bus, members: Vec<Supervised>, grace: Duration) -> Self {
        let sim = &run.cfg.sim;
        Self {
            run,
            bus,
            members,
            progress: Progress {
                both_areas: (sim.envs_in(AreaKind::Flat) > 0 && sim.envs_in(AreaKind::Rough) > 0)
                    || sim.envs_in(AreaKind::Mixed) > 0,
                ..Progress::default()
            },
            failed: None,
            swaps: 0,
            sim_finished: None,
            grace,
            rate: Rate::default(),
            rate_now: None,
            board: Board::new(&run.dir),
            summaries: Summaries::new(&run.dir, &run.cfg.run.learners, run.cfg.run.summary_every),
        }
    }

    /// Loops until the run is done; whether it was interrupted.
    fn until_done(&mut self, ports: &Ports) -> anyhow::Result<bool> {
        loop {
            self.show_progress(ports)?;
            self.watch_members()?;
            if let Some(request) = ports.swap.receive()? {
                let req = *request.payload();
                let (ok, message) = self.swap(&req);
                say(&self.run.bar, format!("swap-learner: {message}"));
                if let Err(e) = request.send_copy(SwapReply::new(ok, &message)) {
                    say(&self.run.bar, format!("swap-learner: cannot reply: {e:?}"));
                }
            }
            let alive = |pick: &dyn Fn(Role) -> bool| {
                self.members.iter().any(|s| pick(s.role()) && s.alive())
            };
            // What takes the sim's last chunk: the learners, or on a sim host its bridge,
            // which ends once that chunk is out.
            let taker_alive = alive(&|r| r.is_learner() || r == Role::Bridge);
            // Once the sim is done they get one grace period to take the last chunk.
            let taker_late = self.sim_finished.is_some_and(|t| t.elapsed() > self.grace);
            // A learner host has no sim: its run ends when its learners have finished.
            let learner_host_done =
                !self.run.host.starts(Role::Sim) && !alive(&|r: Role| r.is_learner());
            if self.failed.is_some()
                || learner_host_done
                || (self.sim_finished.is_some() && (!taker_alive || taker_late))
            {
                return Ok(false);
            }
            if self.bus.node().wait(Duration::from_millis(100)).is_err() {
                say(&self.run.bar, "interrupted: stopping the run".into());
                return Ok(true);
            }
        }
    }

    fn show_progress(&mut self, ports: &Ports) -> anyhow::Result<()> {
        if let Some(s) = ports.telemetry.latest()? {
            self.progress.tick = *s.user_header();
        }
        if let Some(s) = ports.terrain.latest()? {
            self.progress.terrain = *s.user_header();
        }
        for (slot, rx) in &ports.policies {
            if let Some(s) = rx.latest()? {
                let h = s.user_header();
                let w = self.progress.write_failures.entry(*slot).or_default();
                w.saw(h.learner, h.write_failures);
                self.progress.learned_steps = self.progress.learned_steps.max(h.env_steps);
                self.progress.learned_version = self.progress.learned_version.max(h.version);
            }
        }
        let p = &self.progress;
        let bar = &self.run.bar;
        // A learner host sees no telemetry: its progress is what its learners learned from.
        let steps = p.tick.env_steps.max(p.learned_steps);
        bar.set_position(steps.min(self.run.cfg.run.total_steps));
        let rate = self.rate.update(Instant::now(), steps);
        self.rate_now = rate;
        bar.set_message(console::bar_message(p, rate));
        if let Some(e) = self.board.write(p, steps, rate, false) {
            say(bar, format!("lavatube: {e}"));
        }
        self.summaries.print_due(bar);
        Ok(())
    }

    /// Looks at every member once, in order, and acts on what happened to each.
    fn watch_members(&mut self) -> anyhow::Result<()> {
        let may_restart = self.sim_finished.is_none();
        for i in 0..self.members.len() {
            let (logs, bar) = (&self.run.logs, &self.run.bar);
            if let Some(event) = self.members[i].watch(logs, bar, may_restart)? {
                self.on_event(i, event, may_restart);
            }
        }
        Ok(())
    }

    /// What `event` of member `i` means for the run: a line above the progress bar, the
    /// sim's finish, or the run's failure.
    fn on_event(&mut self, i: usize, event: Event, may_restart: bool) {
        let m = &self.members[i];
        let (role, name) = (m.role(), m.role().name());
        let bar = &self.run.bar;
        match event {
            Event::Restarting {
                status,
                after,
                recent,
            } => {
                let cleaned = self.bus.cleanup_dead_nodes();
                let budget = restart_budget(&m.spec.policy, recent);
                say(
                    bar,
                    format!(
                        "{name} exited with {status}; restart {} ({budget}) in {:.1} s ({cleaned} dead node(s) cleaned up)",
                        m.restarts + 1,
                        after.as_secs_f64()
                    ),
                );
            }
            Event::Restarted { pid } => {
                say(bar, format!("{name} restarted: pid {pid}"));
            }
            Event::Exited(status) if role == Role::Sim && status.success() => {
                self.sim_finished = Some(Instant::now());
            }
            Event::Exited(status) if role == Role::Estimator && may_restart => {
                // DESIGN §5: without estimates the sim keeps acting on its last ones.
                self.bus.cleanup_dead_nodes();
                say(
                    bar,
                    format!(
                        "estimator exited with {status} for good; the sim keeps its last terrain estimates"
                    ),
                );
            }
            Event::Exited(status) if role == Role::Recorder && !status.success() => {
                say(
                    bar,
                    format!(
                        "recorder exited with {status}; the run goes on without its recording (see its log)"
                    ),
                );
            }
            Event::Exited(status) if !status.success() && self.failed.is_none() => {
                self.failed = Some(format!("{name} exited with {status}"));
            }
            Event::Exited(_) => {}
        }
    }

    /// Answers one swap request: whether it happened, and what to tell the requester.
    fn swap(&mut self, req: &common::wire::SwapRequest) -> (bool, String) {
        let slot = match requested_slot(req) {
            Ok(slot) => slot,
            Err(refusal) => return (false, refusal),
        };
        let Some(learner) = self
            .members
            .iter_mut()
            .find(|m| m.role() == Role::Learner(slot))
        else {
            return (false, format!("this run has no {}", slot.learner_name()));
        };
        let ctx = SwapContext {
            running: self.run.cfg,
            run_dir: &self.run.dir,
            logs: &self.run.logs,
            bar: &self.run.bar,
            grace: self.grace,
        };
        match swap_learner(learner, req, self.swaps + 1, &ctx) {
            Ok(m) => {
                self.swaps += 1;
                self.bus.cleanup_dead_nodes();
                (true, m)
            }
            Err(m) => (false, m),
        }
    }
}

/// The slot a swap request names, or its refusal when the index names no slot.
fn requested_slot(req: &common::wire::SwapRequest) -> Result<PolicySlot, String> {
    PolicySlot::from_index(req.slot).ok_or_else(|| {
        let names: Vec<_> = PolicySlot::ALL
            .iter()
            .map(|s| format!("{} {}", s.index(), s.name()))
            .collect();
        format!(
            "no policy slot {}: the slots are {}",
            req.slot,
            names.join(", ")
        )
    })
}

/// How many restarts `policy` allows and how many of them `recent` has used.
fn restart_budget(policy: &RestartPolicy, recent: u32) -> String {
    policy.window().map_or_else(
        || format!("{recent} of {} in this run", policy.max_restarts),
        |w| {
            format!(
                "{recent} of {} within {} s",
                policy.max_restarts,
                w.as_secs()
            )
        },
    )
}

/// Stops every member's process (see [`ladder::stop`]).
fn stop_all(members: &mut [Supervised], request: &dyn Fn(), grace: Duration) {
    let mut children: Vec<_> = members.iter_mut().map(|m| &mut m.child).collect();
    ladder::stop(&mut children, request, grace);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_swap_for_a_slot_past_the_last_is_refused_not_clamped() {
        let mut req = common::wire::SwapRequest {
            slot: 5,
            ..Default::default()
        };
        assert_eq!(requested_slot(&req), Ok(PolicySlot::Sand));
        req.slot = 6;
        assert_eq!(
            requested_slot(&req),
            Err("no policy slot 6: the slots are 0 general, 1 flat, 2 rough, 3 slope, 4 gravel, 5 sand".into())
        );
    }
}
