//! The device records filled from the renderer layer ([`crate::render`]): the settings'
//! checks and parameters, the photon pass's emitter and cell tables, the camera pass's
//! uniforms and the accumulation handed back to a device. The records themselves are in
//! [`crate::gpu::layout`], which needs only the per-photon stages.

use crate::accumulate::image::Accumulation;
use crate::emit::emission::PackedLight;
use crate::gpu::layout::{AccumPixel, CameraParams, EmitterRange, PhotonCounters, PhotonParams, StoreCounts};
use crate::render::photon_path::{source_cells, PhotonPassSetup};
use crate::render::prepared_scene::PreparedScene;
use crate::render::scene::{Camera, SceneError};
use crate::render::tracer::{BackendKind, InvalidSettings, IterationStats, RenderSettings, StageError};
use alloc::vec::Vec;

/// Refuses settings whose record keys (`photon_index · max_depth + depth`, as
/// [`KeyedFootprint::key`](crate::gpu::layout::KeyedFootprint::key) and [`KeyedPhoton::key`](crate::gpu::layout::KeyedPhoton::key)) would not all fit a `u32`: the check a
/// GPU backend's `upload_scene` adds to [`crate::render::tracer::prepare_upload`] (which has
/// already refused `max_depth = 0`). The message names `backend` and the largest photon
/// count per iteration at this depth.
pub fn check_record_keys(settings: &RenderSettings, backend: BackendKind) -> Result<(), StageError> {
    if u64::from(settings.photons_per_iteration) * u64::from(settings.max_depth) <= u64::from(u32::MAX) {
        return Ok(());
    }
    Err(StageError::Settings(InvalidSettings(alloc::format!(
        "photons_per_iteration {} × max_depth {} exceeds the u32 record keys of the {backend} backend (at most {} photons at this depth)",
        settings.photons_per_iteration,
        settings.max_depth,
        u32::MAX / settings.max_depth.max(1)
    ))))
}

impl PhotonParams {
    /// The parameters of the photons `batch` (global indices) of iteration `iteration`
    /// under `settings`, with `emitters` emitters.
    pub fn new(settings: &RenderSettings, iteration: u32, emitters: u32, batch: core::ops::Range<u32>) -> Self {
        Self {
            photon_count: batch.end.saturating_sub(batch.start),
            iteration,
            seed: settings.seed,
            max_depth: settings.max_depth,
            method: crate::gpu::codes::method_code(settings.method),
            direct_lighting: settings.direct_lighting as u32,
            emitter_count: emitters,
            first_photon: batch.start,
            smoothing: [settings.smoothing.caustic as f32, settings.smoothing.global as f32],
            pad1: [0.0; 2],
        }
    }
}

/// The photon pass's light and range buffers of an iteration: one
/// [`PackedLight`] (with its caustic weight and the place of its cells
/// in [`cell_table`], and its emitter's record in the texture words from
/// `emission_records`, [`crate::gpu::texture::emitter_records`]) and one [`EmitterRange`]
/// per source of `setup` (`2 ×` the scene's emitters; one zeroed element each for a scene
/// without emitters: storage bindings must not be empty).
pub fn emitter_tables(setup: &PhotonPassSetup, emission_records: &[u32]) -> (Vec<PackedLight>, Vec<EmitterRange>) {
    let n = setup.lights.len().max(1);
    let mut lights = alloc::vec![PackedLight::default(); n];
    let mut ranges = alloc::vec![EmitterRange::default(); n];
    for (e, light) in setup.lights.iter().enumerate() {
        let caustic_only = setup.is_caustic_source(e) as u32;
        ranges[e] = EmitterRange { first_index: setup.first_index[e], count: setup.allocation[e], valid: light.is_some() as u32, caustic_only };
        if let Some(l) = light {
            let mut packed = l.pack();
            packed.caustic_weight = setup.caustic_weight[e] as f32;
            packed.cell_first = setup.cell_first[e];
            packed.emission_record = e.checked_rem(setup.emitters).and_then(|i| emission_records.get(i)).copied().unwrap_or(u32::MAX);
            lights[e] = packed;
        }
    }
    (lights, ranges)
}

