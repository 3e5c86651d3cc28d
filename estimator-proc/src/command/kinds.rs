//! `estimator-proc kinds TRACES.csv --out DIR [--config F] [--components K]`: several terrain
//! kinds told apart offline, beyond SPEC S7's two (docs/EXPERIMENT.md E14).
//!
//! Per window size: the mixture over `estimator.features` fitted to every window (labels
//! unused), each component named after the kind most of its windows have in a one-to-one
//! assignment (Hungarian), and the confusion and macro accuracy this gives on the same
//! windows. At `estimator.online-window` each feature is also left out once. `kinds.json`
//! holds every model with its naming, `kinds.md` the tables; `fig_kinds_confusion.png` the
//! confusion matrices and, with two features or more, `fig_kinds_scatter_w<W>.png` the first
//! two features' windows at the online window with the mixture's 2σ ellipses.

use super::input::{InputArgs, Resolved};
use crate::analysis;
use crate::features::{self, FeatureWindows};
use crate::kinds::{self, KindsResult};
use crate::mixture::MixtureOptions;
use crate::report::{create_dir, print_output, to_json, write_file};
use crate::{figures, traces};
use anyhow::Context as _;
use common::AreaKind;
use common::config::{KindsFit, WindowFeature};
use serde::Serialize;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct KindsArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Mixture components, 1 ..= 16 [default: one per terrain kind in the recording].
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=16))]
    pub components: Option<u64>,
    /// Score the recording with the named classifiers of this `kinds.json` (written by an
    /// earlier `kinds` run, e.g. on another recording) instead of fitting: its window sizes
    /// and features, no ablation.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Output directory for kinds.json and kinds.md (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// What `kinds.json` holds.
#[derive(Debug, Serialize)]
struct KindsReport {
    input: String,
    /// The `kinds.json` whose classifiers scored the recording (`--model`); none: fitted here.
    model: Option<String>,
    seed: u64,
    warmup_ticks: usize,
    covariance: common::config::Covariance,
    kinds_fit: KindsFit,
    unknown_beyond: f64,
    windows: Vec<KindsResult>,
    /// At the online window, the macro accuracy without each feature in turn.
    ablation: Vec<Ablation>,
    /// The PNGs written beside this file.
    figures: Vec<String>,
}

/// Every window size's K-kind confusion matrix.
pub const FIG_CONFUSION: &str = "fig_kinds_confusion.png";

#[derive(Debug, Serialize)]
struct Ablation {
    window: usize,
    without: &'static str,
    macro_accuracy: f64,
}

pub fn execute(args: &KindsArgs) -> anyhow::Result<()> {
    let Resolved {
        est: cfg,
        seed,
        min_step_travel: gate,
        wheels,
    } = args.input.resolve()?;
    let path = &args.input.traces;
    let rows = traces::read_any_kind(path, cfg.signal)?;
    let series = analysis::split_series(&rows, cfg.warmup_ticks);
    let kinds: Vec<AreaKind> = AreaKind::KINDS
        .into_iter()
        .filter(|k| series.iter().any(|s| s.area == *k))
        .collect();
    let components = args.components.map_or(kinds.len(), |k| k as usize);
    let opts = MixtureOptions::from_config(&cfg, components, seed);
    let names: Vec<&'static str> = cfg.features.iter().map(|f| f.name()).collect();
    tracing::info!(rows = rows.len(), series = series.len(), kinds = kinds.len(), features = ?names, "telemetry read");
    let fit = |windows: &FeatureWindows, w: usize, features: &[WindowFeature]| {
        kinds::fit_and_name(
            windows,
            w,
            features,
            &kinds,
            (&opts, cfg.kinds_fit),
            cfg.unknown_beyond,
        )
        .with_context(|| format!("window {w}"))
    };
    let mut results = Vec::new();
    let mut ablation = Vec::new();
    let mut scatter = None;
    let stored = args.model.as_deref().map(kinds::read_stored).transpose()?;
    for named in stored.into_iter().flatten() {
        let w = named.window;
        let windows = features::window_features(&series, w, &named.features, gate, wheels)
            .with_context(|| format!("window {w}"))?;
        results.push(kinds::score_stored(named, &windows, cfg.unknown_beyond));
        if w == cfg.online_window && windows.dim > 1 {
            scatter = Some((windows, results.len() - 1));
        }
    }
    let windows_to_fit = if args.model.is_some() {
        &[][..]
    } else {
        &cfg.windows[..]
    };
    for &w in windows_to_fit {
        let windows = features::window_features(&series, w, &cfg.features, gate, wheels)
            .with_context(|| format!("window {w}"))?;
        results.push(fit(&windows, w, &cfg.features)?);
        if w == cfg.online_window && names.len() > 1 {
            for (i, &without) in names.iter().enumerate() {
                let keep: Vec<usize> = (0..names.len()).filter(|&j| j != i).collect();
                let kept: Vec<WindowFeature> = keep.iter().map(|&j| cfg.features[j]).collect();
                let r = fit(&windows.select(&keep), w, &kept)?;
                ablation.push(Ablation {
                    window: w,
                    without,
                    macro_accuracy: r.macro_accuracy,
                });
            }
            scatter = Some((windows, results.len() - 1));
        }
    }
    create_dir(&args.out)?;
    let mut figures = vec![FIG_CONFUSION.to_string()];
    figures::kinds::draw_kinds_confusions(
        &args.out.join(FIG_CONFUSION),
        &results.iter().collect::<Vec<_>>(),
    )?;
    if let Some((windows, i)) = &scatter {
        let name = format!("fig_kinds_scatter_w{}.png", results[*i].window);
        figures::kinds::draw_feature_scatter(&args.out.join(&name), windows, &results[*i])?;
        figures.push(name);
    }
    let report = KindsReport {
        input: path.display().to_string(),
        model: args.model.as_ref().map(|m| m.display().to_string()),
        seed,
        warmup_ticks: cfg.warmup_ticks,
        covariance: cfg.covariance,
        kinds_fit: cfg.kinds_fit,
        unknown_beyond: cfg.unknown_beyond,
        windows: results,
        ablation,
        figures,
    };
    let markdown = to_markdown(&report);
    write_file(&args.out.join("kinds.json"), &to_json(&report))?;
    write_file(&args.out.join("kinds.md"), &markdown)?;
    print_output(&markdown);
    Ok(())
}

