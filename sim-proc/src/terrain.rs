//! The lava-tube floor as a rapier collider: the height grid itself (SPEC S1) is
//! `common::terrain`, shared with the map and the recorder.

pub use common::terrain::Terrain;
use rapier3d::prelude::{HeightFieldFlags, SharedShape};

/// The collider shape of `terrain` and where its centre goes (parry centres a heightfield on
/// its body).
pub fn shape(terrain: &Terrain) -> (SharedShape, [f64; 3]) {
    let b = terrain.bounds();
    let (rows, cols) = terrain.dims();
    let heights = rapier3d::parry::utils::Array2::new(rows, cols, terrain.heights().to_vec());
    let scale =
        rapier3d::math::Vector::new((b.x[1] - b.x[0]) as f32, 1.0, (b.z[1] - b.z[0]) as f32);
    let shape =
        SharedShape::heightfield_with_flags(heights, scale, HeightFieldFlags::FIX_INTERNAL_EDGES);
    (
        shape,
        [0.5 * (b.x[0] + b.x[1]), 0.0, 0.5 * (b.z[0] + b.z[1])],
    )
}
