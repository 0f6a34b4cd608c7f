//! Wavefront OBJ meshes through `tobj`: all objects and groups merged into one mesh,
//! polygons triangulated, per-vertex normals and texture coordinates kept when every vertex
//! has them (`v` flipped to `1 − v`, as Mitsuba's OBJ loader does by default); materials
//! (`.mtl`) are ignored (the scene's `<bsdf>` applies).

use super::mesh::RawMesh;
use super::error::SceneFileError;
use glam::{DVec2, DVec3};
use std::path::Path;

/// Parses the OBJ file `bytes`; `path` names it in errors. `mtllib` lines are ignored
/// (the loader never opens material libraries).
pub(crate) fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh, SceneFileError> {
    let err = |message: String| SceneFileError::Obj { path: path.to_path_buf(), message };
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        err(format!("line {line}: not UTF-8 text"))
    })?;
    check_references(text).map_err(err)?;
    let options = tobj::LoadOptions { single_index: true, triangulate: true, ignore_points: true, ignore_lines: true };
    let no_materials = |_: &Path| -> tobj::MTLLoadResult { Err(tobj::LoadError::OpenFileFailed) };
    let loaded = std::panic::catch_unwind(|| tobj::load_obj_buf(&mut &bytes[..], &options, no_materials)).map_err(|_| err("the OBJ parser failed on this file".into()))?;
    let (models, _materials) = loaded.map_err(|e| err(format!("cannot parse: {e}")))?;
    let mut out = RawMesh { positions: Vec::new(), normals: Some(Vec::new()), uvs: Some(Vec::new()), indices: Vec::new(), face_normals: false };
    for m in &models {
        let mesh = &m.mesh;
        let base = out.positions.len();
        let n = mesh.positions.len() / 3;
        out.positions.extend(mesh.positions.chunks_exact(3).map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)));
        match (&mut out.normals, mesh.normals.len() == mesh.positions.len()) {
            (Some(normals), true) => normals.extend(mesh.normals.chunks_exact(3).map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))),
            (normals, _) => *normals = None,
        }
        match (&mut out.uvs, mesh.texcoords.len() == 2 * n) {
            (Some(uvs), true) => uvs.extend(mesh.texcoords.chunks_exact(2).map(|t| DVec2::new(t[0] as f64, 1.0 - t[1] as f64))),
            (uvs, _) => *uvs = None,
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

/// Checks that every vertex reference of every face (`f`) and line (`l`) element names an
/// existing position, texture coordinate or normal before `tobj` resolves it: `tobj`
/// computes with out-of-range references unchecked (an index overflow, found by fuzzing).
/// A relative (negative) index counts back from the elements defined so far; an absolute
/// one must not exceed the file's count (`tobj` resolves them after reading the file).
/// `Err` names the line, the reference and the problem.
fn check_references(text: &str) -> Result<(), String> {
    const KINDS: [(&str, &str); 3] = [("v", "vertex position"), ("vt", "texture coordinate"), ("vn", "normal")];
    let kind = |word: Option<&str>| KINDS.iter().position(|(k, _)| Some(*k) == word);
    let mut total = [0usize; 3];
    for line in text.lines() {
        if let Some(k) = kind(line.split_whitespace().next()) {
            total[k] += 1;
        }
    }
    let mut seen = [0usize; 3];
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let first = words.next();
        if let Some(k) = kind(first) {
            seen[k] += 1;
            continue;
        }
        if !matches!(first, Some("f" | "l")) {
            continue;
        }
        for word in words {
            for (k, field) in word.split('/').enumerate().take(3) {
                // Malformed numbers are tobj's to report.
                let Ok(x) = field.parse::<i64>() else { continue };
                let (name, line) = (KINDS[k].1, number + 1);
                if x == 0 {
                    return Err(format!("line {line}: '{word}' has {name} index 0 (OBJ indices start at 1, or count back from -1)"));
                }
                if x < 0 && x.unsigned_abs() > seen[k] as u64 {
                    return Err(format!("line {line}: '{word}' has relative {name} index {x}, but only {} precede it", seen[k]));
                }
                if x > 0 && x as u64 > total[k] as u64 {
                    return Err(format!("line {line}: '{word}' has {name} index {x}, but the file has {}", total[k]));
                }
            }
        }
    }
    Ok(())
}
