//! The suite catches broken backends: the CPU backend wrapped so that it misbehaves in one
//! way each fails the case meant to catch that (and a faithful wrapper passes them all).
#![cfg(feature = "cpu")]

use arpa_conformance::suite::ci_is_set;
use arpa_conformance::{BoxError, Case, CaseBody, DynTracer, backends, cases};
use arpa_core::accumulate::image::Accumulation;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{Capabilities, Image, IterationStats, QueryRecord, RenderSettings};

#[derive(Clone, Copy, Debug, PartialEq)]
enum Fault {
    None,
    /// Every pixel 3% too bright.
    Bright,
    /// Pixels off by 1e-4 relative.
    SlightlyOff,
    /// The last stored footprint is lost.
    DropFootprint,
    /// A footprint's flux density 1% off.
    FootprintFlux,
    /// Each read of the image differs in the last bit of one pixel.
    Nondeterministic,
    /// `upload_scene` ignores validation errors (uploads a good scene instead).
    AcceptsAnything,
    /// Every image half as bright (a lost light or bounce).
    Half,
    /// Every image mirrored left–right (geometry or camera frame flipped).
    FlippedImage,
    /// Query points moved 5 mm along +x.
    QueryShift,
    /// Query-point weights 2% high.
    QueryWeight,
    /// `restore_accumulation` keeps the sums but continues one iteration index too far (the
    /// resumed iterations use other random streams and radii).
    ResumeRestartsStreams,
    /// `read_accumulation` keeps the sums in `f32` (a lossy state format).
    StateInF32,
}

struct Sabotaged {
    inner: Box<dyn DynTracer>,
    fault: Fault,
    reads: std::cell::Cell<u32>,
}

impl DynTracer for Sabotaged {
    fn capabilities(&self) -> Capabilities {
        self.inner.capabilities()
    }
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), BoxError> {
        let r = self.inner.upload_scene(scene, settings);
        if self.fault == Fault::AcceptsAnything && r.is_err() {
            return self
                .inner
                .upload_scene(&arpa_conformance::scenes::lit_plane(8), settings);
        }
        r
    }
    fn camera_pass(&mut self) -> Result<(), BoxError> {
        self.inner.camera_pass()
    }
    fn photon_pass(&mut self) -> Result<(), BoxError> {
        self.inner.photon_pass()
    }
    fn build_acceleration_structure(&mut self) -> Result<(), BoxError> {
        self.inner.build_acceleration_structure()
    }
    fn gather(&mut self) -> Result<(), BoxError> {
        self.inner.gather()
    }
    fn accumulate(&mut self) -> Result<(), BoxError> {
        self.inner.accumulate()
    }
    fn iterate(&mut self) -> Result<(), BoxError> {
        self.inner.iterate()
    }
    fn iterations(&self) -> u32 {
        self.inner.iterations()
    }
    fn read_image(&self) -> Result<Image, BoxError> {
        let mut img = self.inner.read_image()?;
        let n = self.reads.get();
        self.reads.set(n + 1);
        match self.fault {
            Fault::Bright => img.pixels.iter_mut().for_each(|p| *p *= 1.03),
            Fault::SlightlyOff => img.pixels.iter_mut().for_each(|p| *p *= 1.0 + 1e-4),
            Fault::Half => img.pixels.iter_mut().for_each(|p| *p *= 0.5),
            Fault::FlippedImage => {
                let w = img.width as usize;
                img.pixels
                    .chunks_mut(w.max(1))
                    .for_each(|row| row.reverse());
            }
            Fault::Nondeterministic => {
                if let Some(p) = img.pixels.iter_mut().find(|p| p.x > 0.0) {
                    p.x = f32::from_bits(p.x.to_bits() + (n & 1));
                }
            }
            _ => {}
        }
        Ok(img)
    }
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, BoxError> {
        let mut v = self.inner.read_query_points()?;
        for r in &mut v {
            match self.fault {
                Fault::QueryShift => r.position[0] += 0.005,
                Fault::QueryWeight => r.weight = r.weight.map(|w| w * 1.02),
                _ => {}
            }
        }
        Ok(v)
    }
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, BoxError> {
        let mut v = self.inner.read_footprints()?;
        match self.fault {
            Fault::DropFootprint => {
                v.pop();
            }
            Fault::FootprintFlux => {
                let mid = v.len() / 2;
                if let Some(f) = v.get_mut(mid) {
                    f.flux_density_g *= 1.01;
                }
            }
            _ => {}
        }
        Ok(v)
    }
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, BoxError> {
        self.inner.read_photons()
    }
    fn read_stats(&self) -> Result<IterationStats, BoxError> {
        self.inner.read_stats()
    }
    fn read_accumulation(&self) -> Result<Accumulation, BoxError> {
        let mut a = self.inner.read_accumulation()?;
        if self.fault == Fault::StateInF32 {
            for p in &mut a.pixels {
                p.sum = p.sum.map(|x| x as f32 as f64);
                p.compensation = p.compensation.map(|x| x as f32 as f64);
            }
        }
        Ok(a)
    }
    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), BoxError> {
        if self.fault == Fault::ResumeRestartsStreams && state.iterations > 0 {
            // The sums of `state`, continued from one iteration index too far.
            let shifted = Accumulation { first_iteration: state.first_iteration + 1, ..state.clone() };
            return self.inner.restore_accumulation(&shifted);
        }
        self.inner.restore_accumulation(state)
    }
}

