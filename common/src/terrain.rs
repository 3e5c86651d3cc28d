//! The lava-tube floor: a height grid covering every training area (SPEC S1's flat and rough,
//! and the `slope`, `gravel` and `sand` kinds) and the mixed course.
//!
//! Procedural by default (deterministic from `terrain.seed`): millimetre micro-relief
//! everywhere, plus each kind's ground: multi-octave bumps on rough ground scaled by
//! `roughness-scale`, small dense stones on gravel, a pyramid of the incline on a slope,
//! crossing ripples on sand.
//! A measured heightmap (16-bit PNG or a plain `.grid` text file) can replace it.
//! The grid is built once and shared by every env's physics world (sim-proc makes it a
//! collider); the map and the Rerun recording draw the same grid.

use crate::config::{Area, AreaKind, HeightmapConfig, Rect, TerrainConfig};
use std::path::{Path, PathBuf};

/// A heightmap file that cannot be used, named with why.
#[derive(Debug, thiserror::Error)]
#[error("heightmap {path}: {reason}")]
pub struct HeightmapError {
    pub path: PathBuf,
    pub reason: String,
}

/// Heights on a regular grid. Row `i` runs along +Z, column `j` along +X; sample `(i, j)` sits
/// at `(x0 + j·cell, z0 + i·cell)`. Heights are metres, Y up.
#[derive(Debug, Clone, PartialEq)]
pub struct Terrain {
    x0: f64,
    z0: f64,
    cell: f64,
    rows: usize,
    cols: usize,
    /// Column-major like parry's `Array2`: index `i + j·rows`.
    heights: Vec<f32>,
}

impl Terrain {
    /// The floor for `cfg`: the user's heightmap if one is set, the procedural one otherwise.
    pub fn build(cfg: &TerrainConfig) -> Result<Self, HeightmapError> {
        match &cfg.heightmap {
            Some(h) => Self::load(h),
            None => Ok(Self::procedural(cfg)),
        }
    }

    /// SPEC S1 (interpretation): a procedural floor covering every area and the mixed course
    /// plus a border, micro-relief everywhere, and each kind's ground in its area and its
    /// mixed-course parts: bumps on rough ground, stones on gravel, a pyramid on a slope,
    /// ripples on sand.
    pub fn procedural(cfg: &TerrainConfig) -> Self {
        let areas: Vec<Rect> = cfg
            .areas
            .iter()
            .map(Area::rect)
            .chain([cfg.mixed_area])
            .collect();
        let lo = |f: fn(&Rect) -> f64| areas.iter().map(f).fold(f64::INFINITY, f64::min);
        let hi = |f: fn(&Rect) -> f64| areas.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
        let x0 = lo(|a| a.x[0]) - cfg.border;
        let x1 = hi(|a| a.x[1]) + cfg.border;
        let z0 = lo(|a| a.z[0]) - cfg.border;
        let z1 = hi(|a| a.z[1]) + cfg.border;
        let cols = ((x1 - x0) / cfg.cell_size).ceil() as usize + 1;
        let rows = ((z1 - z0) / cfg.cell_size).ceil() as usize + 1;
        let micro = Noise::new(cfg.seed, 0);
        let bumps = Noise::new(cfg.seed, 1);
        let stones = Stones::new(cfg.seed, &cfg.gravel);
        let rough: Vec<Rect> = cfg.rects_of(AreaKind::Rough).collect();
        let gravel: Vec<Rect> = cfg.rects_of(AreaKind::Gravel).collect();
        let slopes: Vec<Rect> = cfg.rects_of(AreaKind::Slope).collect();
        let sand: Vec<Rect> = cfg.rects_of(AreaKind::Sand).collect();
        let rough_peak = cfg.rough_amplitude * cfg.roughness_scale;
        let incline = cfg.slope.incline_deg.to_radians().tan();
        let mut heights = vec![0.0f32; rows * cols];
        for j in 0..cols {
            for i in 0..rows {
                let (x, z) = (x0 + j as f64 * cfg.cell_size, z0 + i as f64 * cfg.cell_size);
                let mut h = cfg.flat_relief
                    * micro.fbm(x / cfg.flat_wavelength, z / cfg.flat_wavelength, 2);
                let w = blend_weight(&rough, cfg.blend, x, z);
                if w > 0.0 {
                    let octaves = cfg.rough_octaves;
                    h += w
                        * rough_peak
                        * bumps.fbm(x / cfg.rough_wavelength, z / cfg.rough_wavelength, octaves);
                }
                let w = blend_weight(&gravel, cfg.blend, x, z);
                if w > 0.0 {
                    h += w * stones.height(x, z);
                }
                let w = blend_weight(&sand, cfg.blend, x, z);
                if w > 0.0 {
                    h += w * ripples(&cfg.sand, x, z);
                }
                let rise = slopes.iter().map(|r| inset(r, x, z)).fold(0.0, f64::max);
                if rise > 0.0 {
                    h += incline * rise;
                }
                heights[i + j * rows] = h as f32;
            }
        }
        Self {
            x0,
            z0,
            cell: cfg.cell_size,
            rows,
            cols,
            heights,
        }
    }

