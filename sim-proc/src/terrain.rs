//! The lava-tube floor as a rapier collider: the height grid itself (SPEC S1) is
//! `common::terrain`, shared with the map and the recorder.

use common::config::TerrainCollider;
pub use common::terrain::Terrain;
use rapier3d::prelude::{HeightFieldFlags, SharedShape, TriMeshFlags};

/// The collider shape of `terrain` and where its centre goes (parry centres a heightfield on
/// its body). Both kinds hold the same triangles, with their internal edges fixed (no ghost
/// contacts where two triangles meet); the mesh computes those edges' normals once, where
/// the heightfield does it at every contact (DESIGN §10).
pub fn shape(terrain: &Terrain, collider: TerrainCollider) -> (SharedShape, [f64; 3]) {
    let b = terrain.bounds();
    let (rows, cols) = terrain.dims();
    let heights = rapier3d::parry::utils::Array2::new(rows, cols, terrain.heights().to_vec());
    let scale =
        rapier3d::math::Vector::new((b.x[1] - b.x[0]) as f32, 1.0, (b.z[1] - b.z[0]) as f32);
    let field = rapier3d::parry::shape::HeightField::with_flags(
        heights,
        scale,
        HeightFieldFlags::FIX_INTERNAL_EDGES,
    );
    let shape = match collider {
        TerrainCollider::Heightfield => SharedShape::new(field),
        TerrainCollider::Trimesh => {
            let (vertices, triangles) = field.to_trimesh();
            // One-sided, as the heightfield is: as a two-sided mesh the floor let a jointed
            // robot climb a 12° slope at 75 % of its command, against 93 % on the heightfield
            // and on this mesh (docs/RESULTS.md, R45).
            let flags = TriMeshFlags::FIX_INTERNAL_EDGES | TriMeshFlags::ORIENTED;
            SharedShape::trimesh_with_flags(vertices, triangles, flags)
                .expect("a heightfield's triangles make a valid mesh")
        }
    };
    (
        shape,
        [0.5 * (b.x[0] + b.x[1]), 0.0, 0.5 * (b.z[0] + b.z[1])],
    )
}
