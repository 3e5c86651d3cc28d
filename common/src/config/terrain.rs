//! `[sim.terrain]`: the procedural lava-tube floor, or a measured heightmap in its place.

use super::range::{count_in, in_range, invalid};
use super::{ConfigError, Rect};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The lava-tube floor (SPEC S1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", default)]
pub struct TerrainConfig {
    /// Seed of the procedural floor (independent of the run seed, so runs can share a floor).
    pub seed: u64,
    /// Flat area rectangle. Default x ∈ [-2.5, 0.5], z ∈ [-1.0, 0.5] (SPEC S1).
    pub flat_area: Rect,
    /// Rough area rectangle. Default x ∈ [-9.0, -7.5], z ∈ [1.5, 5.0] (SPEC S1).
    pub rough_area: Rect,
    /// The mixed course (not in the paper): a strip whose robots cross between flat and rough
    /// ground. Default x ∈ [-6.0, -3.0], z ∈ [2.25, 3.25], between the two areas.
    pub mixed_area: Rect,
    /// The rough part of the mixed course: its bumps are the rough area's, with the same
    /// `blend` at the edge; the rest of the course is flat. Default x ∈ [-6.0, -4.5],
    /// z ∈ [2.25, 3.25] (the half towards the rough area).
    pub mixed_rough: Rect,
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
    /// A measured heightmap to use instead of the procedural floor.
    pub heightmap: Option<HeightmapConfig>,
}

impl Default for TerrainConfig {
    fn default() -> Self {
        Self {
            seed: 2026,
            flat_area: Rect {
                x: [-2.5, 0.5],
                z: [-1.0, 0.5],
            },
            rough_area: Rect {
                x: [-9.0, -7.5],
                z: [1.5, 5.0],
            },
            mixed_area: Rect {
                x: [-6.0, -3.0],
                z: [2.25, 3.25],
            },
            mixed_rough: Rect {
                x: [-6.0, -4.5],
                z: [2.25, 3.25],
            },
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
            heightmap: None,
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
    pub(super) fn validate(&self) -> Result<(), ConfigError> {
        for (field, a) in [
            ("sim.terrain.flat-area", self.flat_area),
            ("sim.terrain.rough-area", self.rough_area),
            ("sim.terrain.mixed-area", self.mixed_area),
            ("sim.terrain.mixed-rough", self.mixed_rough),
        ] {
            if !(a.x[0] < a.x[1] && a.z[0] < a.z[1])
                || a.x.iter().chain(&a.z).any(|v| !v.is_finite())
            {
                return Err(invalid(field, a, "needs finite min < max on x and z"));
            }
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
        if let Some(h) = &self.heightmap {
            h.validate()?;
        }
        Ok(())
    }
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
