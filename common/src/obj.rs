//! A world as a Wavefront OBJ mesh (Y up, metres), for any viewer: the floor's height grid as
//! triangles, split along the diagonal the physics collider uses, so the mesh is the surface
//! the robots drive on.

use crate::terrain::Terrain;
use std::io::{self, Write};

/// Writes `terrain` as one object: a vertex per grid sample (row `i` along +Z, column `j`
/// along +X) and two triangles per cell, wound so that their normals point up.
pub fn write(terrain: &Terrain, name: &str, out: &mut impl Write) -> io::Result<()> {
    let (rows, cols) = terrain.dims();
    let b = terrain.bounds();
    let cell = terrain.cell();
    writeln!(
        out,
        "# {name}: {rows} x {cols} samples, {cell} m apart; Y up, metres"
    )?;
    writeln!(out, "o {name}")?;
    for i in 0..rows {
        for j in 0..cols {
            let (x, z) = (b.x[0] + j as f64 * cell, b.z[0] + i as f64 * cell);
            // f32, as the collider holds them.
            let (x, y, z) = (x as f32, terrain.sample(i, j) as f32, z as f32);
            writeln!(out, "v {x} {y} {z}")?;
        }
    }
    // OBJ counts vertices from 1.
    let at = |i: usize, j: usize| i * cols + j + 1;
    for i in 0..rows - 1 {
        for j in 0..cols - 1 {
            writeln!(out, "f {} {} {}", at(i, j), at(i + 1, j), at(i, j + 1))?;
            writeln!(
                out,
                "f {} {} {}",
                at(i + 1, j + 1),
                at(i, j + 1),
                at(i + 1, j)
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::TerrainConfig;

    /// Vertices and faces read back from the text.
    fn parse(text: &str) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
        let (mut v, mut f) = (Vec::new(), Vec::new());
        for line in text.lines() {
            let mut words = line.split_whitespace();
            match words.next() {
                Some("v") => {
                    let p: Vec<f64> = words.map(|w| w.parse().expect("number")).collect();
                    v.push([p[0], p[1], p[2]]);
                }
                Some("f") => {
                    let p: Vec<usize> = words.map(|w| w.parse().expect("index")).collect();
                    f.push([p[0] - 1, p[1] - 1, p[2] - 1]);
                }
                _ => {}
            }
        }
        (v, f)
    }

    #[test]
    fn the_mesh_is_the_surface_the_robots_drive_on() {
        let terrain = Terrain::procedural(&TerrainConfig::default());
        let mut text = Vec::new();
        write(&terrain, "floor", &mut text).expect("write");
        let (v, f) = parse(&String::from_utf8(text).expect("utf-8"));
        let (rows, cols) = terrain.dims();
        assert_eq!(
            (v.len(), f.len()),
            (rows * cols, 2 * (rows - 1) * (cols - 1))
        );
        let mut rng = crate::Rng::new(5);
        for _ in 0..2000 {
            let t = f[rng.below(f.len())];
            let [a, b, c] = t.map(|k| v[k]);
            // Up-facing: the normal's Y of (b − a) × (c − a) is positive.
            let (u, w) = ([b[0] - a[0], b[2] - a[2]], [c[0] - a[0], c[2] - a[2]]);
            assert!(u[1] * w[0] - u[0] * w[1] > 0.0, "a triangle faces down");
            // A point inside the triangle lies on the floor as height_at computes it.
            let (s, r) = (rng.range(0.0, 0.5), rng.range(0.0, 0.5));
            let p: Vec<f64> = (0..3)
                .map(|k| a[k] + s * (b[k] - a[k]) + r * (c[k] - a[k]))
                .collect();
            let floor = terrain.height_at(p[0], p[2]);
            assert!((p[1] - floor).abs() < 1e-6, "{} against {floor}", p[1]);
        }
    }
}
