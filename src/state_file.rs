//! Render state files: the accumulation of a render (or of a range of its iterations) with
//! what identifies the render it belongs to, written atomically and checked on reading.
//!
//! A state file is what `--checkpoint` writes, `--resume` continues, a partial render
//! (`--iterations A..B`) leaves beside its image and `arpa merge` combines. Because every
//! random stream and the radius schedule depend only on the seed and the iteration index,
//! the accumulated sums and their iteration range are the whole state of a render
//! ([`Accumulation`]).
//!
//! # Format (version 2)
//! All integers and floats little-endian.
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `ARPASTAT` |
//! | 4 | format version |
//! | 4 + n | header length, header (UTF-8 `key=value` lines: backend, seed, scene hash, settings) |
//! | 5 × 4 | width, height, planes per pixel (1, or 8 for `--bandwidth per-pixel`), first iteration, iterations |
//! | 64 × planes × pixels | plane after plane, per pixel: sum (3 × f64), compensation (3 × f64), rejected (u64), 0 (u64) |
//!
//! Version 1 (before per-pixel bandwidth) had no planes field and one plane.
//! | 32 | SHA-256 of everything before it |
//!
//! # Writing
//! [`StateFile::write_atomic`] writes a temporary file in the same directory, flushes it to
//! the disk (`fsync`), renames it over the target and syncs the directory: a crash at any
//! moment leaves either the previous file or the new one, never a mixture, and a file that
//! is damaged later fails its checksum.

use arpa_core::accumulate::image::{Accumulation, PixelSum};
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::RenderSettings;
use sha2::{Digest, Sha256};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// The first bytes of every state file.
pub const MAGIC: &[u8; 8] = b"ARPASTAT";

/// The format version this build writes and reads.
pub const VERSION: u32 = 2;

/// Bytes of one pixel's sums in the file.
const PIXEL_BYTES: usize = 64;

/// Why a state file cannot be written, read or used.
#[derive(Debug, thiserror::Error)]
pub enum StateFileError {
    /// The file could not be read or written.
    #[error("state file '{}': {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The file is not a state file, is truncated or fails its checksum.
    #[error("state file '{}' is damaged: {why}", path.display())]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        why: String,
    },
    /// The file was written by another format version.
    #[error("state file '{}' has format version {found}; this build reads version {VERSION}", path.display())]
    Version {
        /// The file.
        path: PathBuf,
        /// Its version.
        found: u32,
    },
    /// The file belongs to another render: another scene, settings or seed.
    #[error("state file '{}' is from another render (different {what}: {file}; this render: {this})", path.display())]
    Mismatch {
        /// The file.
        path: PathBuf,
        /// `scene`, `settings`, `seed` or `image size`.
        what: &'static str,
        /// The file's value.
        file: String,
        /// This render's value.
        this: String,
    },
}

/// What identifies the render a state belongs to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderIdentity {
    /// Backend that accumulated the sums (informational: another backend may continue them,
    /// but only the same one reproduces its image bit for bit).
    pub backend: String,
    /// Seed of every random stream.
    pub seed: u32,
    /// SHA-256 (hex) of the scene as loaded (geometry, materials, lights, camera, film size).
    pub scene_hash: String,
    /// The render settings except the seed, as text.
    pub settings: String,
}

impl RenderIdentity {
    /// The identity of rendering `scene` with `settings` on `backend`.
    pub fn new(scene: &Scene, settings: &RenderSettings, backend: &str) -> Self {
        Self { backend: backend.to_owned(), seed: settings.seed, scene_hash: scene_hash(scene), settings: settings_text(settings) }
    }

    /// Refuses a state of another render (the error says which part differs); `path` is
    /// the state file, for the message.
    pub fn check(&self, path: &Path, file: &RenderIdentity) -> Result<(), StateFileError> {
        let mismatch = |what, file: &str, this: &str| StateFileError::Mismatch { path: path.to_path_buf(), what, file: file.to_owned(), this: this.to_owned() };
        if file.scene_hash != self.scene_hash {
            return Err(mismatch("scene", &format!("scene hash {}", short(&file.scene_hash)), &format!("scene hash {}", short(&self.scene_hash))));
        }
        if file.seed != self.seed {
            return Err(mismatch("seed", &file.seed.to_string(), &self.seed.to_string()));
        }
        if file.settings != self.settings {
            return Err(mismatch("settings", &file.settings, &self.settings));
        }
        Ok(())
    }

    fn to_header(&self) -> String {
        format!("backend={}\nseed={}\nscene_sha256={}\nsettings={}\n", self.backend, self.seed, self.scene_hash, self.settings)
    }

    fn from_header(text: &str) -> Option<Self> {
        let get = |key: &str| text.lines().find_map(|l| l.strip_prefix(key)?.strip_prefix('=')).map(str::to_owned);
        Some(Self { backend: get("backend")?, seed: get("seed")?.parse().ok()?, scene_hash: get("scene_sha256")?, settings: get("settings")? })
    }
}

