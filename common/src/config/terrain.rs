//! `[sim.terrain]`: the procedural lava-tube floor, or a measured heightmap in its place.

use super::range::{count_in, in_range, invalid};
use super::{AreaKind, ConfigError, Rect};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The lava-tube floor (SPEC S1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct TerrainConfig {
    /// Seed of the procedural floor (independent of the run seed, so runs can share a floor).
    pub seed: u64,
    /// The training areas, at most one per terrain kind (`flat`, `rough`, `slope`, `gravel`,
    /// `sand`),
    /// each `{ kind, x = [min, max], z = [min, max] }`. Default SPEC S1's two: flat at
    /// x ∈ [-2.5, 0.5], z ∈ [-1.0, 0.5] and rough at x ∈ [-9.0, -7.5], z ∈ [1.5, 5.0].
    pub areas: Vec<Area>,
    /// The mixed course (not in the paper): a strip whose robots cross between terrain kinds.
    /// Default x ∈ [-6.0, -3.0], z ∈ [2.25, 3.25], between the two areas.
    pub mixed_area: Rect,
    /// The mixed course's parts that are not flat, each `{ kind, x, z }`, with the ground of
    /// that kind's area (the same `blend` at their edges); the rest of the course is flat.
    /// Default one rough part, x ∈ [-6.0, -4.5], z ∈ [2.25, 3.25] (the half towards the rough
    /// area).
    pub mixed_parts: Vec<Area>,
    /// Heightfield cell size, metres. [0.005, 0.5]. Default 0.04.
    pub cell_size: f64,
    /// How the physics collides with the floor: `heightfield` (parry's, the grid itself, as
    /// Unity's terrain collider is, recomputing its internal-edge normals at every contact) or
    /// `trimesh` (the same triangles as a mesh whose edge normals are computed once: SPEC S1's
    /// calibration within 0.001, a physics step about a sixth cheaper). Default `heightfield`.
    pub collider: TerrainCollider,
    /// Extra floor around each area, metres, so a robot at the edge still has ground. [0.5, 10]. Default 1.0.
    pub border: f64,
    /// Peak height of the micro-relief everywhere (RMS ≈ ⅓ of it), metres. [0, 0.05]. Default 0.007
    /// (calibrated so go-to-target driving gives SPEC S1's flat rolling std of sin θx).
    pub flat_relief: f64,
    /// Wavelength of the micro-relief, metres. [0.01, 5]. Default 0.15.
    pub flat_wavelength: f64,
    /// Peak amplitude of the rough area's bumps before `roughness-scale`, metres. [0, 1]. Default 0.07
    /// (calibrated to SPEC S1's rough rolling std).
    pub rough_amplitude: f64,
    /// Wavelength of the rough area's largest octave, metres. [0.02, 10]. Default 0.4.
    pub rough_wavelength: f64,
    /// Octaves of value noise in the rough area. 1 ..= 8. Default 5.
    pub rough_octaves: usize,
    /// Scale of the rough area's unevenness (SPEC S1: the paper used 80 % of the scan). [0, 2]. Default 0.8.
    pub roughness_scale: f64,
    /// Width of the blend between areas and the surrounding floor, metres. [0, 5]. Default 0.3.
    pub blend: f64,
    /// The `slope` kind's ground.
    pub slope: SlopeConfig,
    /// The `gravel` kind's ground.
    pub gravel: GravelConfig,
    /// The `sand` kind's ground.
    pub sand: SandConfig,
    /// A measured heightmap to use instead of the procedural floor.
    pub heightmap: Option<HeightmapConfig>,
}

impl Default for TerrainConfig {
    fn default() -> Self {
        Self {
            seed: 2026,
            areas: vec![
                Area {
                    kind: AreaKind::Flat,
                    x: [-2.5, 0.5],
                    z: [-1.0, 0.5],
                },
                Area {
                    kind: AreaKind::Rough,
                    x: [-9.0, -7.5],
                    z: [1.5, 5.0],
                },
            ],
            mixed_area: Rect {
                x: [-6.0, -3.0],
                z: [2.25, 3.25],
            },
            mixed_parts: vec![Area {
                kind: AreaKind::Rough,
                x: [-6.0, -4.5],
                z: [2.25, 3.25],
            }],
            cell_size: 0.04,
            collider: TerrainCollider::Heightfield,
            border: 1.0,
            flat_relief: 0.007,
            flat_wavelength: 0.15,
            rough_amplitude: 0.07,
            rough_wavelength: 0.4,
            rough_octaves: 5,
            roughness_scale: 0.8,
            blend: 0.3,
            slope: SlopeConfig::default(),
            gravel: GravelConfig::default(),
            sand: SandConfig::default(),
            heightmap: None,
        }
    }
}

/// One area of a terrain kind: a rectangle on the ground.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Area {
    /// `flat`, `rough`, `slope`, `gravel` or `sand`.
    pub kind: AreaKind,
    /// [min, max] along X, metres.
    pub x: [f64; 2],
    /// [min, max] along Z, metres.
    pub z: [f64; 2],
}

