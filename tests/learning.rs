//! SPEC S6 for real: PPO through the three-process runtime learns the paper's reaching task
//! on the flat area. Slow in a debug build, so it is ignored by default; run it with
//! `cargo test --release --test learning -- --ignored`.

mod support;

/// Mean of the `success_rate` column over metrics rows `rows` (rows without episodes skipped).
fn mean_success(rows: &[csv::StringRecord], col: usize) -> f64 {
    let v: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.get(col)?.parse().ok())
        .collect();
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

#[test]
#[ignore = "about 2 minutes in release; see the module docs"]
fn flat_success_rises_from_random_to_80_percent_within_250k_steps() {
    let root = support::root();
    let run_id = format!("learn-{}", std::process::id());
    let (code, text) = support::lavatube_run("configs/default.toml", &run_id);
    assert_eq!(code, 0, "lavatube run failed:\n{text}");
    let mut reader = csv::Reader::from_path(root.join("runs").join(&run_id).join("metrics.csv"))
        .expect("metrics.csv");
    let col = reader
        .headers()
        .expect("header")
        .iter()
        .position(|h| h == "success_rate")
        .expect("success_rate column");
    let rows: Vec<csv::StringRecord> = reader.records().map(|r| r.expect("row")).collect();
    // configs/default.toml: 8 flat envs, 2048 transitions per update, 250 k steps ≈ 122 updates.
    assert!(rows.len() >= 120, "{} updates", rows.len());
    let first = mean_success(&rows[..10], col);
    let last = mean_success(&rows[rows.len() - 10..], col);
    assert!(
        first < 0.5,
        "the untrained policy should mostly fail, got {first}"
    );
    assert!(
        last >= 0.8,
        "success over the last 10 updates {last} (first 10: {first})"
    );
}
