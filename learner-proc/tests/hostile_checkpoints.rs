//! Checkpoints that are no checkpoints: every single-bit flip class, truncations, random
//! bytes. Each is refused with a one-line error naming the file; nothing panics. 10 000 cases
//! a class. (A checkpoint of another network is refused by the unit tests beside the loader.)

use common::{ACT_DIM, Config, OBS_DIM, PolicyLayout};
use learner_proc::Learner;
use learner_proc::checkpoint::decode;
use proptest::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// A valid checkpoint of a small network, written once.
fn valid() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let mut cfg = Config::default();
        cfg.ppo.hidden = vec![4, 4];
        let layout = PolicyLayout::new(OBS_DIM, &cfg.ppo.hidden, ACT_DIM);
        let learner = Learner::new(&cfg, layout, 1).expect("learner");
        let dir = tempfile::tempdir().expect("tempdir");
        let path = learner.save_checkpoint(dir.path()).expect("save");
        std::fs::read(path).expect("read")
    })
}

fn refused(bytes: &[u8]) -> String {
    let Err(e) = decode(bytes, Path::new("run/checkpoints/c.ckpt")) else {
        panic!("a damaged checkpoint was accepted");
    };
    let text = e.to_string();
    assert!(!text.contains('\n'), "one line: {text}");
    assert!(text.contains("c.ckpt"), "names the file: {text}");
    text
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(10_000))]

    #[test]
    fn a_flipped_bit_anywhere_is_refused(at in any::<prop::sample::Index>(), bit in 0u8..8) {
        let mut bytes = valid().to_vec();
        let i = at.index(bytes.len());
        bytes[i] ^= 1 << bit;
        refused(&bytes);
    }

    #[test]
    fn a_truncated_file_is_refused(at in any::<prop::sample::Index>()) {
        let bytes = valid();
        refused(&bytes[..at.index(bytes.len())]);
    }

    #[test]
    fn random_bytes_are_refused(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        refused(&bytes);
    }
}

#[test]
fn the_valid_checkpoint_loads() {
    decode(valid(), Path::new("c.ckpt")).expect("a written checkpoint decodes");
}
