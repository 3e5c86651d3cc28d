//! The paper's figures (SPEC S7 step 4) as PNG, drawn with plotters' bitmap backend.
//!
//! Text needs a font, and nothing outside the repository may be assumed on a machine: the
//! DejaVu Sans TTFs ship inside the `dejavu` crate and are registered with plotters'
//! `ab_glyph` text renderer as "sans-serif" the first time a figure is drawn.

use crate::analysis::{Series, WindowResult};
use crate::{EstimatorError, Result};
use common::AreaKind;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

pub mod kinds;

use common::plot::FONT;
const GRID: RGBColor = RGBColor(242, 242, 242);

/// The area's colour (`AreaKind::colour`).
fn area_color(area: AreaKind) -> RGBColor {
    let [r, g, b] = area.colour();
    RGBColor(r, g, b)
}

/// Registers the bundled font once per process.
fn ensure_font(path: &Path) -> Result<()> {
    common::plot::register_fonts().map_err(|e| plot_error(path, e))
}

fn plot_error(path: &Path, reason: impl std::fmt::Display) -> EstimatorError {
    EstimatorError::Plot {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// Opens a white canvas of `size` pixels at `path`, runs `draw` on it and writes the PNG.
fn with_canvas<F>(path: &Path, size: (u32, u32), draw: F) -> Result<()>
where
    F: FnOnce(
        &DrawingArea<BitMapBackend<'_>, Shift>,
    ) -> std::result::Result<(), Box<dyn std::error::Error>>,
{
    ensure_font(path)?;
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_error(path, e))?;
    draw(&root).map_err(|e| plot_error(path, e))?;
    root.present().map_err(|e| plot_error(path, e))
}

/// An axis label: the shortest decimal of the value rounded to 6 places, and "0", never "-0".
fn axis_number(v: &f64) -> String {
    let r = (v * 1e6).round() / 1e6;
    if r == 0.0 { "0".into() } else { format!("{r}") }
}

/// `[min, max]` of the values, padded by 5 %, never empty.
fn padded_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-3);
    (lo - pad, hi + pad)
}

/// Paper Figs. 5–6: one signal over the ticks of the first series of each area, one panel per
/// area on a shared y-axis. `signal` picks the series' values; `label` names it.
pub fn draw_time_series(
    path: &Path,
    title: &str,
    label: &str,
    series: &[Series],
    signal: fn(&Series) -> &[f64],
) -> Result<()> {
    let shown: Vec<&Series> = [AreaKind::Flat, AreaKind::Rough]
        .iter()
        .filter_map(|&a| series.iter().find(|s| s.area == a))
        .collect();
    let (lo, hi) = padded_range(shown.iter().flat_map(|s| signal(s).iter().copied()));
    let height = 120 + 300 * shown.len().max(1) as u32;
    with_canvas(path, (1100, height), |root| {
        let root = root.titled(title, (FONT, 28).into_font().style(FontStyle::Bold))?;
        for (panel, s) in root
            .split_evenly((shown.len().max(1), 1))
            .iter()
            .zip(&shown)
        {
            let values = signal(s);
            let last = s.first_tick + values.len().saturating_sub(1) as u64;
            let mut chart = ChartBuilder::on(panel)
                .caption(
                    format!(
                        "{} area (env {}, ticks {}–{last})",
                        s.area.name(),
                        s.env,
                        s.first_tick
                    ),
                    (FONT, 20),
                )
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(75)
                .build_cartesian_2d(s.first_tick as f64..last as f64, lo..hi)?;
            chart
                .configure_mesh()
                .x_desc("tick (0.1 s)")
                .y_desc(label)
                .x_label_formatter(&axis_number)
                .y_label_formatter(&axis_number)
                .label_style((FONT, 15))
                .axis_desc_style((FONT, 17))
                .light_line_style(GRID)
                .draw()?;
            let color = area_color(s.area);
            chart.draw_series(LineSeries::new(
                values
                    .iter()
                    .enumerate()
                    .map(|(i, &v)| ((s.first_tick + i as u64) as f64, v)),
                color.stroke_width(2),
            ))?;
        }
        Ok(())
    })
}

