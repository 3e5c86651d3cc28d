//! Checkpoints: everything a replacement learner needs to continue bit-exactly (DESIGN §4).
//!
//! File format (little-endian): a 24-byte header — magic `LVTBCKPT`, format version `u32`,
//! CRC-32 of the payload `u32`, payload length `u64` — then the payload, the bincode (serde)
//! encoding of [`Checkpoint`]. A file is refused, naming it, when it is short, has another
//! magic or version, a length that disagrees with the file, or a checksum that does not match.
//!
//! Files are `checkpoint-<update, 10 digits>.ckpt` ([`checkpoint_file`]) in one directory, written atomically (temp
//! file in the same directory, fsync, rename, fsync the directory) so a crash leaves either the
//! old set or the new file, never a half-written checkpoint under a real name. After each save
//! only the newest `keep-checkpoints` remain. Loading "the latest" walks from the newest back
//! past corrupt or unreadable files.

use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};

use common::config::Config;
use common::policy::PolicyLayout;
use common::run_dir::{checkpoint_file, parse_checkpoint_file};
use common::{ACT_DIM, OBS_DIM, Rng};
use serde::{Deserialize, Serialize};

use crate::LearnerError;
use crate::adam::Adam;
use crate::obs_norm::RunningMeanStd;
use crate::ppo::{Counters, Learner, LearnerState};

const MAGIC: &[u8; 8] = b"LVTBCKPT";
/// Bump when [`Checkpoint`] changes shape.
pub const FORMAT_VERSION: u32 = 1;
const HEADER_LEN: usize = 24;

/// A learner's complete state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// The actor's architecture (the critic mirrors its hidden widths).
    pub layout: PolicyLayout,
    /// Update and step counters (the step counter is the learning-rate schedule's position)
    /// and the policy version.
    pub counters: Counters,
    /// The learning rate the next update would use, for inspection.
    pub learning_rate: f64,
    /// Actor, log-std and critic in the learner's flat order (`net` module).
    pub params: Vec<f32>,
    /// Adam's step count and moments.
    pub adam: Adam,
    pub obs_norm: RunningMeanStd,
    /// The learner's minibatch-shuffling stream.
    pub rng: Rng,
}

/// Header and payload of `ckpt`.
pub fn encode(ckpt: &Checkpoint) -> Result<Vec<u8>, LearnerError> {
    let payload =
        bincode::serde::encode_to_vec(ckpt, bincode::config::standard()).map_err(|e| {
            LearnerError::Encode {
                reason: e.to_string(),
            }
        })?;
    let mut bytes = Vec::with_capacity(HEADER_LEN + payload.len());
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&payload);
    Ok(bytes)
}

/// Checks and decodes a checkpoint file's bytes; `path` names it in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<Checkpoint, LearnerError> {
    let corrupt = |reason: String| LearnerError::Corrupt {
        path: path.to_path_buf(),
        reason,
    };
    let Some((header, payload)) = bytes.split_at_checked(HEADER_LEN) else {
        return Err(corrupt(format!(
            "{} bytes, shorter than the {HEADER_LEN}-byte header",
            bytes.len()
        )));
    };
    let word = |at: usize| {
        u32::from_le_bytes([header[at], header[at + 1], header[at + 2], header[at + 3]])
    };
    if &header[..8] != MAGIC {
        return Err(corrupt("not a lavatube checkpoint (bad magic)".into()));
    }
    let version = word(8);
    if version != FORMAT_VERSION {
        return Err(LearnerError::Incompatible {
            path: path.to_path_buf(),
            reason: format!("format version {version}; this build reads version {FORMAT_VERSION}"),
        });
    }
    let crc = word(12);
    let len = u64::from(word(16)) | (u64::from(word(20)) << 32);
    if len != payload.len() as u64 {
        return Err(corrupt(format!(
            "the header promises {len} payload bytes but the file has {} (truncated or appended to)",
            payload.len()
        )));
    }
    let actual = crc32fast::hash(payload);
    if actual != crc {
        return Err(corrupt(format!(
            "checksum mismatch: header {crc:#010x}, payload {actual:#010x}"
        )));
    }
    let (ckpt, used): (Checkpoint, usize) =
        bincode::serde::decode_from_slice(payload, bincode::config::standard())
            .map_err(|e| corrupt(format!("undecodable payload: {e}")))?;
    if used != payload.len() {
        return Err(corrupt(format!(
            "{} trailing payload bytes",
            payload.len() - used
        )));
    }
    Ok(ckpt)
}

/// Reads and checks one checkpoint file.
pub fn read(path: &Path) -> Result<Checkpoint, LearnerError> {
    let bytes = fs::read(path).map_err(LearnerError::io("reading", path))?;
    decode(&bytes, path)
}

