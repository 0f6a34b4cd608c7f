//! The suite runs on a tracer from outside the facade's registry ([`Backend::external`]),
//! as a renderer author's own tests would: a type of this file that implements
//! [`Tracer`] by handing every call to the CPU backend passes a few quick cases, and a
//! second one that doubles every image fails the physics case that measures radiance (so
//! the external path really runs the cases and cannot pass vacuously).
#![cfg(feature = "cpu")]

use arpa_conformance::suite::AVAILABILITY_ROW;
use arpa_conformance::{Backend, Case, SuiteOptions, Verdict, cases, run_suite_with};
use arpa_core::accumulate::image::Accumulation;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::scene::Scene;
use arpa_core::render::tracer::{Capabilities, Image, IterationStats, QueryRecord, RenderSettings, Tracer};
use arpa_cpu::{CpuError, CpuTracer};

/// A renderer that is not in the registry: the CPU backend behind a type of its own,
/// `SCALE` times every pixel of its image (1: faithful; 2: a lost factor of two, as from
/// a light counted twice).
struct Outside<const SCALE: u32>(CpuTracer);

impl<const SCALE: u32> Tracer for Outside<SCALE> {
    type Error = CpuError;

    fn capabilities(&self) -> Capabilities {
        self.0.capabilities()
    }
    fn upload_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<(), CpuError> {
        self.0.upload_scene(scene, settings)
    }
    fn camera_pass(&mut self) -> Result<(), CpuError> {
        self.0.camera_pass()
    }
    fn photon_pass(&mut self) -> Result<(), CpuError> {
        self.0.photon_pass()
    }
    fn build_acceleration_structure(&mut self) -> Result<(), CpuError> {
        self.0.build_acceleration_structure()
    }
    fn gather(&mut self) -> Result<(), CpuError> {
        self.0.gather()
    }
    fn accumulate(&mut self) -> Result<(), CpuError> {
        self.0.accumulate()
    }
    fn iterate(&mut self) -> Result<(), CpuError> {
        self.0.iterate()
    }
    fn iterations(&self) -> u32 {
        self.0.iterations()
    }
    fn read_image(&self) -> Result<Image, CpuError> {
        let mut image = self.0.read_image()?;
        image.pixels.iter_mut().for_each(|p| *p *= SCALE as f32);
        Ok(image)
    }
    fn read_query_points(&self) -> Result<Vec<QueryRecord>, CpuError> {
        self.0.read_query_points()
    }
    fn read_footprints(&self) -> Result<Vec<PackedFootprint>, CpuError> {
        self.0.read_footprints()
    }
    fn read_photons(&self) -> Result<Vec<PackedPhoton>, CpuError> {
        self.0.read_photons()
    }
    fn read_stats(&self) -> Result<IterationStats, CpuError> {
        self.0.read_stats()
    }
    fn read_accumulation(&self) -> Result<Accumulation, CpuError> {
        self.0.read_accumulation()
    }
    fn restore_accumulation(&mut self, state: &Accumulation) -> Result<(), CpuError> {
        self.0.restore_accumulation(state)
    }
}

/// The faithful outside tracer, as a renderer author declares it.
const FAITHFUL: Backend =
    Backend::external("outside", |_| Ok(Box::new(Outside::<1>(CpuTracer::new()?))));
/// The outside tracer whose images are twice too bright.
const DOUBLED: Backend = Backend::external("outside-doubled", |_| {
    Ok(Box::new(Outside::<2>(CpuTracer::new()?)))
});

/// Quick cases (seconds together): photon-pass agreement with the core, exact gather, the
/// radiance over a lit plane against its closed form, rejection of bad scenes.
const QUICK: [&str; 4] = [
    "stage-photon-pass",
    "gather-exact-arpa-constant",
    "analytic-plane-arpa",
    "bad-input",
];

fn case(id: &str) -> Case {
    cases::all()
        .into_iter()
        .find(|c| c.id == id)
        .unwrap_or_else(|| panic!("no case '{id}'"))
}

#[test]
fn the_suite_runs_on_a_tracer_outside_the_registry() {
    let options = SuiteOptions {
        required: vec![FAITHFUL.name.into(), DOUBLED.name.into()],
        filter: QUICK.map(String::from).to_vec(),
    };
    let run = run_suite_with(&[FAITHFUL, DOUBLED], &cases::all(), &options);
    let md = run.to_markdown();
    eprintln!("{md}");
    let report = &run.report;
    let device = CpuTracer::new().expect("cpu tracer").capabilities().device;
    for backend in [FAITHFUL.name, DOUBLED.name] {
        assert!(
            run.devices.contains(&(backend.to_owned(), device.clone())),
            "{backend} did not start: {md}"
        );
        assert!(
            matches!(
                report.get(AVAILABILITY_ROW, backend),
                Some(Verdict::Pass { .. })
            ),
            "{md}"
        );
    }
    // The faithful tracer passes every case it ran, and it ran each of them.
    for id in QUICK {
        let v = report.get(case(id).title, FAITHFUL.name);
        assert!(
            matches!(v, Some(Verdict::Pass { .. })),
            "{id} on the faithful tracer: {v:?}\n{md}"
        );
    }
    // Twice the radiance of the closed form fails the plane case, and so the run.
    let v = report.get(case("analytic-plane-arpa").title, DOUBLED.name);
    assert!(
        matches!(v, Some(Verdict::Fail { .. })),
        "doubled image not caught: {v:?}\n{md}"
    );
    assert!(
        !report.all_ok() && md.contains("**unexpected failures**"),
        "{md}"
    );
    // Nothing else ran: the table is the availability row and the quick cases.
    assert_eq!(
        report.to_markdown().lines().count(),
        2 + 1 + QUICK.len(),
        "{md}"
    );
}
