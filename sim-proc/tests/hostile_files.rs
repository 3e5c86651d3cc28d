//! Heightmaps that are no heightmaps: random bytes as `.png` and `.grid`, headers of huge
//! dimensions, NaN heights. Each is refused with a one-line error naming the file; nothing
//! panics and nothing is allocated for dimensions the file cannot hold. 10 000 cases a class.

use common::config::HeightmapConfig;
use proptest::prelude::*;
use sim_proc::terrain::Terrain;
use std::path::Path;

fn config(path: &Path) -> HeightmapConfig {
    HeightmapConfig {
        path: path.to_path_buf(),
        metres_per_pixel: 0.05,
        height_scale: 1.0,
        origin: [0.0, 0.0],
    }
}

/// Loads `bytes` as the heightmap `name`: an error must be one line naming the file.
fn load(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), String> {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write");
    match Terrain::load(&config(&path)) {
        Ok(_) => Ok(()),
        Err(e) => {
            let text = e.to_string();
            assert!(!text.contains('\n'), "one line: {text}");
            assert!(text.contains(name), "names the file: {text}");
            Err(text)
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(10_000))]

    #[test]
    fn random_bytes_as_png_are_refused(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        png.extend(&bytes);
        prop_assert!(load(dir.path(), "map.png", &bytes).is_err());
        prop_assert!(load(dir.path(), "signed.png", &png).is_err());
    }

    #[test]
    fn random_text_as_grid_never_panics(text in "[0-9a-z .+\\-\\n#]{0,200}") {
        let dir = tempfile::tempdir().expect("tempdir");
        let _ = load(dir.path(), "map.grid", text.as_bytes());
    }

    #[test]
    fn grid_headers_past_the_largest_map_are_refused(rows in 8193usize.., cols in 2usize..) {
        let dir = tempfile::tempdir().expect("tempdir");
        let e = load(dir.path(), "huge.grid", format!("{rows} {cols}\n0 0\n").as_bytes());
        prop_assert!(e.is_err_and(|t| t.contains("at most 8192")));
    }
}

#[test]
fn nan_heights_and_short_rows_are_refused_naming_what_is_wrong() {
    let dir = tempfile::tempdir().expect("tempdir");
    let e = load(dir.path(), "nan.grid", b"2 2\n0 nan\n0 0\n").expect_err("NaN");
    assert!(e.contains("not finite"), "{e}");
    let e = load(dir.path(), "short.grid", b"2 3\n0 0 0\n0 0\n").expect_err("short row");
    assert!(e.contains("row 2 has 2 values, expected 3"), "{e}");
    load(dir.path(), "good.grid", b"2 2\n0 0.1\n0.2 0\n").expect("a 2×2 grid loads");
}