fn pct(x: f64) -> String {
    format!("{:.2}", 100.0 * x)
}

/// `items`' names, joined by `sep`.
fn names<T: Copy>(items: &[T], name: fn(T) -> &'static str, sep: &str) -> String {
    items.iter().map(|&i| name(i)).collect::<Vec<_>>().join(sep)
}

fn to_markdown(r: &KindsReport) -> String {
    let Some(first) = r.windows.first() else {
        return String::new();
    };
    let named_by = r.model.as_ref().map_or_else(
        || match r.kinds_fit {
            KindsFit::Em => "Mixture fitted by EM without the labels, its components named by them (Hungarian).",
            KindsFit::Labelled => "One component fitted to each kind's windows, named by the labels (Hungarian).",
        }
        .to_string(),
        |m| format!("Classifiers and their naming read from `{m}`."),
    );
    let mut md = format!(
        "# Terrain kinds on `{}`\n\nFeatures: {}. Kinds: {}. {named_by}\n\n| window | windows | macro accuracy % | accuracy % | unknown | components → kinds |\n|---:|---:|---:|---:|---:|---|\n",
        r.input,
        names(&first.features, WindowFeature::name, ", "),
        names(&first.kinds, AreaKind::name, ", ")
    );
    for w in &r.windows {
        md += &format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            w.window,
            w.n,
            pct(w.macro_accuracy),
            pct(w.accuracy),
            w.unknown,
            names(&w.component_kinds, AreaKind::name, ", ")
        );
    }
    for w in &r.windows {
        md += &format!(
            "\n## Window {}: windows of each true kind (rows) by the kind given (columns)\n\n| true \\ given | {} | unknown |\n|---|{}---:|\n",
            w.window,
            names(&w.kinds, AreaKind::name, " | "),
            "---:|".repeat(w.kinds.len())
        );
        for (kind, row) in w.kinds.iter().map(|k| k.name()).zip(&w.confusion) {
            let total: u64 = row.iter().sum::<u64>().max(1);
            let cells: Vec<String> = row
                .iter()
                .map(|&c| format!("{c} ({:.1} %)", 100.0 * c as f64 / total as f64))
                .collect();
            md += &format!("| {kind} | {} |\n", cells.join(" | "));
        }
    }
    if !r.ablation.is_empty() {
        md += "\n## Each feature left out once\n\n| window | without | macro accuracy % |\n|---:|---|---:|\n";
        for a in &r.ablation {
            md += &format!(
                "| {} | {} | {} |\n",
                a.window,
                a.without,
                pct(a.macro_accuracy)
            );
        }
    }
    md
}
