//! The sim's side of `track.csv` (`--track`, see `common::track`): every env's thinned path
//! with the estimator's class, its targets and endings, written at each rollout chunk. A
//! write that fails (a full disk) stops the track with one warning; the sim goes on.

use crate::env::Env;
use common::track::{STRIDE, Seen, TrackPoint, TrackWriter, Tracker};
use common::wire::{self, EnvTick};
use std::path::Path;

pub struct SimTrack {
    tracker: Tracker,
    writer: Option<TrackWriter>,
    points: Vec<TrackPoint>,
}

impl SimTrack {
    /// Appends to `path` (a restarted sim continues the file).
    pub fn append(path: &Path, envs: usize) -> anyhow::Result<Self> {
        let writer = TrackWriter::append(path)
            .map_err(|e| anyhow::anyhow!("track {}: {e}", path.display()))?;
        Ok(Self {
            tracker: Tracker::new(envs, STRIDE),
            writer: Some(writer),
            points: Vec::new(),
        })
    }

    /// Takes one tick of every env from the telemetry it was published as (`ticks`) and the
    /// estimator's `classes`.
    pub fn see(&mut self, envs: &[Env], ticks: &[EnvTick], classes: &[u8]) {
        if self.writer.is_none() {
            return;
        }
        let ends = wire::EVENT_TERMINATED | wire::EVENT_TRUNCATED;
        for ((env, t), &class) in envs.iter().zip(ticks).zip(classes) {
            let ended = t.events & ends != 0;
            self.tracker.see(
                &Seen {
                    env: env.id,
                    tick: env.tick - 1,
                    episode: env.episode_index - u64::from(ended),
                    pos: [t.pos[0], t.pos[2]],
                    target: t.target,
                    class,
                    ended: ended.then_some(t.events & wire::EVENT_SUCCESS != 0),
                },
                &mut self.points,
            );
        }
    }

    /// Writes the points taken since the last call.
    pub fn flush(&mut self) {
        let Some(w) = self.writer.as_mut() else {
            return;
        };
        if let Err(e) = w.write(&self.points) {
            tracing::warn!(path = %w.path().display(), error = %e, "track not written; the map will stop here");
            self.writer = None;
        }
        self.points.clear();
    }
}
