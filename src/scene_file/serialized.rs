//! Mitsuba `serialized` meshes (`<shape type="serialized">`): the zlib-compressed binary
//! triangle-mesh format that Mitsuba 0.5/0.6, 2 and 3 read, in its versions 3 and 4.
//!
//! # Format
//!
//! Every number is little endian. A file is one or more shapes, then a dictionary.
//!
//! * A shape starts with an uncompressed header: the format identifier `0x041C` (`u16`) and
//!   the version (`u16`, 3 or 4). Then comes one zlib stream (RFC 1950), which inflates to
//!   - a `u32` flag word: `0x0001` vertex normals, `0x0002` texture coordinates, `0x0008`
//!     vertex colors, `0x0010` shade with face normals, `0x1000` single and `0x2000` double
//!     precision (the data is `f64` when `0x2000` is set, `f32` otherwise; `0x0004`,
//!     tangents, has never had data and is ignored like any other bit);
//!   - in version 4 only, the shape's name: UTF-8 bytes ended by a NUL byte;
//!   - the vertex count `V` and the triangle count `F`, both `u64`;
//!   - `3V` positions, then, each only where its flag is set, `3V` normals, `2V` texture
//!     coordinates and `3V` RGB colors, all `f32` or all `f64`;
//!   - `3F` vertex indices, `u32`.
//! * The dictionary closes the file: the byte offset of each shape's header (`u32` each in
//!   version 3, `u64` in version 4; the first is 0), then the number of shapes as a `u32`.
//!
//! As in Mitsuba, shape 0 is read from the start of the file without the dictionary (so
//! single-shape files written without one load), and the other shapes through it. The
//! format's description allows `u64` indices above `0xFFFF_FFFF` vertices, which no Mitsuba
//! reads; such counts are an error here. Positions, normals and texture coordinates come
//! back as stored (object space, no transform, normals not renormalised, texture
//! coordinates not flipped); colors and the name are read and discarded. Every array is
//! read from the inflated data before anything of its size is allocated, so a malformed
//! file gives an error naming the problem, never a panic or an allocation its size did not
//! pay for.

use super::error::SceneFileError;
use super::mesh::RawMesh;
use flate2::bufread::ZlibDecoder;
use glam::{DVec2, DVec3};
use std::io::{BufRead, BufReader, ErrorKind};
use std::path::Path;

/// Format identifier that starts every shape's header.
const FORMAT_ID: u16 = 0x041C;
/// Version whose dictionary offsets are `u32` and whose shapes have no name.
const VERSION_3: u16 = 3;
/// Version whose dictionary offsets are `u64` and whose shapes carry a name.
const VERSION_4: u16 = 4;
/// Size of a shape's uncompressed header (identifier and version).
const HEADER_BYTES: usize = 4;
/// Size of the shape count that ends the dictionary.
const COUNT_BYTES: usize = 4;
/// Flag: per-vertex normals follow the positions.
const HAS_NORMALS: u32 = 0x0001;
/// Flag: per-vertex texture coordinates follow the normals.
const HAS_UVS: u32 = 0x0002;
/// Flag: per-vertex RGB colors follow the texture coordinates.
const HAS_COLORS: u32 = 0x0008;
/// Flag: the shape is to be shaded with face normals (stored normals are ignored).
const FACE_NORMALS: u32 = 0x0010;
/// Flag: the vertex data is `f64` (otherwise `f32`).
const DOUBLE_PRECISION: u32 = 0x2000;

/// Reads shape `shape_index` of the serialized file `bytes` (`path` only names the file in
/// errors). Normals are `None` where the file has none or asks for face normals.
pub(crate) fn parse(bytes: &[u8], path: &Path, shape_index: u32) -> Result<RawMesh, SceneFileError> {
    parse_shape(bytes, shape_index).map_err(|message| error(path, message))
}

/// Number of shapes in the file (for the error message of an out-of-range `shape_index`
/// and for tests), from the dictionary at its end, whose every entry must point at a shape
/// header. A file without a dictionary is an error here, though [`parse`] reads its shape 0.
pub(crate) fn shape_count(bytes: &[u8], path: &Path) -> Result<u32, SceneFileError> {
    count_shapes(bytes).map_err(|message| error(path, message))
}

/// The loader's error for the file `path` with `message`.
fn error(path: &Path, message: impl Into<String>) -> SceneFileError {
    SceneFileError::Serialized { path: path.to_path_buf(), message: message.into() }
}

/// The little-endian `u16` at byte `at`, if the file is long enough.
fn u16_at(bytes: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(bytes.get(at..at.checked_add(2)?)?.try_into().ok()?))
}

/// The little-endian `u32` at byte `at`, if the file is long enough.
fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(bytes.get(at..at.checked_add(4)?)?.try_into().ok()?))
}

/// The little-endian `u64` at byte `at`, if the file is long enough.
fn u64_at(bytes: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(bytes.get(at..at.checked_add(8)?)?.try_into().ok()?))
}

