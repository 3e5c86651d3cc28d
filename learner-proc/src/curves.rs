//! Learning curves: a run's `metrics.csv` drawn as one PNG of eight panels over env steps.
//!
//! The CSV is read by column name, not as [`UpdateMetrics`](crate::UpdateMetrics), so a file
//! with other columns than this build writes still plots. A metric left empty (no episode
//! ended) or not finite (explained variance of constant returns) is skipped in its panel only.
//! Each panel shows the raw values faintly and a debiased exponential moving average on top,
//! since per-update episode statistics rest on few episodes and are noisy.
//!
//! Text needs a font and nothing outside the repository may be assumed on a machine: the
//! DejaVu Sans TTFs inside the `dejavu` crate are registered with plotters' `ab_glyph`
//! renderer, as estimator-proc does for its figures. The picture is drawn into memory and
//! encoded with `png`, so the file is replaced atomically like a checkpoint and a reader never
//! sees half a figure.

use std::error::Error;
use std::fs::File;
use std::ops::Range;
use std::path::Path;

use common::plot::FONT;
use plotters::backend::RGBPixel;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::LearnerError;
use crate::checkpoint::write_atomic;

/// The figure's size in pixels: a 4 × 2 grid of panels about 800 × 330 each, under a title.
pub const SIZE: (u32, u32) = (1600, 1400);
const GRID: RGBColor = RGBColor(242, 242, 242);
/// Weight of the past in the moving average (TensorBoard's smoothing slider).
const SMOOTHING: f64 = 0.9;
/// Significant digits of tick labels. Ticks are round numbers, so digits beyond their own only
/// remove float noise; a fixed small count would print a narrow range (entropy 2.8372 to
/// 2.8378) as one repeated label.
const TICK_DIGITS: i32 = 10;
/// The x column: env steps, also the learning-rate schedule's position.
const STEPS: &str = "global_step";

/// One panel: the CSV column it plots, its caption and colour, and a fixed y range when the
/// metric has natural bounds.
struct Panel {
    column: &'static str,
    title: &'static str,
    color: RGBColor,
    y_range: Option<(f64, f64)>,
}

/// Row by row, left to right: outcome, losses, policy change, value fit (matplotlib's tab10).
const PANELS: [Panel; 8] = [
    Panel {
        column: "mean_episode_return",
        title: "mean episode return",
        color: RGBColor(31, 119, 180),
        y_range: None,
    },
    Panel {
        column: "success_rate",
        title: "success rate",
        color: RGBColor(44, 160, 44),
        y_range: Some((-0.02, 1.02)),
    },
    Panel {
        column: "policy_loss",
        title: "policy loss",
        color: RGBColor(214, 39, 40),
        y_range: None,
    },
    Panel {
        column: "value_loss",
        title: "value loss",
        color: RGBColor(148, 103, 189),
        y_range: None,
    },
    Panel {
        column: "entropy",
        title: "entropy",
        color: RGBColor(140, 86, 75),
        y_range: None,
    },
    Panel {
        column: "approx_kl",
        title: "approx KL",
        color: RGBColor(227, 119, 194),
        y_range: None,
    },
    Panel {
        column: "clip_fraction",
        title: "clip fraction",
        color: RGBColor(255, 127, 14),
        y_range: None,
    },
    Panel {
        column: "explained_variance",
        title: "explained variance",
        color: RGBColor(23, 190, 207),
        y_range: None,
    },
];

/// What a metrics CSV holds for the figure: each row's env steps and panel values.
#[derive(Debug, Default, PartialEq)]
struct Curves {
    steps: Vec<f64>,
    /// `values[row][panel]`; `None` where the metric was empty or not finite.
    values: Vec<[Option<f64>; PANELS.len()]>,
}

impl Curves {
    /// The points of panel `p`, in step order.
    fn points(&self, p: usize) -> Vec<(f64, f64)> {
        self.steps
            .iter()
            .zip(&self.values)
            .filter_map(|(&x, row)| row[p].map(|y| (x, y)))
            .collect()
    }
}

