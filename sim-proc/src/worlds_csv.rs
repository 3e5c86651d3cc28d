//! `worlds.csv` (`--worlds`, in a run with `[sim.randomize]`): the world every episode of
//! every env drew, one row each (`env,episode,` then [`WorldDraw::columns`]), so a failure
//! can be traced to the world it happened in. A write that fails (a full disk) stops the
//! file with one warning; the sim goes on.

use crate::env::Env;
use crate::randomize::WorldDraw;
use std::path::{Path, PathBuf};

pub struct WorldsCsv {
    path: PathBuf,
    writer: Option<csv::Writer<std::fs::File>>,
    /// Per env, the episodes recorded so far.
    recorded: Vec<u64>,
}

impl WorldsCsv {
    /// Appends to `path`, with the header only if the file is empty (a restarted sim writes
    /// its episodes again from its first).
    pub fn append(path: &Path, envs: usize) -> anyhow::Result<Self> {
        let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("worlds {}: {e}", path.display());
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| err(&e))?;
        let fresh = file.metadata().map_err(|e| err(&e))?.len() == 0;
        let mut writer = csv::WriterBuilder::new().from_writer(file);
        if fresh {
            let header = ["env", "episode"].map(String::from);
            let columns = header.into_iter().chain(WorldDraw::columns());
            writer.write_record(columns).map_err(|e| err(&e))?;
        }
        Ok(Self {
            path: path.to_path_buf(),
            writer: Some(writer),
            recorded: vec![0; envs],
        })
    }

    /// Records the worlds of the episodes each env has started since the last call, the
    /// current one included.
    pub fn see(&mut self, envs: &[Env]) {
        let Some(w) = self.writer.as_mut() else {
            return;
        };
        let mut written = Ok(());
        for (env, recorded) in envs.iter().zip(&mut self.recorded) {
            for episode in *recorded..=env.episode_index {
                let Some(world) = env.world_of(episode) else {
                    return;
                };
                let row = [env.id as f64, episode as f64]
                    .into_iter()
                    .chain(world.values())
                    .map(|v| v.to_string());
                written = written.and(w.write_record(row));
            }
            *recorded = env.episode_index + 1;
        }
        if let Err(e) = written {
            self.stop(&e);
        }
    }

    /// Writes the rows buffered so far.
    pub fn flush(&mut self) {
        if let Some(Err(e)) = self.writer.as_mut().map(csv::Writer::flush) {
            self.stop(&e);
        }
    }

    fn stop(&mut self, e: &dyn std::fmt::Display) {
        tracing::warn!(path = %self.path.display(), error = %e, "worlds not written: episodes from here on are not recorded");
        self.writer = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SharedTerrain;
    use common::config::SimConfig;

    #[test]
    fn every_episode_of_every_env_is_recorded_once_with_its_draw() {
        let mut cfg = SimConfig {
            envs: [(common::AreaKind::Flat, 2)].into(),
            ..SimConfig::default()
        };
        cfg.randomize.mass_scale = [0.5, 2.0];
        cfg.task.stall_steps = 3;
        let terrain = SharedTerrain::new(
            crate::terrain::Terrain::procedural(&cfg.terrain),
            cfg.terrain.collider,
        );
        let mut envs: Vec<Env> = (0..2).map(|i| Env::new(i, &cfg, &terrain, 9)).collect();
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("worlds.csv");
        let mut csv = WorldsCsv::append(&path, 2).expect("open");
        for _ in 0..10 {
            envs.iter_mut().for_each(|e| {
                e.step([0.0, 0.0]);
            });
            csv.see(&envs);
        }
        csv.flush();
        assert!(
            envs.iter().all(|e| e.episode_index >= 2),
            "stalls end episodes"
        );
        let mut reader = csv::Reader::from_path(&path).expect("read");
        let header = reader.headers().expect("header").clone();
        assert_eq!(&header[2], "friction_scale_flat");
        let rows: Vec<Vec<f64>> = reader
            .records()
            .map(|r| {
                r.expect("row")
                    .iter()
                    .map(|v| v.parse().expect("number"))
                    .collect()
            })
            .collect();
        for env in &envs {
            let mine: Vec<_> = rows.iter().filter(|r| r[0] == env.id as f64).collect();
            assert_eq!(
                mine.len() as u64,
                env.episode_index + 1,
                "one row per episode"
            );
            for (k, row) in mine.iter().enumerate() {
                assert_eq!(row[1], k as f64);
                let world = env.world_of(k as u64).expect("randomized");
                assert_eq!(row[2..], world.values()[..]);
            }
        }
    }
}
