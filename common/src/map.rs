//! The map of a run (feature `plot`): the floor's height shaded from above, the areas and the
//! mixed course outlined, each robot's path coloured by its class's terrain kind (the kind of
//! the specialist that acted, else the estimator's), targets,
//! successes and failures marked. World X runs right, world Z up; each height sample is a
//! square of [`Map::scale`] pixels, so the image has the terrain's proportions.

use crate::config::{AreaKind, Rect};
use crate::plot::{FONT, register_fonts, write_png};
use crate::terrain::Terrain;
use crate::track::{Mark, TrackPoint};
use plotters::prelude::*;
use std::path::Path;

/// The longest side a map is drawn at, pixels (at least one pixel per sample).
const MAX_SIDE: usize = 1600;
/// Episodes drawn per robot, its last ones: a whole run's thousands would cover the ground.
pub const EPISODES_PER_ROBOT: u64 = 6;

/// A path's colour where it has no class (no estimate yet, or the general model acting).
const UNKNOWN: RGBColor = RGBColor(20, 20, 20);
const SUCCESS: RGBColor = RGBColor(20, 170, 60);
/// Magenta: no kind is drawn in it (rough ground is red).
const FAILURE: RGBColor = RGBColor(230, 0, 230);

/// How a terrain maps onto pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Map {
    /// Pixels per height sample.
    pub scale: usize,
    /// Image size, pixels: columns × scale by rows × scale.
    pub width: usize,
    pub height: usize,
    bounds: Rect,
}

impl Map {
    pub fn of(terrain: &Terrain) -> Self {
        let (rows, cols) = terrain.dims();
        let scale = (MAX_SIDE / rows.max(cols)).max(1);
        Self {
            scale,
            width: cols * scale,
            height: rows * scale,
            bounds: terrain.bounds(),
        }
    }

    /// The pixel of world point `(x, z)`.
    fn pixel(&self, x: f64, z: f64) -> (i32, i32) {
        let b = &self.bounds;
        let u = (x - b.x[0]) / (b.x[1] - b.x[0]) * (self.width - 1) as f64;
        let v = (b.z[1] - z) / (b.z[1] - b.z[0]) * (self.height - 1) as f64;
        (u.round() as i32, v.round() as i32)
    }
}

/// The floor lit from the north-west, slopes exaggerated so centimetre bumps show, as RGB
/// bytes row by row (top row = largest Z).
fn hillshade(terrain: &Terrain, map: &Map) -> Vec<u8> {
    const EXAGGERATION: f64 = 2.0;
    let (rows, cols) = terrain.dims();
    let light = {
        let l = [-1.0f64, 1.5, 1.0];
        let n = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        [l[0] / n, l[1] / n, l[2] / n]
    };
    let h = |i: usize, j: usize| terrain.sample(i, j);
    let mut shade = vec![0u8; rows * cols];
    for i in 0..rows {
        for j in 0..cols {
            let (jl, jr) = (j.saturating_sub(1), (j + 1).min(cols - 1));
            let (il, ir) = (i.saturating_sub(1), (i + 1).min(rows - 1));
            let dx =
                EXAGGERATION * (h(i, jr) - h(i, jl)) / ((jr - jl).max(1) as f64 * terrain.cell());
            let dz =
                EXAGGERATION * (h(ir, j) - h(il, j)) / ((ir - il).max(1) as f64 * terrain.cell());
            let n = (dx * dx + 1.0 + dz * dz).sqrt();
            let lit = ((-dx * light[0] + light[1] - dz * light[2]) / n).clamp(0.0, 1.0);
            shade[i * cols + j] = (60.0 + 180.0 * lit) as u8;
        }
    }
    let mut rgb = vec![0u8; map.width * map.height * 3];
    for (py, row) in rgb.chunks_exact_mut(map.width * 3).enumerate() {
        let i = rows - 1 - py / map.scale;
        for (px, p) in row.chunks_exact_mut(3).enumerate() {
            let s = shade[i * cols + px / map.scale];
            // A warm grey, like basalt under a lamp.
            p.copy_from_slice(&[s, s.saturating_sub(6), s.saturating_sub(14)]);
        }
    }
    rgb
}