/// The photon pass's cell buffer of `scene` (`photon_cells`, the same every iteration):
/// every source's projection cells ([`crate::render::photon_path::source_cells`]) in source order,
/// where [`PhotonPassSetup::cell_first`] points; one zero for a scene
/// without any (storage bindings must not be empty).
pub fn cell_table(scene: &PreparedScene) -> Vec<u32> {
    let sources = 2 * scene.projections().len();
    let mut cells: Vec<u32> = (0..sources).flat_map(|s| source_cells(scene, s).cells.iter().copied()).collect();
    if cells.is_empty() {
        cells.push(0);
    }
    cells
}

impl AccumPixel {
    /// The device records of `state`'s sums, for a GPU backend's
    /// [`Tracer::restore_accumulation`](crate::render::tracer::Tracer::restore_accumulation):
    /// refused when a sum is not exactly `f32` ([`AccumPixel::from_sum`]).
    pub fn from_accumulation(state: &Accumulation) -> Result<Vec<Self>, StageError> {
        state.pixels.iter().map(Self::from_sum).collect::<Option<Vec<_>>>().ok_or_else(|| {
            StageError::Accumulation(
                "its sums are not f32 values (merged parts or an f64 accumulator); a GPU backend continues only its own f32 sums exactly".into(),
            )
        })
    }
}

impl CameraParams {
    /// The parameters of iteration 0 for `camera` under `settings`, dispatched on a grid of
    /// `row_invocations` invocations per row (the caller checks that `width · height`
    /// fits a `u32` and its grid).
    pub fn new(camera: &Camera, settings: &RenderSettings, row_invocations: u32) -> Result<Self, SceneError> {
        let frame = camera.frame()?;
        Ok(Self {
            position: camera.position.to_array(),
            width: camera.width,
            forward: frame.forward.to_array(),
            height: camera.height,
            right: frame.right.to_array(),
            tan_half_fov: frame.tan_half_fov,
            up: frame.up.to_array(),
            aspect: frame.aspect,
            seed: settings.seed,
            iteration: 0,
            max_depth: settings.max_depth,
            direct_lighting: settings.direct_lighting as u32,
            pixel_count: camera.width.wrapping_mul(camera.height),
            row_invocations,
            pad: [0; 2],
        })
    }
}

/// The statistics of the GPU backends' photon passes (defined here, beside the records
/// they read, so the renderer layer does not depend on the device layouts).
impl IterationStats {
    /// Adds the GPU photon batches `batches` ([`add_photon_batch`](Self::add_photon_batch)
    /// each) and the records they dropped to [`IterationStats::overflowed`].
    pub fn add_photon_batches(&mut self, batches: &[crate::gpu::layout::BatchCounts]) {
        for b in batches {
            self.add_photon_batch(&b.photon, &b.store);
        }
        self.overflowed += crate::gpu::layout::BatchCounts::dropped_in(batches);
    }

    /// Adds one GPU photon batch: what its photon pass counted and what its store kept.
    pub fn add_photon_batch(&mut self, counters: &PhotonCounters, counts: &StoreCounts) {
        self.photons_emitted += u64::from(counters.emitted);
        self.photon_segments += u64::from(counters.segments);
        for m in 0..2 {
            self.footprints[m] += u64::from(counts.footprints[m]);
            self.progressive[m] += u64::from(counts.photons[m]);
        }
        self.degenerate += u64::from(counts.degenerate);
        self.culled += u64::from(counts.culled);
        self.unrepresentable += u64::from(counts.unrepresentable);
        self.differential_lost += u64::from(counters.differential_lost);
    }
}
