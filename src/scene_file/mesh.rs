//! The mesh a file gives before the scene places it, and how the loader reads mesh files.

use glam::{DVec2, DVec3};
use std::path::Path;

/// A mesh as read from a PLY or OBJ file (or generated for a built-in shape), in object
/// space before the shape's `to_world`: what [`super::parse_ply`] and [`super::parse_obj`] return. Not yet
/// checked for non-finite vertices (the scene loader does that when it places the mesh).
#[derive(Clone, Debug, PartialEq)]
pub struct RawMesh {
    /// Vertex positions as stored.
    pub positions: Vec<DVec3>,
    /// Per-vertex normals as stored, if every vertex has one.
    pub normals: Option<Vec<DVec3>>,
    /// Per-vertex texture coordinates `(u, v)` in Mitsuba's convention (`v = 0` is the
    /// first image row), if every vertex has them.
    pub uvs: Option<Vec<DVec2>>,
    /// Triangles (polygons fan-triangulated); every index is below `positions.len()`.
    pub indices: Vec<[u32; 3]>,
    /// The file asks for face normals (a serialized mesh's flag), unless the scene's
    /// `face_normals` property says otherwise.
    pub face_normals: bool,
}

/// Reads a mesh file named by a scene (`<string name="filename">`, resolved against the
/// scene file's directory). [`super::load_scene`] reads the file system; [`super::load_scene_bytes`] takes
/// any reader, e.g. in-memory files for fuzzing and tests.
pub type MeshReader<'a> = &'a dyn Fn(&Path) -> std::io::Result<Vec<u8>>;

