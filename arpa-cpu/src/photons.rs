//! The photon pass: the core's photon paths for every photon of the iteration, in chunks
//! of [`PHOTON_CHUNK`] photon indices, stored in photon-index order.
//!
//! # Chunks and their merge
//! One loop per thread takes chunks in index order. Each chunk is traced into its own
//! buffers ([`trace_chunk`]); a finished chunk is appended to the pass's store as soon as
//! every chunk before it has been ([`ChunkMerge`]), so the store holds the records in
//! photon-index order whatever the number of threads, and only the few chunks in flight
//! are held twice. The store and the chunk buffers are kept from one pass to the next,
//! sized from the previous pass's store rate.
//!
//! # Two photons in flight per thread
//! A chunk runs two photons at once, interleaved segment by segment. After Embree answers
//! a segment, the hit's triangle records are usually not in cache (Embree's BVH keeps its
//! own copy of the vertices), and everything the photon does next waits for them. So each
//! answer only prefetches those records ([`PreparedScene::prefetch_hit`]), and the thread
//! goes on with the *other* photon: it takes that photon's previous hit (whose records
//! were prefetched one step earlier), stores and scatters, and casts its next segment.
//! Each photon runs exactly the core's [`PhotonWalk`], so what it stores does not depend
//! on the interleaving.
//!
//! The records come out in photon-index order, as a sequential loop over
//! [`arpa_core::render::photon_path::trace_photon`] gives them: the photon with the lower index
//! in flight writes straight to the chunk's store; the other one's records (packed and
//! boxed already) wait in its slot's small side buffer, which moves to the store when
//! that photon becomes the lower-indexed one in flight.

use core::sync::atomic::{AtomicU32, Ordering};
use std::ops::Range;
use std::sync::Mutex;

use arpa_core::render::photon_path::{PhotonPassSetup, PhotonWalk};
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::render::ray_cast::{RayCaster, RayHit};
use arpa_core::render::tracer::{IterationStats, RenderSettings};
use rayon::prelude::*;

use crate::caster::EmbreeCaster;
use crate::photon_store::PhotonStore;

/// Photon indices traced by one task of the photon pass. The stored photons of each chunk
/// are concatenated in chunk order, so the buffers do not depend on the thread count.
pub const PHOTON_CHUNK: u32 = 4096;

/// Headroom of the buffer sizes estimated from the previous iteration's store rate.
const CAPACITY_HEADROOM: f64 = 1.25;

/// The photon buffers, kept from one photon pass to the next.
#[derive(Debug, Default)]
pub(crate) struct PhotonBuffers {
    /// The records stored by the last pass, in photon-index order.
    pub store: PhotonStore,
    /// Progressive radii `[caustic, global]` of the photons in `store`.
    pub radii: [f32; 2],
    /// Photons traced for `store` (with its counts: the store rate that sizes the next
    /// pass's buffers).
    emitted: u32,
    /// Chunk buffers, kept for the next pass.
    spare_parts: Vec<PhotonStore>,
}