/// Checks the shape header at byte `at` and returns its version.
fn read_header(bytes: &[u8], at: usize) -> Result<u16, String> {
    let (Some(id), Some(version)) = (u16_at(bytes, at), u16_at(bytes, at.saturating_add(2))) else {
        let got = bytes.len().saturating_sub(at).min(HEADER_BYTES);
        return Err(format!("truncated header at byte {at}: expected {HEADER_BYTES} bytes, got {got}"));
    };
    if id == FORMAT_ID.swap_bytes() {
        return Err(format!(
            "format identifier 0x{id:04x} at byte {at} is that of an early Mitsuba version's files; re-export the mesh"
        ));
    }
    if id != FORMAT_ID {
        return Err(format!("unknown format identifier 0x{id:04x} at byte {at} (expected 0x{FORMAT_ID:04x})"));
    }
    if version != VERSION_3 && version != VERSION_4 {
        // Mitsuba 3's development branch after 3.9.1 writes a packed layout as version 5.
        let hint = if version == 5 { "; version 5 is the packed layout of Mitsuba 3 after 3.9.1" } else { "" };
        return Err(format!("unsupported version {version} (only versions 3 and 4 are supported{hint})"));
    }
    Ok(version)
}

/// The dictionary of shape offsets at the end of a file.
struct Dictionary {
    /// Number of shapes it lists (at least 1).
    count: u32,
    /// Size of one offset: 4 bytes in version 3, 8 in version 4.
    entry_bytes: usize,
    /// Byte where the offsets start, which is where the shape data ends.
    start: usize,
}

impl Dictionary {
    /// Locates the dictionary of a file of `version` and checks that it fits in the file and
    /// that its first offset is 0 (which tells a dictionary from the end of a zlib stream).
    fn read(bytes: &[u8], version: u16) -> Result<Self, String> {
        let len = bytes.len();
        let no_dictionary = "no valid shape dictionary at the end of the file";
        let Some(count) = len.checked_sub(COUNT_BYTES).filter(|&at| at >= HEADER_BYTES).and_then(|at| u32_at(bytes, at)) else {
            return Err(format!("{no_dictionary}: the file has only {len} bytes"));
        };
        if count == 0 {
            return Err(format!("{no_dictionary}: it lists 0 shapes"));
        }
        let entry_bytes = if version == VERSION_3 { 4 } else { 8 };
        let table = u64::from(count) * entry_bytes as u64 + COUNT_BYTES as u64;
        // `len >= HEADER_BYTES + COUNT_BYTES` here, so `len - HEADER_BYTES` cannot wrap.
        let Some(start) = usize::try_from(table).ok().and_then(|table| (len - HEADER_BYTES).checked_sub(table)) else {
            return Err(format!(
                "{no_dictionary}: its last {COUNT_BYTES} bytes claim {count} shapes, whose offsets need {table} bytes, \
                 but the file has {len} (a file without a dictionary holds one shape, read with shape_index 0)"
            ));
        };
        let dictionary = Self { count, entry_bytes, start: start + HEADER_BYTES };
        let first = dictionary.offset(bytes, 0);
        if first != 0 {
            return Err(format!("{no_dictionary}: the first shape's offset is {first}, not 0"));
        }
        Ok(dictionary)
    }

    /// The offset the dictionary stores for shape `index` (`u64::MAX` if it has none).
    fn offset(&self, bytes: &[u8], index: u32) -> u64 {
        let at = (index as usize).saturating_mul(self.entry_bytes).saturating_add(self.start);
        let offset = if self.entry_bytes == 4 { u32_at(bytes, at).map(u64::from) } else { u64_at(bytes, at) };
        offset.unwrap_or(u64::MAX)
    }

    /// Where shape `index` starts, checked to leave room for its header before the
    /// dictionary, and the version its header states.
    fn shape_start(&self, bytes: &[u8], index: u32) -> Result<(usize, u16), String> {
        let offset = self.offset(bytes, index);
        let start = usize::try_from(offset)
            .ok()
            .filter(|start| start.checked_add(HEADER_BYTES).is_some_and(|end| end <= self.start))
            .ok_or_else(|| {
                format!("the shape dictionary gives shape {index} the offset {offset}, outside the shape data (bytes 0..{})", self.start)
            })?;
        let version = read_header(bytes, start).map_err(|e| format!("shape {index} (offset {start} in the dictionary): {e}"))?;
        Ok((start, version))
    }
}

/// [`shape_count`] with a bare message.
fn count_shapes(bytes: &[u8]) -> Result<u32, String> {
    let version = read_header(bytes, 0)?;
    let dictionary = Dictionary::read(bytes, version)?;
    for index in 1..dictionary.count {
        let (_, shape_version) = dictionary.shape_start(bytes, index)?;
        check_same_version(index, shape_version, version)?;
    }
    Ok(dictionary.count)
}

/// Fails if shape `index`'s header has another version than the file's first shape (Mitsuba
/// reads every shape by the first header's version, so a mix means a bad offset).
fn check_same_version(index: u32, shape_version: u16, version: u16) -> Result<(), String> {
    if shape_version == version {
        Ok(())
    } else {
        Err(format!("shape {index}'s header states version {shape_version}, the file's first shape version {version}"))
    }
}

/// [`parse`] with a bare message.
fn parse_shape(bytes: &[u8], shape_index: u32) -> Result<RawMesh, String> {
    let version = read_header(bytes, 0)?;
    let start = if shape_index == 0 {
        0
    } else {
        let dictionary = Dictionary::read(bytes, version).map_err(|e| format!("cannot locate shape_index {shape_index}: {e}"))?;
        if shape_index >= dictionary.count {
            let plural = if dictionary.count == 1 { "" } else { "s" };
            return Err(format!("shape_index {shape_index} out of range: the file holds {} shape{plural}", dictionary.count));
        }
        let (start, shape_version) = dictionary.shape_start(bytes, shape_index)?;
        check_same_version(shape_index, shape_version, version)?;
        start
    };
    let stream = bytes.get(start + HEADER_BYTES..).unwrap_or_default();
    read_shape(stream, version).map_err(|e| format!("shape {shape_index}: {e}"))
}