/// Draws the learning curves of the metrics CSV at `metrics` into the PNG `out` (replaced
/// atomically); returns how many updates the figure shows.
pub fn plot(metrics: &Path, out: &Path) -> Result<usize, LearnerError> {
    let curves = read(metrics)?;
    let run = metrics
        .parent()
        .and_then(Path::file_name)
        .map(|d| format!("{}: ", d.to_string_lossy()))
        .unwrap_or_default();
    let title = match curves.steps.last() {
        Some(&steps) => format!(
            "{run}{}, {} env steps (faint: each update, bold: moving average)",
            updates(curves.steps.len()),
            number(steps, 4)
        ),
        None => format!("{run}no updates yet"),
    };
    write_atomic(out, &draw(&curves, &title, out)?)?;
    Ok(curves.steps.len())
}

/// "1 update", "3 updates".
pub(crate) fn updates(n: usize) -> String {
    format!("{n} update{}", if n == 1 { "" } else { "s" })
}

/// Reads the x column and the panels' columns of a metrics CSV. A learner resumed from an
/// older checkpoint appends rows whose steps go back; they replace the rows from that step on,
/// as the resumed run replaced what the crashed one did.
fn read(path: &Path) -> Result<Curves, LearnerError> {
    let bad = |reason: String| LearnerError::MetricsFormat {
        path: path.to_path_buf(),
        reason,
    };
    let csv_err = |source| LearnerError::Metrics {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(LearnerError::io("opening", path))?;
    let mut reader = csv::ReaderBuilder::new().flexible(true).from_reader(file);
    let header = reader.headers().map_err(csv_err)?.clone();
    if header.is_empty() {
        return Err(bad("the file is empty, not even a header row".into()));
    }
    let column = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| bad(format!("line 1: no column `{name}` in the header")))
    };
    let x_col = column(STEPS)?;
    let cols = PANELS
        .iter()
        .map(|p| column(p.column))
        .collect::<Result<Vec<_>, _>>()?;

    let mut curves = Curves::default();
    for record in reader.records() {
        let record = record.map_err(csv_err)?;
        let line = record.position().map_or(0, csv::Position::line);
        let field = |col: usize| -> Result<Option<f64>, LearnerError> {
            let name = &header[col];
            let Some(text) = record.get(col) else {
                return Err(bad(format!(
                    "line {line}, column `{name}`: missing (the row has {} fields, the header {})",
                    record.len(),
                    header.len()
                )));
            };
            let text = text.trim();
            if text.is_empty() {
                return Ok(None);
            }
            let v: f64 = text.parse().map_err(|_| {
                bad(format!(
                    "line {line}, column `{name}`: {text:?} is not a number"
                ))
            })?;
            Ok(v.is_finite().then_some(v))
        };
        let Some(x) = field(x_col)? else {
            return Err(bad(format!(
                "line {line}, column `{STEPS}`: empty or not finite"
            )));
        };
        let mut row = [None; PANELS.len()];
        for (v, &col) in row.iter_mut().zip(&cols) {
            *v = field(col)?;
        }
        let keep = curves.steps.partition_point(|&s| s < x);
        curves.steps.truncate(keep);
        curves.values.truncate(keep);
        curves.steps.push(x);
        curves.values.push(row);
    }
    Ok(curves)
}

/// Registers the bundled font once per process.
fn ensure_font(path: &Path) -> Result<(), LearnerError> {
    common::plot::register_fonts().map_err(|e| plot_error(path, e))
}

