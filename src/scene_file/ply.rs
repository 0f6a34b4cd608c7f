//! PLY meshes through `ply-rs`: ASCII or binary (either byte order); vertex properties
//! `x y z` (float or double) with optional `nx ny nz` and texture coordinates `u v`,
//! `texture_u texture_v` or `s t` (the names Mitsuba's PLY loader reads, not flipped; other
//! properties are read and ignored); faces `list <int type> <int type> vertex_indices` (or `vertex_index`).
//! Triangles are kept, larger polygons (quads) are fan-triangulated, anything smaller is
//! an error. Every failure is a [`SceneFileError::Ply`] naming the file.

use super::mesh::RawMesh;
use super::error::SceneFileError;
use glam::{DVec2, DVec3};
use ply_rs::parser::Parser;
use ply_rs::ply::{DefaultElement, ElementDef, Encoding, Property, PropertyAccess, PropertyType, ScalarType};
use std::io::ErrorKind;
use std::path::Path;

#[derive(Default)]
struct Vertex {
    p: [f64; 3],
    n: [f64; 3],
    uv: [f64; 2],
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        _ => return None,
    })
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Self::default()
    }
    fn set_property(&mut self, name: String, p: Property) {
        let Some(v) = scalar(&p) else { return };
        match name.as_str() {
            "x" => self.p[0] = v,
            "y" => self.p[1] = v,
            "z" => self.p[2] = v,
            "nx" => self.n[0] = v,
            "ny" => self.n[1] = v,
            "nz" => self.n[2] = v,
            "u" | "texture_u" | "s" => self.uv[0] = v,
            "v" | "texture_v" | "t" => self.uv[1] = v,
            _ => {}
        }
    }
}

#[derive(Default)]
struct Face {
    /// Vertex indices; `None` if one is negative.
    idx: Option<Vec<u32>>,
}

fn list<T: Copy + TryInto<u32>>(v: &[T]) -> Option<Vec<u32>> {
    v.iter().map(|&i| i.try_into().ok()).collect()
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face { idx: Some(Vec::new()) }
    }
    fn set_property(&mut self, name: String, p: Property) {
        if name != "vertex_indices" && name != "vertex_index" {
            return;
        }
        self.idx = match &p {
            Property::ListChar(v) => list(v),
            Property::ListUChar(v) => list(v),
            Property::ListShort(v) => list(v),
            Property::ListUShort(v) => list(v),
            Property::ListInt(v) => list(v),
            Property::ListUInt(v) => list(v),
            _ => None,
        };
    }
}

fn has_scalar(def: &ElementDef, name: &str) -> bool {
    def.properties.get(name).is_some_and(|p| matches!(p.data_type, PropertyType::Scalar(_)))
}

/// Parses the PLY file `bytes`; `path` names it in errors.
pub(crate) fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh, SceneFileError> {
    // The checks in `read` keep ply-rs off the inputs fuzzing found it to panic on; should it
    // panic on another, a malformed file must still not take the program down.
    std::panic::catch_unwind(|| read(bytes, path)).unwrap_or_else(|_| Err(ply_err(path, "the PLY parser failed on this file".into())))
}

fn ply_err(path: &Path, message: String) -> SceneFileError {
    SceneFileError::Ply { path: path.to_path_buf(), message }
}

/// Rejects header numbers `ply-rs` cannot hold: its grammar unwraps the parse of every
/// `element` count and `format` version number as a `u64` and panics on a larger one
/// (found by fuzzing). Checks the leading digits of every word after `element` or
/// `format` on each header line; `Err` names the line.
fn check_header_numbers(bytes: &[u8]) -> Result<(), String> {
    for (number, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut words = line.split([' ', '\t', '\r']).filter(|w| !w.is_empty());
        match words.next() {
            Some("end_header") => break,
            Some("element" | "format") => {}
            _ => continue,
        }
        for part in words.flat_map(|w| w.split('.')) {
            let digits = part.find(|c: char| !c.is_ascii_digit()).map_or(part, |end| &part[..end]);
            if !digits.is_empty() && digits.parse::<u64>().is_err() {
                return Err(format!("header line {}: the number {digits} is too large", number + 1));
            }
        }
    }
    Ok(())
}