/// Reads one shape from its zlib stream `compressed` (what follows its header).
fn read_shape(compressed: &[u8], version: u16) -> Result<RawMesh, String> {
    let mut data = Inflated::new(compressed);
    let flags = data.u32("flags")?;
    if version == VERSION_4 {
        data.skip_name()?;
    }
    let vertex_count = data.u64("vertex count")?;
    let triangle_count = data.u64("triangle count")?;
    let too_many = |what: &str, count: u64| format!("{what} count {count} exceeds the 32-bit index range (at most {})", u32::MAX);
    let vertices = u32::try_from(vertex_count).map_err(|_| too_many("vertex", vertex_count))?;
    let triangles = u32::try_from(triangle_count).map_err(|_| too_many("triangle", triangle_count))?;
    let double = flags & DOUBLE_PRECISION != 0;
    let scalar_bytes: u64 = if double { 8 } else { 4 };
    // At most 2^32 vertices of 3 doubles: the byte counts below cannot overflow a u64.
    let vector_bytes = |dimension: u64| u64::from(vertices) * dimension * scalar_bytes;

    let positions = vec3s(&data.block("vertex positions", vector_bytes(3))?, double);
    let normals = if flags & HAS_NORMALS == 0 {
        None
    } else if flags & FACE_NORMALS != 0 {
        data.skip("vertex normals", vector_bytes(3))?;
        None
    } else {
        Some(vec3s(&data.block("vertex normals", vector_bytes(3))?, double))
    };
    let uvs = if flags & HAS_UVS == 0 {
        None
    } else {
        let values = scalars(&data.block("texture coordinates", vector_bytes(2))?, double);
        Some(values.chunks_exact(2).map(|c| if let [u, v] = c { DVec2::new(*u, *v) } else { DVec2::NAN }).collect())
    };
    if flags & HAS_COLORS != 0 {
        data.skip("vertex colors", vector_bytes(3))?;
    }

    let index_bytes = data.block("triangle indices", u64::from(triangles) * 12)?;
    let mut indices = Vec::with_capacity(index_bytes.len() / 12);
    for (t, triangle) in index_bytes.chunks_exact(12).enumerate() {
        let mut corners = [0u32; 3];
        for (corner, bytes) in corners.iter_mut().zip(triangle.chunks_exact(4)) {
            *corner = bytes.try_into().map_or(u32::MAX, u32::from_le_bytes);
            if *corner >= vertices {
                return Err(format!("triangle {t} uses vertex index {corner}, but the mesh has {vertices} vertices"));
            }
        }
        indices.push(corners);
    }
    data.finish()?;
    Ok(RawMesh { positions, normals, uvs, indices, face_normals: flags & FACE_NORMALS != 0 })
}

/// Decodes little-endian `f64`s (`double`) or `f32`s from `bytes`, widened to `f64`.
fn scalars(bytes: &[u8], double: bool) -> Vec<f64> {
    if double {
        bytes.chunks_exact(8).map(|c| c.try_into().map_or(f64::NAN, f64::from_le_bytes)).collect()
    } else {
        bytes.chunks_exact(4).map(|c| c.try_into().map(f32::from_le_bytes).map_or(f64::NAN, f64::from)).collect()
    }
}

/// Decodes consecutive `x y z` triples (see [`scalars`]).
fn vec3s(bytes: &[u8], double: bool) -> Vec<DVec3> {
    let values = scalars(bytes, double);
    values.chunks_exact(3).map(|c| if let [x, y, z] = c { DVec3::new(*x, *y, *z) } else { DVec3::NAN }).collect()
}

/// A shape's inflated data, read front to back with every length checked against what the
/// stream actually yields.
struct Inflated<'a> {
    /// The zlib decoder over the shape's compressed bytes.
    reader: BufReader<ZlibDecoder<&'a [u8]>>,
}

impl<'a> Inflated<'a> {
    /// Starts inflating `compressed` (the stream may be followed by other data, which is
    /// never read).
    fn new(compressed: &'a [u8]) -> Self {
        Self { reader: BufReader::new(ZlibDecoder::new(compressed)) }
    }

    /// The next inflated bytes, empty at the end of the stream. A stream cut short is an
    /// `UnexpectedEof` error.
    fn fill(&mut self) -> std::io::Result<&[u8]> {
        self.reader.fill_buf()
    }

    /// The message for a failure to inflate the `what` (`expected` bytes, if known) after
    /// `got` bytes of it.
    fn failure(what: &str, expected: Option<u64>, got: u64, e: &std::io::Error) -> String {
        let expected = expected.map(|n| format!("expected {n} bytes, ")).unwrap_or_default();
        if e.kind() == ErrorKind::UnexpectedEof {
            format!("truncated {what}: {expected}got {got} before the compressed data ends ({e})")
        } else {
            format!("corrupt zlib stream (detected while reading the {what}, {expected}got {got}): {e}")
        }
    }