/// Writes `bytes` to `path` so that `path` holds either its old content or all of `bytes`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), LearnerError> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
    let written = (|| {
        let mut f = File::create(&tmp).map_err(LearnerError::io("creating", &tmp))?;
        f.write_all(bytes)
            .map_err(LearnerError::io("writing", &tmp))?;
        f.sync_all().map_err(LearnerError::io("syncing", &tmp))?;
        fs::rename(&tmp, path).map_err(LearnerError::io("renaming into place", path))
    })();
    if written.is_err() {
        // Best effort: the temp name is never read, so a leftover only wastes space.
        let _ = fs::remove_file(&tmp);
    }
    written?;
    File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(LearnerError::io("syncing directory", dir))
}

/// The checkpoints in `dir`, oldest first, as `(update, path)`; other files are ignored, and
/// a directory that does not exist yet holds none.
pub fn list(dir: &Path) -> Result<Vec<(u64, PathBuf)>, LearnerError> {
    let entries = match fs::read_dir(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        other => other.map_err(LearnerError::io("listing", dir))?,
    };
    let mut found = Vec::new();
    for entry in entries {
        let entry = entry.map_err(LearnerError::io("listing", dir))?;
        let name = entry.file_name();
        let update = name.to_str().and_then(parse_checkpoint_file);
        if let Some(update) = update {
            found.push((update, entry.path()));
        }
    }
    found.sort();
    Ok(found)
}

/// Writes `ckpt` into `dir` (created if needed) and deletes all but the newest `keep`,
/// sparing milestones: checkpoints whose update is a multiple of `milestone_every` (not 0).
pub fn save(
    dir: &Path,
    ckpt: &Checkpoint,
    keep: usize,
    milestone_every: usize,
) -> Result<PathBuf, LearnerError> {
    fs::create_dir_all(dir).map_err(LearnerError::io("creating", dir))?;
    let path = dir.join(checkpoint_file(ckpt.counters.update));
    write_atomic(&path, &encode(ckpt)?)?;
    let all = list(dir)?;
    let milestone =
        |update: u64| milestone_every > 0 && update.is_multiple_of(milestone_every as u64);
    for (update, old) in all.iter().take(all.len().saturating_sub(keep.max(1))) {
        if !milestone(*update) {
            fs::remove_file(old).map_err(LearnerError::io("removing old checkpoint", old))?;
        }
    }
    Ok(path)
}

/// The newest checkpoint in `dir` that reads back intact, with the newer ones that did not
/// (each with its error). Corrupt and unreadable files are skipped; a well-formed file this
/// build cannot use (another format version) stops the search, since older ones will not be
/// what the user wants either.
pub fn load_latest_good(
    dir: &Path,
) -> Result<(Checkpoint, PathBuf, Vec<LearnerError>), LearnerError> {
    let mut skipped = Vec::new();
    for (_, path) in list(dir)?.into_iter().rev() {
        match read(&path) {
            Ok(ckpt) => return Ok((ckpt, path, skipped)),
            Err(e @ (LearnerError::Corrupt { .. } | LearnerError::Io { .. })) => {
                tracing::warn!(error = %e, "skipping checkpoint");
                skipped.push(e);
            }
            Err(e) => return Err(e),
        }
    }
    Err(LearnerError::NoCheckpoint {
        dir: dir.to_path_buf(),
        tried: skipped.len(),
        newest_error: skipped.into_iter().next().map(Box::new),
    })
}

impl Checkpoint {
    /// The actor as a `common::Policy` (what `learner-proc export` writes and the sim runs),
    /// exactly the weights the learner published for this version.
    pub fn policy(&self, obs_clip: f32) -> Result<common::Policy, LearnerError> {
        let shape = crate::net::NetShape::new(&self.layout);
        if self.params.len() < shape.actor_len() {
            return Err(LearnerError::setting(
                "layout",
                format!(
                    "{} parameters cannot hold a {} actor",
                    self.params.len(),
                    widths(&self.layout)
                ),
            ));
        }
        let w = crate::ppo::shipped_weights(&self.obs_norm, &shape, &self.params);
        common::Policy::new(self.layout.clone(), w, obs_clip)
            .map_err(|e| LearnerError::setting("layout", e.to_string()))
    }
}

impl Learner {
    /// A snapshot of the complete learner state.
    pub fn checkpoint(&self) -> Checkpoint {
        Checkpoint {
            layout: self.shape.layout.clone(),
            counters: self.counters,
            learning_rate: self.learning_rate(),
            params: self.params.clone(),
            adam: self.adam.clone(),
            obs_norm: self.obs_norm.clone(),
            rng: self.rng.clone(),
        }
    }

