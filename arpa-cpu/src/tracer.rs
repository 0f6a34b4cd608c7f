//! [`CpuTracer`]: the CPU backend of [`arpa_core::tracer::Tracer`] on Embree 4 and rayon.

use core::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use arpa_core::accumulate::ImageAccumulator;
use arpa_core::camera_path::trace_camera_path;
use arpa_core::estimate::IrradianceEstimate;
use arpa_core::footprint::PackedFootprint;
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::kernel::Kernel;
use arpa_core::photon_path::PhotonPassSetup;
use arpa_core::prefetch::prefetch;
use arpa_core::prepared_scene::PreparedScene;
use arpa_core::progressive_photon::PackedPhoton;
use arpa_core::scene::{Scene as CoreScene, SceneError};
use arpa_core::tracer::{
    Capabilities, Image, IterationStats, Method, QueryRecord, RenderSettings, Tracer,
};
use rayon::prelude::*;

use crate::caster::EmbreeCaster;
use crate::device::Device;
use crate::error::EmbreeError;
use crate::photon_chunk::trace_chunk;
use crate::photon_store::{PhotonStore, photon_box};
use crate::scene::{Aabb, BuildQuality, Scene, SceneBuilder};

/// Photon indices traced by one task of the photon pass. The stored photons of each chunk
/// are concatenated in chunk order, so the buffers do not depend on the thread count.
pub const PHOTON_CHUNK: u32 = 4096;

/// Headroom of the buffer sizes estimated from the previous iteration's store rate.
const CAPACITY_HEADROOM: f64 = 1.25;

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