    /// Reads the stream to its end, which verifies that it is complete and its checksum
    /// right (catching corrupted data). Data after the last field is ignored, as by Mitsuba.
    fn finish(&mut self) -> Result<(), String> {
        loop {
            match self.fill() {
                Ok([]) => return Ok(()),
                Ok(rest) => {
                    let n = rest.len();
                    self.reader.consume(n);
                }
                Err(e) if e.kind() == ErrorKind::UnexpectedEof => {
                    return Err(format!("truncated zlib stream after the triangle indices ({e})"));
                }
                Err(e) => return Err(format!("corrupt zlib stream after the triangle indices: {e}")),
            }
        }
    }

    /// Feeds the next `len` bytes to `sink` (or fails with how many there were) without
    /// reserving anything up front: memory grows only with data that has arrived.
    fn take(&mut self, what: &str, len: u64, mut sink: impl FnMut(&[u8])) -> Result<(), String> {
        let mut got = 0u64;
        while got < len {
            let available = self.fill().map_err(|e| Self::failure(what, Some(len), got, &e))?;
            if available.is_empty() {
                return Err(format!("truncated {what}: expected {len} bytes, got {got}"));
            }
            let n = available.len().min(usize::try_from(len - got).unwrap_or(usize::MAX));
            sink(available.get(..n).unwrap_or_default());
            self.reader.consume(n);
            got += n as u64;
        }
        Ok(())
    }

