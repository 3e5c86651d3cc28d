//! The floor as a triangle mesh for the viewer: the sim's height grid, decimated to a
//! vertex budget (a viewer draws ~64 k vertices at once without effort; the fine grids of
//! measured heightmaps have millions), with normals for shading and colours by height so
//! rough ground stands out even when viewed from straight above.

use common::terrain::Terrain;

/// Vertex budget of the floor mesh.
pub const MAX_VERTICES: usize = 65_536;

/// Colours of the lowest and highest ground.
const LOW: [f32; 3] = [70.0, 62.0, 58.0];
const HIGH: [f32; 3] = [214.0, 184.0, 150.0];

/// A grid mesh: vertices row by row (row along +Z, column along +X), two triangles per cell.
#[derive(Debug, Clone, PartialEq)]
pub struct GridMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub colors: Vec<[u8; 3]>,
    /// Counter-clockwise seen from above (+Y), so the faces point up.
    pub triangles: Vec<[u32; 3]>,
    /// Grid samples per mesh vertex along each axis (1: every sample).
    pub stride: usize,
    /// Mesh vertices along Z (rows) and X (columns).
    pub dims: (usize, usize),
}

impl GridMesh {
    /// The mesh of `terrain` with at most `max_vertices` vertices (at least 4): every
    /// `stride`-th sample along each axis, and always the last row and column, so the mesh
    /// covers the whole floor.
    pub fn of(terrain: &Terrain, max_vertices: usize) -> Self {
        let (rows, cols) = terrain.dims();
        let max_vertices = max_vertices.max(4);
        let stride = (1..)
            .find(|&s| picks(rows, s).len() * picks(cols, s).len() <= max_vertices)
            .unwrap_or(1);
        let (is, js) = (picks(rows, stride), picks(cols, stride));
        let bounds = terrain.bounds();
        let cell = terrain.cell();
        let at = |i: usize, j: usize| {
            [
                bounds.x[0] + j as f64 * cell,
                terrain.sample(i, j),
                bounds.z[0] + i as f64 * cell,
            ]
        };
        let mut positions = Vec::with_capacity(is.len() * js.len());
        let mut normals = Vec::with_capacity(positions.capacity());
        for (r, &i) in is.iter().enumerate() {
            for (c, &j) in js.iter().enumerate() {
                positions.push(at(i, j).map(|v| v as f32));
                // Central differences over the neighbouring mesh vertices (one-sided at edges).
                let (i0, i1) = (is[r.saturating_sub(1)], is[(r + 1).min(is.len() - 1)]);
                let (j0, j1) = (js[c.saturating_sub(1)], js[(c + 1).min(js.len() - 1)]);
                let dhdx = slope(at(i, j0), at(i, j1), 0);
                let dhdz = slope(at(i0, j), at(i1, j), 2);
                normals.push(unit([-dhdx, 1.0, -dhdz]));
            }
        }
        let (lo, hi) = positions
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[1]), hi.max(p[1]))
            });
        let colors = positions
            .iter()
            .map(|p| {
                let t = if hi > lo {
                    (p[1] - lo) / (hi - lo)
                } else {
                    0.0
                };
                std::array::from_fn(|k| (LOW[k] + t * (HIGH[k] - LOW[k])).round() as u8)
            })
            .collect();
        let width = js.len();
        let mut triangles = Vec::with_capacity(2 * (is.len() - 1) * (width - 1));
        for r in 0..is.len() - 1 {
            for c in 0..width - 1 {
                let a = (r * width + c) as u32;
                let b = a + 1;
                let below = a + width as u32;
                // Split along the diagonal from (r + 1, c) to (r, c + 1), as the physics does.
                triangles.push([a, below, b]);
                triangles.push([b, below, below + 1]);
            }
        }
        Self {
            positions,
            normals,
            colors,
            triangles,
            stride,
            dims: (is.len(), width),
        }
    }
}

/// Sample indices `0, s, 2s, …` below `n`, and `n − 1` (a grid has at least 2 samples a side).
fn picks(n: usize, s: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..n).step_by(s).collect();
    if v.last() != Some(&(n - 1)) {
        v.push(n - 1);
    }
    v
}

/// The height change per metre from `a` to `b` along coordinate `axis` (0 for 0 distance).
fn slope(a: [f64; 3], b: [f64; 3], axis: usize) -> f64 {
    let d = b[axis] - a[axis];
    if d == 0.0 { 0.0 } else { (b[1] - a[1]) / d }
}

fn unit(v: [f64; 3]) -> [f32; 3] {
    let n = v.iter().map(|c| c * c).sum::<f64>().sqrt();
    v.map(|c| (c / n) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use common::config::TerrainConfig;

    #[test]
    fn the_default_floor_fits_the_budget_and_covers_the_grid() {
        let terrain = Terrain::procedural(&TerrainConfig::default());
        let (rows, cols) = terrain.dims();
        let mesh = GridMesh::of(&terrain, MAX_VERTICES);
        assert!(mesh.positions.len() <= MAX_VERTICES);
        assert_eq!(mesh.positions.len(), mesh.dims.0 * mesh.dims.1);
        assert_eq!(mesh.normals.len(), mesh.positions.len());
        assert_eq!(mesh.colors.len(), mesh.positions.len());
        assert_eq!(
            mesh.triangles.len(),
            2 * (mesh.dims.0 - 1) * (mesh.dims.1 - 1)
        );
        let b = terrain.bounds();
        let last = mesh.positions[mesh.positions.len() - 1];
        assert!((f64::from(last[0]) - b.x[1]).abs() < 1e-4);
        assert!((f64::from(last[2]) - b.z[1]).abs() < 1e-4);
        assert!((f64::from(last[1]) - terrain.sample(rows - 1, cols - 1)).abs() < 1e-6);
    }

    #[test]
    fn a_small_budget_decimates_and_faces_point_up() {
        let terrain = Terrain::procedural(&TerrainConfig::default());
        let mesh = GridMesh::of(&terrain, 1000);
        assert!(mesh.stride > 1 && mesh.positions.len() <= 1000);
        let p = &mesh.positions;
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|k| p[k as usize]);
            let (u, v) = ([b[0] - a[0], b[2] - a[2]], [c[0] - a[0], c[2] - a[2]]);
            // The Y component of (b − a) × (c − a) is positive for an upward face.
            assert!(u[1] * v[0] - u[0] * v[1] > 0.0, "{t:?}");
        }
        assert!(mesh.normals.iter().all(|n| n[1] > 0.0));
    }
}
