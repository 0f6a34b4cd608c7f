//! Wavefront OBJ meshes through `tobj`: all objects and groups merged into one mesh,
//! polygons triangulated, per-vertex normals kept when every vertex has one; materials
//! (`.mtl`) are ignored (the scene's `<bsdf>` applies).

use super::RawMesh;
use super::error::SceneFileError;
use glam::DVec3;
use std::path::Path;

/// Loads `path`.
pub(crate) fn load(path: &Path) -> Result<RawMesh, SceneFileError> {
    // Distinguish a missing/unreadable file (I/O error) from a malformed one.
    std::fs::metadata(path).map_err(|source| SceneFileError::Io { path: path.to_path_buf(), source })?;
    let err = |message: String| SceneFileError::Obj { path: path.to_path_buf(), message };
    let options = tobj::LoadOptions { single_index: true, triangulate: true, ignore_points: true, ignore_lines: true };
    let loaded = std::panic::catch_unwind(|| tobj::load_obj(path, &options)).map_err(|_| err("the OBJ parser failed on this file".into()))?;
    let (models, _materials) = loaded.map_err(|e| err(format!("cannot parse: {e}")))?;
    let mut out = RawMesh { positions: Vec::new(), normals: Some(Vec::new()), indices: Vec::new() };
    for m in &models {
        let mesh = &m.mesh;
        let base = out.positions.len();
        let n = mesh.positions.len() / 3;
        out.positions.extend(mesh.positions.chunks_exact(3).map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)));
        match (&mut out.normals, mesh.normals.len() == mesh.positions.len()) {
            (Some(normals), true) => normals.extend(mesh.normals.chunks_exact(3).map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))),
            (normals, _) => *normals = None,
        }
        if mesh.indices.len() % 3 != 0 {
            return Err(err(format!("object '{}' has an index count that is not a multiple of 3", m.name)));
        }
        for t in mesh.indices.chunks_exact(3) {
            if let Some(&bad) = t.iter().find(|&&i| i as usize >= n) {
                return Err(err(format!("object '{}' refers to vertex {bad}, but it has {n} vertices", m.name)));
            }
            let b = u32::try_from(base).map_err(|_| err("too many vertices".into()))?;
            out.indices.push([t[0] + b, t[1] + b, t[2] + b]);
        }
    }
    if out.indices.is_empty() {
        return Err(err("no faces".into()));
    }
    Ok(out)
}
