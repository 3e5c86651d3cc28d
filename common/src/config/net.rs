//! `[net]`: a run across hosts (DESIGN §9): the shared key that admits hosts and seals their
//! frames, how a sim host asks for the newest policies, and how much one host may send.

use super::ConfigError;
use super::range::invalid;
use super::setting::{count, form, settings};
use std::path::{Path, PathBuf};

/// The shortest shared secret accepted, bytes: below the 256-bit keys derived from it, it is
/// weaker than they are.
pub const MIN_KEY_BYTES: usize = 32;

settings! {
    /// How the hosts of a run talk to each other.
    pub struct NetConfig {
        /// File with the run's shared secret (at least 32 bytes; every host needs the same
        /// one): only hosts holding it join, and every frame between hosts is sealed
        /// (AES-256-GCM) under a key derived from it. Required across hosts.
        pub key_file: Option<PathBuf> = None => form("a key file"), "", Essential;
        /// How often a sim host asks for the newest policies until it has them.
        pub policy_query_ms: u64 = 500 => count(50, 60_000), "ms", Advanced;
        /// Sim hosts the learner host trains with: its run ends once each has stepped
        /// `run.total-steps`.
        pub sim_hosts: u32 = 1 => count(1, 1024), "hosts", Essential;
        /// Rollout frames the learner host reads from one sim host per second; the rest are
        /// dropped unread and counted, so a flood from one host cannot starve the others.
        pub source_frames_per_s: u32 = 200 => count(1, 100_000), "frames/s", Advanced;
    }
}

impl NetConfig {
    /// The shared key, read from `key-file`: fails in one line when the run has none, or it
    /// cannot be read or is too short.
    pub fn read_key(&self) -> Result<Vec<u8>, ConfigError> {
        let Some(path) = &self.key_file else {
            return Err(invalid(
                "net.key-file",
                Option::<&Path>::None,
                "a run across hosts needs a shared key file (e.g. 32 random bytes from `head -c 32 /dev/urandom`)",
            ));
        };
        let key = std::fs::read(path).map_err(|e| ConfigError::Read {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        if key.len() < MIN_KEY_BYTES {
            return Err(invalid(
                "net.key-file",
                path,
                format!(
                    "holds {} bytes; a shared key needs at least {MIN_KEY_BYTES}",
                    key.len()
                ),
            ));
        }
        Ok(key)
    }
}

#[cfg(test)]
mod tests {
    use crate::config::tests::parse;

    #[test]
    fn the_key_file_is_required_long_enough_and_read_whole() {
        let none = parse("").expect("valid");
        let err = none.net.read_key().expect_err("no key file");
        assert!(err.to_string().contains("net.key-file"), "{err}");
        let dir = tempfile::tempdir().expect("tempdir");
        let short = dir.path().join("short.key");
        std::fs::write(&short, [7u8; 31]).expect("write");
        let long = dir.path().join("long.key");
        std::fs::write(&long, [7u8; 40]).expect("write");
        for (path, ok) in [(&short, false), (&long, true)] {
            let c = parse(&format!(
                "[net]\nkey-file = {:?}\n",
                path.display().to_string()
            ))
            .expect("valid");
            match c.net.read_key() {
                Ok(key) => assert!(ok && key == [7u8; 40], "{}", path.display()),
                Err(e) => assert!(!ok && e.to_string().contains("31 bytes"), "{e}"),
            }
        }
        let err = parse("[net]\npolicy-query-ms = 10\n").expect_err("too often");
        assert!(err.to_string().contains("net.policy-query-ms"), "{err}");
    }
}