/// Errors of the CPU backend.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CpuError {
    /// The scene failed validation.
    #[error("invalid scene: {0}")]
    Scene(#[from] SceneError),
    /// A render setting is out of range.
    #[error("invalid render settings: {0}")]
    Settings(String),
    /// The image has more pixels than the `u32` pixel index can address.
    #[error("image of {width}×{height} pixels is too large (at most 2^32 − 1 pixels)")]
    ImageTooLarge {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// Embree failed (device creation, BVH build).
    #[error(transparent)]
    Embree(#[from] EmbreeError),
    /// A stage was called before the stage it depends on (in this iteration).
    #[error("{stage} called before {needs}")]
    StageOrder {
        /// The stage called.
        stage: &'static str,
        /// What has to run first.
        needs: &'static str,
    },
    /// `u32::MAX − 1` iterations have been accumulated: the iteration index of the random
    /// streams and the radius schedule cannot go further.
    #[error("iteration limit reached ({0} iterations)")]
    IterationLimit(u32),
    /// A buffer could not be allocated.
    #[error("out of memory allocating {0}")]
    OutOfMemory(&'static str),
}

/// The photon-mapping pipeline on the CPU: Embree 4 for rays and box queries, rayon for
/// parallelism.
///
/// Shaped like a GPU backend: the tracer owns every buffer (scene BVH, query records,
/// footprints, progressive photons, their box BVH, the iteration image and the running
/// mean); the stages only read and write those buffers, and the host sees them only
/// through the `read_*` calls.
///
/// | stage | what it does on the CPU |
/// |---|---|
/// | [`upload_scene`](Tracer::upload_scene) | validates scene and settings ([`PreparedScene`]), builds the triangle BVH ([`EmbreeCaster`]), resets the accumulation |
/// | [`camera_pass`](Tracer::camera_pass) | [`trace_camera_path`] for every pixel, in parallel |
/// | [`photon_pass`](Tracer::photon_pass) | frees the previous box BVH, then the core's `PhotonWalk` for every photon (two in flight per thread, interleaved segment by segment, see `photon_chunk`; the records are those of `trace_photon`, in photon order), in chunks of [`PHOTON_CHUNK`] photon indices taken in order by one loop per thread; each finished chunk is appended to the buffers (reused from the last iteration, sized from its store rate) as soon as the chunks before it are |
/// | [`build_acceleration_structure`](Tracer::build_acceleration_structure) | one Embree box geometry for the footprints (the core's box of each footprint's elliptic slab, made in the photon pass), one for the progressive photons' cubes `x ± r_map` ([`BuildQuality::Low`]); boxes padded a little beyond `f32` rounding, handed to Embree without a copy and freed once the BVH is built |
/// | [`gather`](Tracer::gather) | per query point: the boxes containing it (Embree point query, whose callback only notes and prefetches each candidate), then the exact test of each in `(kind, index)` order, and the `f64` sum of the contributions in `(kind, index)` order: bit for bit what [`arpa_core::estimate::gather_brute_force`] gives over the same records |
/// | [`accumulate`](Tracer::accumulate) | adds the iteration's image to the compensated running mean |
///
/// # Determinism
/// Images are bit-identical for the same scene, settings and seed whatever the number of
/// threads: every random stream depends only on `(seed, iteration, index)`; photons are
/// traced in fixed chunks whose outputs are concatenated in photon-index order; every
/// pixel is computed by one task; and the gather sorts the candidates a query point gets
/// from the BVH by `(kind, index)` before testing and summing, so the summation order does not depend
/// on the BVH's traversal order either.
///
/// # Stage order
/// The stages of an iteration must run in the order above (camera and photon pass in
/// either order); a stage whose input is missing or stale returns
/// [`CpuError::StageOrder`]. Re-running a stage within an iteration is allowed and
/// gives the same result; it invalidates the outputs of the stages after it. (Re-running
/// the build on unchanged buffers keeps the BVH already built: the boxes it was built from
/// are freed after the build.)
#[derive(Debug)]
pub struct CpuTracer {
    device: Device,
    state: Option<Box<Loaded>>,
}

/// The box BVH of an iteration.
#[derive(Debug)]
enum Accel {
    /// Nothing was stored: every query gathers nothing.
    Empty,
    /// Embree scene with up to two box geometries.
    Boxes {
        scene: Scene,
        /// Geometry id of the footprint boxes (box `i` bounds footprint `i`).
        footprints: Option<u32>,
        /// Geometry id of the photon cubes (box `i` bounds photon `i`).
        photons: Option<u32>,
    },
}

/// Everything that exists once a scene is uploaded.
#[derive(Debug)]
struct Loaded {
    prepared: PreparedScene,
    settings: RenderSettings,
    caster: EmbreeCaster,
    width: u32,
    height: u32,
    accumulator: ImageAccumulator,
    /// Iterations accumulated; also the 0-based index of the iteration in progress.
    completed: u32,
    stats: IterationStats,
    /// Iteration whose counts `stats` holds.
    stats_for: Option<u32>,
    queries: Vec<QueryRecord>,
    queries_for: Option<u32>,
    store: PhotonStore,
    /// Photons traced for `store` (with its counts: the store rate that sizes the next
    /// pass's buffers).
    store_emitted: u32,
    /// Chunk buffers of the photon pass, kept for the next pass.
    spare_parts: Vec<PhotonStore>,
    /// Progressive radii `[caustic, global]` of the photons in `store`.
    radii: [f32; 2],
    store_for: Option<u32>,
    accel: Accel,
    accel_for: Option<u32>,
    image: Vec<Vec3>,
    image_for: Option<u32>,
    /// Failed point queries of the gather (answered as "nothing found").
    gather_errors: AtomicU64,
}

impl Loaded {
    /// Refuses to start an iteration whose index the core cannot represent
    /// (`PhotonPassSetup::new` computes the 1-based `iteration + 1`).
    fn check_iteration_limit(&self) -> Result<(), CpuError> {
        if self.completed >= u32::MAX - 1 {
            Err(CpuError::IterationLimit(self.completed))
        } else {
            Ok(())
        }
    }

    /// Starts (or continues) the counts of the iteration in progress.
    fn begin_stage(&mut self) {
        if self.stats_for != Some(self.completed) {
            self.stats = IterationStats {
                iteration: self.completed,
                radii: self.stats.radii,
                ..IterationStats::default()
            };
            self.stats_for = Some(self.completed);
        }
    }

    fn require(
        &self,
        have: Option<u32>,
        stage: &'static str,
        needs: &'static str,
    ) -> Result<(), CpuError> {
        if have == Some(self.completed) {
            Ok(())
        } else {
            Err(CpuError::StageOrder { stage, needs })
        }
    }
}

impl CpuTracer {
    /// A tracer on a new Embree device (all hardware threads for BVH builds).
    pub fn new() -> Result<Self, CpuError> {
        Ok(Self::with_device(Device::new()?))
    }

    /// A tracer on an existing Embree device.
    pub fn with_device(device: Device) -> Self {
        Self {
            device,
            state: None,
        }
    }

    /// The Embree device.
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// The uploaded scene, validated and prepared.
    pub fn prepared_scene(&self) -> Option<&PreparedScene> {
        self.state.as_ref().map(|s| &s.prepared)
    }

    /// The settings of the uploaded scene.
    pub fn settings(&self) -> Option<&RenderSettings> {
        self.state.as_ref().map(|s| &s.settings)
    }

    /// Embree queries that failed since the upload (answered as misses / nothing found).
    /// Always 0 unless something is wrong.
    pub fn embree_errors(&self) -> u64 {
        self.state.as_ref().map_or(0, |s| {
            s.caster.errors() + s.gather_errors.load(Ordering::Relaxed)
        })
    }

    fn loaded(&self, stage: &'static str) -> Result<&Loaded, CpuError> {
        self.state.as_deref().ok_or(CpuError::StageOrder {
            stage,
            needs: "upload_scene",
        })
    }

    fn loaded_mut(&mut self, stage: &'static str) -> Result<&mut Loaded, CpuError> {
        self.state.as_deref_mut().ok_or(CpuError::StageOrder {
            stage,
            needs: "upload_scene",
        })
    }
}

/// Rejects settings no render can use ([`RenderSettings::validate`]).
pub fn validate_settings(s: &RenderSettings) -> Result<(), CpuError> {
    s.validate().map_err(|e| CpuError::Settings(e.0))
}

fn cpu_description() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|s| {
        s.lines()
            .find(|l| l.starts_with("model name"))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
            .filter(|v| !v.is_empty())
    });
    format!(
        "{} ({} threads)",
        model.as_deref().unwrap_or("CPU"),
        rayon::current_num_threads()
    )
}

/// Replaces non-finite components by 0.
fn finite_or_zero(v: DVec3) -> DVec3 {
    DVec3::select(v.is_finite_mask(), v, DVec3::ZERO)
}

/// Candidate key of the gather: footprints (`index`) before progressive photons
/// (`2³² + index`), the order [`arpa_core::estimate::gather_brute_force`] sums in.
const PHOTON_KEY: u64 = 1 << 32;

/// The gather of one query record: its pixel's radiance and the number of contributions.
///
/// Two phases. The Embree point query reports every box containing the query point (and
/// possibly a few more); its callback only notes the candidate's key in `keys` and
/// prefetches the record, so the records' cache misses overlap instead of stalling the
/// traversal one by one. Then the candidates are sorted and deduplicated by key and each
/// is tested exactly (the same tests as [`IrradianceEstimate::add_footprint`] /
/// [`IrradianceEstimate::add_photon`]); the non-zero contributions are summed in `f64` in
/// `(kind, index)` order, so the sum is bit-identical to a brute-force gather over the
/// same records, whatever order the BVH reported them in.
#[allow(clippy::too_many_arguments)]
fn gather_one(
    rec: &QueryRecord,
    accel: &Accel,
    store: &PhotonStore,
    kernel: Kernel,
    radii: [f32; 2],
    keys: &mut Vec<u64>,
    errors: &AtomicU64,
) -> (Vec3, u32) {
    let known = Vec3::from_array(rec.radiance).as_dvec3();
    if rec.valid == 0 {
        return (finite_or_zero(known).as_vec3(), 0);
    }
    let mut estimate = IrradianceEstimate::default();
    if let Accel::Boxes {
        scene,
        footprints,
        photons,
    } = accel
    {
        let (q, n) = (Vec3::from_array(rec.position), Vec3::from_array(rec.normal));
        keys.clear();
        let found = scene.point_query(rec.position, 0.0, |c| {
            let i = c.prim_id as usize;
            if Some(c.geom_id) == *footprints {
                if let Some(fp) = store.footprints.get(i) {
                    prefetch(fp);
                    keys.push(i as u64);
                }
            } else if Some(c.geom_id) == *photons
                && let Some(ph) = store.photons.get(i)
            {
                prefetch(ph);
                keys.push(PHOTON_KEY | i as u64);
            }
        });
        if found.is_err() {
            errors.fetch_add(1, Ordering::Relaxed);
        }
        keys.sort_unstable();
        keys.dedup();
        for &key in keys.iter() {
            let i = (key & (PHOTON_KEY - 1)) as usize;
            let (e, map) = if key < PHOTON_KEY {
                let fp = &store.footprints[i];
                (fp.irradiance(q, n, kernel), fp.photon_map())
            } else {
                let ph = &store.photons[i];
                let map = ph.photon_map();
                (ph.irradiance(q, n, radii[map.index()]), map)
            };
            // What IrradianceEstimate::add_footprint/add_photon skip.
            if e != Vec3::ZERO && e.is_finite() {
                estimate.per_map[map.index()] += e.as_dvec3();
                if key < PHOTON_KEY {
                    estimate.footprints += 1;
                } else {
                    estimate.photons += 1;
                }
            }
        }
    }
    let weight = Vec3::from_array(rec.weight).as_dvec3();
    let radiance = known + weight * estimate.irradiance();
    (
        finite_or_zero(radiance).as_vec3(),
        estimate.footprints + estimate.photons,
    )
}

impl Tracer for CpuTracer {
    type Error = CpuError;

    fn capabilities(&self) -> Capabilities {
        Capabilities {
            backend: "cpu",
            device: cpu_description(),
            methods: vec![Method::Arpa, Method::Rtpm],
            max_photons_per_iteration: None,
            deterministic: true,
        }
    }

    fn upload_scene(
        &mut self,
        scene: &CoreScene,
        settings: &RenderSettings,
    ) -> Result<(), CpuError> {
        // A failed upload leaves no scene behind.
        self.state = None;
        validate_settings(settings)?;
        let prepared = PreparedScene::new(scene.clone())?;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let pixels = width as u64 * height as u64;
        if pixels > u32::MAX as u64 {
            return Err(CpuError::ImageTooLarge { width, height });
        }
        // Probe the per-pixel allocations before making them (ImageAccumulator aborts on
        // allocation failure).
        let mut probe: Vec<[u8; 64]> = Vec::new();
        probe
            .try_reserve_exact(pixels as usize)
            .map_err(|_| CpuError::OutOfMemory("the image buffers"))?;
        drop(probe);
        let caster = EmbreeCaster::new(&self.device, &prepared)?;
        self.state = Some(Box::new(Loaded {
            prepared,
            settings: *settings,
            caster,
            width,
            height,
            accumulator: ImageAccumulator::new(width, height),
            completed: 0,
            stats: IterationStats::default(),
            stats_for: Some(0),
            queries: Vec::new(),
            queries_for: None,
            store: PhotonStore::default(),
            store_emitted: 0,
            spare_parts: Vec::new(),
            radii: [0.0; 2],
            store_for: None,
            accel: Accel::Empty,
            accel_for: None,
            image: Vec::new(),
            image_for: None,
            gather_errors: AtomicU64::new(0),
        }));
        Ok(())
    }

    fn camera_pass(&mut self) -> Result<(), CpuError> {
        let st = self.loaded_mut("camera_pass")?;
        st.check_iteration_limit()?;
        st.begin_stage();
        let start = Instant::now();
        let iteration = st.completed;
        let pixels = st.width * st.height;
        let mut queries = core::mem::take(&mut st.queries);
        (0..pixels)
            .into_par_iter()
            .map(|pixel| {
                trace_camera_path(&st.prepared, &st.caster, &st.settings, iteration, pixel)
            })
            .collect_into_vec(&mut queries);
        st.stats.query_points = queries.iter().filter(|q| q.valid != 0).count() as u64;
        st.queries = queries;
        st.queries_for = Some(iteration);
        st.image_for = None;
        st.stats.times.camera = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn photon_pass(&mut self) -> Result<(), CpuError> {
        let st = self.loaded_mut("photon_pass")?;
        st.check_iteration_limit()?;
        st.begin_stage();
        let start = Instant::now();
        // The box BVH is rebuilt after this pass anyway: free it (and the previous
        // iteration's buffers it refers to) before the new buffers fill.
        st.accel = Accel::Empty;
        st.accel_for = None;
        st.store_for = None;
        st.image_for = None;
        let iteration = st.completed;
        let setup = PhotonPassSetup::new(&st.prepared, &st.settings, iteration);
        let count = setup.photon_count();
        let chunks = count.div_ceil(PHOTON_CHUNK);
        // Buffer sizes from the previous pass's store rate (records per photon traced).
        let (fp_rate, ph_rate) = match st.store_emitted {
            0 => (0.0, 0.0),
            n => {
                let c = &st.store.counts;
                (
                    c.footprints.iter().sum::<u64>() as f64 / n as f64,
                    c.progressive.iter().sum::<u64>() as f64 / n as f64,
                )
            }
        };
        let expect = |rate: f64, photons: u32| (rate * photons as f64 * CAPACITY_HEADROOM) as usize;
        st.store.clear();
        st.store
            .reserve_total(expect(fp_rate, count), expect(ph_rate, count));
        let (part_fp, part_ph) = (
            expect(fp_rate, PHOTON_CHUNK) + 64,
            expect(ph_rate, PHOTON_CHUNK) + 64,
        );
        let (prepared, caster, settings) = (&st.prepared, &st.caster, &st.settings);
        let merge = Mutex::new(ChunkMerge {
            out: &mut st.store,
            pending: (0..chunks).map(|_| None).collect(),
            next: 0,
            free: core::mem::take(&mut st.spare_parts),
            segments: 0,
        });
        let lock = || merge.lock().unwrap_or_else(|e| e.into_inner());
        // One loop per thread, taking chunks in index order.
        let next_chunk = AtomicU32::new(0);
        let workers = rayon::current_num_threads().clamp(1, chunks.max(1) as usize);
        (0..workers).into_par_iter().for_each(|_| {
            let mut part: Option<PhotonStore> = None;
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
        st.spare_parts = merge.free;
        st.store_emitted = count;
        let c = st.store.counts;
        let stats = &mut st.stats;
        stats.photons_emitted = count as u64;
        stats.photon_segments = segments;
        stats.footprints = c.footprints;
        stats.progressive = c.progressive;
        stats.degenerate = c.degenerate;
        stats.culled = c.culled;
        stats.unrepresentable = c.unrepresentable;
        stats.differential_lost = c.differential_lost;
        stats.overflowed = 0;
        stats.radii = setup.radii;
        st.radii = setup.radii.map(|r| r as f32);
        st.store_for = Some(iteration);
        st.accel_for = None;
        st.image_for = None;
        st.stats.times.photon = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn build_acceleration_structure(&mut self) -> Result<(), CpuError> {
        let device = self.device.clone();
        let st = self.loaded_mut("build_acceleration_structure")?;
        st.require(st.store_for, "build_acceleration_structure", "photon_pass")?;
        st.begin_stage();
        let start = Instant::now();
        if st.accel_for == Some(st.completed) {
            // Built from the same buffers in this iteration: the BVH is current (the boxes
            // it was built from are gone, see below).
            st.image_for = None;
            st.stats.times.build = start.elapsed().as_secs_f64();
            return Ok(());
        }
        // Drop the previous BVH first: only one lives at a time.
        st.accel = Accel::Empty;
        st.accel_for = None;
        if st.store.footprint_boxes.len() != st.store.footprints.len() {
            // A failed build consumed the boxes: the photon pass has to make them again.
            return Err(CpuError::StageOrder {
                stage: "build_acceleration_structure",
                needs: "photon_pass",
            });
        }
        let radii = st.radii;
        // The boxes move into Embree's scene (no copy) and are freed once the BVH is
        // built, so only the BVH stays next to the records.
        let footprint_boxes = core::mem::take(&mut st.store.footprint_boxes);
        let photon_boxes: Vec<Aabb> = st
            .store
            .photons
            .par_iter()
            .map(|p| photon_box(p, radii[p.photon_map().index()]))
            .collect();
        let accel = if footprint_boxes.is_empty() && photon_boxes.is_empty() {
            Accel::Empty
        } else {
            let mut builder = SceneBuilder::new(&device)?.build_quality(BuildQuality::Low);
            let footprints = if footprint_boxes.is_empty() {
                None
            } else {
                Some(builder.add_boxes_owned(footprint_boxes)?)
            };
            let photons = if photon_boxes.is_empty() {
                None
            } else {
                Some(builder.add_boxes_owned(photon_boxes)?)
            };
            let mut scene = builder.commit()?;
            drop(scene.release_boxes());
            Accel::Boxes {
                scene,
                footprints,
                photons,
            }
        };
        st.accel = accel;
        st.accel_for = Some(st.completed);
        st.image_for = None;
        st.stats.times.build = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn gather(&mut self) -> Result<(), CpuError> {
        let st = self.loaded_mut("gather")?;
        st.require(st.queries_for, "gather", "camera_pass")?;
        st.require(st.accel_for, "gather", "build_acceleration_structure")?;
        st.begin_stage();
        let start = Instant::now();
        let gathered = AtomicU64::new(0);
        let (kernel, radii) = (st.settings.kernel, st.radii);
        let mut image = core::mem::take(&mut st.image);
        st.queries
            .par_iter()
            .map_init(Vec::new, |scratch, rec| {
                let (l, n) = gather_one(
                    rec,
                    &st.accel,
                    &st.store,
                    kernel,
                    radii,
                    scratch,
                    &st.gather_errors,
                );
                gathered.fetch_add(n as u64, Ordering::Relaxed);
                l
            })
            .collect_into_vec(&mut image);
        st.image = image;
        st.stats.gathered = gathered.into_inner();
        st.image_for = Some(st.completed);
        st.stats.times.gather = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn accumulate(&mut self) -> Result<(), CpuError> {
        let st = self.loaded_mut("accumulate")?;
        st.require(st.image_for, "accumulate", "gather")?;
        st.begin_stage();
        let start = Instant::now();
        st.accumulator
            .add_iteration(&st.image)
            .map_err(|_| CpuError::StageOrder {
                stage: "accumulate",
                needs: "an image of the scene's size",
            })?;
        st.completed += 1;
        st.image_for = None;
        st.stats.iteration = st.completed;
        st.stats.times.accumulate = start.elapsed().as_secs_f64();
        Ok(())
    }

    fn iterations(&self) -> u32 {
        self.state.as_ref().map_or(0, |s| s.completed)
    }

    fn read_image(&self) -> Result<Image, CpuError> {
        let st = self.loaded("read_image")?;
        Ok(Image {
            width: st.width,
            height: st.height,
            pixels: st.accumulator.mean(),
        })
    }

    fn read_query_points(&self) -> Result<Vec<QueryRecord>, CpuError> {
        let st = self.loaded("read_query_points")?;
        if st.queries_for.is_none() {
            return Err(CpuError::StageOrder {
                stage: "read_query_points",
                needs: "camera_pass",
            });
        }
        Ok(st.queries.clone())
    }

    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, CpuError> {
        let st = self.loaded("read_footprints")?;
        if st.store_for.is_none() {
            return Err(CpuError::StageOrder {
                stage: "read_footprints",
                needs: "photon_pass",
            });
        }
        Ok(st.store.footprints.clone())
    }

    fn read_photons(&self) -> Result<Vec<PackedPhoton>, CpuError> {
        let st = self.loaded("read_photons")?;
        if st.store_for.is_none() {
            return Err(CpuError::StageOrder {
                stage: "read_photons",
                needs: "photon_pass",
            });
        }
        Ok(st.store.photons.clone())
    }

    fn read_stats(&self) -> Result<IterationStats, CpuError> {
        Ok(self.loaded("read_stats")?.stats)
    }
}
