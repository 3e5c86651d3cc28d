//! `[sim.terrain]`: the procedural lava-tube floor, or a measured heightmap in its place.

use super::range::invalid;
use super::setting::{Setting, choices, count, form, real, settings};
use super::{AreaKind, ConfigError, Rect};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

settings! {
    /// The lava-tube floor (SPEC S1).
    pub struct TerrainConfig {
        /// Seed of the procedural floor (independent of the run seed, so runs can share a floor).
        pub seed: u64 = 2026 => count(0, u64::MAX), "", Advanced;
        /// The training areas, at most one per terrain kind, each `{ kind, x = [min, max],
        /// z = [min, max] }`; by default SPEC S1's two.
        pub areas: Vec<Area> = vec![
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
        ] => form("a list of areas"), "", Essential;
        /// The mixed course (not in the paper): a strip whose robots cross between terrain
        /// kinds; by default between the two areas.
        pub mixed_area: Rect = Rect {
            x: [-6.0, -3.0],
            z: [2.25, 3.25],
        };
        /// The mixed course's parts that are not flat, each `{ kind, x, z }`, with the ground of
        /// that kind's area (the same `blend` at their edges); the rest of the course is flat.
        /// By default one rough part, the half towards the rough area.
        pub mixed_parts: Vec<Area> = vec![Area {
            kind: AreaKind::Rough,
            x: [-6.0, -4.5],
            z: [2.25, 3.25],
        }] => form("a list of areas"), "", Research;
        /// Heightfield cell size.
        pub cell_size: f64 = 0.04 => real(0.005, 0.5), "m", Advanced;
        /// How the physics collides with the floor: `heightfield` (parry's, the grid itself, as
        /// Unity's terrain collider is, recomputing its internal-edge normals at every contact) or
        /// `trimesh` (the same triangles as a mesh whose edge normals are computed once: SPEC S1's
        /// calibration within 0.001, a physics step about a sixth cheaper).
        pub collider: TerrainCollider = TerrainCollider::Heightfield
            => choices::<TerrainCollider>(), "", Advanced;
        /// Extra floor around each area, so a robot at the edge still has ground.
        pub border: f64 = 1.0 => real(0.5, 10.0), "m", Advanced;
        /// Peak height of the micro-relief everywhere (RMS ≈ ⅓ of it), calibrated so
        /// go-to-target driving gives SPEC S1's flat rolling std of sin θx.
        pub flat_relief: f64 = 0.007 => real(0.0, 0.05), "m", Research;
        /// Wavelength of the micro-relief.
        pub flat_wavelength: f64 = 0.15 => real(0.01, 5.0), "m", Research;
        /// Peak amplitude of the rough area's bumps before `roughness-scale`, calibrated to
        /// SPEC S1's rough rolling std.
        pub rough_amplitude: f64 = 0.07 => real(0.0, 1.0), "m", Research;
        /// Wavelength of the rough area's largest octave.
        pub rough_wavelength: f64 = 0.4 => real(0.02, 10.0), "m", Research;
        /// Octaves of value noise in the rough area.
        pub rough_octaves: usize = 5 => count(1, 8), "octaves", Research;
        /// Scale of the rough area's unevenness (SPEC S1: the paper used 80 % of the scan).
        pub roughness_scale: f64 = 0.8 => real(0.0, 2.0), "", Research;
        /// Width of the blend between areas and the surrounding floor.
        pub blend: f64 = 0.3 => real(0.0, 5.0), "m", Advanced;
        /// Friction of flat and rough ground, of which a contact takes the lower with the wheel's
        /// (or the skid's); none: the paper's 1.0, averaged with the wheel's. Lunar regolith:
        /// the tangent of its friction angle (configs/moon.toml).
        pub ground_friction: Option<f64> = None => real(0.0, 5.0), "", Research;
        /// The `slope` kind's ground.
        pub slope: SlopeConfig = SlopeConfig::default();
        /// The `gravel` kind's ground.
        pub gravel: GravelConfig = GravelConfig::default();
        /// The `sand` kind's ground.
        pub sand: SandConfig = SandConfig::default();
        /// A measured heightmap to use instead of the procedural floor.
        pub heightmap: Option<HeightmapConfig> = None;
    }
}

settings! {
    /// One area of a terrain kind: a rectangle on the ground.
    #[derive(Copy)]
    pub struct Area, required {
        /// The terrain kind (not `mixed`, the course).
        pub kind: AreaKind => choices::<AreaKind>(), "", Advanced;
        /// [min, max] along X.
        pub x: [f64; 2] => real(-1000.0, 1000.0), "m", Advanced;
        /// [min, max] along Z.
        pub z: [f64; 2] => real(-1000.0, 1000.0), "m", Advanced;
    }
}

impl Area {
    pub fn rect(&self) -> Rect {
        Rect {
            x: self.x,
            z: self.z,
        }
    }
}

