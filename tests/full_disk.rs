//! DESIGN §4 on a full disk: a run whose directory sits on a 2 MiB tmpfs fills it with
//! checkpoints. The learner says so once in its log, keeps training and publishing, retries at
//! every checkpoint, and the newest checkpoint on disk stays whole and loadable; the run's
//! summary counts the failed writes. Needs root (CI runs as root) to mount the tmpfs.

use common::Config;
use common::run_dir;
use common::wire::PolicyHeader;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

mod support;

const PATIENCE: Duration = Duration::from_secs(180);

/// A tmpfs of `size` mounted at a directory of its own, unmounted and removed on drop.
struct Tmpfs(PathBuf);

impl Tmpfs {
    fn mount(dir: PathBuf, size: &str) -> Self {
        std::fs::create_dir_all(&dir).expect("mount point");
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(&dir)
            .output()
            .expect("mount runs");
        assert!(
            out.status.success(),
            "mount: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Self(dir)
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
        let _ = std::fs::remove_dir(&self.0);
    }
}

/// The newest checkpoint file in `dir`, by its update number.
fn newest_checkpoint(dir: &Path) -> PathBuf {
    std::fs::read_dir(dir)
        .expect("checkpoints")
        .filter_map(|e| {
            let p = e.ok()?.path();
            let n = run_dir::parse_checkpoint_file(&p.file_name()?.to_string_lossy())?;
            Some((n, p))
        })
        .max()
        .expect("a checkpoint")
        .1
}

#[test]
fn a_full_disk_costs_checkpoints_not_training() {
    // SAFETY: geteuid(2) has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        eprintln!("skipped: mounting a tmpfs needs root");
        return;
    }
    let run = format!("fulldisk-{}", std::process::id());
    let disk = Tmpfs::mount(
        support::root().join("target").join(format!("{run}-disk")),
        "2m",
    );
    let fixture = std::fs::read_to_string(support::root().join("tests/fixtures/survival.toml"))
        .expect("fixture");
    let mut cfg = Config::parse(&fixture, Path::new("survival.toml")).expect("fixture parses");
    cfg.run.out_dir = disk.0.clone();
    let cfg_dir = tempfile::tempdir().expect("tempdir");
    let cfg_path = cfg_dir.path().join("full-disk.toml");
    std::fs::write(&cfg_path, cfg.to_toml()).expect("config");

    let launcher = support::Launched::run(
        &[
            "--config",
            &cfg_path.display().to_string(),
            "--run-id",
            &run,
        ],
        &run,
    );
    let watch = support::Watch::connect(&run, "monitor");
    let (ticks, policies) = (&watch.ticks, &watch.policies);
    let give_up = Instant::now() + PATIENCE;
    let mut failed_at = None;
    let mut newest = PolicyHeader::default();
    while failed_at.is_none_or(|v| newest.version < v + 3) {
        assert!(
            Instant::now() < give_up,
            "no training past a full disk: {newest:?}"
        );
        ticks.wait(Duration::from_millis(10)).expect("wait");
        while ticks.try_recv().expect("telemetry").is_some() {}
        while let Some(p) = policies.try_recv().expect("policy") {
            newest = *p.user_header();
            if newest.write_failures > 0 {
                failed_at.get_or_insert(newest.version);
            }
        }
    }
    drop(watch);
    let (code, said) = launcher.wait_interrupted();
    assert_eq!(code, 130, "{said}");

    let dir = disk.0.join(&run);
    let log = std::fs::read_to_string(run_dir::log_file(&dir, "learner")).expect("learner log");
    let errors = log.lines().filter(|l| l.contains("write failed")).count();
    assert!(errors >= 1, "the failure is in the log:\n{log}");
    assert!(
        errors < 5,
        "one line per spell of failures, not one per update: {errors}"
    );
    let ckpt = newest_checkpoint(&dir.join(run_dir::CHECKPOINTS));
    learner_proc::Learner::load_checkpoint(&cfg, &ckpt)
        .unwrap_or_else(|e| panic!("{} is not loadable: {e}", ckpt.display()));
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join(run_dir::SUMMARY_JSON)).expect("summary"),
    )
    .expect("summary json");
    assert!(
        summary["write_failures"]["learner"].as_u64() >= Some(1),
        "{summary}"
    );
    assert!(said.contains("write(s) failed"), "{said}");
}