fn plot_error(path: &Path, reason: impl std::fmt::Display) -> LearnerError {
    LearnerError::Plot {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// The figure as PNG bytes; `path` (where it will go) names it in errors.
fn draw(curves: &Curves, title: &str, path: &Path) -> Result<Vec<u8>, LearnerError> {
    ensure_font(path)?;
    let (width, height) = SIZE;
    let mut rgb = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::<RGBPixel>::with_buffer_and_format(&mut rgb, SIZE)
            .map_err(|e| plot_error(path, e))?
            .into_drawing_area();
        draw_panels(&root, curves, title).map_err(|e| plot_error(path, e))?;
        root.present().map_err(|e| plot_error(path, e))?;
    }
    let mut png = Vec::new();
    let mut encoder = png::Encoder::new(&mut png, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()
        .and_then(|mut w| w.write_image_data(&rgb).and_then(|()| w.finish()))
        .map_err(|e| plot_error(path, e))?;
    Ok(png)
}

type DrawResult = Result<(), Box<dyn Error>>;

fn draw_panels(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    curves: &Curves,
    title: &str,
) -> DrawResult {
    root.fill(&WHITE)?;
    let root = root.titled(title, (FONT, 26).into_font().style(FontStyle::Bold))?;
    // From 0, where training starts, to the last row (1 when there is none yet).
    let x = 0.0..curves.steps.last().map_or(1.0, |&hi| hi.max(1.0));
    for (p, area) in root.split_evenly((4, 2)).iter().enumerate() {
        draw_panel(area, &PANELS[p], &curves.points(p), x.clone())?;
    }
    Ok(())
}

fn draw_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    panel: &Panel,
    points: &[(f64, f64)],
    x: Range<f64>,
) -> DrawResult {
    let (lo, hi) = panel
        .y_range
        .unwrap_or_else(|| padded_range(points.iter().map(|p| p.1)));
    let caption = match points.last() {
        Some(&(_, v)) => format!("{} (last {})", panel.title, number(v, 4)),
        None => format!("{} (no values yet)", panel.title),
    };
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x, lo..hi)?;
    chart
        .configure_mesh()
        .x_desc("env steps")
        .x_label_formatter(&|v| number(*v, TICK_DIGITS))
        .y_label_formatter(&|v| number(*v, TICK_DIGITS))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .light_line_style(GRID)
        .max_light_lines(4)
        .draw()?;
    let color = panel.color;
    chart.draw_series(LineSeries::new(
        points.iter().copied(),
        color.mix(0.3).stroke_width(1),
    ))?;
    chart.draw_series(LineSeries::new(
        smoothed(points, SMOOTHING),
        color.stroke_width(2),
    ))?;
    // A line needs two points; a lone value would otherwise not show at all.
    if let [only] = points {
        chart.draw_series([Circle::new(*only, 4, color.filled())])?;
    }
    Ok(())
}

/// `[min, max]` of the values, padded by 5 %, never empty.
fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    // A constant series gets a band around it, so its line shows in the middle of the panel.
    let pad = match (hi - lo) * 0.05 {
        spread if spread > 0.0 => spread,
        _ if lo != 0.0 => lo.abs() * 0.05,
        _ => 1.0,
    };
    (lo - pad, hi + pad)
}

/// TensorBoard's smoothing: an exponential moving average with `weight` on the past, divided
/// by the weights' sum so the first points are not pulled towards zero.
fn smoothed(points: &[(f64, f64)], weight: f64) -> impl Iterator<Item = (f64, f64)> + '_ {
    let (mut ema, mut decay) = (0.0, 1.0);
    points.iter().map(move |&(x, y)| {
        ema = weight * ema + (1.0 - weight) * y;
        decay *= weight;
        (x, ema / (1.0 - decay))
    })
}

/// `v` for a label: at most `digits` significant digits and without float noise (0.3, not
/// 0.30000000000000004), k/M/G from 10⁴ on (env steps run to millions), scientific below 10⁻³
/// (KL is often that small), and "0", never "-0".
fn number(v: f64, digits: i32) -> String {
    let a = v.abs();
    if a == 0.0 || !a.is_finite() {
        return if a == 0.0 { "0".into() } else { v.to_string() };
    }
    let (scaled, suffix) = match a {
        a if a >= 1e9 => (v / 1e9, "G"),
        a if a >= 1e6 => (v / 1e6, "M"),
        a if a >= 1e4 => (v / 1e3, "k"),
        _ => (v, ""),
    };
    let r = round_significant(scaled, digits);
    if a < 1e-3 {
        format!("{r:e}")
    } else {
        format!("{r}{suffix}")
    }
}