settings! {
    /// `[sim.terrain.slope]`: loose regolith on an incline. Each slope area or part is a
    /// four-sided pyramid rising from its edges at `incline-deg`, so wherever a robot stands on
    /// it the ground tilts by that angle, uphill, downhill or across, by heading.
    pub struct SlopeConfig {
        /// The incline.
        pub incline_deg: f64 = 12.0 => real(0.0, 30.0), "deg", Research;
        /// The wheels' friction on it: a wheel contact takes the lower of this and
        /// `robot.wheel-friction` (loose regolith); at 0.3 the go-to controller's robots crawl
        /// below 2 cm/s for 94 % of their ticks.
        pub friction: f64 = 0.5 => real(0.0, 5.0), "", Research;
    }
}

settings! {
    /// `[sim.terrain.gravel]`: a field of small broken rock, bumps far smaller and denser than
    /// the rough area's. Needs a `cell-size` of at most a quarter of `spacing` to be resolved.
    pub struct GravelConfig {
        /// Height of the tallest stones (each is 40–100 % of it).
        pub amplitude: f64 = 0.01 => real(0.0, 0.05), "m", Research;
        /// Distance between neighbouring stones: one stone per square of this side, at a random
        /// spot in it, 70–100 % of this across.
        pub spacing: f64 = 0.05 => real(0.01, 1.0), "m", Research;
        /// The wheels' friction on it, as the slope's.
        pub friction: f64 = 0.8 => real(0.0, 5.0), "", Research;
    }
}

settings! {
    /// `[sim.terrain.sand]`: loose, level sand with wind ripples, where a wheel that spins fast
    /// digs itself in and then spins in its rut (sim-proc's `sinkage` module). A robot there
    /// must drive gently, which costs it time on every other kind.
    pub struct SandConfig {
        /// Peak height of the ripples (two crossing sine waves, so a robot meets them at any
        /// heading).
        pub ripple_amplitude: f64 = 0.005 => real(0.0, 0.05), "m", Research;
        /// Distance between ripple crests.
        pub ripple_wavelength: f64 = 0.3 => real(0.02, 5.0), "m", Research;
        /// The wheels' friction on it, as the slope's.
        pub friction: f64 = 0.6 => real(0.0, 5.0), "", Research;
        /// Rim speed |ω|·r above which a wheel throws out more sand than it packs and sinks;
        /// the default is 57 % of the default robot's top speed.
        pub dig_speed: f64 = 0.06 => real(0.0, 10.0), "m/s", Research;
        /// Sinkage gained per metre of rim travel above `dig-speed` (sinkage 1 is a wheel dug
        /// in fully); at the default, full sinkage takes 1.1 s at full command.
        pub dig_rate: f64 = 20.0 => real(0.0, 1e4), "1/m", Research;
        /// Time constant with which a wheel at or below `dig-speed` rolls out of its rut.
        pub settle_time: f64 = 1.0 => real(1e-3, 100.0), "s", Research;
        /// A fully sunk wheel's friction: it spins in its rut without pushing. A wheel's
        /// friction slides from `robot.wheel-friction` to this as it sinks.
        pub dug_friction: f64 = 0.05 => real(0.0, 5.0), "", Research;
    }
}

/// The floor's collider shape (`sim.terrain.collider`); both hold the same triangles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TerrainCollider {
    Heightfield,
    Trimesh,
}

impl Setting for TerrainCollider {}

settings! {
    /// A user heightmap: a 16-bit grayscale PNG or a plain grid (`.grid` text: first line
    /// `rows cols`, then `rows` lines of `cols` heights in metres, row = +Z, column = +X).
    pub struct HeightmapConfig, required {
        /// The file, relative to the config file's directory; it must exist.
        pub path: PathBuf => form("a file path"), "", Essential;
        /// Ground distance between samples.
        pub metres_per_pixel: f64 => real(1e-4, 1.0), "m", Advanced;
        /// Height of the brightest 16-bit value, 65535 (PNG only).
        #[serde(default = "one")]
        pub height_scale: f64 = one() => real(1e-6, 100.0), "m", Advanced;
        /// World X, Z of the map's first sample (row 0, column 0).
        pub origin: [f64; 2] => real(-1000.0, 1000.0), "m", Advanced;
    }
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

    /// The wheels' friction on ground of `kind`: for SPEC S1's flat and rough ground
    /// `ground-friction`, whose `None` is the paper's contact (the floor's 1.0 averaged with the
    /// wheel's); the kind's setting otherwise.
    pub fn friction_of(&self, kind: AreaKind) -> Option<f64> {
        match kind {
            AreaKind::Slope => Some(self.slope.friction),
            AreaKind::Gravel => Some(self.gravel.friction),
            AreaKind::Sand => Some(self.sand.friction),
            AreaKind::Flat | AreaKind::Rough => self.ground_friction,
            AreaKind::Mixed => None,
        }
    }

    /// The rules between fields and list rules (each field's own range is
    /// [`super::setting::Setting::check`]'s).
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
        if let Some(h) = &self.heightmap {
            h.validate()?;
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
    /// The file must exist (the ranges are [`super::setting::Setting::check`]'s).
    fn validate(&self) -> Result<(), ConfigError> {
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
