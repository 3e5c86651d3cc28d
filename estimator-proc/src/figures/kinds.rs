//! The figures of `estimator-proc kinds`: the K-kind confusion matrices, and two features'
//! windows coloured by true kind with the mixture's ellipses.

use super::{
    FONT, GRID, Heatmap, area_color, axis_number, draw_heatmaps, draw_legend, padded_range,
    with_canvas,
};
use crate::Result;
use crate::features::FeatureWindows;
use crate::kinds::{Classifier, KindsResult};
use crate::mixture::Mixture;
use plotters::prelude::*;
use std::path::Path;

/// One K-kind confusion matrix per result, side by side: true kind × kind given, with an
/// "unknown" column when some window was unknown.
pub fn draw_kinds_confusions(path: &Path, results: &[&KindsResult]) -> Result<()> {
    let counts: Vec<Vec<Vec<u64>>> = results
        .iter()
        .map(|r| {
            let shown = r.kinds.len() + usize::from(r.unknown > 0);
            r.confusion
                .iter()
                .map(|row| row[..shown].to_vec())
                .collect()
        })
        .collect();
    let maps: Vec<Heatmap<'_>> = results
        .iter()
        .zip(&counts)
        .map(|(r, counts)| {
            let mut columns: Vec<String> = r.kinds.iter().map(|k| k.name().to_string()).collect();
            if r.unknown > 0 {
                columns.push("unknown".into());
            }
            Heatmap {
                caption: format!(
                    "window = {} (macro accuracy {:.2} %)",
                    r.window,
                    100.0 * r.macro_accuracy
                ),
                rows: r.kinds.iter().map(|k| k.name().to_string()).collect(),
                columns,
                counts,
                x_desc: "kind given",
                y_desc: "true kind",
            }
        })
        .collect();
    draw_heatmaps(
        path,
        "Confusion matrices (true kind × kind given)",
        620,
        &maps,
    )
}

/// The most windows drawn per kind (every n-th one, so each kind's spread stays visible).
const POINTS_PER_KIND: usize = 1500;

/// The windows of `windows` on features 0 (x) and 1 (y), coloured by true kind, with each
/// component's 2σ ellipse of those two features (in the colour of the kind it is named
/// after). Needs at least two features and the several-feature mixture.
pub fn draw_feature_scatter(path: &Path, windows: &FeatureWindows, r: &KindsResult) -> Result<()> {
    let Classifier::Several(model) = &r.model else {
        return Ok(());
    };
    let d = windows.dim;
    let point = |i: usize| (windows.values[i * d], windows.values[i * d + 1]);
    let (x_range, y_range) = (
        padded_range((0..windows.len()).map(|i| point(i).0)),
        padded_range((0..windows.len()).map(|i| point(i).1)),
    );
    with_canvas(path, (1000, 800), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                format!(
                    "Windows of {} ticks: {} against {}",
                    r.window,
                    r.features[1].name(),
                    r.features[0].name()
                ),
                (FONT, 24).into_font().style(FontStyle::Bold),
            )
            .margin(20)
            .x_label_area_size(55)
            .y_label_area_size(90)
            .build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)?;
        chart
            .configure_mesh()
            .x_desc(r.features[0].name())
            .y_desc(r.features[1].name())
            .x_label_formatter(&axis_number)
            .y_label_formatter(&axis_number)
            .label_style((FONT, 16))
            .axis_desc_style((FONT, 18))
            .light_line_style(GRID)
            .draw()?;
        for &kind in &r.kinds {
            let name = kind.name();
            let mine: Vec<usize> = (0..windows.len())
                .filter(|&i| windows.kinds[i] == kind)
                .collect();
            let step = mine.len().div_ceil(POINTS_PER_KIND).max(1);
            let color = area_color(kind);
            chart
                .draw_series(
                    mine.iter()
                        .step_by(step)
                        .map(|&i| Circle::new(point(i), 2, color.mix(0.35).filled())),
                )?
                .label(format!("{name} (n = {})", mine.len()))
                .legend(move |(x, y)| Circle::new((x + 9, y), 5, color.filled()));
        }
        for (c, &kind) in r.component_kinds.iter().enumerate() {
            let color = area_color(kind);
            chart.draw_series(std::iter::once(PathElement::new(
                ellipse_2sigma(model, c, d),
                color.stroke_width(3),
            )))?;
        }
        draw_legend(&mut chart)?;
        Ok(())
    })
}

/// Component `c`'s 2σ ellipse over features 0 and 1 of `model` (of `d` features), in raw
/// units, as a closed path.
fn ellipse_2sigma(model: &Mixture, c: usize, d: usize) -> Vec<(f64, f64)> {
    // The two features' marginal covariance, back in raw units.
    let (sx, sy) = (model.scale[0], model.scale[1]);
    let cov = &model.covs[c];
    let (a, b, e) = (cov[0] * sx * sx, cov[1] * sx * sy, cov[d + 1] * sy * sy);
    let (mx, my) = (
        model.centre[0] + sx * model.means[c][0],
        model.centre[1] + sy * model.means[c][1],
    );
    // Cholesky of [[a, b], [b, e]] maps the circle of radius 2 onto the 2σ ellipse.
    let l11 = a.sqrt();
    let l21 = b / l11;
    let l22 = (e - l21 * l21).max(0.0).sqrt();
    (0..=96)
        .map(|k| {
            let t = std::f64::consts::TAU * f64::from(k) / 96.0;
            let (u, v) = (2.0 * t.cos(), 2.0 * t.sin());
            (mx + l11 * u, my + l21 * u + l22 * v)
        })
        .collect()
}