    /// Continues from `ckpt` with the hyperparameters of `cfg` (the architecture must match).
    pub fn from_checkpoint(cfg: &Config, ckpt: Checkpoint) -> Result<Self, LearnerError> {
        let state = LearnerState {
            params: ckpt.params,
            adam: ckpt.adam,
            obs_norm: ckpt.obs_norm,
            rng: ckpt.rng,
            counters: ckpt.counters,
        };
        Self::from_state(cfg, ckpt.layout, state)
    }

    /// Saves into `dir` as `checkpoint-<update>.ckpt`, keeping the newest `keep-checkpoints`
    /// and every `milestone-every`th.
    pub fn save_checkpoint(&self, dir: &Path) -> Result<PathBuf, LearnerError> {
        save(
            dir,
            &self.checkpoint(),
            self.ppo.keep_checkpoints,
            self.ppo.milestone_every,
        )
    }

    /// Loads one named checkpoint file.
    pub fn load_checkpoint(cfg: &Config, path: &Path) -> Result<Self, LearnerError> {
        Self::from_checkpoint(cfg, read(path)?).map_err(|e| incompatible(path, e))
    }

    /// Loads the newest good checkpoint in `dir` (see [`load_latest_good`]); returns its path.
    pub fn resume(cfg: &Config, dir: &Path) -> Result<(Self, PathBuf), LearnerError> {
        let (ckpt, path, _) = load_latest_good(dir)?;
        let learner = Self::from_checkpoint(cfg, ckpt).map_err(|e| incompatible(&path, e))?;
        Ok((learner, path))
    }

    /// A warm start from the checkpoint file `path`, for the paper's pipeline (the general
    /// model starts from the flat model; FTM and RTM from the general model): its actor,
    /// log-std, critic and observation statistics, with everything that belongs to a run of
    /// training fresh. Update and step counters are 0, so the learning-rate schedule starts
    /// over at `ppo.learning-rate` over `run.total-steps`; Adam's moments are zero, since the
    /// source's describe another task's gradients; the minibatch RNG comes from `cfg.run.seed`.
    ///
    /// The policy version restarts at 0 too. A warm start begins a run directory (`serve`
    /// resumes that directory's own checkpoints instead when it has any), so no version in it
    /// came before; and versions keep meaning "updates done in this run", as the metrics and
    /// the sync-mode wait read them. The observation statistics keep their sample count: the
    /// weights were trained on inputs normalised with them, and a reset count would let the
    /// first rollouts of the new task move them abruptly under those weights.
    ///
    /// The configured network (`ppo.hidden`) must match the checkpoint's; a mismatch is
    /// refused naming both shapes and the file.
    pub fn warm_start(cfg: &Config, path: &Path) -> Result<Self, LearnerError> {
        let ckpt = read(path)?;
        let layout = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM);
        if ckpt.layout != layout {
            return Err(LearnerError::Incompatible {
                path: path.to_path_buf(),
                reason: format!(
                    "its network is {} but the config's (ppo.hidden) is {}",
                    widths(&ckpt.layout),
                    widths(&layout)
                ),
            });
        }
        let state = LearnerState {
            adam: Adam::new(ckpt.params.len(), cfg.ppo.adam_eps as f32),
            params: ckpt.params,
            obs_norm: ckpt.obs_norm,
            rng: Rng::new(cfg.run.seed),
            counters: Counters::default(),
        };
        Self::from_state(cfg, layout, state).map_err(|e| incompatible(path, e))
    }
}

/// The layer widths of `layout`, input to output: `10 -> 64 -> 64 -> 2`.
pub(crate) fn widths(layout: &PolicyLayout) -> String {
    let widths: Vec<String> = std::iter::once(layout.obs_dim)
        .chain(layout.hidden.iter().copied())
        .chain([layout.act_dim])
        .map(|w| w.to_string())
        .collect();
    widths.join(" -> ")
}