/// The photon pass of iteration `iteration`: traces every photon into `buffers` (emptied
/// first) and writes the pass's counts and radii to `stats`.
pub(crate) fn photon_pass(
    buffers: &mut PhotonBuffers,
    prepared: &PreparedScene,
    caster: &EmbreeCaster,
    settings: &RenderSettings,
    iteration: u32,
    stats: &mut IterationStats,
) {
    let setup = PhotonPassSetup::new(prepared, settings, iteration);
    let count = setup.photon_count();
    let chunks = count.div_ceil(PHOTON_CHUNK);
    // Buffer sizes from the previous pass's store rate (records per photon traced).
    let (fp_rate, ph_rate) = match buffers.emitted {
        0 => (0.0, 0.0),
        n => {
            let c = &buffers.store.counts;
            (
                c.footprints.iter().sum::<u64>() as f64 / n as f64,
                c.progressive.iter().sum::<u64>() as f64 / n as f64,
            )
        }
    };
    let expect = |rate: f64, photons: u32| (rate * photons as f64 * CAPACITY_HEADROOM) as usize;
    buffers.store.clear();
    buffers
        .store
        .reserve_total(expect(fp_rate, count), expect(ph_rate, count));
    let (part_fp, part_ph) = (
        expect(fp_rate, PHOTON_CHUNK) + 64,
        expect(ph_rate, PHOTON_CHUNK) + 64,
    );
    let merge = Mutex::new(ChunkMerge {
        out: &mut buffers.store,
        pending: (0..chunks).map(|_| None).collect(),
        next: 0,
        free: core::mem::take(&mut buffers.spare_parts),
        segments: 0,
    });
    let lock = || merge.lock().unwrap_or_else(|e| e.into_inner());
    // One loop per thread, taking chunks in index order.
    let next_chunk = AtomicU32::new(0);
    let workers = rayon::current_num_threads().clamp(1, chunks.max(1) as usize);
    (0..workers).into_par_iter().for_each(|_| {
        // Start from a recycled part: a fresh one here would join the pool at the end and
        // grow it by one part per worker and iteration.
        let mut part: Option<PhotonStore> = lock().free.pop();
        loop {
            let chunk = next_chunk.fetch_add(1, Ordering::Relaxed);
            if chunk >= chunks {
                break;
            }
            let mut p = part.take().unwrap_or_default();
            p.clear();
            p.reserve_total(part_fp, part_ph);
            let first = chunk * PHOTON_CHUNK;
            let end = first.saturating_add(PHOTON_CHUNK).min(count);
            let segments = trace_chunk(prepared, caster, settings, &setup, first..end, &mut p);
            let mut m = lock();
            m.finish(chunk as usize, p, segments);
            part = m.free.pop();
        }
        if let Some(p) = part {
            lock().free.push(p);
        }
    });
    let merge = merge.into_inner().unwrap_or_else(|e| e.into_inner());
    debug_assert_eq!(merge.next, chunks as usize);
    let segments = merge.segments;
    buffers.spare_parts = merge.free;
    buffers.emitted = count;
    let c = buffers.store.counts;
    stats.photons_emitted = count as u64;
    setup.record_plan(stats);
    stats.photon_segments = segments;
    stats.footprints = c.footprints;
    stats.progressive = c.progressive;
    stats.degenerate = c.degenerate;
    stats.culled = c.culled;
    stats.unrepresentable = c.unrepresentable;
    stats.differential_lost = c.differential_lost;
    stats.overflowed = 0;
    stats.radii = setup.radii;
    buffers.radii = setup.radii.map(|r| r as f32);
}

/// The ordered merge of the photon pass: chunks finish in any order, and each is appended
/// to the store as soon as every chunk before it has been (by whichever worker completes
/// the next chunk in order), so only the few chunks in flight are held twice. Chunk
/// buffers are recycled through `free`.
struct ChunkMerge<'a> {
    out: &'a mut PhotonStore,
    /// Finished chunks waiting for an earlier one, by chunk index.
    pending: Vec<Option<PhotonStore>>,
    /// Next chunk to append.
    next: usize,
    free: Vec<PhotonStore>,
    segments: u64,
}

impl ChunkMerge<'_> {
    /// Files chunk `chunk` and appends every chunk that is now next in order.
    fn finish(&mut self, chunk: usize, part: PhotonStore, segments: u64) {
        self.segments += segments;
        self.pending[chunk] = Some(part);
        while let Some(ready) = self.pending.get_mut(self.next).and_then(Option::take) {
            self.out.append(&ready);
            self.free.push(ready);
            self.next += 1;
        }
    }
}

/// A photon in flight.
struct Slot {
    walk: PhotonWalk,
    /// Global photon index.
    index: u32,
    /// The answer to the segment cast last, not yet taken by the walk.
    hit: Option<Option<RayHit>>,
}

