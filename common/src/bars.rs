//! A grouped bar chart with 95 % intervals: one group of bars per named case, one bar per
//! series in each (`lavatube evaluate`'s success per world and policy).

use crate::plot::{FONT, register_fonts, write_png};
use plotters::prelude::*;
use std::path::Path;

/// One series: its label and, per group, its value and the half-width of its interval
/// (not finite: no whisker).
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub values: Vec<(f64, f64)>,
}

/// matplotlib's tab10, one colour per series in turn.
const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Draws `series` over `groups` with values in `[0, y_max]` to the PNG `path`.
pub fn grouped_bars(
    path: &Path,
    title: &str,
    y_label: &str,
    groups: &[String],
    series: &[Series],
    y_max: f64,
) -> Result<(), String> {
    register_fonts()?;
    let size = (
        160 + 110 * groups.len().max(1) as u32 * series.len().clamp(1, 4) as u32 / 2,
        560,
    );
    let mut rgb = vec![255u8; (size.0 * size.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        draw(&root, title, y_label, groups, series, y_max).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    write_png(path, size, &rgb).map_err(|e| format!("{}: {e}", path.display()))
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

fn draw(
    root: &Area,
    title: &str,
    y_label: &str,
    groups: &[String],
    series: &[Series],
    y_max: f64,
) -> Result<(), Box<dyn std::error::Error>> {
    let n = groups.len() as f64;
    // Headroom above the highest value for the legend, so it covers no bar.
    let top = y_max * 1.3;
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FONT, 20))
        .margin(12)
        .x_label_area_size(70)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..n, 0.0..top)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .y_desc(y_label)
        .label_style((FONT, 14))
        .draw()?;
    let width = 0.8 / series.len().max(1) as f64;
    for (k, s) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let left = |g: usize| g as f64 + 0.1 + k as f64 * width;
        chart
            .draw_series(s.values.iter().enumerate().map(|(g, &(v, _))| {
                Rectangle::new(
                    [(left(g), 0.0), (left(g) + width, v.max(0.0))],
                    colour.filled(),
                )
            }))?
            .label(&s.label)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], colour.filled()));
        chart.draw_series(
            s.values
                .iter()
                .enumerate()
                .filter(|(_, (_, h))| h.is_finite())
                .map(|(g, &(v, h))| {
                    let x = left(g) + 0.5 * width;
                    PathElement::new(vec![(x, (v - h).max(0.0)), (x, (v + h).min(y_max))], BLACK)
                }),
        )?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT, 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    let style = TextStyle::from((FONT, 14).into_font()).pos(text_anchor());
    for (g, name) in groups.iter().enumerate() {
        let (x, y) = chart.backend_coord(&(g as f64 + 0.5, 0.0));
        root.draw_text(name, &style, (x, y + 8))?;
    }
    Ok(())
}

fn text_anchor() -> plotters::style::text_anchor::Pos {
    use plotters::style::text_anchor::{HPos, Pos, VPos};
    Pos::new(HPos::Center, VPos::Top)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_is_a_png_of_its_stated_size() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("bars.png");
        let groups: Vec<String> = ["nominal", "heavy", "slippery"].map(String::from).into();
        let series = [
            Series {
                label: "nominal-trained".into(),
                values: vec![(98.0, 1.5), (90.0, 3.0), (70.0, f64::NAN)],
            },
            Series {
                label: "randomized".into(),
                values: vec![(97.0, 2.0), (96.0, 2.0), (92.0, 4.0)],
            },
        ];
        grouped_bars(&path, "success", "success %", &groups, &series, 100.0).expect("drawn");
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(&path).expect("png"),
        ));
        let info = decoder.read_info().expect("header").info().clone();
        assert_eq!((info.width, info.height), (160 + 110 * 3 * 2 / 2, 560));
        assert!(!dir.path().join("bars.png.tmp").exists());
    }
}