impl Area {
    pub fn rect(&self) -> Rect {
        Rect {
            x: self.x,
            z: self.z,
        }
    }
}

/// `[sim.terrain.slope]`: loose regolith on an incline. Each slope area or part is a
/// four-sided pyramid rising from its edges at `incline-deg`, so wherever a robot stands on it
/// the ground tilts by that angle, uphill, downhill or across, by heading.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct SlopeConfig {
    /// The incline, degrees. [0, 30]. Default 12.
    pub incline_deg: f64,
    /// The wheels' friction on it: a wheel contact takes the lower of this and
    /// `robot.wheel-friction` (loose regolith). [0, 5]. Default 0.5 (at 0.3 the go-to
    /// controller's robots crawl below 2 cm/s for 94 % of their ticks).
    pub friction: f64,
}

impl Default for SlopeConfig {
    fn default() -> Self {
        Self {
            incline_deg: 12.0,
            friction: 0.5,
        }
    }
}

/// `[sim.terrain.gravel]`: a field of small broken rock, bumps far smaller and denser than
/// the rough area's. Needs a `cell-size` of at most a quarter of `spacing` to be resolved.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct GravelConfig {
    /// Height of the tallest stones, metres (each is 40–100 % of it). [0, 0.05]. Default 0.01.
    pub amplitude: f64,
    /// Distance between neighbouring stones, metres: one stone per square of this side, at
    /// a random spot in it, 70–100 % of this across. [0.01, 1]. Default 0.05.
    pub spacing: f64,
    /// The wheels' friction on it, as the slope's. [0, 5]. Default 0.8.
    pub friction: f64,
}

impl Default for GravelConfig {
    fn default() -> Self {
        Self {
            amplitude: 0.01,
            spacing: 0.05,
            friction: 0.8,
        }
    }
}

/// `[sim.terrain.sand]`: loose, level sand with wind ripples, where a wheel that spins fast
/// digs itself in and then spins in its rut (sim-proc's `sinkage` module). A robot there must
/// drive gently, which costs it time on every other kind.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct SandConfig {
    /// Peak height of the ripples, metres (two crossing sine waves, so a robot meets them
    /// at any heading). [0, 0.05]. Default 0.005.
    pub ripple_amplitude: f64,
    /// Distance between ripple crests, metres. [0.02, 5]. Default 0.3.
    pub ripple_wavelength: f64,
    /// The wheels' friction on it, as the slope's. [0, 5]. Default 0.6.
    pub friction: f64,
    /// Rim speed |ω|·r above which a wheel throws out more sand than it packs and sinks,
    /// m/s. [0, 10]. Default 0.06 (57 % of the default robot's top speed).
    pub dig_speed: f64,
    /// Sinkage gained per metre of rim travel above `dig-speed` (sinkage 1 is a wheel dug
    /// in fully). [0, 10^4]. Default 20 (full sinkage in 1.1 s at full command).
    pub dig_rate: f64,
    /// Time constant with which a wheel at or below `dig-speed` rolls out of its rut,
    /// seconds. [0.001, 100]. Default 1.
    pub settle_time: f64,
    /// A fully sunk wheel's friction: it spins in its rut without pushing. A wheel's friction
    /// slides from `robot.wheel-friction` to this as it sinks. [0, 5]. Default 0.05.
    pub dug_friction: f64,
}

