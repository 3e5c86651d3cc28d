//! Where a run's robots went: `track.csv` in the run directory, a thinned record of every
//! env's path with the estimator's class at each point, its targets, and how each episode
//! ended. The sim writes it; the map (`lavatube map`) is drawn from it, or from a telemetry
//! CSV, which holds the same facts at every tick but no class.

use crate::TelemetryRow;
use crate::wire::CLASS_UNKNOWN;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A path point every this many ticks per env: 0.5 s of driving at the paper's 10 Hz.
pub const STRIDE: u64 = 5;

/// What a [`TrackPoint`] marks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mark {
    /// The robot passed here.
    Path,
    /// An episode's target (the first point of each episode).
    Target,
    /// An episode ended here by reaching its target.
    Success,
    /// An episode ended here any other way (time limit, distance, fault).
    Failure,
}

/// One point of `track.csv`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackPoint {
    pub env: u32,
    pub episode: u64,
    pub mark: Mark,
    /// Ground position, metres.
    pub x: f32,
    pub z: f32,
    /// What the path is coloured by at that tick, a terrain kind's code (255: none): the
    /// kind of the specialist that acted, else the estimator's class.
    pub class: u8,
}

/// Thins per-tick positions into [`TrackPoint`]s: every `stride`-th tick of each env, plus
/// every target and episode end.
#[derive(Debug)]
pub struct Tracker {
    stride: u64,
    /// Per env: the episode being tracked (`None` before the first tick) and where it was
    /// at the last tick (an ending tick already shows the next episode's spawn).
    episode: Vec<Option<u64>>,
    last: Vec<[f32; 2]>,
}

/// One env at one tick, as the tracker needs it.
#[derive(Debug, Clone, Copy)]
pub struct Seen {
    pub env: usize,
    pub tick: u64,
    /// The episode this tick belongs to.
    pub episode: u64,
    pub pos: [f32; 2],
    pub target: [f32; 2],
    pub class: u8,
    /// How the episode ended on this tick, if it did: reached its target or not.
    pub ended: Option<bool>,
}

impl Tracker {
    /// A path point every `stride` ticks (at least 1).
    pub fn new(envs: usize, stride: u64) -> Self {
        Self {
            stride: stride.max(1),
            episode: vec![None; envs],
            last: vec![[0.0; 2]; envs],
        }
    }

    /// The points `s` adds (none for an env out of range).
    pub fn see(&mut self, s: &Seen, out: &mut Vec<TrackPoint>) {
        let Some(current) = self.episode.get_mut(s.env) else {
            return;
        };
        let point = |mark, [x, z]: [f32; 2]| TrackPoint {
            env: s.env as u32,
            episode: s.episode,
            mark,
            x,
            z,
            class: s.class,
        };
        if *current != Some(s.episode) {
            *current = Some(s.episode);
            out.push(point(Mark::Target, s.target));
        }
        match s.ended {
            Some(true) => out.push(point(Mark::Success, s.target)),
            Some(false) => out.push(point(Mark::Failure, self.last[s.env])),
            None => {
                if s.tick.is_multiple_of(self.stride) {
                    out.push(point(Mark::Path, s.pos));
                }
                self.last[s.env] = s.pos;
            }
        }
    }
}

/// Appends [`TrackPoint`]s to a `track.csv` (a restarted sim continues the file).
pub struct TrackWriter {
    path: PathBuf,
    writer: csv::Writer<std::fs::File>,
}