fn short(hash: &str) -> &str {
    &hash[..hash.len().min(12)]
}

/// The settings without the seed, as one line of text (`Debug`, which prints every field
/// and every float exactly).
fn settings_text(settings: &RenderSettings) -> String {
    format!("{:?}", RenderSettings { seed: 0, ..*settings }).replace('\n', " ")
}

/// SHA-256 (hex) of the scene's `Debug` text, which prints every field and every float
/// exactly, streamed into the hash.
pub fn scene_hash(scene: &Scene) -> String {
    struct HashWriter(Sha256);
    impl std::fmt::Write for HashWriter {
        fn write_str(&mut self, s: &str) -> std::fmt::Result {
            self.0.update(s.as_bytes());
            Ok(())
        }
    }
    let mut w = HashWriter(Sha256::new());
    let _ = std::fmt::Write::write_fmt(&mut w, format_args!("{scene:?}"));
    hex(&w.0.finalize())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A state file's content.
#[derive(Clone, Debug, PartialEq)]
pub struct StateFile {
    /// The render it belongs to.
    pub identity: RenderIdentity,
    /// The accumulated sums and their iteration range.
    pub accumulation: Accumulation,
}

impl StateFile {
    /// The file's bytes (see the module docs).
    pub fn to_bytes(&self) -> Vec<u8> {
        let a = &self.accumulation;
        let header = self.identity.to_header();
        let mut out = Vec::with_capacity(64 + header.len() + a.pixels.len() * PIXEL_BYTES);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        for v in [a.width, a.height, a.planes, a.first_iteration, a.iterations] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for p in &a.pixels {
            for v in p.sum.iter().chain(&p.compensation) {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(&p.rejected.to_le_bytes());
            out.extend_from_slice(&0u64.to_le_bytes());
        }
        let digest = Sha256::digest(&out);
        out.extend_from_slice(&digest);
        out
    }

    /// Parses a state file's bytes; `path` names it in errors.
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Self, StateFileError> {
        let corrupt = |why: &str| StateFileError::Corrupt { path: path.to_path_buf(), why: why.to_owned() };
        if bytes.len() < MAGIC.len() + 8 || &bytes[..8] != MAGIC {
            return Err(corrupt("not an arpa state file (no ARPASTAT magic)"));
        }
        let found = u32::from_le_bytes(bytes[8..12].try_into().unwrap_or_default());
        if found != VERSION {
            return Err(StateFileError::Version { path: path.to_path_buf(), found });
        }
        if bytes.len() < 12 + 32 {
            return Err(corrupt("truncated"));
        }
        let (body, digest) = bytes.split_at(bytes.len() - 32);
        if Sha256::digest(body).as_slice() != digest {
            return Err(corrupt("checksum mismatch (truncated or modified)"));
        }
        let mut r = Reader { bytes: body, at: 12 };
        let header_len = r.u32().ok_or_else(|| corrupt("truncated header"))? as usize;
        let header = r.take(header_len).and_then(|h| std::str::from_utf8(h).ok()).ok_or_else(|| corrupt("header is not UTF-8 text"))?;
        let identity = RenderIdentity::from_header(header).ok_or_else(|| corrupt("header lacks backend, seed, scene hash or settings"))?;
        let [width, height, planes, first_iteration, iterations] = [r.u32(), r.u32(), r.u32(), r.u32(), r.u32()].map(|v| v.unwrap_or(u32::MAX));
        if planes != 1 && planes as usize != arpa_core::gather::scales::PLANES {
            return Err(corrupt(&format!("{planes} planes per pixel (1 or {} expected)", arpa_core::gather::scales::PLANES)));
        }
        let pixels = width as u64 * height as u64 * u64::from(planes);
        if (r.bytes.len() - r.at) as u64 != pixels * PIXEL_BYTES as u64 {
            return Err(corrupt(&format!("{} bytes of pixel sums for {width}x{height} pixels of {planes} planes", r.bytes.len() - r.at)));
        }
        let pixels = (0..pixels)
            .map(|_| {
                let mut f = [0.0; 6];
                f.iter_mut().for_each(|v| *v = r.f64().unwrap_or(f64::NAN));
                let rejected = r.u64().unwrap_or(0);
                let _pad = r.u64();
                PixelSum { sum: [f[0], f[1], f[2]], compensation: [f[3], f[4], f[5]], rejected, pad: 0 }
            })
            .collect();
        let accumulation = Accumulation { width, height, planes, first_iteration, iterations, pixels };
        accumulation.validate().map_err(|e| corrupt(&e.to_string()))?;
        Ok(Self { identity, accumulation })
    }

    /// Reads and checks the state file at `path`.
    pub fn read(path: &Path) -> Result<Self, StateFileError> {
        let bytes = std::fs::read(path).map_err(|source| StateFileError::Io { path: path.to_path_buf(), source })?;
        Self::from_bytes(path, &bytes)
    }

    /// Writes the state to `path` atomically: a temporary file beside it, flushed to the
    /// disk, renamed over `path`, and the directory synced.
    pub fn write_atomic(&self, path: &Path) -> Result<(), StateFileError> {
        let io = |source| StateFileError::Io { path: path.to_path_buf(), source };
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let name = path.file_name().ok_or_else(|| io(std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file name")))?;
        let mut tmp_name = name.to_os_string();
        tmp_name.push(format!(".tmp{}", std::process::id()));
        let tmp = dir.join(tmp_name);
        let written = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(&self.to_bytes())?;
            f.sync_all()?;
            drop(f);
            std::fs::rename(&tmp, path)?;
            // The rename is durable once the directory is synced.
            std::fs::File::open(dir)?.sync_all()
        })();
        if written.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        written.map_err(io)
    }
}

/// A cursor over little-endian values.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::default_scene::default_scene;

    fn state() -> StateFile {
        let scene = default_scene();
        let mut a = Accumulation::empty(3, 2, 5);
        a.iterations = 4;
        for (i, p) in a.pixels.iter_mut().enumerate() {
            p.sum = [i as f64 * 0.1, 1.0 / 3.0, 1e-300];
            p.compensation = [1e-17, -2e-18, 0.0];
            p.rejected = i as u64;
        }
        StateFile { identity: RenderIdentity::new(&scene, &RenderSettings::default(), "cpu"), accumulation: a }
    }

    #[test]
    fn round_trips_exactly_through_a_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("render.state");
        let s = state();
        s.write_atomic(&path).unwrap();
        assert_eq!(StateFile::read(&path).unwrap(), s);
        // No temporary file is left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn per_pixel_planes_round_trip_and_a_wrong_plane_count_is_refused() {
        let mut s = state();
        let planes = arpa_core::gather::scales::PLANES as u32;
        let mut a = Accumulation::empty_planes(3, 2, planes, 5);
        a.iterations = 2;
        for (i, p) in a.pixels.iter_mut().enumerate() {
            p.sum = [i as f64, 0.5, 1e-30];
        }
        s.accumulation = a;
        let bytes = s.to_bytes();
        assert_eq!(StateFile::from_bytes(Path::new("p.state"), &bytes).unwrap(), s);
        // Planes field (after magic, version, header) set to 3: refused, not misread.
        let header = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let at = 16 + header + 8;
        let mut b = bytes[..bytes.len() - 32].to_vec();
        b[at..at + 4].copy_from_slice(&3u32.to_le_bytes());
        let digest = Sha256::digest(&b);
        b.extend_from_slice(&digest);
        let e = StateFile::from_bytes(Path::new("p.state"), &b).unwrap_err();
        assert!(e.to_string().contains("3 planes"), "{e}");
    }

    #[test]
    fn every_damage_is_refused_with_the_file_named() {
        let bytes = state().to_bytes();
        let path = Path::new("some/render.state");
        for cut in [0, 7, 12, 40, bytes.len() - 33, bytes.len() - 1] {
            let e = StateFile::from_bytes(path, &bytes[..cut]).unwrap_err();
            assert!(matches!(e, StateFileError::Corrupt { .. }) && e.to_string().contains("some/render.state"), "cut {cut}: {e}");
        }
        for i in [9usize, 20, bytes.len() / 2, bytes.len() - 5] {
            let mut b = bytes.clone();
            b[i] ^= 1;
            let e = StateFile::from_bytes(path, &b).unwrap_err();
            let expected = if i < 12 { "version" } else { "checksum" };
            assert!(e.to_string().contains(expected), "byte {i}: {e}");
        }
    }

    #[test]
    fn another_render_is_refused_naming_what_differs() {
        let scene = default_scene();
        let settings = RenderSettings::default();
        let this = RenderIdentity::new(&scene, &settings, "cpu");
        let path = Path::new("s.state");
        assert!(this.check(path, &RenderIdentity::new(&scene, &settings, "wgpu")).is_ok(), "another backend may continue");
        let mut other_scene = scene.clone();
        other_scene.camera.width += 1;
        let cases = [
            (RenderIdentity::new(&other_scene, &settings, "cpu"), "scene"),
            (RenderIdentity::new(&scene, &RenderSettings { seed: 9, ..settings }, "cpu"), "seed"),
            (RenderIdentity::new(&scene, &RenderSettings { photons_per_iteration: 7, ..settings }, "cpu"), "settings"),
        ];
        for (file, what) in cases {
            match this.check(path, &file) {
                Err(StateFileError::Mismatch { what: w, .. }) => assert_eq!(w, what),
                other => panic!("{what}: {other:?}"),
            }
        }
    }
}