    /// Loads a user heightmap: `.png` (16-bit grayscale) or anything else as a `.grid` text file.
    pub fn load(h: &HeightmapConfig) -> Result<Self, HeightmapError> {
        let bad = |reason: String| HeightmapError {
            path: h.path.clone(),
            reason,
        };
        let (rows, cols, row_major) = if h
            .path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            read_png16(&h.path, h.height_scale).map_err(bad)?
        } else {
            read_grid(&h.path).map_err(bad)?
        };
        if rows < 2 || cols < 2 {
            return Err(bad(format!(
                "needs at least 2×2 samples, got {rows}×{cols}"
            )));
        }
        if let Some(k) = row_major.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!("sample {k} is not finite")));
        }
        let mut heights = vec![0.0f32; rows * cols];
        for i in 0..rows {
            for j in 0..cols {
                heights[i + j * rows] = row_major[i * cols + j] as f32;
            }
        }
        Ok(Self {
            x0: h.origin[0],
            z0: h.origin[1],
            cell: h.metres_per_pixel,
            rows,
            cols,
            heights,
        })
    }

    /// World-space X-Z bounds `[x0, x1] × [z0, z1]` of the grid.
    pub fn bounds(&self) -> Rect {
        Rect {
            x: [self.x0, self.x0 + (self.cols - 1) as f64 * self.cell],
            z: [self.z0, self.z0 + (self.rows - 1) as f64 * self.cell],
        }
    }

    /// Ground height at `(x, z)`, following parry's triangulation of each cell so it equals
    /// the collider's surface (clamped to the grid's edge outside it).
    pub fn height_at(&self, x: f64, z: f64) -> f64 {
        let u = ((x - self.x0) / self.cell).clamp(0.0, (self.cols - 1) as f64);
        let v = ((z - self.z0) / self.cell).clamp(0.0, (self.rows - 1) as f64);
        let (j, i) = (
            (u.floor() as usize).min(self.cols - 2),
            (v.floor() as usize).min(self.rows - 2),
        );
        let (fx, fz) = (u - j as f64, v - i as f64);
        let h00 = self.sample(i, j);
        let h01 = self.sample(i, j + 1);
        let h10 = self.sample(i + 1, j);
        let h11 = self.sample(i + 1, j + 1);
        // parry splits each cell along the diagonal from (i + 1, j) to (i, j + 1).
        if fx + fz <= 1.0 {
            h00 + fx * (h01 - h00) + fz * (h10 - h00)
        } else {
            h11 + (1.0 - fx) * (h10 - h11) + (1.0 - fz) * (h01 - h11)
        }
    }

    /// Samples along Z (rows) and X (columns).
    pub fn dims(&self) -> (usize, usize) {
        (self.rows, self.cols)
    }

    /// Ground distance between neighbouring samples, metres.
    pub fn cell(&self) -> f64 {
        self.cell
    }

    /// The heights, column-major (index `i + j·rows`, row `i` along +Z, column `j` along +X),
    /// as parry's heightfield takes them.
    pub fn heights(&self) -> &[f32] {
        &self.heights
    }

    /// The height of sample `(i, j)`: row `i` along +Z, column `j` along +X.
    pub fn sample(&self, i: usize, j: usize) -> f64 {
        f64::from(self.heights[i.min(self.rows - 1) + j.min(self.cols - 1) * self.rows])
    }
}