/// The points of each env's last `episodes` episodes.
fn recent(track: &[TrackPoint], episodes: u64) -> Vec<TrackPoint> {
    let mut last = std::collections::BTreeMap::new();
    for p in track {
        let e = last.entry(p.env).or_insert(p.episode);
        *e = (*e).max(p.episode);
    }
    track
        .iter()
        .filter(|p| p.episode + episodes > last[&p.env])
        .copied()
        .collect()
}

/// A path's colour: its class's terrain kind's, as in every figure.
fn class_colour(class: u8) -> RGBColor {
    AreaKind::KINDS
        .into_iter()
        .find(|k| k.code() == class)
        .map_or(UNKNOWN, |k| {
            let [r, g, b] = k.colour();
            RGBColor(r, g, b)
        })
}

/// Draws the map of `terrain` with `areas` outlined and labelled and the `track` on it, to
/// `path` as PNG. Returns the image size.
pub fn draw(
    terrain: &Terrain,
    areas: &[(&str, Rect)],
    track: &[TrackPoint],
    path: &Path,
) -> Result<(usize, usize), String> {
    register_fonts()?;
    let map = Map::of(terrain);
    let track = recent(track, EPISODES_PER_ROBOT);
    let mut rgb = hillshade(terrain, &map);
    let size = (map.width as u32, map.height as u32);
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        overlay(&root, &map, areas, &track).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    write_png(path, size, &rgb).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((map.width, map.height))
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

fn overlay(
    root: &Area,
    map: &Map,
    areas: &[(&str, Rect)],
    track: &[TrackPoint],
) -> Result<(), Box<dyn std::error::Error>> {
    let px = |x: f32, z: f32| map.pixel(f64::from(x), f64::from(z));
    let label = (FONT, 16).into_font().color(&WHITE);
    for (name, r) in areas {
        let (a, b) = (map.pixel(r.x[0], r.z[1]), map.pixel(r.x[1], r.z[0]));
        root.draw(&Rectangle::new([a, b], WHITE.stroke_width(2)))?;
        root.draw(&Text::new(
            name.to_string(),
            (a.0 + 4, a.1 + 4),
            label.clone(),
        ))?;
    }
    // Paths: runs of consecutive points of one env and episode, split where the class
    // changes. The file interleaves envs; a stable sort keeps each env's points in order.
    let mut paths: Vec<&TrackPoint> = track.iter().filter(|p| p.mark == Mark::Path).collect();
    paths.sort_by_key(|p| p.env);
    let mut run: Vec<(i32, i32)> = Vec::new();
    let mut colour = UNKNOWN;
    let mut key = None;
    for p in paths {
        let c = class_colour(p.class);
        let k = Some((p.env, p.episode));
        if key != k || c != colour {
            if run.len() > 1 {
                root.draw(&PathElement::new(run.clone(), colour.stroke_width(2)))?;
            }
            // Keep the last point when only the class changed, so the path stays joined.
            let keep = (key == k).then(|| run.last().copied()).flatten();
            run.clear();
            run.extend(keep);
            (key, colour) = (k, c);
        }
        run.push(px(p.x, p.z));
    }
    if run.len() > 1 {
        root.draw(&PathElement::new(run, colour.stroke_width(2)))?;
    }
    for p in track {
        let at = px(p.x, p.z);
        match p.mark {
            Mark::Path => {}
            Mark::Target => root.draw(&Cross::new(at, 3, WHITE.stroke_width(1)))?,
            Mark::Success => root.draw(&Circle::new(at, 2, SUCCESS.filled()))?,
            Mark::Failure => root.draw(&Cross::new(at, 4, FAILURE.stroke_width(2)))?,
        }
    }
    legend(root, map, track)
}

/// The legend: a path colour per kind on the track, then the marks.
fn legend(root: &Area, map: &Map, track: &[TrackPoint]) -> Result<(), Box<dyn std::error::Error>> {
    let mut rows: Vec<(String, RGBColor)> = AreaKind::KINDS
        .into_iter()
        .filter(|k| track.iter().any(|p| p.class == k.code()))
        .map(|k| (format!("path, {}", k.name()), class_colour(k.code())))
        .collect();
    rows.extend([
        ("path, no class".to_string(), UNKNOWN),
        ("target".into(), WHITE),
        ("success".into(), SUCCESS),
        ("failure".into(), FAILURE),
    ]);
    let font = (FONT, 14).into_font().color(&WHITE);
    let (x, mut y) = (10, map.height as i32 - (rows.len() as i32 + 1) * 18 - 10);
    root.draw(&Rectangle::new(
        [(x - 6, y - 6), (x + 230, map.height as i32 - 6)],
        BLACK.mix(0.55).filled(),
    ))?;
    let title = format!("last {EPISODES_PER_ROBOT} episodes of each robot");
    root.draw(&Text::new(title, (x, y), font.clone()))?;
    y += 18;
    for (text, c) in rows {
        root.draw(&Rectangle::new([(x, y + 3), (x + 14, y + 11)], c.filled()))?;
        root.draw(&Text::new(text, (x + 22, y), font.clone()))?;
        y += 18;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::TerrainConfig;

    #[test]
    fn only_each_robots_last_episodes_are_drawn() {
        let p = |env, episode| TrackPoint {
            env,
            episode,
            mark: Mark::Path,
            x: 0.0,
            z: 0.0,
            class: 0,
        };
        let track = [p(0, 0), p(0, 1), p(0, 2), p(1, 7), p(0, 3)];
        let kept: Vec<(u32, u64)> = recent(&track, 2)
            .iter()
            .map(|p| (p.env, p.episode))
            .collect();
        assert_eq!(kept, [(0, 2), (1, 7), (0, 3)]);
    }

    #[test]
    fn a_map_has_the_terrains_size_and_shows_the_track() {
        let cfg = TerrainConfig::default();
        let terrain = Terrain::procedural(&cfg);
        let (rows, cols) = terrain.dims();
        let dir = tempfile::tempdir().expect("tempdir");
        let png_path = dir.path().join("map.png");
        let at = |mark, x, z, class| TrackPoint {
            env: 0,
            episode: 0,
            mark,
            x,
            z,
            class,
        };
        // Two envs' points interleaved, as the sim writes them.
        let other = TrackPoint {
            env: 1,
            ..at(Mark::Path, -8.0, 3.0, 1)
        };
        let track = [
            at(Mark::Target, 0.0, 0.0, 255),
            at(Mark::Path, -2.0, 0.0, 0),
            other,
            at(Mark::Path, -1.0, 0.0, 0),
            other,
            at(Mark::Success, 0.0, 0.0, 0),
        ];
        let size = draw(
            &terrain,
            &[("flat", cfg.areas[0].rect())],
            &track,
            &png_path,
        )
        .expect("draw");
        let map = Map::of(&terrain);
        assert_eq!(size, (cols * map.scale, rows * map.scale));
        assert!(map.width.max(map.height) <= MAX_SIDE);
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(&png_path).expect("png"),
        ));
        let mut reader = decoder.read_info().expect("info");
        let mut buf = vec![0u8; reader.output_buffer_size().expect("size")];
        let info = reader.next_frame(&mut buf).expect("frame");
        assert_eq!((info.width as usize, info.height as usize), size);
        // The path's midpoint is drawn in the flat class's colour; the world's corner is floor.
        let pixel = |(u, v): (i32, i32)| {
            let k = (v as usize * info.width as usize + u as usize) * 3;
            [buf[k], buf[k + 1], buf[k + 2]]
        };
        let flat = AreaKind::Flat.colour();
        assert_eq!(pixel(map.pixel(-1.5, 0.0)), flat);
        assert_ne!(pixel(map.pixel(-1.5, -0.6)), flat);
    }
}