/// Paper Fig. 7: the distribution of the window std per area, as the fraction of each area's
/// values per bin, overlaid.
pub fn draw_distribution(path: &Path, window: usize, flat: &[f64], rough: &[f64]) -> Result<()> {
    const BINS: usize = 40;
    let hi = flat
        .iter()
        .chain(rough)
        .copied()
        .fold(0.0f64, f64::max)
        .max(1e-6)
        * 1.02;
    let width = hi / BINS as f64;
    // Bin i as a rectangle from the axis up to `f`.
    let bar = |i: usize, f: f64| [(i as f64 * width, 0.0), ((i + 1) as f64 * width, f)];
    let histogram = |values: &[f64]| {
        let mut h = vec![0.0; BINS];
        for &v in values {
            h[((v / width) as usize).min(BINS - 1)] += 1.0 / values.len().max(1) as f64;
        }
        h
    };
    let hists = [
        (AreaKind::Flat, histogram(flat), flat.len()),
        (AreaKind::Rough, histogram(rough), rough.len()),
    ];
    let top = hists
        .iter()
        .flat_map(|h| h.1.iter().copied())
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.1;
    with_canvas(path, (1000, 650), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!("Distribution of sin θx std ({window}-tick window)"),
                (FONT, 26).into_font().style(FontStyle::Bold),
            )
            .margin(20)
            .x_label_area_size(55)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..hi, 0.0..top)?;
        chart
            .configure_mesh()
            .x_desc("rolling std of sin θx")
            .y_desc("fraction of the area's values")
            .x_label_formatter(&axis_number)
            .y_label_formatter(&axis_number)
            .label_style((FONT, 16))
            .axis_desc_style((FONT, 18))
            .light_line_style(GRID)
            .draw()?;
        for (area, h, n) in &hists {
            if *n == 0 {
                continue;
            }
            let color = area_color(*area);
            chart
                .draw_series(
                    h.iter()
                        .enumerate()
                        .map(|(i, &f)| Rectangle::new(bar(i, f), color.mix(0.45).filled())),
                )?
                .label(format!("{} (n = {n})", area.name()))
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 7), (x + 18, y + 7)], color.mix(0.6).filled())
                });
            chart.draw_series(
                h.iter()
                    .enumerate()
                    .filter(|(_, f)| **f > 0.0)
                    .map(|(i, &f)| Rectangle::new(bar(i, f), color.stroke_width(1))),
            )?;
        }
        draw_legend(&mut chart)?;
        Ok(())
    })
}

/// The series' legend, upper right, as every figure here draws it.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT, 18))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()
}

/// Paper Fig. 8: one confusion heatmap per result, side by side. Rows: true area; columns:
/// mixture class (0 = flat). Cells are shaded by the fraction of their row and show the count
/// and that fraction.
pub fn draw_confusions(path: &Path, results: &[&WindowResult]) -> Result<()> {
    let maps: Vec<Heatmap<'_>> = results.iter().map(|r| paper_heatmap(r)).collect();
    draw_heatmaps(
        path,
        "Confusion matrices (true area × GMM class)",
        560,
        &maps,
    )
}

/// `maps` side by side under `title`, each panel `side` pixels square.
pub fn draw_heatmaps(path: &Path, title: &str, side: u32, maps: &[Heatmap<'_>]) -> Result<()> {
    let panels = maps.len().max(1);
    with_canvas(path, (side * panels as u32, side), |root| {
        let root = root.titled(title, (FONT, 24).into_font().style(FontStyle::Bold))?;
        for (area, h) in root.split_evenly((1, panels)).iter().zip(maps) {
            draw_heatmap(area, h)?;
        }
        Ok(())
    })
}

/// One confusion matrix to draw: counts by true row and given column, rows listed top to
/// bottom, each cell shaded by its share of the row.
pub struct Heatmap<'a> {
    pub caption: String,
    pub rows: Vec<String>,
    pub columns: Vec<String>,
    pub counts: &'a [Vec<u64>],
    pub x_desc: &'static str,
    pub y_desc: &'static str,
}

