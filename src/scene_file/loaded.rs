//! A loaded scene with what the loader noticed, and the camera's field of view as Mitsuba
//! defines it.

use super::error::Warning;
use arpa_core::render::scene::Scene;
use std::path::PathBuf;

/// Which image axis a Mitsuba `fov` spans.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FovAxis {
    /// Horizontal (Mitsuba's default).
    X,
    /// Vertical.
    Y,
    /// Diagonal.
    Diagonal,
    /// The smaller image side.
    Smaller,
    /// The larger image side.
    Larger,
}

/// The vertical field of view (radians) of a `fov_degrees` field of view along `axis` on a
/// `width × height` film.
pub fn vertical_fov(fov_degrees: f64, axis: FovAxis, width: u32, height: u32) -> f32 {
    let (w, h) = (width.max(1) as f64, height.max(1) as f64);
    let t = (0.5 * fov_degrees.to_radians()).tan();
    let tan_half_v = match axis {
        FovAxis::Y => t,
        FovAxis::X => t * h / w,
        FovAxis::Diagonal => t * h / (w * w + h * h).sqrt(),
        FovAxis::Smaller => if w < h { t * h / w } else { t },
        FovAxis::Larger => if w > h { t * h / w } else { t },
    };
    (2.0 * tan_half_v.atan()) as f32
}

/// A loaded (and validated) scene with what the loader noticed.
#[derive(Clone, Debug)]
pub struct LoadedScene {
    /// The scene; its camera has the file's film size.
    pub scene: Scene,
    /// Approximations and ignored elements, each naming its line.
    pub warnings: Vec<Warning>,
    /// The scene file.
    pub path: PathBuf,
    /// The `<integrator>`'s `max_depth`, if any (informative: arpa has its own setting).
    pub max_depth: Option<u32>,
    /// The sensor's sampler `sample_count`, if any (informative).
    pub sample_count: Option<u32>,
    /// The sensor's `fov` in degrees, along [`LoadedScene::fov_axis`].
    pub fov_degrees: f64,
    /// The axis `fov` spans.
    pub fov_axis: FovAxis,
}

impl LoadedScene {
    /// Changes the image size, keeping the field of view along the file's `fov_axis` (as
    /// Mitsuba does when the film size changes).
    pub fn set_resolution(&mut self, width: u32, height: u32) {
        let c = &mut self.scene.camera;
        c.width = width;
        c.height = height;
        c.vertical_fov = vertical_fov(self.fov_degrees, self.fov_axis, width, height);
    }

    /// Total number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.scene.meshes.iter().map(|m| m.indices.len()).sum()
    }
}

