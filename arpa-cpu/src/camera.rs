//! The camera pass: one camera path per pixel, through specular chains to its first
//! diffuse query point.

use arpa_core::render::camera_path::trace_camera_path;
use arpa_core::render::prepared_scene::PreparedScene;
use arpa_core::render::tracer::{QueryRecord, RenderSettings};
use rayon::prelude::*;

use crate::caster::EmbreeCaster;

/// Writes the query record of every pixel `0..pixels` of iteration `iteration` to
/// `queries` (resized to `pixels`; one [`trace_camera_path`] per pixel, in parallel) and
/// returns the number of valid query points.
pub(crate) fn camera_pass(
    prepared: &PreparedScene,
    caster: &EmbreeCaster,
    settings: &RenderSettings,
    iteration: u32,
    pixels: u32,
    queries: &mut Vec<QueryRecord>,
) -> u64 {
    (0..pixels)
        .into_par_iter()
        .map(|pixel| trace_camera_path(prepared, caster, settings, iteration, pixel))
        .collect_into_vec(queries);
    queries.iter().filter(|q| q.valid != 0).count() as u64
}