/// Smallest number of payload bytes one element of `def` takes: the sizes of its scalars
/// and list counts in a binary file; in an ASCII file one character and a separator per
/// property (at least the line break).
fn min_element_bytes(def: &ElementDef, encoding: Encoding) -> u128 {
    let size = |t: &ScalarType| match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    };
    match encoding {
        Encoding::Ascii => 2 * (def.properties.len() as u128).max(1),
        Encoding::BinaryBigEndian | Encoding::BinaryLittleEndian => def
            .properties
            .values()
            .map(|p| match &p.data_type {
                PropertyType::Scalar(t) | PropertyType::List(t, _) => size(t),
            })
            .sum::<u128>()
            .max(1),
    }
}

fn read(mut r: &[u8], path: &Path) -> Result<RawMesh, SceneFileError> {
    let err = |m: String| ply_err(path, m);
    let vparser = Parser::<Vertex>::new();
    let fparser = Parser::<Face>::new();
    check_header_numbers(r).map_err(err)?;
    let header = vparser.read_header(&mut r).map_err(|e| err(format!("bad header: {}", e.to_string().replace('\n', " ").replace('\t', ""))))?;
    // ply-rs reads `count` elements whatever the file holds: an element of no properties
    // costs no bytes, so a huge count would loop and allocate without end. Every element
    // needs at least `min_element_bytes` of the payload (+1: the last line break).
    let payload = r.len() as u128;
    let mut needed = 0u128;
    for (name, def) in &header.elements {
        needed += def.count as u128 * min_element_bytes(def, header.encoding);
        if needed > payload + 1 {
            return Err(err(format!("file ends early (truncated?): the header declares {} '{name}' elements, more than the {payload} bytes after the header can hold", def.count)));
        }
    }
    let vdef = header.elements.get("vertex").ok_or_else(|| err("no 'vertex' element".into()))?;
    if !["x", "y", "z"].iter().all(|k| has_scalar(vdef, k)) {
        return Err(err("the 'vertex' element lacks scalar x, y, z properties".into()));
    }
    let has_normals = ["nx", "ny", "nz"].iter().all(|k| has_scalar(vdef, k));
    let has_uvs = [["u", "v"], ["texture_u", "texture_v"], ["s", "t"]].iter().any(|pair| pair.iter().all(|k| has_scalar(vdef, k)));
    let fdef = header.elements.get("face").ok_or_else(|| err("no 'face' element (point clouds are not meshes)".into()))?;
    let index_prop = fdef.properties.get("vertex_indices").or_else(|| fdef.properties.get("vertex_index"));
    match index_prop.map(|p| &p.data_type) {
        Some(PropertyType::List(_, t)) if !matches!(t, ScalarType::Float | ScalarType::Double) => {}
        _ => return Err(err("the 'face' element lacks an integer list property 'vertex_indices'".into())),
    }

    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for (name, def) in &header.elements {
        let what = |e: std::io::Error| {
            let text = e.to_string().replace('\n', " ").replace('\t', "");
            if e.kind() == ErrorKind::UnexpectedEof || text.contains("list element") {
                err(format!("file ends early (truncated?) while reading {} '{name}' elements: {text}", def.count))
            } else {
                err(format!("cannot read the '{name}' elements: {text}"))
            }
        };
        match name.as_str() {
            "vertex" => vertices = vparser.read_payload_for_element(&mut r, def, &header).map_err(what)?,
            "face" => faces = fparser.read_payload_for_element(&mut r, def, &header).map_err(what)?,
            _ => {
                Parser::<DefaultElement>::new().read_payload_for_element(&mut r, def, &header).map_err(what)?;
            }
        }
    }

    let count = vertices.len();
    let mut indices = Vec::with_capacity(faces.len());
    for (f, face) in faces.iter().enumerate() {
        let Some(idx) = &face.idx else { return Err(err(format!("face {f} has a negative or non-integer vertex index"))) };
        if idx.len() < 3 {
            return Err(err(format!("face {f} has {} vertices (at least 3 needed)", idx.len())));
        }
        if let Some(&bad) = idx.iter().find(|&&i| i as usize >= count) {
            return Err(err(format!("face {f} refers to vertex {bad}, but the file has {count} vertices")));
        }
        for k in 1..idx.len() - 1 {
            indices.push([idx[0], idx[k], idx[k + 1]]);
        }
    }
    let positions = vertices.iter().map(|v| DVec3::from_array(v.p)).collect();
    let normals = has_normals.then(|| vertices.iter().map(|v| DVec3::from_array(v.n)).collect());
    let uvs = has_uvs.then(|| vertices.iter().map(|v| DVec2::from_array(v.uv)).collect());
    Ok(RawMesh { positions, normals, uvs, indices, face_normals: false })
}
