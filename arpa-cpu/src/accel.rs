//! The acceleration-structure build: an Embree box BVH over the photon pass's footprints
//! and progressive photons, which the gather's point queries traverse.

use arpa_core::render::tracer::{Stage, StageError};
use rayon::prelude::*;

use crate::embree::{BuildQuality, Device, EmbreeBox, EmbreeScene, EmbreeSceneBuilder};
use crate::photon_store::{PhotonStore, photon_box};
use crate::error::CpuError;

/// The box BVH of an iteration.
#[derive(Debug)]
pub(crate) enum Accel {
    /// Nothing was stored: every query gathers nothing.
    Empty,
    /// Embree scene with up to two box geometries.
    Boxes {
        scene: EmbreeScene,
        /// Geometry id of the footprint boxes (box `i` bounds footprint `i`).
        footprints: Option<u32>,
        /// Geometry id of the photon cubes (box `i` bounds photon `i`).
        photons: Option<u32>,
    },
}

impl Accel {
    /// Builds the box BVH of `store` on `device`: one box geometry for the footprints (the
    /// boxes the photon pass made, the core's box of each footprint's elliptic slab,
    /// padded), one for the progressive photons' cubes `x ± r_map` (`radii` per map,
    /// padded); built with [`BuildQuality::Low`].
    ///
    /// The footprint boxes move out of `store` into Embree's scene (no copy) and are freed
    /// once the BVH is built, so that only the BVH stays next to the records. A second
    /// build from the same store therefore finds no boxes: it fails with the order error
    /// "needs photon_pass" (the photon pass has to make them again).
    pub(crate) fn build(
        device: &Device,
        store: &mut PhotonStore,
        radii: [f32; 2],
    ) -> Result<Self, CpuError> {
        if store.footprint_boxes.len() != store.footprints.len() {
            return Err(
                StageError::order(Stage::BuildAccelerationStructure, Stage::PhotonPass).into(),
            );
        }
        let footprint_boxes = core::mem::take(&mut store.footprint_boxes);
        let photon_boxes: Vec<EmbreeBox> = store
            .photons
            .par_iter()
            .map(|p| photon_box(p, radii[p.photon_map().index()]))
            .collect();
        if footprint_boxes.is_empty() && photon_boxes.is_empty() {
            return Ok(Accel::Empty);
        }
        let mut builder = EmbreeSceneBuilder::new(device)?.build_quality(BuildQuality::Low);
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
        Ok(Accel::Boxes {
            scene,
            footprints,
            photons,
        })
    }
}