fn run(fault: Fault, case: &str) -> Result<String, String> {
    let cpu = backends::compiled()
        .into_iter()
        .find(|b| b.name == "cpu")
        .expect("cpu backend");
    let mut t = Sabotaged {
        inner: (cpu.create)(&Default::default()).expect("cpu tracer"),
        fault,
        reads: 0.into(),
    };
    let c: Case = cases::all()
        .into_iter()
        .find(|c| c.id == case)
        .expect("case");
    match c.run {
        CaseBody::Tracer(body) => body(&mut t),
        CaseBody::Kernels(_) => panic!("{case} runs kernels, not the tracer"),
    }
}

#[test]
fn faithful_wrapper_passes() {
    for case in [
        "stage-photon-pass",
        "gather-exact-arpa-constant",
        "analytic-plane-arpa",
        "camera-mirror",
        "camera-glass-slab",
        "analytic-glass-slab-arpa",
        "analytic-mirror-caustic-arpa",
        "analytic-open-mirror",
        "determinism",
        "determinism-threads",
        "resume-merge",
        "bad-input",
    ] {
        run(Fault::None, case).unwrap_or_else(|e| panic!("{case}: {e}"));
    }
}

#[test]
fn each_fault_is_caught() {
    for (fault, case) in [
        (Fault::Bright, "analytic-plane-arpa"),
        (Fault::Bright, "analytic-furnace-arpa-direct"),
        (Fault::SlightlyOff, "gather-exact-arpa-biweight"),
        (Fault::SlightlyOff, "gather-exact-rtpm"),
        (Fault::DropFootprint, "stage-photon-pass"),
        (Fault::FootprintFlux, "stage-photon-pass"),
        (Fault::Nondeterministic, "determinism"),
        (Fault::Nondeterministic, "determinism-threads"),
        (Fault::AcceptsAnything, "bad-input"),
        (Fault::QueryShift, "camera-mirror"),
        (Fault::QueryShift, "camera-glass-slab"),
        (Fault::QueryWeight, "camera-mirror"),
        (Fault::QueryWeight, "camera-glass-slab"),
        (Fault::Bright, "analytic-glass-slab-arpa"),
        (Fault::Bright, "analytic-glass-slab-rtpm"),
        (Fault::Bright, "analytic-mirror-caustic-arpa"),
        (Fault::Bright, "analytic-mirror-caustic-rtpm"),
        (Fault::Bright, "analytic-open-mirror"),
        (Fault::QueryShift, "analytic-open-mirror"),
        (Fault::QueryWeight, "analytic-open-mirror"),
        (Fault::ResumeRestartsStreams, "resume-merge"),
        (Fault::StateInF32, "resume-merge"),
    ] {
        match run(fault, case) {
            Ok(m) => panic!("{fault:?} not caught by {case}: {m}"),
            Err(e) => eprintln!("{fault:?} caught by {case}: {e}"),
        }
    }
}

/// The reference cases catch a backend that loses half the light or flips the image (each needs the shared
/// scenes: skipped loudly without them, a failure under CI). The faithful backend passing
/// them is the suite's own test (`tests/suite.rs`).
#[test]
fn reference_cases_catch_lost_light_and_flipped_images() {
    for case in cases::all()
        .iter()
        .filter(|c| c.id.starts_with("reference-"))
    {
        if let Some(Err(missing)) = case.needs.map(|f| f()) {
            // Same rule as the suite: skip loudly, fail under CI.
            assert!(!ci_is_set(), "{}: {missing} (CI is set)", case.id);
            eprintln!(
                "\n*** WARNING: sabotage check of '{}' SKIPPED: {missing} ***\n",
                case.id
            );
            continue;
        }
        // Flipping is checked on the two quickest scenes only (CI time); the limits it
        // trips (SSIM, FLIP, regions) are the same code for every scene.
        let flip = matches!(
            case.id,
            "reference-caustic-glass" | "reference-cornell-caustic"
        );
        for fault in [Fault::Half, Fault::FlippedImage]
            .into_iter()
            .filter(|f| flip || *f == Fault::Half)
        {
            match run(fault, case.id) {
                Ok(m) => panic!("{fault:?} not caught by {}: {m}", case.id),
                Err(e) => eprintln!("{fault:?} caught by {}: {e}", case.id),
            }
        }
    }
}
