//! The sim's side of `track.csv` (`--track`, see `common::track`): every env's thinned path
//! with the estimator's class, its targets and endings, written at each rollout chunk. A
//! write that fails (a full disk) stops the track with one warning; the sim goes on.

use crate::env::{Env, StepInfo};
use crate::task::Ending;
use common::track::{STRIDE, Seen, TrackPoint, TrackWriter, Tracker};
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

    /// Takes one tick of every env: `infos` from the step, `classes` the estimator's.
    pub fn see(&mut self, envs: &[Env], infos: &[StepInfo], classes: &[u8]) {
        if self.writer.is_none() {
            return;
        }
        for ((env, info), &class) in envs.iter().zip(infos).zip(classes) {
            let p = env.pose().pos;
            let ended = info.ending.is_some();
            self.tracker.see(
                &Seen {
                    env: env.id,
                    tick: env.tick - 1,
                    episode: env.episode_index - u64::from(ended),
                    pos: [p[0] as f32, p[2] as f32],
                    target: [info.target[0] as f32, info.target[1] as f32],
                    class,
                    ended: ended.then_some(info.ending == Some(Ending::Success)),
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
