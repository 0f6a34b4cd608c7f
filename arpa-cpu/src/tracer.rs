//! [`CpuTracer`]: the CPU backend of [`arpa_core::render::tracer::Tracer`] on Embree 4 and rayon.
//!
//! This module holds the tracer's state and the stage bookkeeping (the core's
//! [`StageClock`]); each stage's work is in its own module ([`camera`](crate::camera),
//! [`photons`](crate::photons), [`accel`](crate::accel), [`gather`](crate::gather)), and
//! the accumulation is the core's [`ImageAccumulator`].

use core::sync::atomic::{AtomicU64, Ordering};

use arpa_core::accumulate::image::{Accumulation, ImageAccumulator};
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::glam::Vec3;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{
    BackendKind, Call, Capabilities, Image, IterationStats, QueryRecord, RenderSettings,
    Stage, StageClock, StageError, Tracer, prepare_upload, uploaded,
};

use crate::accel::Accel;
use crate::caster::EmbreeCaster;
use crate::embree::Device;
use crate::error::CpuError;
use crate::gather::GatherInput;
use crate::photons::PhotonBuffers;

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
/// | [`upload_scene`](Tracer::upload_scene) | validates scene and settings ([`prepare_upload`]), builds the triangle BVH ([`EmbreeCaster`]), resets the accumulation |
/// | [`camera_pass`](Tracer::camera_pass) | the core's `trace_camera_path` for every pixel, in parallel |
/// | [`photon_pass`](Tracer::photon_pass) | frees the previous box BVH, then the core's `PhotonWalk` for every photon (two in flight per thread, interleaved segment by segment; the records are those of `trace_photon`, in photon order), in chunks of [`PHOTON_CHUNK`](crate::PHOTON_CHUNK) photon indices taken in order by one loop per thread; each finished chunk is appended to the buffers (reused from the last iteration, sized from its store rate) as soon as the chunks before it are |
/// | [`build_acceleration_structure`](Tracer::build_acceleration_structure) | one Embree box geometry for the footprints (the core's box of each footprint's elliptic slab, made in the photon pass), one for the progressive photons' cubes `x ± r_map` (`BuildQuality::Low`); boxes padded a little beyond `f32` rounding, handed to Embree without a copy and freed once the BVH is built |
/// | [`gather`](Tracer::gather) | per query point: the boxes containing it (Embree point query, whose callback only notes and prefetches each candidate), then the core's estimator (`IrradianceEstimate::add_footprint` / `add_photon`) over the candidates in `(kind, index)` order: bit for bit what [`arpa_core::gather::estimate::gather_brute_force`] gives over the same records |
/// | [`accumulate`](Tracer::accumulate) | adds the iteration's image to the compensated running mean |
///
/// # Determinism
/// Images are bit-identical for the same scene, settings and seed whatever the number of
/// threads: every random stream depends only on `(seed, iteration, index)`; photons are
/// traced in fixed chunks whose outputs are concatenated in photon-index order; every
/// pixel is computed by one task; and the gather sorts the candidates a query point gets
/// from the BVH by `(kind, index)` before testing and summing, so the summation order does
/// not depend on the BVH's traversal order either.
///
/// # Stage order
/// The stages of an iteration must run in the order above (camera and photon pass in
/// either order); a stage whose input is missing or stale returns
/// [`StageError::Order`] (in [`CpuError::Stage`]). Re-running a stage within an iteration
/// is allowed and gives the same result; it invalidates the outputs of the stages after
/// it. (Re-running the build on unchanged buffers keeps the BVH already built: the boxes
/// it was built from are freed after the build.)
#[derive(Debug)]
pub struct CpuTracer {
    device: Device,
    state: Option<Box<Loaded>>,
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
    /// Which iteration each stage's output belongs to, and the iteration's statistics.
    clock: StageClock,
    /// Output of the camera pass.
    queries: Vec<QueryRecord>,
    /// Output of the photon pass.
    photons: PhotonBuffers,
    /// Output of the build.
    accel: Accel,
    /// Output of the gather: the iteration's image.
    image: Vec<Vec3>,
    /// Per-pixel scratch of a per-pixel bandwidth gather (kept between iterations).
    planes: Vec<[Vec3; arpa_core::gather::scales::PLANES]>,
    /// Failed point queries of the gather (answered as "nothing found").
    gather_errors: AtomicU64,
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

    /// The uploaded state, or the error saying that `call` needs `upload_scene` first.
    fn loaded(&self, call: impl Into<Call>) -> Result<&Loaded, StageError> {
        uploaded(self.state.as_deref(), call)
    }

    /// [`CpuTracer::loaded`], mutable.
    fn loaded_mut(&mut self, call: impl Into<Call>) -> Result<&mut Loaded, StageError> {
        uploaded(self.state.as_deref_mut(), call)
    }
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

impl Tracer for CpuTracer {
    type Error = CpuError;