impl TrackWriter {
    pub fn append(path: &Path) -> std::io::Result<Self> {
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)?;
        let fresh = file.metadata()?.len() == 0;
        Ok(Self {
            path: path.to_path_buf(),
            writer: csv::WriterBuilder::new()
                .has_headers(fresh)
                .from_writer(file),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes `points` and flushes them, so the file is whole between calls.
    pub fn write(&mut self, points: &[TrackPoint]) -> std::io::Result<()> {
        for p in points {
            self.writer.serialize(p).map_err(std::io::Error::other)?;
        }
        self.writer.flush()
    }
}

/// Reads a `track.csv`; the error names the file and the bad line.
pub fn read(path: &Path) -> Result<Vec<TrackPoint>, String> {
    let mut reader =
        csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    reader
        .deserialize()
        .map(|r| r.map_err(|e| format!("{}: {e}", path.display())))
        .collect()
}

/// The track of a telemetry CSV's rows, classed as the sim's own track is (by the `slot` and
/// `estimate` columns; unknown in recordings without them).
pub fn from_telemetry(rows: &[TelemetryRow], stride: u64) -> Vec<TrackPoint> {
    let envs = rows.iter().map(|r| r.env as usize + 1).max().unwrap_or(0);
    let mut tracker = Tracker::new(envs, stride);
    let mut out = Vec::new();
    for r in rows {
        let ended = r.terminated || r.truncated;
        tracker.see(
            &Seen {
                env: r.env as usize,
                tick: r.tick,
                episode: r.episode,
                pos: [r.x as f32, r.z as f32],
                target: [r.target_x as f32, r.target_z as f32],
                class: r
                    .slot
                    .and_then(crate::config::PolicySlot::kind)
                    .or(r.estimate)
                    .map_or(CLASS_UNKNOWN, crate::AreaKind::code),
                ended: ended.then_some(r.success),
            },
            &mut out,
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::AreaKind;

    fn seen(tick: u64, episode: u64, x: f32, ended: Option<bool>) -> Seen {
        Seen {
            env: 0,
            tick,
            episode,
            pos: [x, 0.0],
            target: [5.0, 5.0],
            class: 1,
            ended,
        }
    }

    #[test]
    fn thinned_paths_keep_every_target_and_ending() {
        let mut t = Tracker::new(1, 3);
        let mut out = Vec::new();
        for tick in 0..7 {
            t.see(&seen(tick, 0, tick as f32, None), &mut out);
        }
        // The ending tick already shows the next episode's spawn: the failure is marked
        // where the robot was the tick before.
        t.see(&seen(7, 0, 100.0, Some(false)), &mut out);
        t.see(&seen(8, 1, 0.5, Some(true)), &mut out);
        let marks: Vec<(Mark, f32)> = out.iter().map(|p| (p.mark, p.x)).collect();
        assert_eq!(
            marks,
            [
                (Mark::Target, 5.0),
                (Mark::Path, 0.0),
                (Mark::Path, 3.0),
                (Mark::Path, 6.0),
                (Mark::Failure, 6.0),
                (Mark::Target, 5.0),
                (Mark::Success, 5.0),
            ]
        );
        assert!(out.iter().all(|p| p.class == 1));
    }

    #[test]
    fn track_files_round_trip() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("track.csv");
        let mut out = Vec::new();
        let mut t = Tracker::new(1, 1);
        t.see(&seen(0, 0, 1.5, None), &mut out);
        TrackWriter::append(&path)
            .expect("open")
            .write(&out)
            .expect("write");
        TrackWriter::append(&path)
            .expect("reopen")
            .write(&out)
            .expect("write");
        let back = read(&path).expect("read");
        assert_eq!(back.len(), 2 * out.len(), "one header, rows appended");
        assert_eq!(back[..out.len()], out[..]);
        std::fs::write(&path, "env,episode\n1,x\n").expect("write");
        let err = read(&path).expect_err("bad file");
        assert!(err.contains("track.csv"), "{err}");
    }

    #[test]
    fn a_telemetry_track_is_classed_by_the_acting_specialist_else_the_estimate() {
        use crate::config::PolicySlot;
        let row = |tick, slot, estimate| TelemetryRow {
            tick,
            slot,
            estimate,
            ..TelemetryRow::default()
        };
        let rows = [
            row(0, None, None),
            row(1, Some(PolicySlot::General), Some(AreaKind::Rough)),
            row(2, Some(PolicySlot::Slope), Some(AreaKind::Rough)),
            row(3, Some(PolicySlot::General), None),
        ];
        let classes: Vec<u8> = from_telemetry(&rows, 1)
            .iter()
            .filter(|p| p.mark == Mark::Path)
            .map(|p| p.class)
            .collect();
        let (rough, slope) = (AreaKind::Rough.code(), AreaKind::Slope.code());
        assert_eq!(classes, [CLASS_UNKNOWN, rough, slope, CLASS_UNKNOWN]);
    }
}