/// How much of a kind's ground is at `(x, z)`: the largest [`edge_weight`] over its `rects`,
/// 0 when there are none.
fn blend_weight(rects: &[Rect], blend: f64, x: f64, z: f64) -> f64 {
    rects
        .iter()
        .map(|r| edge_weight(r, blend, x, z))
        .fold(0.0, f64::max)
}

/// The distance from `(x, z)` to the nearest edge of `r`, inside it; 0 outside. A slope's
/// rise is this times the incline: a pyramid whose every face tilts by the incline.
fn inset(r: &Rect, x: f64, z: f64) -> f64 {
    (x - r.x[0])
        .min(r.x[1] - x)
        .min(z - r.z[0])
        .min(r.z[1] - z)
        .max(0.0)
}

/// 1 inside the rectangle, fading smoothly to 0 at `blend` metres outside it.
fn edge_weight(r: &Rect, blend: f64, x: f64, z: f64) -> f64 {
    let dx = (r.x[0] - x).max(x - r.x[1]).max(0.0);
    let dz = (r.z[0] - z).max(z - r.z[1]).max(0.0);
    let d = (dx * dx + dz * dz).sqrt();
    if blend <= 0.0 {
        return if d == 0.0 { 1.0 } else { 0.0 };
    }
    let t = (1.0 - d / blend).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Sand's ripples at `(x, z)`: two sine waves crossing at right angles, half the peak each,
/// so a robot crosses crests at any heading.
fn ripples(s: &crate::config::SandConfig, x: f64, z: f64) -> f64 {
    let k = std::f64::consts::TAU / s.ripple_wavelength;
    0.5 * s.ripple_amplitude * ((k * x).sin() + (k * z).sin())
}

/// Gravel: one stone per `spacing`-square cell, at a random spot in its cell's middle, of
/// random height up to `amplitude` and a radius of 35–50 % of the spacing, shaped
/// `(1 − d²/r²)²` (smooth where it meets the floor). Where stones overlap the taller one
/// shows.
struct Stones {
    /// Three lattice values per cell: the stone's offsets along x and z, and its size.
    at_x: Noise,
    at_z: Noise,
    size: Noise,
    spacing: f64,
    amplitude: f64,
}

impl Stones {
    fn new(seed: u64, g: &crate::config::GravelConfig) -> Self {
        Self {
            at_x: Noise::new(seed, 2),
            at_z: Noise::new(seed, 3),
            size: Noise::new(seed, 4),
            spacing: g.spacing,
            amplitude: g.amplitude,
        }
    }

    fn height(&self, x: f64, z: f64) -> f64 {
        let (u, v) = (x / self.spacing, z / self.spacing);
        let (ci, cj) = (u.floor() as i64, v.floor() as i64);
        let mut top = 0.0f64;
        for i in ci - 1..=ci + 1 {
            for j in cj - 1..=cj + 1 {
                // Lattice values are in [-1, 1]: centres within the cell's middle 60 %.
                let cu = i as f64 + 0.5 + 0.3 * self.at_x.lattice(i, j);
                let cv = j as f64 + 0.5 + 0.3 * self.at_z.lattice(i, j);
                let size = 0.5 + 0.5 * self.size.lattice(i, j);
                let r = 0.35 + 0.15 * size;
                let d2 = ((u - cu).powi(2) + (v - cv).powi(2)) / (r * r);
                if d2 < 1.0 {
                    top = top.max((0.4 + 0.6 * size) * (1.0 - d2).powi(2));
                }
            }
        }
        self.amplitude * top
    }
}

/// Deterministic 2-D value noise with quintic interpolation.
struct Noise {
    seed: u64,
}

impl Noise {
    fn new(seed: u64, layer: u64) -> Self {
        Self {
            seed: crate::Rng::derive(seed, layer).next_u64(),
        }
    }

    /// Lattice value in [-1, 1].
    fn lattice(&self, i: i64, j: i64) -> f64 {
        let mut h = self.seed
            ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        h ^= h >> 33;
        h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
        h ^= h >> 33;
        h = h.wrapping_mul(0xC4CE_B9FE_1A85_EC53);
        h ^= h >> 33;
        (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn value(&self, x: f64, z: f64) -> f64 {
        let (i, j) = (x.floor(), z.floor());
        let (fx, fz) = (fade(x - i), fade(z - j));
        let (i, j) = (i as i64, j as i64);
        let a = self.lattice(i, j) + fx * (self.lattice(i + 1, j) - self.lattice(i, j));
        let b = self.lattice(i, j + 1) + fx * (self.lattice(i + 1, j + 1) - self.lattice(i, j + 1));
        a + fz * (b - a)
    }

    /// Fractal sum of `octaves` layers (frequency ×2, amplitude ×½), normalised so the
    /// largest possible magnitude is 1.
    fn fbm(&self, x: f64, z: f64, octaves: usize) -> f64 {
        let (mut sum, mut norm, mut amp, mut freq) = (0.0, 0.0, 1.0, 1.0);
        for o in 0..octaves {
            // Offset each octave so lattice points do not line up.
            let shift = 17.31 * o as f64;
            sum += amp * self.value(x * freq + shift, z * freq - shift);
            norm += amp;
            amp *= 0.5;
            freq *= 2.0;
        }
        sum / norm
    }
}

fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// The most samples a heightmap may have per side: 8192 × 8192 is a 256 MiB height grid,
/// far past any lava tube scanned at centimetres; a larger header is a broken file.
const MAX_SIDE: usize = 8192;

/// Refuses dimensions no heightmap has, before anything is allocated for them.
fn check_side(rows: usize, cols: usize) -> Result<(), String> {
    if rows > MAX_SIDE || cols > MAX_SIDE {
        return Err(format!(
            "{rows}×{cols} samples: at most {MAX_SIDE}×{MAX_SIDE}"
        ));
    }
    Ok(())
}

/// A 16-bit grayscale PNG as row-major heights (metres): row 0 at the map's origin Z.
fn read_png16(path: &Path, height_scale: f64) -> Result<(usize, usize, Vec<f64>), String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| e.to_string())?;
    let info = reader.info();
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(format!(
            "must be 16-bit grayscale, is {:?} {:?}",
            info.color_type, info.bit_depth
        ));
    }
    let (cols, rows) = (info.width as usize, info.height as usize);
    check_side(rows, cols)?;
    let mut buf = vec![0u8; reader.output_buffer_size().ok_or("image too large")?];
    reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
    let heights = buf
        .chunks_exact(2)
        .take(rows * cols)
        .map(|b| f64::from(u16::from_be_bytes([b[0], b[1]])) / f64::from(u16::MAX) * height_scale)
        .collect();
    Ok((rows, cols, heights))
}

