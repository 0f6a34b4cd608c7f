//! The plain geometry both the builder and the built scene handle: boxes of a box set
//! and the finiteness test of ray and query inputs.

/// An axis-aligned box `[lower, upper]` (closed) in `f32`, in the scene's world frame and
/// units: a primitive of a box set ([`super::EmbreeSceneBuilder::add_boxes`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct EmbreeBox {
    /// Minimum corner (x, y, z).
    pub lower: [f32; 3],
    /// Maximum corner (x, y, z); each component must be `>=` the matching `lower` one.
    pub upper: [f32; 3],
}

impl EmbreeBox {
    /// Whether `p` lies in the closed box (boundary included).
    pub fn contains(&self, p: [f32; 3]) -> bool {
        (0..3).all(|k| self.lower[k] <= p[k] && p[k] <= self.upper[k])
    }

    pub(crate) fn is_valid(&self) -> bool {
        (0..3).all(|k| {
            self.lower[k].is_finite() && self.upper[k].is_finite() && self.lower[k] <= self.upper[k]
        })
    }
}

/// Whether every component of `p` is finite.
pub(crate) fn finite3(p: [f32; 3]) -> bool {
    p.iter().all(|c| c.is_finite())
}