/// SPEC S7's heatmap of one window: true area (flat on top) × mixture class.
fn paper_heatmap(r: &WindowResult) -> Heatmap<'_> {
    let classes = r.means.len();
    Heatmap {
        caption: format!(
            "window = {} (accuracy {:.2} %)",
            r.window,
            100.0 * r.accuracy
        ),
        rows: vec!["flat".into(), "rough".into()],
        columns: (0..classes)
            .map(|k| match (k, classes) {
                (0, _) => "flat (0)".to_string(),
                (1, 2) => "rough (1)".to_string(),
                (k, _) => format!("class {k}"),
            })
            .collect(),
        counts: &r.confusion,
        x_desc: "predicted class",
        y_desc: "true area",
    }
}

fn draw_heatmap(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    h: &Heatmap<'_>,
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let (columns, rows) = (h.columns.len(), h.rows.len());
    let mut chart = ChartBuilder::on(area)
        .caption(&h.caption, (FONT, 20))
        .margin(18)
        .x_label_area_size(60)
        .y_label_area_size(80)
        // plotters' integer ranges include their end: 0..n-1 gives n cells.
        .build_cartesian_2d(
            (0..columns - 1).into_segmented(),
            (0..rows - 1).into_segmented(),
        )?;
    let column_name = |v: &SegmentValue<usize>| match v {
        SegmentValue::CenterOf(k) if *k < columns => h.columns[*k].clone(),
        _ => String::new(),
    };
    // The first row is drawn on top, so the matrix reads as it is listed.
    let row_name = |v: &SegmentValue<usize>| match v {
        SegmentValue::CenterOf(y) if *y < rows => h.rows[rows - 1 - *y].clone(),
        _ => String::new(),
    };
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(h.x_desc)
        .y_desc(h.y_desc)
        .x_label_formatter(&column_name)
        .y_label_formatter(&row_name)
        .label_style((FONT, 17))
        .axis_desc_style((FONT, 18))
        .draw()?;
    let mut cells = Vec::new();
    for (row, counts) in h.counts.iter().enumerate() {
        let total = counts.iter().sum::<u64>().max(1) as f64;
        let y = rows - 1 - row;
        for (k, &count) in counts.iter().enumerate() {
            cells.push((k, y, count, count as f64 / total));
        }
    }
    chart.draw_series(cells.iter().map(|&(k, y, _, frac)| {
        let shade = |c: u8| (255.0 - frac * (255.0 - f64::from(c))).round() as u8;
        Rectangle::new(
            [
                (SegmentValue::Exact(k), SegmentValue::Exact(y)),
                (SegmentValue::Exact(k + 1), SegmentValue::Exact(y + 1)),
            ],
            RGBColor(shade(8), shade(48), shade(107)).filled(),
        )
    }))?;
    let big = if rows > 3 { 20 } else { 28 };
    chart.draw_series(cells.iter().map(|&(k, y, count, frac)| {
        let color: &'static RGBColor = if frac > 0.5 { &WHITE } else { &BLACK };
        let style = |size: u32| {
            (FONT, size)
                .into_font()
                .color(color)
                .pos(Pos::new(HPos::Center, VPos::Center))
        };
        EmptyElement::at((SegmentValue::CenterOf(k), SegmentValue::CenterOf(y)))
            + Text::new(count.to_string(), (0, -14), style(big))
            + Text::new(format!("{:.1} %", 100.0 * frac), (0, 18), style(18))
    }))?;
    Ok(())
}