/// Traces the photons `photons` (global indices) of the iteration `setup` with two in
/// flight, pushing their records to `out` in photon-index order; returns the ray segments
/// cast.
pub(crate) fn trace_chunk(
    prepared: &PreparedScene,
    caster: &impl RayCaster,
    settings: &RenderSettings,
    setup: &PhotonPassSetup,
    photons: Range<u32>,
    out: &mut PhotonStore,
) -> u64 {
    let mut slots: [Option<Slot>; 2] = [None, None];
    // Records of the photon(s) in slot k that is not the lower-indexed one in flight, in
    // photon order (counted in `out` when stored). Only the other slot's is ever
    // non-empty, and it moves to `out` when that slot becomes the lower one.
    let mut side: [PhotonStore; 2] = [PhotonStore::default(), PhotonStore::default()];
    let mut next = photons.start;
    let mut segments = 0u64;
    loop {
        let mut casting = false;
        for k in 0..2 {
            let other = slots[1 - k].as_ref().map(|s| s.index);
            // Take the answer cast for this slot a step ago.
            if let Some(slot) = &mut slots[k]
                && let Some(hit) = slot.hit.take()
            {
                // The lower-indexed photon in flight writes in place: everything before it
                // has ended and been written.
                let direct = other.is_none_or(|o| slot.index < o);
                let held = &mut side[k];
                slot.walk.advance(prepared, settings, setup, hit, &mut |s| {
                    if direct {
                        out.push(s)
                    } else {
                        out.counts.record_stored(&s);
                        held.push_record(s)
                    }
                });
            }
            // Cast this slot's next segment, retiring ended photons and starting new ones.
            loop {
                if let Some(slot) = &mut slots[k] {
                    if let Some((start, direction)) = slot.walk.next_ray() {
                        let hit = start.intersect(caster, direction, f32::INFINITY);
                        if let Some(h) = &hit {
                            prepared.prefetch_hit(h);
                        }
                        slot.hit = Some(hit);
                        casting = true;
                        break;
                    }
                    segments += slot.walk.stats().segments as u64;
                    slots[k] = None;
                    // The other slot's photon (if any) is now the lowest in flight, and
                    // everything before it has been written: its held records are next.
                    let [a, b] = &mut side;
                    out.take_records(if k == 0 { b } else { a });
                }
                if next >= photons.end {
                    break;
                }
                let index = next;
                next += 1;
                if let Some(walk) = PhotonWalk::start(prepared, settings, setup, index) {
                    slots[k] = Some(Slot { walk, index, hit: None });
                }
            }
        }
        if !casting {
            break;
        }
    }
    debug_assert!(side.iter().all(|s| s.footprints.is_empty() && s.photons.is_empty()));
    segments
}

#[cfg(test)]
mod tests {
    use super::*;
    use arpa_core::emit::emission::{Light, QuadLight};
    use arpa_core::glam::{DVec3, Vec3};
    use arpa_core::render::photon_path::trace_photon;
    use arpa_core::render::brute_force::BruteForceCaster;
    use arpa_core::render::scene::{Camera, Material, Scene};
    use arpa_core::render::shapes::{cuboid, icosphere, parallelogram};
    use arpa_core::render::tracer::Method;

    /// A closed 2 m room (diffuse walls), a smooth glass sphere, a smooth diffuse sphere
    /// (shading normals on a diffuse surface), a mirror block and a quad light.
    fn room() -> Scene {
        let (o, x, y, z) = (Vec3::new(-1.0, 0.0, -1.0), Vec3::X * 2.0, Vec3::Y * 2.0, Vec3::Z * 2.0);
        Scene { textures: Default::default(),
            meshes: vec![
                parallelogram("floor", o, z, x, 0),
                parallelogram("ceiling", o + y, x, z, 0),
                parallelogram("back", o, x, y, 0),
                parallelogram("front", o + z, y, x, 0),
                parallelogram("left", o, y, z, 0),
                parallelogram("right", o + x, z, y, 0),
                icosphere("glass", Vec3::new(0.4, 0.41, 0.0), 0.4, 2, true, 1),
                icosphere("ball", Vec3::new(-0.5, 0.3, 0.5), 0.3, 1, true, 0),
                cuboid("block", Vec3::new(-0.8, 0.0, -0.8), Vec3::new(-0.3, 0.8, -0.3), 2),
            ],
            materials: vec![
                Material::Diffuse { albedo: Vec3::splat(0.75) },
                Material::Dielectric { ior: 1.5, transmittance: Vec3::ONE, roughness: 0.0 },
                Material::Conductor { reflectance: Vec3::splat(0.95), roughness: 0.0 },
            ],
            lights: vec![Light::Quad(QuadLight {
                origin: DVec3::new(-0.25, 1.98, -0.25),
                edge_u: DVec3::new(0.5, 0.0, 0.0),
                edge_v: DVec3::new(0.0, 0.0, 0.5),
                radiance: DVec3::splat(20.0),
            })],
            camera: Camera { position: Vec3::new(0.0, 1.0, 0.97), target: Vec3::new(0.0, 0.8, -1.0), up: Vec3::Y, vertical_fov: 1.0, width: 8, height: 8 },
            roughness_cutoff: 0.5,
            instancing: None,
        }
    }

