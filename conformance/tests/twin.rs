//! The WGSL-twin cases on the wgpu backend's kernel runner (a GPU, else lavapipe): each
//! passes with the faithful runner, and each fails with a runner that flips bit 22 of every
//! output word (the top mantissa bit of an f32, a relative change of a third to a half; a
//! label or rng draw becomes another number). Without a ray-query adapter the tests skip
//! loudly, except when env `CI` is set, where they fail (as arpa-wgpu's own GPU tests do).
#![cfg(feature = "wgpu")]

use arpa::backends::kernel_runner::wgpu_kernel_runner;
use arpa_conformance::suite::ci_is_set;
use arpa_conformance::{BoxError, Case, CaseBody, CaseResult, KernelJob, KernelRunner, cases};

/// The wgpu kernel runner, or `None` (with a loud message) without an adapter outside CI.
fn runner() -> Option<Box<dyn KernelRunner>> {
    match wgpu_kernel_runner() {
        Ok(r) => {
            eprintln!("twin cases run on {}", r.device());
            Some(r)
        }
        Err(e) if ci_is_set() => panic!("CI needs a ray-query adapter (lavapipe): {e}"),
        Err(e) => {
            eprintln!(
                "\n*** SKIPPING the WGSL-twin cases: {e}\n*** (run `bash scripts/setup-debian.sh` to install lavapipe)\n"
            );
            None
        }
    }
}

/// A kernel case's body.
type KernelBody = fn(&dyn KernelRunner) -> CaseResult;

/// Every kernel case of the suite: the twin's cases (one per twin file or function group).
fn twin_cases() -> Vec<(Case, KernelBody)> {
    let v: Vec<_> = cases::all()
        .into_iter()
        .filter_map(|c| match c.run {
            CaseBody::Kernels(body) => Some((c, body)),
            CaseBody::Tracer(_) => None,
        })
        .collect();
    let ids: Vec<&str> = v.iter().map(|(c, _)| c.id).collect();
    assert_eq!(
        ids,
        [
            "twin-rng",
            "twin-rng-draws",
            "twin-math",
            "twin-fresnel",
            "twin-differential",
            "twin-emission",
            "twin-spot-falloff",
            "twin-texture",
            "twin-reemission",
            "twin-lambertian",
            "twin-footprint",
            "twin-heuristics",
            "twin-radius"
        ]
    );
    v
}

/// Flips bit 22 of every output word of the runner it wraps.
struct FlipBit22(Box<dyn KernelRunner>);

impl KernelRunner for FlipBit22 {
    fn device(&self) -> String {
        format!("{} with bit 22 of every output flipped", self.0.device())
    }
    fn run(&self, job: &KernelJob<'_>) -> Result<Vec<u32>, BoxError> {
        let mut out = self.0.run(job)?;
        out.iter_mut().for_each(|w| *w ^= 1 << 22);
        Ok(out)
    }
}

#[test]
fn faithful_runner_passes_every_twin_case() {
    let Some(r) = runner() else { return };
    for (case, body) in twin_cases() {
        match body(r.as_ref()) {
            Ok(m) => eprintln!("{}: {m}", case.id),
            Err(e) => panic!("{}: {e}", case.id),
        }
    }
}

#[test]
fn flipped_output_bits_fail_every_twin_case() {
    let Some(r) = runner() else { return };
    let flipped = FlipBit22(r);
    for (case, body) in twin_cases() {
        match body(&flipped) {
            Ok(m) => panic!("flipped bits not caught by {}: {m}", case.id),
            Err(e) => eprintln!(
                "flipped bits caught by {}: {}",
                case.id,
                e.chars().take(300).collect::<String>()
            ),
        }
    }
}
