//! `lavatube reproduce` end to end on configs/quick.toml: every stage runs as real processes
//! (the switching evaluation through the full runtime with frozen FTM and RTM), the report
//! has the paper's tables with finite numbers, and a second invocation resumes, skipping
//! every finished stage.

mod support;

#[test]
fn the_quick_pipeline_reports_every_table_and_resumes() {
    let out = support::root()
        .join("target/e2e-runs")
        .join(format!("reproduce-{}", std::process::id()));
    let run = || {
        std::process::Command::new(env!("CARGO_BIN_EXE_lavatube"))
            .args([
                "reproduce",
                "--config",
                "configs/quick.toml",
                "--quiet",
                "--out",
            ])
            .arg(&out)
            .current_dir(support::root())
            .output()
            .expect("lavatube reproduce")
    };
    let first = run();
    let said = String::from_utf8_lossy(&first.stderr);
    assert!(first.status.success(), "{said}");
    let report = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    assert!(
        report.contains("## Table 1") && report.contains("## Table 3"),
        "{report}"
    );
    let table1: Vec<&str> = report
        .split("## Shape checks")
        .next()
        .unwrap_or_default()
        .lines()
        .filter(|l| {
            ["| general |", "| FTM |", "| RTM |", "| switching |"]
                .iter()
                .any(|m| l.starts_with(m))
        })
        .collect();
    assert_eq!(
        table1.len(),
        12,
        "three models and switching × two areas and the mixed course:\n{report}"
    );
    let checks = report
        .lines()
        .filter(|l| {
            ["| yes |", "| within margin |", "| not shown |", "| no |"]
                .iter()
                .any(|v| l.ends_with(v))
        })
        .count();
    assert_eq!(
        checks, 6,
        "two specialist claims, switching vs the best single model in three areas, switching vs general on the mixed course:\n{report}"
    );
    assert!(
        report.contains("`roughness-scale` 0.8 for stages a-d, 1.2 for the fine-tuning (e) and 1 for this evaluation (f)"),
        "{report}"
    );
    for (stage_cfg, ground) in [
        ("e-specialists/config.toml", "roughness-scale = 1.2"),
        ("e-specialists/config.toml", "learning-rate = 0.0001"),
        ("f-eval/general-rough-0.toml", "roughness-scale = 1.0"),
        ("f-eval/general-rough-0.toml", "episodes = \"course\""),
        ("c-collect/traces.toml", "roughness-scale = 0.8"),
        ("c-collect/traces.toml", "[sim.envs]\nflat = 3\nrough = 3\n"),
    ] {
        let text = std::fs::read_to_string(out.join(stage_cfg)).expect(stage_cfg);
        assert!(text.contains(ground), "{stage_cfg}: {text}");
    }
    // No estimator where one general model acts; the switching stage has one.
    for (stage, estimator) in [
        ("a-flat", false),
        ("b-general", false),
        ("e-specialists", true),
    ] {
        let path = out.join(stage).join("summary.json");
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).expect("summary.json"))
                .expect("summary json");
        assert_eq!(
            summary["pids"].get("estimator").is_some(),
            estimator,
            "{stage}: {summary}"
        );
    }
    // Switching classifies with stage d's mixture, never refitted on one area's windows.
    let switch = std::fs::read_to_string(out.join("f-eval/switching-rough-0/config.toml"))
        .expect("switching config");
    for line in [
        "d-analysis/results.json\"",
        "refit-every = 0",
        "episodes = \"course\"",
        "feature = \"log-std\"",
        "equal-weights = true",
    ] {
        assert!(switch.contains(line), "{line}: {switch}");
    }
    // Early stopping: each specialist is one of the general model and stage e's two
    // checkpoints, validated on its own terrain's courses (seeds 2^20 from stage f's), and
    // switching serves the ones chosen.
    let selection: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("e-select/selection.json")).expect("selection.json"),
    )
    .expect("selection json");
    let chosen: Vec<&str> = ["FTM", "RTM"]
        .iter()
        .enumerate()
        .map(|(i, model)| {
            let s = &selection[i];
            assert_eq!(s["model"], *model, "{selection}");
            let labels: Vec<&str> = s["candidates"]
                .as_array()
                .expect("candidates")
                .iter()
                .map(|c| c["label"].as_str().expect("label"))
                .collect();
            // How many updates each specialist made depends on which envs the online
            // estimator gave its slot; every checkpoint it wrote is a candidate.
            let dir = out.join(format!(
                "e-specialists/learner-{}/checkpoints",
                ["flat", "rough"][i]
            ));
            let mut updates: Vec<u64> = std::fs::read_dir(&dir)
                .expect("specialist checkpoints")
                .filter_map(|e| {
                    let name = e.expect("entry").file_name();
                    common::run_dir::parse_checkpoint_file(name.to_str()?)
                })
                .collect();
            updates.sort_unstable();
            let expected: Vec<String> = std::iter::once("general".to_string())
                .chain(updates.iter().map(|n| format!("update {n}")))
                .collect();
            assert!(expected.len() >= 2, "{selection}");
            assert_eq!(labels, expected, "{selection}");
            s["candidates"][s["chosen"].as_u64().expect("chosen") as usize]["checkpoint"]
                .as_str()
                .expect("checkpoint")
        })
        .collect();
    for path in &chosen {
        assert!(switch.contains(&format!("\"{path}\"")), "{path}: {switch}");
    }
    let validation = std::fs::read_to_string(out.join("e-select/ftm-general-flat-0.toml"))
        .expect("validation config");
    assert!(validation.contains("seed = 1048579"), "{validation}");
    assert!(
        report.contains("## Specialists chosen on validation courses (stage e)"),
        "{report}"
    );
    // The robustness worlds: the general model and switching on the mixed course in each,
    // pushed worlds drawing their pushes, switching through the full runtime.
    let section = report
        .split("## Robustness worlds (stage f)")
        .nth(1)
        .expect("robustness section");
    let worlds: Vec<&str> = section
        .split("\n## ")
        .next()
        .unwrap_or_default()
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| world"))
        .collect();
    assert_eq!(worlds.len(), 2, "{report}");
    assert!(worlds[1].starts_with("| pushed-on-the-moon |"), "{report}");
    let pushed = std::fs::read_to_string(
        out.join("f-robustness/pushed-on-the-moon/switching-mixed-0/config.toml"),
    )
    .expect("a robustness world's switching config");
    assert!(pushed.contains("gravity = 1.62\n"), "{pushed}");
    assert!(pushed.contains("push-interval = 1.0\n"), "{pushed}");
    // The switch's reading: its own (window 20, dwell 10) and the 5-tick dwell at windows 20
    // and 40, each on the mixed validation courses; stage f switches with the one chosen.
    let tuning: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("e-switch/tuning.json")).expect("tuning.json"),
    )
    .expect("tuning json");
    let tried: Vec<(u64, u64)> = tuning["tried"]
        .as_array()
        .expect("tried")
        .iter()
        .map(|t| {
            let r = &t["reading"];
            (
                r["window"].as_u64().expect("w"),
                r["dwell"].as_u64().expect("d"),
            )
        })
        .collect();
    assert_eq!(tried, [(20, 10), (20, 5), (40, 5)], "{tuning}");
    let (window, dwell) = tried[tuning["chosen"].as_u64().expect("chosen") as usize];
    let tried_cfg =
        std::fs::read_to_string(out.join("e-switch/switching-w40-d5-mixed-0/config.toml"))
            .expect("a tried reading's config");
    assert!(tried_cfg.contains("seed = 1048579"), "{tried_cfg}");
    assert!(tried_cfg.contains("online-window = 40\n"), "{tried_cfg}");
    assert!(
        switch.contains(&format!("online-window = {window}\n")),
        "{switch}"
    );
    assert!(
        switch.contains(&format!("switch-dwell = {dwell}\n")),
        "{switch}"
    );
    assert!(
        report.contains("## Online window and dwell chosen on validation courses (stage e)"),
        "{report}"
    );
    assert_eq!(
        report
            .lines()
            .filter(|l| l.ends_with("| **yes** |"))
            .count(),
        3,
        "two specialists and one reading:\n{report}"
    );
    // Paired evaluation: the runtime's sim (switching) and `sim-proc` alone (one model) drive
    // the same course, leg by leg.
    let legs = |csv: &str| -> Vec<[String; 3]> {
        let mut r = csv::Reader::from_path(out.join("f-eval").join(csv)).expect(csv);
        let h = r.headers().expect("headers").clone();
        let col = |name: &str| h.iter().position(|c| c == name).expect(name);
        let (env, leg, x, z) = (col("env"), col("episode"), col("target_x"), col("target_z"));
        let mut legs: Vec<[String; 3]> = r
            .records()
            .map(|row| row.expect("row"))
            .filter(|row| &row[env] == "0")
            .map(|row| [&row[leg], &row[x], &row[z]].map(String::from))
            .collect();
        legs.dedup();
        legs
    };
    let (alone, switching) = (
        legs("general-mixed-0.csv"),
        legs("switching-mixed-0/telemetry.csv"),
    );
    let n = alone.len().min(switching.len());
    assert!(n >= 1, "{alone:?} {switching:?}");
    assert_eq!(alone[..n], switching[..n]);
    let table3 = report
        .split("## Table 3")
        .nth(1)
        .unwrap_or_default()
        .lines()
        .filter(|l| {
            ["| 10 |", "| 20 |", "| 40 |", "| 70 |"]
                .iter()
                .any(|w| l.starts_with(w))
        })
        .count();
    assert_eq!(table3, 4, "four windows:\n{report}");
    for word in report.split(|c: char| c.is_whitespace() || "|()%/".contains(c)) {
        if let Ok(v) = word.parse::<f64>() {
            assert!(v.is_finite(), "{word} in\n{report}");
        }
    }
    for fig in ["fig5_sin_roll.png", "fig8_confusion_w10_w70.png"] {
        assert!(out.join("d-analysis").join(fig).is_file(), "{fig}");
    }
    assert!(out.join("a-flat/curves.png").is_file());

    let again = run();
    let said = String::from_utf8_lossy(&again.stderr);
    assert!(again.status.success(), "{said}");
    for stage in ["a-flat", "b-general", "e-specialists"] {
        assert!(
            said.contains(&format!("{stage}: done before, skipped")),
            "{said}"
        );
    }
}