impl Default for SandConfig {
    fn default() -> Self {
        Self {
            ripple_amplitude: 0.005,
            ripple_wavelength: 0.3,
            friction: 0.6,
            dig_speed: 0.06,
            dig_rate: 20.0,
            settle_time: 1.0,
            dug_friction: 0.05,
        }
    }
}

/// The floor's collider shape (`sim.terrain.collider`); both hold the same triangles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TerrainCollider {
    Heightfield,
    Trimesh,
}

/// A user heightmap: a 16-bit grayscale PNG or a plain grid (`.grid` text: first line
/// `rows cols`, then `rows` lines of `cols` heights in metres, row = +Z, column = +X).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct HeightmapConfig {
    /// The file, relative to the config file's directory.
    pub path: PathBuf,
    /// Ground distance between samples, metres. (0, 1].
    pub metres_per_pixel: f64,
    /// Height of the brightest 16-bit value (65535), metres (PNG only). (0, 100]. Default 1.
    #[serde(default = "one")]
    pub height_scale: f64,
    /// World X, Z of the map's first sample (row 0, column 0), metres.
    pub origin: [f64; 2],
}

fn one() -> f64 {
    1.0
}

impl TerrainConfig {
    /// The terrain kinds the world has an area of, in code order (the paper's: flat, rough).
    pub fn kinds(&self) -> Vec<AreaKind> {
        AreaKind::KINDS
            .into_iter()
            .filter(|k| self.area(*k).is_some())
            .collect()
    }

    /// The rectangle of the `kind` area, if the world has one.
    pub fn area(&self, kind: AreaKind) -> Option<Rect> {
        self.areas.iter().find(|a| a.kind == kind).map(Area::rect)
    }

    /// The terrain kind of the ground at `(x, z)` on the mixed course: the part it is in, or
    /// flat between the parts.
    pub fn mixed_kind_at(&self, x: f64, z: f64) -> AreaKind {
        self.mixed_parts
            .iter()
            .find(|p| p.rect().contains(x, z, 0.0))
            .map_or(AreaKind::Flat, |p| p.kind)
    }

