//! `estimator-proc analyze TRACES.csv --windows 10,20,40,70 --out DIR [--config F]`: the
//! paper's offline experiment (SPEC S7) with its table and figures.

use super::input::{InputArgs, Resolved};
use crate::analysis::{self, DISTRIBUTION_WINDOW, HEATMAP_WINDOWS, Series, WindowResult};
use crate::gmm::FitOptions;
use crate::report::{AnalysisReport, SeriesCount, create_dir, print_output, to_json, write_file};
use crate::{EstimatorError, figures, traces};
use anyhow::Context as _;
use common::AreaKind;
use common::config::MixtureFeature;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct AnalyzeArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Output directory for results.json, results.md and the PNG figures (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// Paper Fig. 5: sin θz (roll) in the two areas.
pub const FIG_ROLL: &str = "fig5_sin_roll.png";
/// Paper Fig. 6: sin θx (pitch) in the two areas.
pub const FIG_PITCH: &str = "fig6_sin_pitch.png";
/// Paper Fig. 7: distribution of the 100-tick window std per area.
pub const FIG_DISTRIBUTION: &str = "fig7_std_distribution_w100.png";
/// Paper Fig. 8: confusion heatmaps for windows 10 and 70.
pub const FIG_CONFUSION: &str = "fig8_confusion_w10_w70.png";

pub fn execute(args: &AnalyzeArgs) -> anyhow::Result<()> {
    let Resolved {
        est: cfg,
        seed,
        min_step_travel: gate,
        ..
    } = args.input.resolve()?;
    let path = &args.input.traces;
    let rows = traces::read_telemetry(path, cfg.signal)?;
    let series = analysis::split_series(&rows, cfg.warmup_ticks);
    tracing::info!(rows = rows.len(), series = series.len(), "telemetry read");
    let opts = FitOptions::from_config(&cfg, seed);
    let results = cfg
        .windows
        .iter()
        .map(|&w| {
            analysis::analyze_window(&series, w, &opts, gate, cfg.feature)
                .with_context(|| format!("window {w}"))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    create_dir(&args.out)?;
    let figures = draw_figures(&args.out, &series, &results, &opts, (gate, cfg.feature))?;
    let count = |a: AreaKind| series.iter().filter(|s| s.area == a).count();
    let report = AnalysisReport {
        input: path.display().to_string(),
        warmup_ticks: cfg.warmup_ticks,
        seed,
        components: cfg.components,
        equal_weights: cfg.equal_weights,
        std: "sample std (ddof = 1, as pandas rolling().std())",
        signal: cfg.signal,
        series: SeriesCount {
            flat: count(AreaKind::Flat),
            rough: count(AreaKind::Rough),
        },
        windows: results,
        paper_table_3: analysis::PAPER_TABLE_3.to_vec(),
        figures,
    };
    let markdown = report.to_markdown();
    write_file(&args.out.join("results.json"), &to_json(&report))?;
    write_file(&args.out.join("results.md"), &markdown)?;
    print_output(&markdown);
    Ok(())
}

/// Figs. 5–8; a figure whose window no series is long enough for is skipped with a warning.
fn draw_figures(
    out: &Path,
    series: &[Series],
    results: &[WindowResult],
    opts: &FitOptions,
    (gate, feature): (f64, MixtureFeature),
) -> anyhow::Result<Vec<String>> {
    let mut written = Vec::new();
    figures::draw_time_series(
        &out.join(FIG_ROLL),
        "sin θz (roll) in the two areas",
        "sin θz",
        series,
        |s| &s.sin_roll,
    )?;
    written.push(FIG_ROLL.to_string());
    figures::draw_time_series(
        &out.join(FIG_PITCH),
        "sin θx (pitch) in the two areas",
        "sin θx",
        series,
        |s| &s.sin_pitch,
    )?;
    written.push(FIG_PITCH.to_string());
    match analysis::window_values(series, DISTRIBUTION_WINDOW, gate) {
        Ok(wv) => {
            let (flat, rough) = (wv.of(AreaKind::Flat), wv.of(AreaKind::Rough));
            figures::draw_distribution(
                &out.join(FIG_DISTRIBUTION),
                DISTRIBUTION_WINDOW,
                &flat,
                &rough,
            )?;
            written.push(FIG_DISTRIBUTION.to_string());
        }
        Err(e @ (EstimatorError::NoWindows { .. } | EstimatorError::AllStationary { .. })) => {
            tracing::warn!(%e, "skipping {FIG_DISTRIBUTION}");
        }
        Err(e) => return Err(e.into()),
    }
    let mut heatmaps = Vec::new();
    for w in HEATMAP_WINDOWS {
        match results.iter().find(|r| r.window == w) {
            Some(r) => heatmaps.push(r.clone()),
            None => match analysis::analyze_window(series, w, opts, gate, feature) {
                Ok(r) => heatmaps.push(r),
                Err(
                    e @ (EstimatorError::NoWindows { .. } | EstimatorError::AllStationary { .. }),
                ) => {
                    tracing::warn!(%e, "confusion heatmap skipped");
                }
                Err(e) => return Err(anyhow::Error::from(e).context(format!("window {w}"))),
            },
        }
    }
    if !heatmaps.is_empty() {
        figures::draw_confusions(
            &out.join(FIG_CONFUSION),
            &heatmaps.iter().collect::<Vec<_>>(),
        )?;
        written.push(FIG_CONFUSION.to_string());
    }
    Ok(written)
}
