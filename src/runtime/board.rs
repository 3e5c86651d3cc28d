//! The launcher's own TensorBoard scalars, in `<run dir>/launcher/` (a run of its own in
//! TensorBoard, beside each learner's): what only the launcher sees across processes.

use super::Progress;
use common::tensorboard::EventWriter;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The launcher's TensorBoard directory in a run directory.
pub const LAUNCHER_EVENTS: &str = "launcher";

/// Writes the launcher's scalars every few seconds. A file that cannot be made or written is
/// reported once; the run goes on without it.
pub struct Board {
    dir: PathBuf,
    events: Option<EventWriter>,
    failed: bool,
    last: Option<Instant>,
}

impl Board {
    const EVERY: Duration = Duration::from_secs(2);

    /// The scalars of the run in `run_dir`; the file is made at the first write.
    pub fn new(run_dir: &std::path::Path) -> Self {
        Self {
            dir: run_dir.join(LAUNCHER_EVENTS),
            events: None,
            failed: false,
            last: None,
        }
    }

    /// Writes the scalars at `steps` if they are due (always when `last`, the run's end); the
    /// error, the first time one fails.
    pub fn write(
        &mut self,
        p: &Progress,
        steps: u64,
        rate: Option<f64>,
        last: bool,
    ) -> Option<String> {
        let now = Instant::now();
        let due = last
            || self
                .last
                .is_none_or(|t| now.duration_since(t) >= Self::EVERY);
        if self.failed || !due {
            return None;
        }
        self.last = Some(now);
        let mut values = vec![
            (
                "lavatube/policy_lag",
                f64::from(p.learned_version.saturating_sub(p.tick.policy_version)),
            ),
            ("Environment/Success Rate", p.episodes().success_rate()),
        ];
        values.extend(rate.map(|r| ("lavatube/steps_per_second", r)));
        values.extend(
            p.terrain_accuracy()
                .map(|a| ("lavatube/terrain_accuracy", a)),
        );
        let written = match &mut self.events {
            Some(e) => e.scalars(steps, &values),
            None => EventWriter::create(&self.dir)
                .and_then(|e| self.events.insert(e).scalars(steps, &values)),
        };
        let e = written.err()?;
        self.failed = true;
        Some(format!(
            "the launcher's TensorBoard events in {} stop: {e}",
            self.dir.display()
        ))
    }
}
