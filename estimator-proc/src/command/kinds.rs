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
use crate::analysis::{self, Series};
use crate::features::{self, FeatureWindows, Wheels};
use crate::kinds::{self, KindsResult, StoredKinds};
use crate::mixture::MixtureOptions;
use crate::report::{create_dir, print_output, to_json, write_file};
use crate::{figures, traces};
use anyhow::Context as _;
use common::AreaKind;
use common::config::{EstimatorConfig, KindsFit, WindowFeature};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct KindsArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Mixture components, 1 ..= 16 [default: `estimator.components-per-kind` per terrain kind
    /// in the recording].
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
    let per_kind = match cfg.kinds_fit {
        KindsFit::Em => cfg.components_per_kind,
        KindsFit::Labelled => 1,
    };
    let components = args
        .components
        .map_or(kinds.len() * per_kind, |k| k as usize);
    anyhow::ensure!(
        components <= 16,
        "estimator.components-per-kind = {per_kind} with {} kinds asks for {components} mixture components; at most 16",
        kinds.len()
    );
    let opts = MixtureOptions::from_config(&cfg, components, seed);
    let names: Vec<&'static str> = cfg.features.iter().map(|f| f.name()).collect();
    tracing::info!(rows = rows.len(), series = series.len(), kinds = kinds.len(), features = ?names, "telemetry read");
    let recording = Recording {
        cfg: &cfg,
        series: &series,
        kinds: &kinds,
        opts: &opts,
        gate,
        wheels,
    };
    let mut scored = Scored::default();
    let stored = args.model.as_deref().map(kinds::read_stored).transpose()?;
    for named in stored.into_iter().flatten() {
        recording.score_stored(named, &mut scored)?;
    }
    if args.model.is_none() {
        for &w in &cfg.windows {
            recording.fit_window(w, &names, &mut scored)?;
        }
    }
    let figures = draw_figures(&args.out, &scored)?;
    let report = KindsReport {
        input: path.display().to_string(),
        model: args.model.as_ref().map(|m| m.display().to_string()),
        seed,
        warmup_ticks: cfg.warmup_ticks,
        covariance: cfg.covariance,
        kinds_fit: cfg.kinds_fit,
        unknown_beyond: cfg.unknown_beyond,
        windows: scored.results,
        ablation: scored.ablation,
        figures,
    };
    let markdown = to_markdown(&report);
    write_file(&args.out.join("kinds.json"), &to_json(&report))?;
    write_file(&args.out.join("kinds.md"), &markdown)?;
    print_output(&markdown);
    Ok(())
}

/// What a `kinds` run scores: the recording's series, the kinds in them, and the settings
/// to cut and fit their windows with.
struct Recording<'a> {
    cfg: &'a EstimatorConfig,
    series: &'a [Series],
    kinds: &'a [AreaKind],
    opts: &'a MixtureOptions,
    /// The stationary gate, metres per tick.
    gate: f64,
    wheels: Wheels,
}

/// The results so far: one per window size, the ablation, and the windows of the scatter
/// figure with the index of their result.
#[derive(Default)]
struct Scored {
    results: Vec<KindsResult>,
    ablation: Vec<Ablation>,
    scatter: Option<(FeatureWindows, usize)>,
}

impl Recording<'_> {
    /// The recording's windows of `w` ticks on `features`.
    fn windows(&self, w: usize, features: &[WindowFeature]) -> anyhow::Result<FeatureWindows> {
        features::window_features(self.series, w, features, self.gate, self.wheels)
            .with_context(|| format!("window {w}"))
    }

    /// The mixture over `features` fitted to `windows` (of `w` ticks), named by the labels.
    fn fit(
        &self,
        windows: &FeatureWindows,
        w: usize,
        features: &[WindowFeature],
    ) -> anyhow::Result<KindsResult> {
        kinds::fit_and_name(
            windows,
            w,
            features,
            self.kinds,
            (self.opts, self.cfg.kinds_fit),
            self.cfg.unknown_beyond,
        )
        .with_context(|| format!("window {w}"))
    }

    /// Scores a stored, named classifier on the recording's windows of its size.
    fn score_stored(&self, named: StoredKinds, scored: &mut Scored) -> anyhow::Result<()> {
        let w = named.window;
        let windows = self.windows(w, &named.features)?;
        let result = kinds::score_stored(named, &windows, self.cfg.unknown_beyond);
        scored.results.push(result);
        if w == self.cfg.online_window && windows.dim > 1 {
            scored.scatter = Some((windows, scored.results.len() - 1));
        }
        Ok(())
    }

    /// Fits and names the mixture on windows of `w` ticks; at the online window, also
    /// without each of the features `names` in turn.
    fn fit_window(
        &self,
        w: usize,
        names: &[&'static str],
        scored: &mut Scored,
    ) -> anyhow::Result<()> {
        let features = &self.cfg.features;
        let windows = self.windows(w, features)?;
        scored.results.push(self.fit(&windows, w, features)?);
        if w == self.cfg.online_window && names.len() > 1 {
            for (i, &without) in names.iter().enumerate() {
                let keep: Vec<usize> = (0..names.len()).filter(|&j| j != i).collect();
                let kept: Vec<WindowFeature> = keep.iter().map(|&j| features[j]).collect();
                let r = self.fit(&windows.select(&keep), w, &kept)?;
                scored.ablation.push(Ablation {
                    window: w,
                    without,
                    macro_accuracy: r.macro_accuracy,
                });
            }
            scored.scatter = Some((windows, scored.results.len() - 1));
        }
        Ok(())
    }
}

/// Creates `out` and draws the confusion matrices and, when there is one, the scatter
/// figure into it; returns the files' names.
fn draw_figures(out: &Path, scored: &Scored) -> anyhow::Result<Vec<String>> {
    create_dir(out)?;
    let mut figures = vec![FIG_CONFUSION.to_string()];
    figures::kinds::draw_kinds_confusions(
        &out.join(FIG_CONFUSION),
        &scored.results.iter().collect::<Vec<_>>(),
    )?;
    if let Some((windows, i)) = &scored.scatter {
        let result = &scored.results[*i];
        let name = format!("fig_kinds_scatter_w{}.png", result.window);
        figures::kinds::draw_feature_scatter(&out.join(&name), windows, result)?;
        figures.push(name);
    }
    Ok(figures)
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