/// The plain grid format: `rows cols` on the first line, then `rows` lines of `cols` heights.
fn read_grid(path: &Path) -> Result<(usize, usize, Vec<f64>), String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let mut lines = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let header = lines.next().ok_or("empty file")?;
    let dims: Vec<usize> = header
        .split_whitespace()
        .map(|t| {
            t.parse()
                .map_err(|_| format!("header `{header}` must be `rows cols`"))
        })
        .collect::<Result<_, _>>()?;
    let [rows, cols] = dims[..] else {
        return Err(format!("header `{header}` must be `rows cols`"));
    };
    check_side(rows, cols)?;
    let mut heights = Vec::with_capacity(rows * cols);
    for (n, line) in lines.enumerate() {
        let row: Vec<f64> = line
            .split_whitespace()
            .map(|t| {
                t.parse()
                    .map_err(|_| format!("row {}: `{t}` is not a number", n + 1))
            })
            .collect::<Result<_, _>>()?;
        if row.len() != cols {
            return Err(format!(
                "row {} has {} values, expected {cols}",
                n + 1,
                row.len()
            ));
        }
        heights.extend(row);
    }
    if heights.len() != rows * cols {
        return Err(format!(
            "{} rows, expected {rows}",
            heights.len() / cols.max(1)
        ));
    }
    Ok((rows, cols, heights))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rms_slope(t: &Terrain, area: &Rect) -> f64 {
        let (mut s, mut n) = (0.0, 0);
        let step = 0.02;
        let mut x = area.x[0];
        while x < area.x[1] {
            let mut z = area.z[0];
            while z < area.z[1] {
                let g = (t.height_at(x + step, z) - t.height_at(x, z)) / step;
                s += g * g;
                n += 1;
                z += step;
            }
            x += step;
        }
        (s / f64::from(n)).sqrt()
    }

    #[test]
    fn procedural_floor_is_deterministic_and_rougher_in_the_rough_area() {
        let cfg = TerrainConfig::default();
        let a = Terrain::procedural(&cfg);
        assert_eq!(a, Terrain::procedural(&cfg));
        let other = Terrain::procedural(&TerrainConfig {
            seed: 7,
            ..cfg.clone()
        });
        assert_ne!(a.heights, other.heights);
        let b = a.bounds();
        assert!(
            b.x[0] <= -10.0 && b.x[1] >= 1.5 && b.z[0] <= -2.0 && b.z[1] >= 6.0,
            "{b:?}"
        );
        let area = |kind| cfg.area(kind).expect("the default world has it");
        let flat = rms_slope(&a, &area(AreaKind::Flat));
        let rough = rms_slope(&a, &area(AreaKind::Rough));
        assert!(flat > 0.0, "the flat area has micro-relief");
        assert!(rough > 2.5 * flat, "rough {rough} vs flat {flat}");
        // The mixed course: rough where it says, flat past the blend.
        let mixed_rough = cfg.mixed_parts[0].rect();
        let course_rough = rms_slope(&a, &mixed_rough);
        let course_flat = rms_slope(
            &a,
            &Rect {
                x: [mixed_rough.x[1] + cfg.blend, cfg.mixed_area.x[1]],
                z: cfg.mixed_area.z,
            },
        );
        assert!(
            course_rough > 0.7 * rough && course_rough < 1.3 * rough,
            "course's rough part {course_rough} vs rough area {rough}"
        );
        assert!(
            course_flat < 1.3 * flat,
            "course's flat part {course_flat} vs flat area {flat}"
        );
        // SPEC S1: the flat area's relief stays within its peak height, and is not a plane.
        let hs: Vec<f64> = (0..100)
            .map(|k| a.height_at(-2.0 + 0.02 * f64::from(k), 0.0))
            .collect();
        assert!(hs.iter().all(|h| h.abs() <= cfg.flat_relief + 1e-6));
        assert!(hs.iter().any(|h| h.abs() > 0.1 * cfg.flat_relief));
    }

    /// The four kinds side by side, each 1.5 m × 2 m, and a mixed course crossing all of
    /// them; a 1 cm grid resolves gravel's 5 cm stones.
    fn four_kinds() -> TerrainConfig {
        let area = |kind, x0: f64| Area {
            kind,
            x: [x0, x0 + 1.5],
            z: [0.0, 2.0],
        };
        TerrainConfig {
            areas: vec![
                area(AreaKind::Flat, 0.0),
                area(AreaKind::Rough, 2.0),
                area(AreaKind::Slope, 4.0),
                area(AreaKind::Gravel, 6.0),
            ],
            mixed_area: Rect {
                x: [0.0, 7.5],
                z: [3.0, 4.0],
            },
            mixed_parts: vec![
                Area {
                    kind: AreaKind::Slope,
                    x: [2.0, 3.5],
                    z: [3.0, 4.0],
                },
                Area {
                    kind: AreaKind::Gravel,
                    x: [4.5, 6.0],
                    z: [3.0, 4.0],
                },
            ],
            cell_size: 0.01,
            ..TerrainConfig::default()
        }
    }

    #[test]
    fn a_slope_tilts_by_its_incline_wherever_the_robot_stands() {
        let cfg = TerrainConfig {
            flat_relief: 0.0,
            ..four_kinds()
        };
        let t = Terrain::procedural(&cfg);
        let tan = cfg.slope.incline_deg.to_radians().tan();
        // A pyramid on x ∈ [4, 5.5], z ∈ [0, 2]: along x from the west edge the ground rises
        // at the incline up to the ridge, 0.75 m in; the eastern face falls as steeply.
        let (a, b) = (t.height_at(4.2, 1.0), t.height_at(4.5, 1.0));
        assert!(((b - a) / 0.3 - tan).abs() < 0.01 * tan, "{a} → {b}");
        let (c, d) = (t.height_at(5.0, 1.0), t.height_at(5.3, 1.0));
        assert!(((c - d) / 0.3 - tan).abs() < 0.01 * tan, "{c} → {d}");
        // Its edges meet the floor, and the top is 0.75 m × the incline up.
        assert!(t.height_at(4.0, 1.0).abs() < 1e-6);
        assert!((t.height_at(4.75, 1.0) - 0.75 * tan).abs() < 1e-3);
        // The mixed course's slope part rises the same way; its flat stretch does not.
        assert!((t.height_at(2.3, 3.5) - 0.3 * tan).abs() < 1e-3);
        assert!(t.height_at(1.0, 3.5).abs() < 1e-6);
    }

    #[test]
    fn gravel_is_small_dense_stones_beside_roughs_larger_bumps() {
        let cfg = TerrainConfig {
            flat_relief: 0.0,
            ..four_kinds()
        };
        let t = Terrain::procedural(&cfg);
        let heights = |x0: f64| -> Vec<f64> {
            (0..120)
                .map(|k| t.height_at(x0 + 0.01 * f64::from(k), 1.0))
                .collect()
        };
        let (gravel, rough) = (heights(6.1), heights(2.1));
        let peak = |h: &[f64]| h.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // Stones stay within their centimetre; the rough bumps are several times taller.
        assert!(peak(&gravel) <= cfg.gravel.amplitude + 1e-6);
        assert!(peak(&gravel) > 0.3 * cfg.gravel.amplitude);
        assert!(peak(&rough) > 2.0 * peak(&gravel));
        // Dense: the relief's typical wavelength, 2π · RMS height ÷ RMS gradient (exact for
        // a sinusoid), is gravel's spacing-sized, several times shorter than rough's.
        let wavelength = |h: &[f64]| {
            let m = h.iter().sum::<f64>() / h.len() as f64;
            let rms = (h.iter().map(|v| (v - m).powi(2)).sum::<f64>() / h.len() as f64).sqrt();
            let g: Vec<f64> = h.windows(2).map(|w| (w[1] - w[0]) / 0.01).collect();
            let grad = (g.iter().map(|v| v * v).sum::<f64>() / g.len() as f64).sqrt();
            std::f64::consts::TAU * rms / grad
        };
        let (lg, lr) = (wavelength(&gravel), wavelength(&rough));
        assert!(lg < 2.0 * cfg.gravel.spacing, "gravel's wavelength {lg} m");
        assert!(lr > 3.0 * lg, "rough's {lr} m against gravel's {lg} m");
    }

    #[test]
    fn sand_ripples_within_their_peak_at_their_wavelength() {
        let mut cfg = four_kinds();
        cfg.flat_relief = 0.0;
        cfg.areas[0].kind = AreaKind::Sand;
        let t = Terrain::procedural(&cfg);
        let s = &cfg.sand;
        // Along z = 0.5 (inside x ∈ [0, 1.5]) the z-wave is the constant ½A·sin(k·0.5): the
        // x-wave's crests sit one wavelength apart, the surface never above the peak.
        let zk =
            0.5 * s.ripple_amplitude * (std::f64::consts::TAU * 0.5 / s.ripple_wavelength).sin();
        let crest = 0.25 * s.ripple_wavelength;
        for x in [crest, crest + s.ripple_wavelength] {
            let want = 0.5 * s.ripple_amplitude + zk;
            assert!(
                (t.height_at(x, 0.5) - want).abs() < 2e-4,
                "crest at x = {x}"
            );
        }
        let trough = t.height_at(3.0 * crest, 0.5);
        assert!(
            (trough - (zk - 0.5 * s.ripple_amplitude)).abs() < 2e-4,
            "{trough}"
        );
        assert!(
            (0..150)
                .all(|k| t.height_at(0.01 * f64::from(k), 0.7).abs() <= s.ripple_amplitude + 1e-6)
        );
        assert_eq!(cfg.friction_of(AreaKind::Sand), Some(s.friction));
    }

    #[test]
    fn the_mixed_course_names_the_kind_under_each_point() {
        let cfg = four_kinds();
        assert_eq!(cfg.mixed_kind_at(1.0, 3.5), AreaKind::Flat);
        assert_eq!(cfg.mixed_kind_at(3.0, 3.5), AreaKind::Slope);
        assert_eq!(cfg.mixed_kind_at(5.0, 3.5), AreaKind::Gravel);
        assert_eq!(cfg.friction_of(AreaKind::Slope), Some(0.5));
        assert_eq!(cfg.friction_of(AreaKind::Rough), None);
        let default = TerrainConfig::default();
        assert_eq!(default.mixed_kind_at(-5.0, 2.75), AreaKind::Rough);
        assert_eq!(default.mixed_kind_at(-4.0, 2.75), AreaKind::Flat);
    }

    #[test]
    fn roughness_scale_scales_the_bumps() {
        let cfg = TerrainConfig {
            flat_relief: 0.0,
            ..TerrainConfig::default()
        };
        let full = Terrain::procedural(&TerrainConfig {
            roughness_scale: 1.0,
            ..cfg.clone()
        });
        let scaled = Terrain::procedural(&TerrainConfig {
            roughness_scale: 0.8,
            ..cfg.clone()
        });
        let (x, z) = (-8.3, 3.1);
        let (hf, hs) = (full.height_at(x, z), scaled.height_at(x, z));
        assert!(hf.abs() > 1e-4);
        assert!((hs - 0.8 * hf).abs() < 1e-6, "{hs} vs 0.8 × {hf}");
    }

    #[test]
    fn height_at_interpolates_the_triangles() {
        let t = Terrain {
            x0: 0.0,
            z0: 0.0,
            cell: 1.0,
            rows: 2,
            cols: 2,
            heights: vec![0.0, 1.0, 2.0, 5.0],
        };
        // (i, j): h00 = 0, h10 (z+1) = 1, h01 (x+1) = 2, h11 = 5 (not planar).
        assert!((t.height_at(0.0, 0.0) - 0.0).abs() < 1e-12);
        assert!((t.height_at(1.0, 1.0) - 5.0).abs() < 1e-12);
        // Lower triangle (h00, h10, h01): the plane 2·fx + 1·fz.
        assert!((t.height_at(0.5, 0.25) - (2.0 * 0.5 + 0.25)).abs() < 1e-12);
        // Upper triangle (h10, h11, h01): 5 + ¼·(1 − 5) + ¼·(2 − 5) = 3.25 (the other diagonal gives 3.75).
        assert!((t.height_at(0.75, 0.75) - 3.25).abs() < 1e-12);
    }

    #[test]
    fn grid_and_png_heightmaps_load() {
        let dir = std::env::temp_dir().join(format!("lavatube-terrain-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("tmp dir");
        let grid = dir.join("floor.grid");
        std::fs::write(&grid, "# two rows\n2 3\n0 0.1 0.2\n0.3 0.4 0.5\n").expect("write");
        let h = HeightmapConfig {
            path: grid.clone(),
            metres_per_pixel: 0.5,
            height_scale: 1.0,
            origin: [1.0, 2.0],
        };
        let t = Terrain::load(&h).expect("grid loads");
        assert_eq!(
            t.bounds(),
            Rect {
                x: [1.0, 2.0],
                z: [2.0, 2.5]
            }
        );
        assert!((t.height_at(2.0, 2.5) - 0.5).abs() < 1e-6);
        std::fs::write(&grid, "2 3\n0 0.1\n").expect("write");
        let err = Terrain::load(&h).expect_err("short row").to_string();
        assert!(
            err.contains("floor.grid") && err.contains("row 1 has 2 values"),
            "{err}"
        );

        let png_path = dir.join("floor.png");
        let file = std::fs::File::create(&png_path).expect("create");
        let mut enc = png::Encoder::new(file, 2, 2);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        let mut w = enc.write_header().expect("header");
        w.write_image_data(&[0, 0, 0xFF, 0xFF, 0x80, 0x00, 0, 0])
            .expect("data");
        w.finish().expect("finish");
        let h = HeightmapConfig {
            path: png_path,
            metres_per_pixel: 0.1,
            height_scale: 2.0,
            origin: [0.0, 0.0],
        };
        let t = Terrain::load(&h).expect("png loads");
        assert!((t.height_at(0.1, 0.0) - 2.0).abs() < 1e-6);
        assert!((t.height_at(0.0, 0.1) - 2.0 * 32768.0 / 65535.0).abs() < 1e-4);
        std::fs::remove_dir_all(&dir).ok();
    }
}