    /// Traces `0..count` of `setup` sequentially with `trace_photon` and as chunks split at
    /// `splits`, and asserts that both store the same records in the same order and count
    /// the same segments.
    fn assert_chunks_match(prepared: &PreparedScene, settings: &RenderSettings, iteration: u32, splits: &[u32]) {
        let caster = BruteForceCaster::new(prepared);
        let setup = PhotonPassSetup::new(prepared, settings, iteration);
        let count = setup.photon_count();
        let mut reference = PhotonStore::default();
        let mut ref_segments = 0u64;
        for index in 0..count {
            ref_segments += trace_photon(prepared, &caster, settings, &setup, index, &mut |s| reference.push(s)).segments as u64;
        }
        let mut store = PhotonStore::default();
        let mut bounds: Vec<u32> = splits.iter().map(|&s| s.min(count)).collect();
        bounds.insert(0, 0);
        bounds.push(count);
        let segments: u64 = bounds.windows(2).map(|w| trace_chunk(prepared, &caster, settings, &setup, w[0]..w[1], &mut store)).sum();
        let what = format!("{:?}, iteration {iteration}, splits {splits:?}", settings.method);
        assert_eq!(segments, ref_segments, "{what}");
        assert_eq!(store.footprints, reference.footprints, "{what}");
        assert_eq!(store.footprint_boxes, reference.footprint_boxes, "{what}");
        assert_eq!(store.photons, reference.photons, "{what}");
        assert_eq!(store.counts, reference.counts, "{what}");
    }

    /// The interleaved chunk stores exactly what `trace_photon` stores photon by photon,
    /// in the same order, and casts as many segments (glass sphere with shading normals,
    /// mirror, diffuse walls: every kind of interaction, photons of very different path
    /// lengths side by side), for both methods, with ragged chunk boundaries.
    #[test]
    fn interleaved_chunk_matches_sequential_trace_photon() {
        let prepared = PreparedScene::new(room()).unwrap();
        for method in [Method::Arpa, Method::Rtpm] {
            let settings = RenderSettings { method, photons_per_iteration: 3000, seed: 7, ..RenderSettings::default() };
            assert_chunks_match(&prepared, &settings, 2, &[1001]);
        }
    }

    /// The same over a grid of seeds, iterations, path lengths (a single segment, where a
    /// photon ends at its first hit, up to the default) and direct lighting on and off
    /// (which decides whether first diffuse hits store), with chunks of 0, 1 and a few
    /// photons among them.
    #[test]
    fn interleaved_chunk_matches_over_settings() {
        let prepared = PreparedScene::new(room()).unwrap();
        for (k, max_depth) in [1u32, 2, 5, RenderSettings::default().max_depth].into_iter().enumerate() {
            for direct_lighting in [true, false] {
                let settings = RenderSettings {
                    method: if k % 2 == 0 { Method::Arpa } else { Method::Rtpm },
                    photons_per_iteration: 500,
                    seed: 11 + k as u32,
                    max_depth,
                    direct_lighting,
                    ..RenderSettings::default()
                };
                assert_chunks_match(&prepared, &settings, k as u32, &[0, 1, 1, 4, 97, 300]);
            }
        }
    }
}
