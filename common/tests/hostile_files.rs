//! Files that are not what they claim: random TOML and random mutations of the shipped
//! configs, policy files with changed bytes or cut short, telemetry CSVs of another tool, and
//! estimator model files that are no analysis. Each is refused with a one-line error (naming
//! the file where the error is about the file rather than a field); nothing panics.
//! 10 000 cases a class.

use common::config::EstimatorConfig;
use common::telemetry::TelemetryReader;
use common::{ACT_DIM, Config, OBS_DIM, Policy, PolicyLayout};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

fn shipped() -> Vec<(PathBuf, String)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("configs/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(&p).expect("read");
            (p, text)
        })
        .collect()
}

/// Parses and validates `text` as a config at `path`: fine, or a one-line error.
fn parse(text: &str, path: &Path) {
    if let Err(e) = Config::parse(text, path).and_then(|c| c.validate()) {
        let msg = e.to_string();
        assert!(!msg.is_empty() && !msg.contains('\n'), "one line: {msg}");
    }
}

/// A tiny policy's file bytes.
fn policy_bytes() -> Vec<u8> {
    let layout = PolicyLayout::new(OBS_DIM, &[3, 2], ACT_DIM);
    let w = vec![0.25f32; layout.len()];
    Policy::new(layout, w, 5.0).expect("policy").to_bytes()
}

/// Reads `bytes` as a policy file: fine, or a one-line error naming it.
fn read_policy(bytes: &[u8]) -> bool {
    match Policy::from_bytes(bytes, Path::new("bad.policy")) {
        Ok(_) => true,
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.contains('\n') && msg.contains("bad.policy"), "{msg}");
            false
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(10_000))]

    #[test]
    fn random_toml_is_refused_in_one_line(
        text in "(\\[[a-z-]{1,8}\\]\n)?([a-z-]{1,12} = ([0-9.e+-]{1,8}|\"[a-z/]{0,8}\"|true|\\[[0-9, ]{0,8}\\])\n){0,6}",
    ) {
        parse(&text, Path::new("random.toml"));
    }

    #[test]
    fn mutated_shipped_configs_are_refused_in_one_line(
        file in any::<prop::sample::Index>(),
        at in any::<prop::sample::Index>(),
        byte in any::<u8>(),
        cut in any::<bool>(),
    ) {
        let files = shipped();
        let (path, text) = &files[file.index(files.len())];
        let mut bytes = text.clone().into_bytes();
        let i = at.index(bytes.len());
        if cut {
            bytes.truncate(i);
        } else {
            bytes[i] = byte;
        }
        // Bytes that are no UTF-8 fail at reading, which `Config::load` reports in one line.
        if let Ok(text) = String::from_utf8(bytes) {
            parse(&text, path);
        }
    }

    #[test]
    fn damaged_policy_files_never_panic(
        at in any::<prop::sample::Index>(),
        byte in any::<u8>(),
        cut in any::<bool>(),
    ) {
        let mut bytes = policy_bytes();
        let i = at.index(bytes.len());
        if cut {
            bytes.truncate(i);
            prop_assert!(!read_policy(&bytes), "a policy file cut short is refused");
        } else {
            bytes[i] = byte;
            read_policy(&bytes);
        }
    }

    #[test]
    fn random_bytes_as_a_policy_file_are_refused(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        prop_assert!(!read_policy(&bytes));
        let mut signed = b"LTPOLICY".to_vec();
        signed.extend(&bytes);
        read_policy(&signed);
    }

    #[test]
    fn telemetry_csvs_of_another_tool_are_refused_naming_the_file(
        header in "[a-z_,]{0,60}",
        rows in proptest::collection::vec("[0-9a-zA-Z.,+-]{0,40}", 0..6),
    ) {
        let text = format!("{header}\n{}\n", rows.join("\n"));
        let path = Path::new("other.csv");
        let read: Result<Vec<_>, _> = TelemetryReader::new(text.as_bytes(), path)
            .and_then(Iterator::collect::<Result<Vec<_>, _>>);
        if let Err(e) = read {
            let msg = e.to_string();
            prop_assert!(!msg.contains('\n') && msg.contains("other.csv"), "{}", msg);
        }
    }

    #[test]
    fn estimator_model_files_that_are_no_analysis_are_refused(text in "[\\[\\]{}\":,a-z0-9. ]{0,80}") {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("results.json");
        std::fs::write(&path, &text).expect("write");
        let cfg = EstimatorConfig {
            model: Some(path),
            ..EstimatorConfig::default()
        };
        if let Err(e) = cfg.offline_mixture() {
            let msg = e.to_string();
            prop_assert!(!msg.contains('\n') && msg.contains("results.json"), "{}", msg);
        }
    }
}

#[test]
fn the_valid_files_load() {
    assert!(read_policy(&policy_bytes()));
    for (path, text) in shipped() {
        if !text.contains("[bench]") {
            // Loaded as files: a config may extend another beside it.
            Config::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
    }
}