/// `v` rounded to `digits` significant digits, dividing by exact powers of ten so the result
/// prints as the short decimal it is.
fn round_significant(v: f64, digits: i32) -> f64 {
    let shift = digits - 1 - v.abs().log10().floor() as i32;
    if shift >= 0 {
        let p = 10f64.powi(shift);
        (v * p).round() / p
    } else {
        let p = 10f64.powi(-shift);
        (v / p).round() * p
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::run_dir::{CURVES_PNG, METRICS_CSV};

    const HEADER: &str = "update,global_step,policy_version,learning_rate,policy_loss,value_loss,\
        entropy,old_approx_kl,approx_kl,clip_fraction,explained_variance,grad_norm,epochs,\
        samples_per_second,mean_policy_lag,stale_transitions,episodes,mean_episode_return,\
        success_rate,mean_reach_time_s";

    /// Row `update` of a run with 2048 steps per update; no episode ends in update 1, and
    /// explained variance is NaN there, as the learner writes it for constant returns.
    fn row(update: u64) -> String {
        let u = update as f64;
        let (episodes, ret, success) = if update == 1 {
            ("0", String::new(), String::new())
        } else {
            (
                "8",
                format!("{}", 10.0 * u),
                format!("{}", (u / 6.0).min(1.0)),
            )
        };
        let ev = if update == 1 {
            "NaN".to_string()
        } else {
            format!("{}", 1.0 - 1.0 / u)
        };
        format!(
            "{update},{},{update},0.0003,{},{},{},0.001,{},{},{ev},0.5,10,90000,0,0,{episodes},{ret},{success},",
            2048 * update,
            -0.01 * u,
            5.0 / u,
            2.8 - 0.1 * u,
            0.01 / u,
            0.2 / u
        )
    }

    fn csv(rows: impl IntoIterator<Item = String>) -> String {
        std::iter::once(HEADER.to_string())
            .chain(rows)
            .map(|l| l + "\n")
            .collect()
    }

    #[test]
    fn a_small_csv_plots_to_a_png_of_the_stated_size() {
        let dir = tempfile::tempdir().expect("tempdir");
        let metrics = dir.path().join(METRICS_CSV);
        std::fs::write(&metrics, csv((1..=6).map(row))).expect("write");
        let out = dir.path().join(CURVES_PNG);
        assert_eq!(plot(&metrics, &out).expect("plot"), 6);
        let png = std::fs::read(&out).expect("read png");
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "PNG magic");
        // IHDR is the first chunk: length, "IHDR", width, height (big-endian).
        assert_eq!(&png[12..16], b"IHDR");
        let be = |at: usize| u32::from_be_bytes([png[at], png[at + 1], png[at + 2], png[at + 3]]);
        assert_eq!((be(16), be(20)), SIZE);
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .expect("ls")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names.len(), 2, "no temp file left behind: {names:?}");
    }

    #[test]
    fn empty_and_nan_values_are_skipped_in_their_panel_only() {
        let dir = tempfile::tempdir().expect("tempdir");
        let metrics = dir.path().join(METRICS_CSV);
        std::fs::write(&metrics, csv((1..=3).map(row))).expect("write");
        let curves = read(&metrics).expect("read");
        assert_eq!(curves.steps, [2048.0, 4096.0, 6144.0]);
        let panel = |column| {
            PANELS
                .iter()
                .position(|p| p.column == column)
                .expect("panel")
        };
        assert_eq!(
            curves.points(panel("mean_episode_return")),
            [(4096.0, 20.0), (6144.0, 30.0)]
        );
        assert_eq!(curves.points(panel("explained_variance")).len(), 2);
        assert_eq!(curves.points(panel("policy_loss")).len(), 3);
    }

    /// A learner resumed from the checkpoint after update 2 rewrote updates 3 and 4.
    #[test]
    fn rows_after_a_resume_replace_the_ones_they_repeat() {
        let dir = tempfile::tempdir().expect("tempdir");
        let metrics = dir.path().join(METRICS_CSV);
        std::fs::write(&metrics, csv([1, 2, 3, 4, 3, 4, 5].map(row))).expect("write");
        let curves = read(&metrics).expect("read");
        assert_eq!(curves.steps, [1, 2, 3, 4, 5].map(|u| 2048.0 * f64::from(u)));
    }

    #[test]
    fn a_malformed_csv_is_refused_naming_file_line_and_column() {
        let dir = tempfile::tempdir().expect("tempdir");
        let metrics = dir.path().join(METRICS_CSV);
        let out = dir.path().join(CURVES_PNG);
        let refuse = |text: String, needles: &[&str]| {
            std::fs::write(&metrics, text).expect("write");
            let msg = plot(&metrics, &out).expect_err("malformed").to_string();
            assert!(msg.contains(&metrics.display().to_string()), "{msg}");
            for needle in needles {
                assert!(msg.contains(needle), "{needle:?} not in {msg}");
            }
            assert!(!msg.contains('\n'), "one line: {msg}");
            assert!(!out.exists(), "nothing written");
        };
        let mut rows: Vec<String> = (1..=3).map(row).collect();
        rows[1] = rows[1].replace(",2.5,", ",2.5x,"); // update 2's value loss
        refuse(csv(rows), &["line 3", "column `value_loss`", "\"2.5x\""]);
        refuse(
            csv([row(1), "2,4096,2,0.0003".into()]),
            &[
                "line 3",
                "column `mean_episode_return`",
                "the row has 4 fields",
            ],
        );
        refuse(
            csv([row(1)]).replace("value_loss", "vloss"),
            &["line 1", "no column `value_loss`"],
        );
        refuse(String::new(), &["empty"]);
        let e = plot(&dir.path().join("nope.csv"), &out).expect_err("missing");
        assert!(
            e.to_string().contains("nope.csv") && e.is_user_error(),
            "{e}"
        );
    }

    #[test]
    fn header_only_still_draws() {
        let dir = tempfile::tempdir().expect("tempdir");
        let metrics = dir.path().join(METRICS_CSV);
        std::fs::write(&metrics, csv([])).expect("write");
        assert_eq!(plot(&metrics, &dir.path().join("c.png")).expect("plot"), 0);
    }

    #[test]
    fn labels_by_hand() {
        assert_eq!(number(0.0, 4), "0");
        assert_eq!(number(-0.0, 4), "0");
        assert_eq!(number(0.1 + 0.2, 4), "0.3");
        assert_eq!(number(47.965_324_503, 4), "47.97");
        assert_eq!(number(-0.015_2, 4), "-0.0152");
        assert_eq!(number(3.0 * 1e-4, 4), "3e-4"); // 0.00030000000000000003
        assert_eq!(number(200_000.0, 4), "200k");
        assert_eq!(number(1_388_544.0, 4), "1.389M");
        assert_eq!(number(5e9, 4), "5G");
        assert_eq!(number(9999.0, 4), "9999");
        // Ticks keep their own digits and lose only the noise.
        assert_eq!(number(2.8 + 0.0372, TICK_DIGITS), "2.8372"); // 2.8371999999999997
        assert_eq!(number(12.0 * 0.1 * 1e6, TICK_DIGITS), "1.2M"); // 1200000.0000000002
    }

    /// Weight 0.9: the first point is its own value; the second is (0.09·y₁ + 0.1·y₂) / 0.19.
    #[test]
    fn smoothing_is_debiased() {
        let s: Vec<(f64, f64)> = smoothed(&[(0.0, 2.0), (1.0, 0.0), (2.0, 1.0)], 0.9).collect();
        assert!((s[0].1 - 2.0).abs() < 1e-12);
        assert!((s[1].1 - 0.18 / 0.19).abs() < 1e-12);
        let flat: Vec<f64> = smoothed(&[(0.0, 3.0); 5], 0.9).map(|p| p.1).collect();
        assert!(flat.iter().all(|v| (v - 3.0).abs() < 1e-12), "{flat:?}");
    }
}