/// A checkpoint whose content does not fit the configured learner.
fn incompatible(path: &Path, e: LearnerError) -> LearnerError {
    match e {
        LearnerError::Setting { field, reason } => LearnerError::Incompatible {
            path: path.to_path_buf(),
            reason: format!("{field}: {reason}"),
        },
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ppo::tests::{OwnedRollout, learner, small_config};

    fn bits(w: &[f32]) -> Vec<u32> {
        w.iter().map(|x| x.to_bits()).collect()
    }

    /// DESIGN §4: resuming from the checkpoint written after update k gives bit-identical
    /// weights, optimizer state, statistics and RNG after update k + 1.
    #[test]
    fn resume_after_update_k_is_bit_identical_at_k_plus_1() {
        let dir = tempfile::tempdir().expect("tempdir");
        let cfg = small_config(64, 10);
        let mut a = learner(&cfg, 11);
        let r1 = OwnedRollout::acted_by(&a, 64, 4, 12);
        a.update(&r1.view()).expect("update 1");
        let saved = a.save_checkpoint(dir.path()).expect("save");
        assert_eq!(saved, dir.path().join("checkpoint-0000000001.ckpt"));
        let r2 = OwnedRollout::acted_by(&a, 64, 4, 13);
        a.update(&r2.view()).expect("update 2");

        let (mut b, from) = Learner::resume(&cfg, dir.path()).expect("resume");
        assert_eq!(from, saved);
        assert_eq!(b.counters().update, 1);
        b.update(&r2.view()).expect("update 2 again");
        assert_eq!(bits(&b.policy_weights()), bits(&a.policy_weights()));
        assert_eq!(
            b.checkpoint(),
            a.checkpoint(),
            "params, Adam moments, obs stats, RNG, counters"
        );
        assert_eq!(
            encode(&b.checkpoint()).expect("encode"),
            encode(&a.checkpoint()).expect("encode")
        );
    }

    fn saved_dir(updates: u64, keep: usize) -> (tempfile::TempDir, Learner) {
        saved_with_milestones(updates, keep, 0)
    }

    fn saved_with_milestones(
        updates: u64,
        keep: usize,
        milestone_every: usize,
    ) -> (tempfile::TempDir, Learner) {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut cfg = small_config(128, 10);
        cfg.ppo.epochs = 1;
        cfg.ppo.keep_checkpoints = keep;
        cfg.ppo.milestone_every = milestone_every;
        // Every update trains on the same rollout, however many versions old it gets.
        cfg.ppo.max_policy_lag = 1000;
        let mut l = learner(&cfg, 21);
        let r = OwnedRollout::acted_by(&l, 64, 4, 22);
        for _ in 0..updates {
            l.update(&r.view()).expect("update");
            l.save_checkpoint(dir.path()).expect("save");
        }
        (dir, l)
    }

    #[test]
    fn only_the_newest_k_are_kept() {
        let (dir, _) = saved_dir(4, 2);
        let kept: Vec<u64> = list(dir.path())
            .expect("list")
            .into_iter()
            .map(|(u, _)| u)
            .collect();
        assert_eq!(kept, vec![3, 4]);
    }

    #[test]
    fn milestones_outlive_the_newest_k() {
        let (dir, _) = saved_with_milestones(7, 2, 3);
        let kept: Vec<u64> = list(dir.path())
            .expect("list")
            .into_iter()
            .map(|(u, _)| u)
            .collect();
        assert_eq!(kept, vec![3, 6, 7]);
    }

    #[test]
    fn damaged_files_are_refused_naming_the_file() {
        let (dir, l) = saved_dir(1, 3);
        let path = dir.path().join(checkpoint_file(1));
        let good = fs::read(&path).expect("read");
        assert_eq!(decode(&good, &path).expect("intact"), l.checkpoint());
        let refuse = |bytes: &[u8], needle: &str| {
            let e = decode(bytes, &path).expect_err(needle);
            let msg = e.to_string();
            assert!(
                msg.contains(&path.display().to_string()) && msg.contains(needle),
                "{msg}"
            );
        };
        refuse(&good[..good.len() - 10], "truncated");
        refuse(&good[..10], "shorter than the 24-byte header");
        let mut flipped = good.clone();
        let at = flipped.len() / 2;
        flipped[at] ^= 0x40;
        refuse(&flipped, "checksum mismatch");
        let mut magic = good.clone();
        magic[0] = b'X';
        refuse(&magic, "bad magic");
        let mut version = good.clone();
        version[8] = 99;
        refuse(&version, "format version 99");
        let mut longer = good.clone();
        longer.push(0);
        refuse(&longer, "appended");
    }

    #[test]
    fn latest_good_falls_back_past_a_corrupt_newest() {
        let (dir, _) = saved_dir(3, 3);
        let newest = dir.path().join(checkpoint_file(3));
        let bytes = fs::read(&newest).expect("read");
        fs::write(&newest, &bytes[..bytes.len() / 2]).expect("truncate");
        let (ckpt, path, skipped) = load_latest_good(dir.path()).expect("fallback");
        assert_eq!(
            (ckpt.counters.update, path),
            (2, dir.path().join(checkpoint_file(2)))
        );
        assert_eq!(skipped.len(), 1);
        assert!(
            skipped[0]
                .to_string()
                .contains("checkpoint-0000000003.ckpt")
        );

        for u in [1, 2] {
            fs::write(dir.path().join(checkpoint_file(u)), b"junk").expect("clobber");
        }
        let e = load_latest_good(dir.path()).expect_err("nothing good");
        let missing = load_latest_good(&dir.path().join("not-yet"));
        assert!(matches!(
            missing,
            Err(LearnerError::NoCheckpoint { tried: 0, .. })
        ));
        assert!(
            e.to_string().contains("3 tried") && e.to_string().contains("checkpoint-0000000003"),
            "{e}"
        );
    }

    /// A failed save leaves the previous file intact and no temp file behind; stray temp files
    /// from a crash are ignored by the loader.
    #[test]
    fn saving_is_atomic() {
        let (dir, l) = saved_dir(1, 3);
        let target = dir.path().join(checkpoint_file(1));
        let before = fs::read(&target).expect("read");

        // Renaming a file over a non-empty directory fails after the temp file was written.
        let blocked = dir.path().join(checkpoint_file(7));
        fs::create_dir(&blocked).expect("mkdir");
        fs::write(blocked.join("x"), b"x").expect("fill");
        assert!(write_atomic(&blocked, &encode(&l.checkpoint()).expect("encode")).is_err());
        fs::remove_dir_all(&blocked).expect("cleanup");
        let names: Vec<String> = fs::read_dir(dir.path())
            .expect("ls")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, vec![checkpoint_file(1)], "no temp file left behind");
        assert_eq!(fs::read(&target).expect("read"), before);

        fs::write(
            dir.path().join(format!(".{}.tmp-1", checkpoint_file(2))),
            &before[..100],
        )
        .expect("stray");
        let (ckpt, _, skipped) = load_latest_good(dir.path()).expect("load");
        assert_eq!((ckpt.counters.update, skipped.len()), (1, 0));
    }

    /// A warm start takes the source's weights and observation statistics and nothing of its
    /// training: counters, Adam moments, schedule and RNG are a new run's.
    #[test]
    fn warm_start_takes_weights_and_starts_counters_fresh() {
        let (dir, source) = saved_dir(2, 3);
        let path = dir.path().join(checkpoint_file(2));
        let mut cfg = small_config(128, 10);
        cfg.run.seed = 99;
        let mut l = Learner::warm_start(&cfg, &path).expect("warm start");
        assert_eq!(
            bits(&l.params),
            bits(&source.params),
            "actor, log-std, critic"
        );
        assert_eq!(l.obs_norm, source.obs_norm);
        assert_eq!(bits(&l.policy_weights()), bits(&source.policy_weights()));
        assert_eq!(l.counters(), Counters::default());
        assert_eq!(l.learning_rate(), cfg.ppo.learning_rate);
        assert_eq!(l.adam.step, 0);
        assert!(l.adam.m.iter().chain(&l.adam.v).all(|&x| x == 0.0));
        assert!(
            source.adam.m.iter().any(|&x| x != 0.0),
            "the source's were not"
        );
        assert_eq!(l.rng, Rng::new(99));

        let before = l.params.clone();
        let r = OwnedRollout::acted_by(&l, 64, 4, 23);
        let m = l.update(&r.view()).expect("update");
        assert_ne!(
            bits(&l.params),
            bits(&before),
            "one update moves the weights"
        );
        assert_eq!((m.update, m.policy_version, m.global_step), (1, 1, 256));
    }

    #[test]
    fn a_warm_start_into_another_network_is_refused_naming_both() {
        let (dir, _) = saved_dir(1, 3);
        let path = dir.path().join(checkpoint_file(1));
        let mut cfg = small_config(128, 10);
        cfg.ppo.hidden = vec![32, 32];
        let e = Learner::warm_start(&cfg, &path).err().expect("mismatch");
        let msg = e.to_string();
        assert!(
            msg.contains(&path.display().to_string())
                && msg.contains("10 -> 64 -> 64 -> 2")
                && msg.contains("10 -> 32 -> 32 -> 2")
                && e.is_user_error(),
            "{msg}"
        );
    }

    #[test]
    fn an_architecture_mismatch_is_incompatible() {
        let (dir, _) = saved_dir(1, 3);
        let mut cfg = small_config(128, 10);
        cfg.ppo.hidden = vec![32, 32];
        let e = Learner::load_checkpoint(&cfg, &dir.path().join(checkpoint_file(1)))
            .err()
            .expect("mismatch");
        assert!(matches!(e, LearnerError::Incompatible { .. }), "{e}");
    }
}