    fn capabilities(&self) -> Capabilities {
        Capabilities::new(BackendKind::Cpu, cpu_description())
    }

    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), CpuError> {
        // A failed upload leaves no scene behind.
        self.state = None;
        let prepared = prepare_upload(scene, settings)?;
        let (width, height) = (scene.camera.width, scene.camera.height);
        let pixels = width as u64 * height as u64;
        if pixels > u32::MAX as u64 {
            return Err(CpuError::ImageTooLarge { width, height });
        }
        // Probe the per-pixel allocations before making them (ImageAccumulator aborts on
        // allocation failure).
        let mut probe: Vec<[u8; 64]> = Vec::new();
        probe
            .try_reserve_exact(pixels as usize * settings.bandwidth.planes())
            .map_err(|_| CpuError::OutOfMemory("the image buffers"))?;
        drop(probe);
        let caster = EmbreeCaster::new(&self.device, &prepared)?;
        self.state = Some(Box::new(Loaded {
            prepared,
            settings: *settings,
            caster,
            width,
            height,
            accumulator: ImageAccumulator::with_planes(width, height, settings.bandwidth.planes() as u32),
            clock: StageClock::new(),
            queries: Vec::new(),
            photons: PhotonBuffers::default(),
            accel: Accel::Empty,
            image: Vec::new(),
            planes: Vec::new(),
            gather_errors: AtomicU64::new(0),
        }));
        Ok(())
    }

    fn camera_pass(&mut self) -> Result<(), CpuError> {
        let st = self.loaded_mut(Stage::CameraPass)?;
        st.clock.run(Stage::CameraPass, |clock| {
            let pixels = st.width * st.height;
            clock.stats_mut().query_points =
                crate::camera::camera_pass(&st.prepared, &st.caster, &st.settings, clock.completed(), pixels, &mut st.queries);
            Ok(())
        })
    }

    fn photon_pass(&mut self) -> Result<(), CpuError> {
        let st = self.loaded_mut(Stage::PhotonPass)?;
        st.clock.run(Stage::PhotonPass, |clock| {
            // The box BVH is rebuilt after this pass anyway: free it (and the previous
            // iteration's buffers it refers to) before the new buffers fill.
            st.accel = Accel::Empty;
            let iteration = clock.completed();
            crate::photons::photon_pass(&mut st.photons, &st.prepared, &st.caster, &st.settings, iteration, clock.stats_mut());
            Ok(())
        })
    }

    fn build_acceleration_structure(&mut self) -> Result<(), CpuError> {
        let device = self.device.clone();
        let st = self.loaded_mut(Stage::BuildAccelerationStructure)?;
        // Built from the same buffers in this iteration: the BVH is current (and the boxes
        // it was built from are gone, see `Accel::build`).
        let current = st.clock.is_current(Stage::BuildAccelerationStructure);
        st.clock.run(Stage::BuildAccelerationStructure, |_| {
            if !current {
                // Drop the previous BVH first: only one lives at a time.
                st.accel = Accel::Empty;
                st.accel = Accel::build(&device, &mut st.photons.store, st.photons.radii)?;
            }
            Ok(())
        })
    }

    fn gather(&mut self) -> Result<(), CpuError> {
        let st = self.loaded_mut(Stage::Gather)?;
        st.clock.run(Stage::Gather, |clock| {
            let input = GatherInput {
                accel: &st.accel,
                store: &st.photons.store,
                kernel: st.settings.kernel,
                radii: st.photons.radii,
                scales: st.settings.bandwidth.scales(),
                errors: &st.gather_errors,
            };
            let counts = crate::gather::gather(&st.queries, &input, &mut st.image, &mut st.planes);
            let stats = clock.stats_mut();
            stats.candidates = counts.candidates;
            stats.contributions = counts.contributions;
            stats.covered = counts.covered;
            Ok(())
        })
    }

    fn accumulate(&mut self) -> Result<(), CpuError> {
        let st = self.loaded_mut(Stage::Accumulate)?;
        st.clock.run(Stage::Accumulate, |_| {
            // The gather writes one pixel per query record, so the sizes agree; a
            // mismatch would mean the image is not the gather's output.
            st.accumulator
                .add_iteration(&st.image)
                .map_err(|_| CpuError::from(StageError::order(Stage::Accumulate, Stage::Gather)))
        })
    }

    fn iterations(&self) -> u32 {
        self.state.as_ref().map_or(0, |s| s.clock.completed())
    }

    fn read_accumulation(&self) -> Result<Accumulation, CpuError> {
        let st = self.loaded(Call::ReadAccumulation)?;
        Ok(st.accumulator.to_accumulation(st.clock.first_iteration()))
    }

    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), CpuError> {
        let st = self.loaded_mut(Call::RestoreAccumulation)?;
        let state = state.with_planes(st.settings.bandwidth.planes() as u32).map_err(|e| StageError::Accumulation(e.to_string()))?;
        st.clock = StageClock::for_restore(&state, st.width, st.height)?;
        st.accumulator = ImageAccumulator::from_accumulation(&state);
        Ok(())
    }

    fn read_image(&self) -> Result<Image, CpuError> {
        let st = self.loaded(Call::ReadImage)?;
        Ok(Image {
            width: st.width,
            height: st.height,
            pixels: st.accumulator.mean(),
        })
    }

    fn read_query_points(&self) -> Result<Vec<QueryRecord>, CpuError> {
        let st = self.loaded(Call::ReadQueryPoints)?;
        st.clock.require_output(Call::ReadQueryPoints, Stage::CameraPass)?;
        Ok(st.queries.clone())
    }

    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, CpuError> {
        let st = self.loaded(Call::ReadFootprints)?;
        st.clock.require_output(Call::ReadFootprints, Stage::PhotonPass)?;
        Ok(st.photons.store.footprints.clone())
    }

    fn read_photons(&self) -> Result<Vec<PackedPhoton>, CpuError> {
        let st = self.loaded(Call::ReadPhotons)?;
        st.clock.require_output(Call::ReadPhotons, Stage::PhotonPass)?;
        Ok(st.photons.store.photons.clone())
    }

    fn read_stats(&self) -> Result<IterationStats, CpuError> {
        Ok(*self.loaded(Call::ReadStats)?.clock.stats())
    }
}