    /// The next `len` bytes.
    fn block(&mut self, what: &str, len: u64) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        self.take(what, len, |chunk| out.extend_from_slice(chunk))?;
        Ok(out)
    }

    /// Skips the next `len` bytes.
    fn skip(&mut self, what: &str, len: u64) -> Result<(), String> {
        self.take(what, len, |_| ())
    }

    /// The next little-endian `u32`.
    fn u32(&mut self, what: &str) -> Result<u32, String> {
        let bytes = self.block(what, 4)?;
        Ok(bytes.as_slice().try_into().map_or(u32::MAX, u32::from_le_bytes))
    }

    /// The next little-endian `u64`.
    fn u64(&mut self, what: &str) -> Result<u64, String> {
        let bytes = self.block(what, 8)?;
        Ok(bytes.as_slice().try_into().map_or(u64::MAX, u64::from_le_bytes))
    }

    /// Skips the NUL-terminated shape name of version 4.
    fn skip_name(&mut self) -> Result<(), String> {
        let mut skipped = 0u64;
        loop {
            let available = self.fill().map_err(|e| Self::failure("shape name", None, skipped, &e))?;
            if available.is_empty() {
                return Err(format!("truncated shape name: no terminating NUL byte after {skipped} bytes"));
            }
            let (n, done) = match available.iter().position(|&b| b == 0) {
                Some(nul) => (nul + 1, true),
                None => (available.len(), false),
            };
            self.reader.consume(n);
            if done {
                return Ok(());
            }
            skipped += n as u64;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::Compression;
    use flate2::write::ZlibEncoder;
    use std::io::Write;

    /// Name under which the tests' files are parsed.
    const PATH: &str = "meshes/test.serialized";
    /// Flag the writer sets for `f32` data.
    const SINGLE_PRECISION: u32 = 0x1000;

    /// One shape for the test writer, in `f64` (written as `f32` unless `double`).
    #[derive(Clone)]
    struct Shape {
        name: &'static str,
        double: bool,
        face_normals: bool,
        positions: Vec<[f64; 3]>,
        normals: Option<Vec<[f64; 3]>>,
        uvs: Option<Vec<[f64; 2]>>,
        colors: Option<Vec<[f64; 3]>>,
        indices: Vec<[u32; 3]>,
    }

    impl Shape {
        /// A unit square of two triangles, positions only.
        fn square() -> Self {
            Self {
                name: "square",
                double: false,
                face_normals: false,
                positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
                normals: None,
                uvs: None,
                colors: None,
                indices: vec![[0, 1, 2], [0, 2, 3]],
            }
        }

        /// One triangle with every optional array.
        fn full_triangle() -> Self {
            Self {
                name: "tri",
                double: true,
                face_normals: false,
                positions: vec![[0.1, -2.5, 3.0], [1e300, 0.0, -0.0], [4.0, 5.0, 6.000000000001]],
                normals: Some(vec![[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
                uvs: Some(vec![[0.0, 0.0], [1.0, 0.25], [0.5, 1.0]]),
                colors: Some(vec![[0.9, 0.8, 0.7], [0.6, 0.5, 0.4], [0.3, 0.2, 0.1]]),
                indices: vec![[2, 1, 0]],
            }
        }

        /// The flag word this shape is written with.
        fn flags(&self) -> u32 {
            let mut flags = if self.double { DOUBLE_PRECISION } else { SINGLE_PRECISION };
            for (present, flag) in [
                (self.normals.is_some(), HAS_NORMALS),
                (self.uvs.is_some(), HAS_UVS),
                (self.colors.is_some(), HAS_COLORS),
                (self.face_normals, FACE_NORMALS),
            ] {
                if present {
                    flags |= flag;
                }
            }
            flags
        }

        /// The inflated stream of this shape in `version`.
        fn payload(&self, version: u16) -> Vec<u8> {
            let mut out = self.flags().to_le_bytes().to_vec();
            if version == VERSION_4 {
                out.extend_from_slice(self.name.as_bytes());
                out.push(0);
            }
            out.extend_from_slice(&(self.positions.len() as u64).to_le_bytes());
            out.extend_from_slice(&(self.indices.len() as u64).to_le_bytes());
            let mut put = |values: &[f64]| {
                for &v in values {
                    if self.double {
                        out.extend_from_slice(&v.to_le_bytes());
                    } else {
                        out.extend_from_slice(&(v as f32).to_le_bytes());
                    }
                }
            };
            put(self.positions.as_flattened());
            if let Some(n) = &self.normals {
                put(n.as_flattened());
            }
            if let Some(uv) = &self.uvs {
                put(uv.as_flattened());
            }
            if let Some(c) = &self.colors {
                put(c.as_flattened());
            }
            for i in self.indices.as_flattened() {
                out.extend_from_slice(&i.to_le_bytes());
            }
            out
        }
    }

    /// A shape header and `payload` compressed.
    fn shape_bytes(version: u16, payload: &[u8]) -> Vec<u8> {
        let mut out = FORMAT_ID.to_le_bytes().to_vec();
        out.extend_from_slice(&version.to_le_bytes());
        let mut encoder = ZlibEncoder::new(out, Compression::default());
        encoder.write_all(payload).unwrap();
        encoder.finish().unwrap()
    }

    /// A file of the given shape payloads, with the dictionary if `dictionary`.
    fn file_of(version: u16, payloads: &[Vec<u8>], dictionary: bool) -> Vec<u8> {
        let mut out = Vec::new();
        let mut offsets = Vec::new();
        for payload in payloads {
            offsets.push(out.len() as u64);
            out.extend(shape_bytes(version, payload));
        }
        if dictionary {
            for offset in &offsets {
                if version == VERSION_3 {
                    out.extend_from_slice(&(*offset as u32).to_le_bytes());
                } else {
                    out.extend_from_slice(&offset.to_le_bytes());
                }
            }
            out.extend_from_slice(&(offsets.len() as u32).to_le_bytes());
        }
        out
    }

    /// A file of `shapes` with a dictionary.
    fn file(version: u16, shapes: &[Shape]) -> Vec<u8> {
        file_of(version, &shapes.iter().map(|s| s.payload(version)).collect::<Vec<_>>(), true)
    }

    fn parse_ok(bytes: &[u8], shape_index: u32) -> RawMesh {
        match parse(bytes, Path::new(PATH), shape_index) {
            Ok(mesh) => mesh,
            Err(e) => panic!("shape {shape_index}: {e}"),
        }
    }

    /// The message of an error of this module, checking that it names the file.
    fn message<T: std::fmt::Debug>(result: Result<T, SceneFileError>) -> String {
        match result {
            Err(SceneFileError::Serialized { path, message }) => {
                assert_eq!(path, Path::new(PATH));
                message
            }
            other => panic!("expected a Serialized error, got {other:?}"),
        }
    }

    fn parse_err(bytes: &[u8], shape_index: u32) -> String {
        message(parse(bytes, Path::new(PATH), shape_index))
    }

    fn count(bytes: &[u8]) -> Result<u32, SceneFileError> {
        shape_count(bytes, Path::new(PATH))
    }

    fn dvec3s(v: &[[f64; 3]]) -> Vec<DVec3> {
        v.iter().map(|&a| DVec3::from_array(a)).collect()
    }

    /// `v` rounded to `f32` and back, as a single-precision file stores it.
    fn rounded(v: &[[f64; 3]]) -> Vec<DVec3> {
        v.iter().map(|a| DVec3::from_array(a.map(|x| x as f32 as f64))).collect()
    }

    #[test]
    fn version_3_single_precision_positions_only() {
        let bytes = file(VERSION_3, &[Shape::square()]);
        let mesh = parse_ok(&bytes, 0);
        assert_eq!(mesh.positions, dvec3s(&Shape::square().positions));
        assert_eq!(mesh.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(mesh.normals, None);
        assert_eq!(mesh.uvs, None);
        assert_eq!(count(&bytes).unwrap(), 1);
    }

    #[test]
    fn version_4_double_precision_keeps_every_bit() {
        let shape = Shape::full_triangle();
        let mesh = parse_ok(&file(VERSION_4, std::slice::from_ref(&shape)), 0);
        assert_eq!(mesh.positions, dvec3s(&shape.positions));
        assert_eq!(mesh.positions[0].x.to_bits(), 0.1f64.to_bits());
        assert_eq!(mesh.positions[1].x, 1e300);
        assert!(mesh.positions[1].z.is_sign_negative());
        assert_eq!(mesh.normals, Some(dvec3s(shape.normals.as_ref().unwrap())));
        assert_eq!(mesh.uvs, Some(vec![DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.25), DVec2::new(0.5, 1.0)]));
        assert_eq!(mesh.indices, vec![[2, 1, 0]]);
    }

    #[test]
    fn single_precision_values_are_widened_exactly() {
        let shape = Shape { double: false, positions: vec![[0.1, 1.0 / 3.0, -7.25]; 3], ..Shape::full_triangle() };
        for version in [VERSION_3, VERSION_4] {
            let mesh = parse_ok(&file(version, std::slice::from_ref(&shape)), 0);
            assert_eq!(mesh.positions, rounded(&shape.positions));
            assert_eq!(mesh.positions[0].x, 0.1f32 as f64);
            assert_ne!(mesh.positions[0].x, 0.1);
            assert_eq!(mesh.normals, Some(rounded(shape.normals.as_ref().unwrap())));
            assert_eq!(mesh.uvs.as_ref().unwrap()[1], DVec2::new(1.0, 0.25));
            assert_eq!(mesh.indices, vec![[2, 1, 0]]);
        }
    }

    #[test]
    fn optional_arrays_in_every_combination() {
        for version in [VERSION_3, VERSION_4] {
            for double in [false, true] {
                for mask in 0..8u32 {
                    let full = Shape::full_triangle();
                    let shape = Shape {
                        double,
                        normals: full.normals.clone().filter(|_| mask & 1 != 0),
                        uvs: full.uvs.clone().filter(|_| mask & 2 != 0),
                        colors: full.colors.clone().filter(|_| mask & 4 != 0),
                        ..full
                    };
                    let mesh = parse_ok(&file(version, std::slice::from_ref(&shape)), 0);
                    let expect = |v: &[[f64; 3]]| if double { dvec3s(v) } else { rounded(v) };
                    assert_eq!(mesh.positions, expect(&shape.positions), "v{version} double={double} mask={mask}");
                    assert_eq!(mesh.normals, shape.normals.as_deref().map(expect));
                    assert_eq!(mesh.uvs.is_some(), mask & 2 != 0);
                    assert_eq!(mesh.indices, vec![[2, 1, 0]], "colors must be skipped before the indices");
                }
            }
        }
    }

    #[test]
    fn face_normals_flag_drops_stored_normals() {
        let shape = Shape { face_normals: true, ..Shape::full_triangle() };
        let mesh = parse_ok(&file(VERSION_4, std::slice::from_ref(&shape)), 0);
        assert_eq!(mesh.normals, None);
        assert_eq!(mesh.positions, dvec3s(&shape.positions));
        assert_eq!(mesh.uvs.unwrap()[2], DVec2::new(0.5, 1.0));
        assert_eq!(mesh.indices, vec![[2, 1, 0]]);
        let without = Shape { normals: None, ..shape };
        assert_eq!(parse_ok(&file(VERSION_3, &[without]), 0).normals, None);
    }

    #[test]
    fn missing_precision_flag_means_single() {
        let mut payload = Shape::square().payload(VERSION_3);
        payload[..4].copy_from_slice(&0u32.to_le_bytes());
        let mesh = parse_ok(&file_of(VERSION_3, &[payload], true), 0);
        assert_eq!(mesh.positions[2], DVec3::new(1.0, 1.0, 0.0));
    }

    #[test]
    fn two_shapes_by_shape_index() {
        let second = Shape { double: true, ..Shape::full_triangle() };
        for version in [VERSION_3, VERSION_4] {
            let bytes = file(version, &[Shape::square(), second.clone()]);
            assert_eq!(count(&bytes).unwrap(), 2);
            let first = parse_ok(&bytes, 0);
            assert_eq!(first.positions.len(), 4);
            assert_eq!(first.indices, vec![[0, 1, 2], [0, 2, 3]]);
            let other = parse_ok(&bytes, 1);
            assert_eq!(other.positions, dvec3s(&second.positions));
            assert_eq!(other.normals, Some(dvec3s(second.normals.as_ref().unwrap())));
            assert_eq!(other.indices, vec![[2, 1, 0]]);
            assert_eq!(parse_err(&bytes, 2), "shape_index 2 out of range: the file holds 2 shapes");
            assert_eq!(parse_err(&bytes, u32::MAX), format!("shape_index {} out of range: the file holds 2 shapes", u32::MAX));
        }
    }

    #[test]
    fn file_without_dictionary_has_only_shape_0() {
        let bytes = file_of(VERSION_4, &[Shape::square().payload(VERSION_4)], false);
        assert_eq!(parse_ok(&bytes, 0).positions.len(), 4);
        assert!(message(count(&bytes)).starts_with("no valid shape dictionary at the end of the file"));
        assert!(parse_err(&bytes, 1).starts_with("cannot locate shape_index 1: no valid shape dictionary"));
    }

    #[test]
    fn large_mesh_spans_many_reads() {
        let n = 5000u32;
        let positions: Vec<[f64; 3]> = (0..n).map(|i| [f64::from(i), f64::from(i) * 0.5, -f64::from(i)]).collect();
        let shape = Shape {
            double: true,
            positions: positions.clone(),
            normals: Some(vec![[0.0, 0.0, 1.0]; n as usize]),
            uvs: Some((0..n).map(|i| [f64::from(i) / 8.0, 1.0]).collect()),
            colors: Some(vec![[0.5; 3]; n as usize]),
            indices: (0..n - 2).map(|i| [i, i + 1, i + 2]).collect(),
            ..Shape::square()
        };
        let bytes = file(VERSION_4, &[Shape::square(), shape]);
        let mesh = parse_ok(&bytes, 1);
        assert_eq!(mesh.positions, dvec3s(&positions));
        assert_eq!(mesh.uvs.as_ref().unwrap()[4999], DVec2::new(4999.0 / 8.0, 1.0));
        assert_eq!(mesh.normals.as_ref().unwrap().len(), 5000);
        assert_eq!(mesh.indices[4997], [4997, 4998, 4999]);
    }

    #[test]
    fn empty_mesh_is_not_an_error() {
        let empty = Shape { positions: vec![], indices: vec![], ..Shape::square() };
        let mesh = parse_ok(&file(VERSION_4, &[empty]), 0);
        assert!(mesh.positions.is_empty() && mesh.indices.is_empty());
    }

    #[test]
    fn bad_headers() {
        let mut bytes = file(VERSION_3, &[Shape::square()]);
        bytes[..2].copy_from_slice(&0x1234u16.to_le_bytes());
        assert_eq!(parse_err(&bytes, 0), "unknown format identifier 0x1234 at byte 0 (expected 0x041c)");
        assert_eq!(message(count(&bytes)), "unknown format identifier 0x1234 at byte 0 (expected 0x041c)");
        bytes[..2].copy_from_slice(&0x1C04u16.to_le_bytes());
        assert!(parse_err(&bytes, 0).contains("0x1c04 at byte 0 is that of an early Mitsuba version"));
        for version in [0u16, 1, 2, 5, 0xFFFF] {
            bytes[..2].copy_from_slice(&FORMAT_ID.to_le_bytes());
            bytes[2..4].copy_from_slice(&version.to_le_bytes());
            let m = parse_err(&bytes, 0);
            assert!(m.starts_with(&format!("unsupported version {version} (only versions 3 and 4 are supported")), "{m}");
            assert_eq!(m.contains("packed layout"), version == 5);
        }
        assert_eq!(parse_err(&[], 0), "truncated header at byte 0: expected 4 bytes, got 0");
        assert_eq!(parse_err(&[0x1C, 0x04, 0x03], 0), "truncated header at byte 0: expected 4 bytes, got 3");
    }

    #[test]
    fn truncated_inflated_data_names_the_field() {
        let shape = Shape { double: true, ..Shape::full_triangle() };
        let payload = shape.payload(VERSION_4);
        let name_end = 4 + shape.name.len() + 1;
        let counts_end = name_end + 16;
        // (cut, expected message): each array is 3 vertices x dimension x 8 bytes.
        let cases = [
            (2, "truncated flags: expected 4 bytes, got 2".to_string()),
            (5, "truncated shape name: no terminating NUL byte after 1 bytes".to_string()),
            (name_end + 3, "truncated vertex count: expected 8 bytes, got 3".to_string()),
            (name_end + 8, "truncated triangle count: expected 8 bytes, got 0".to_string()),
            (counts_end + 10, "truncated vertex positions: expected 72 bytes, got 10".to_string()),
            (counts_end + 72 + 71, "truncated vertex normals: expected 72 bytes, got 71".to_string()),
            (counts_end + 144 + 8, "truncated texture coordinates: expected 48 bytes, got 8".to_string()),
            (counts_end + 192, "truncated vertex colors: expected 72 bytes, got 0".to_string()),
            (payload.len() - 1, "truncated triangle indices: expected 12 bytes, got 11".to_string()),
        ];
        for (cut, expected) in cases {
            let bytes = file_of(VERSION_4, &[payload[..cut].to_vec()], true);
            assert_eq!(parse_err(&bytes, 0), format!("shape 0: {expected}"), "cut at {cut}");
        }
        let face_normals = Shape { face_normals: true, ..shape }.payload(VERSION_4);
        let bytes = file_of(VERSION_4, &[face_normals[..counts_end + 80].to_vec()], true);
        assert_eq!(parse_err(&bytes, 0), "shape 0: truncated vertex normals: expected 72 bytes, got 8");
    }

    #[test]
    fn truncated_files_fail_cleanly_at_every_length() {
        let bytes = file(VERSION_4, &[Shape::full_triangle(), Shape::square()]);
        let first_end = shape_bytes(VERSION_4, &Shape::full_triangle().payload(VERSION_4)).len();
        for len in 0..bytes.len() {
            let prefix = &bytes[..len];
            // Only the dictionary is cut: shape 0 needs none, so it still loads.
            let shape_0_whole = len >= first_end;
            assert_eq!(parse(prefix, Path::new(PATH), 0).is_ok(), shape_0_whole, "length {len}");
            assert!(parse(prefix, Path::new(PATH), 1).is_err(), "length {len}");
            assert!(count(prefix).is_err(), "length {len}");
        }
        for len in HEADER_BYTES..first_end {
            let m = parse_err(&bytes[..len], 0);
            assert!(m.starts_with("shape 0: truncated "), "length {len}: {m}");
        }
        assert_eq!(
            parse_err(&bytes[..8], 0),
            "shape 0: truncated flags: expected 4 bytes, got 0 before the compressed data ends (incomplete deflate stream)"
        );
    }

    #[test]
    fn corrupted_compressed_bytes_are_caught() {
        let bytes = file(VERSION_4, &[Shape::full_triangle()]);
        let original = parse_ok(&bytes, 0);
        let stream_end = bytes.len() - 12; // before the dictionary
        let mut unnoticed = 0;
        for at in HEADER_BYTES..stream_end {
            for bit in 0..8 {
                let mut corrupted = bytes.clone();
                corrupted[at] ^= 1 << bit;
                if let Ok(mesh) = parse(&corrupted, Path::new(PATH), 0) {
                    // Only bits that do not change the data (padding, compression level hint).
                    assert_eq!(mesh, original, "bit {bit} of byte {at} changed the mesh unnoticed");
                    unnoticed += 1;
                }
            }
        }
        assert!(unnoticed < 8, "{unnoticed} flipped bits went unnoticed");
        let mut last = bytes.clone();
        last[stream_end - 1] ^= 1; // the checksum's last byte
        let m = parse_err(&last, 0);
        assert!(m.starts_with("shape 0: corrupt zlib stream") && m.ends_with("corrupt deflate stream"), "{m}");
    }

    #[test]
    fn index_out_of_range() {
        let shape = Shape { indices: vec![[0, 1, 2], [0, 3, 4]], ..Shape::full_triangle() };
        assert_eq!(parse_err(&file(VERSION_3, &[shape]), 0), "shape 0: triangle 1 uses vertex index 3, but the mesh has 3 vertices");
        let shape = Shape { indices: vec![[u32::MAX, 0, 0]], ..Shape::square() };
        assert_eq!(parse_err(&file(VERSION_3, &[shape]), 0), format!("shape 0: triangle 0 uses vertex index {}, but the mesh has 4 vertices", u32::MAX));
    }

    /// A version 3 payload of `flags` and counts only.
    fn counts_payload(vertices: u64, triangles: u64) -> Vec<u8> {
        let mut out = SINGLE_PRECISION.to_le_bytes().to_vec();
        out.extend_from_slice(&vertices.to_le_bytes());
        out.extend_from_slice(&triangles.to_le_bytes());
        out.extend_from_slice(&[0; 64]);
        out
    }

    #[test]
    fn huge_counts_are_errors_without_huge_allocations() {
        let one = |vertices, triangles| parse_err(&file_of(VERSION_3, &[counts_payload(vertices, triangles)], true), 0);
        assert_eq!(one(u64::MAX, 1), format!("shape 0: vertex count {} exceeds the 32-bit index range (at most 4294967295)", u64::MAX));
        assert_eq!(one(1 << 32, 1), "shape 0: vertex count 4294967296 exceeds the 32-bit index range (at most 4294967295)");
        assert_eq!(one(3, 1 << 40), "shape 0: triangle count 1099511627776 exceeds the 32-bit index range (at most 4294967295)");
        assert_eq!(one(u64::from(u32::MAX), 0), "shape 0: truncated vertex positions: expected 51539607540 bytes, got 64");
        assert_eq!(one(0, u64::from(u32::MAX)), "shape 0: truncated triangle indices: expected 51539607540 bytes, got 64");
    }

    #[test]
    fn corrupt_zlib_stream() {
        let mut bytes = file(VERSION_3, &[Shape::square()]);
        bytes[4] ^= 0xFF; // zlib header byte
        assert!(parse_err(&bytes, 0).starts_with("shape 0: corrupt zlib stream (detected while reading the flags, expected 4 bytes, got 0): "));
        let mut bytes = FORMAT_ID.to_le_bytes().to_vec();
        bytes.extend_from_slice(&VERSION_4.to_le_bytes());
        bytes.extend_from_slice(&[0x78, 0x9C, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]);
        assert!(parse_err(&bytes, 0).starts_with("shape 0: corrupt zlib stream"));
    }

    #[test]
    fn bad_dictionaries() {
        let payloads = [Shape::square().payload(VERSION_4), Shape::full_triangle().payload(VERSION_4)];
        let good = file_of(VERSION_4, &payloads, true);
        let len = good.len();
        let set_count = |count: u32| {
            let mut b = good.clone();
            b[len - 4..].copy_from_slice(&count.to_le_bytes());
            b
        };
        assert_eq!(message(count(&set_count(0))), "no valid shape dictionary at the end of the file: it lists 0 shapes");
        assert!(parse_err(&set_count(1000), 1).contains("claim 1000 shapes, whose offsets need 8004 bytes"));
        // One shape fewer: the dictionary then starts at the second offset, which is not 0.
        assert!(message(count(&set_count(1))).contains("the first shape's offset is"));

        let second_entry = len - 4 - 8;
        let with_offset = |offset: u64| {
            let mut b = good.clone();
            b[second_entry..len - 4].copy_from_slice(&offset.to_le_bytes());
            b
        };
        assert_eq!(
            parse_err(&with_offset(u64::MAX), 1),
            format!("the shape dictionary gives shape 1 the offset {}, outside the shape data (bytes 0..{})", u64::MAX, len - 20)
        );
        assert!(message(count(&with_offset(len as u64))).contains("gives shape 1 the offset"));
        assert!(parse_err(&with_offset(7), 1).starts_with("shape 1 (offset 7 in the dictionary): unknown format identifier"));

        let mut mixed = good.clone();
        let second_start = shape_bytes(VERSION_4, &payloads[0]).len();
        mixed[second_start + 2] = 3;
        assert_eq!(parse_err(&mixed, 1), "shape 1's header states version 3, the file's first shape version 4");
        assert_eq!(message(count(&mixed)), "shape 1's header states version 3, the file's first shape version 4");
        assert_eq!(parse_ok(&mixed, 0).positions.len(), 4);
    }

    #[test]
    fn mutated_files_never_panic() {
        let base = file(VERSION_4, &[Shape::full_triangle(), Shape::square()]);
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..3000 {
            let mut bytes = base.clone();
            for _ in 0..=next() % 4 {
                let at = (next() % bytes.len() as u64) as usize;
                bytes[at] = next() as u8;
            }
            if next() % 4 == 0 {
                bytes.truncate((next() % bytes.len() as u64) as usize);
            }
            for index in 0..3 {
                if let Ok(mesh) = parse(&bytes, Path::new(PATH), index) {
                    assert!(mesh.indices.as_flattened().iter().all(|&i| (i as usize) < mesh.positions.len()));
                }
            }
            let _ = count(&bytes);
        }
    }
}
