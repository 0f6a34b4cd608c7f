//! [`DynTracer`]: an object-safe view of any [`Tracer`], so one case body drives every
//! backend through `&mut dyn DynTracer` and the registry can hold backends of different
//! types side by side.

use arpa_core::footprint::PackedFootprint;
use arpa_core::progressive_photon::PackedPhoton;
use arpa_core::scene::Scene;
use arpa_core::tracer::{Capabilities, Image, IterationStats, QueryRecord, RenderSettings, Tracer};

/// A backend's error, boxed (the backend's own `thiserror` enum inside).
pub type BoxError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// [`Tracer`] with its associated error type erased: the same stage and `read_*` calls,
/// each error boxed. Implemented for every `T: Tracer + Send`; cases never name a backend
/// type. `Send` lets a case drive the backend from a thread pool of its choosing (the
/// thread-count determinism case).
pub trait DynTracer: Send {
    /// [`Tracer::capabilities`].
    fn capabilities(&self) -> Capabilities;
    /// [`Tracer::upload_scene`].
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), BoxError>;
    /// [`Tracer::camera_pass`].
    fn camera_pass(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::photon_pass`].
    fn photon_pass(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::build_acceleration_structure`].
    fn build_acceleration_structure(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::gather`].
    fn gather(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::accumulate`].
    fn accumulate(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::iterate`] (the backend's own, which may fuse stages).
    fn iterate(&mut self) -> Result<(), BoxError>;
    /// [`Tracer::iterations`].
    fn iterations(&self) -> u32;
    /// [`Tracer::read_image`].
    fn read_image(&self) -> Result<Image, BoxError>;
    /// [`Tracer::read_query_points`].
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, BoxError>;
    /// [`Tracer::read_footprints`].
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, BoxError>;
    /// [`Tracer::read_photons`].
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, BoxError>;
    /// [`Tracer::read_stats`].
    fn read_stats(&self) -> Result<IterationStats, BoxError>;
}

fn boxed<E: std::error::Error + Send + Sync + 'static>(e: E) -> BoxError {
    Box::new(e)
}

impl<T: Tracer + Send> DynTracer for T {
    fn capabilities(&self) -> Capabilities {
        Tracer::capabilities(self)
    }
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), BoxError> {
        Tracer::upload_scene(self, scene, settings).map_err(boxed)
    }
    fn camera_pass(&mut self) -> Result<(), BoxError> {
        Tracer::camera_pass(self).map_err(boxed)
    }
    fn photon_pass(&mut self) -> Result<(), BoxError> {
        Tracer::photon_pass(self).map_err(boxed)
    }
    fn build_acceleration_structure(&mut self) -> Result<(), BoxError> {
        Tracer::build_acceleration_structure(self).map_err(boxed)
    }
    fn gather(&mut self) -> Result<(), BoxError> {
        Tracer::gather(self).map_err(boxed)
    }
    fn accumulate(&mut self) -> Result<(), BoxError> {
        Tracer::accumulate(self).map_err(boxed)
    }
    fn iterate(&mut self) -> Result<(), BoxError> {
        Tracer::iterate(self).map_err(boxed)
    }
    fn iterations(&self) -> u32 {
        Tracer::iterations(self)
    }
    fn read_image(&self) -> Result<Image, BoxError> {
        Tracer::read_image(self).map_err(boxed)
    }
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, BoxError> {
        Tracer::read_query_points(self).map_err(boxed)
    }
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, BoxError> {
        Tracer::read_footprints(self).map_err(boxed)
    }
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, BoxError> {
        Tracer::read_photons(self).map_err(boxed)
    }
    fn read_stats(&self) -> Result<IterationStats, BoxError> {
        Tracer::read_stats(self).map_err(boxed)
    }
}