    /// Every rectangle whose ground is of `kind`: its area and its mixed-course parts.
    pub fn rects_of(&self, kind: AreaKind) -> impl Iterator<Item = Rect> + '_ {
        self.areas
            .iter()
            .chain(&self.mixed_parts)
            .filter(move |a| a.kind == kind)
            .map(Area::rect)
    }

    /// The wheels' friction on ground of `kind`: `None` for SPEC S1's flat and rough ground
    /// (the paper's contact, the floor's 1.0 averaged with the wheel's), the kind's setting
    /// otherwise.
    pub fn friction_of(&self, kind: AreaKind) -> Option<f64> {
        match kind {
            AreaKind::Slope => Some(self.slope.friction),
            AreaKind::Gravel => Some(self.gravel.friction),
            AreaKind::Sand => Some(self.sand.friction),
            AreaKind::Flat | AreaKind::Rough | AreaKind::Mixed => None,
        }
    }

    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        check_rect("sim.terrain.mixed-area", self.mixed_area)?;
        for (field, list) in [
            ("sim.terrain.areas", &self.areas),
            ("sim.terrain.mixed-parts", &self.mixed_parts),
        ] {
            for (i, a) in list.iter().enumerate() {
                check_rect(field, a.rect())?;
                if a.kind == AreaKind::Mixed {
                    return Err(invalid(
                        field,
                        a.kind.name(),
                        "`mixed` is the course (sim.terrain.mixed-area), not a terrain kind",
                    ));
                }
                if field == "sim.terrain.areas" && list[..i].iter().any(|b| b.kind == a.kind) {
                    return Err(invalid(
                        field,
                        a.kind.name(),
                        "holds at most one area per kind",
                    ));
                }
            }
        }
        if self.areas.is_empty() {
            return Err(invalid(
                "sim.terrain.areas",
                &self.areas,
                "needs at least one area",
            ));
        }
        in_range("sim.terrain.cell-size", self.cell_size, 0.005, 0.5)?;
        in_range("sim.terrain.border", self.border, 0.5, 10.0)?;
        in_range("sim.terrain.flat-relief", self.flat_relief, 0.0, 0.05)?;
        in_range(
            "sim.terrain.flat-wavelength",
            self.flat_wavelength,
            0.01,
            5.0,
        )?;
        in_range(
            "sim.terrain.rough-amplitude",
            self.rough_amplitude,
            0.0,
            1.0,
        )?;
        in_range(
            "sim.terrain.rough-wavelength",
            self.rough_wavelength,
            0.02,
            10.0,
        )?;
        count_in("sim.terrain.rough-octaves", self.rough_octaves, 1, 8)?;
        in_range(
            "sim.terrain.roughness-scale",
            self.roughness_scale,
            0.0,
            2.0,
        )?;
        in_range("sim.terrain.blend", self.blend, 0.0, 5.0)?;
        in_range(
            "sim.terrain.slope.incline-deg",
            self.slope.incline_deg,
            0.0,
            30.0,
        )?;
        in_range("sim.terrain.slope.friction", self.slope.friction, 0.0, 5.0)?;
        in_range(
            "sim.terrain.gravel.amplitude",
            self.gravel.amplitude,
            0.0,
            0.05,
        )?;
        in_range("sim.terrain.gravel.spacing", self.gravel.spacing, 0.01, 1.0)?;
        in_range(
            "sim.terrain.gravel.friction",
            self.gravel.friction,
            0.0,
            5.0,
        )?;
        self.sand.validate()?;
        if let Some(h) = &self.heightmap {
            h.validate()?;
        }
        Ok(())
    }
}

impl SandConfig {
    fn validate(&self) -> Result<(), ConfigError> {
        for (field, v, lo, hi) in [
            (
                "sim.terrain.sand.ripple-amplitude",
                self.ripple_amplitude,
                0.0,
                0.05,
            ),
            (
                "sim.terrain.sand.ripple-wavelength",
                self.ripple_wavelength,
                0.02,
                5.0,
            ),
            ("sim.terrain.sand.friction", self.friction, 0.0, 5.0),
            ("sim.terrain.sand.dig-speed", self.dig_speed, 0.0, 10.0),
            ("sim.terrain.sand.dig-rate", self.dig_rate, 0.0, 1e4),
            (
                "sim.terrain.sand.settle-time",
                self.settle_time,
                1e-3,
                100.0,
            ),
            ("sim.terrain.sand.dug-friction", self.dug_friction, 0.0, 5.0),
        ] {
            in_range(field, v, lo, hi)?;
        }
        Ok(())
    }
}

/// A rectangle needs finite bounds, min < max on both axes.
fn check_rect(field: &'static str, a: Rect) -> Result<(), ConfigError> {
    if !(a.x[0] < a.x[1] && a.z[0] < a.z[1]) || a.x.iter().chain(&a.z).any(|v| !v.is_finite()) {
        return Err(invalid(field, a, "needs finite min < max on x and z"));
    }
    Ok(())
}

impl HeightmapConfig {
    fn validate(&self) -> Result<(), ConfigError> {
        in_range(
            "sim.terrain.heightmap.metres-per-pixel",
            self.metres_per_pixel,
            1e-4,
            1.0,
        )?;
        in_range(
            "sim.terrain.heightmap.height-scale",
            self.height_scale,
            1e-6,
            100.0,
        )?;
        if !self.path.exists() {
            return Err(invalid(
                "sim.terrain.heightmap.path",
                &self.path,
                "file not found",
            ));
        }
        Ok(())
    }
}
