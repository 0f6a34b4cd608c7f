//! The core's WGSL twin ([`arpa_core::gpu::shaders`]) against the Rust core, run on a backend's
//! [`KernelRunner`]: one case per twin file or group of functions (rng streams, rng draws
//! mirroring the core's f64 uses, math helpers, Fresnel reflectance + refraction,
//! differential, emission, spot falloff, re-emission, Lambertian shading, footprint +
//! kernel, heuristics, radius schedule, texture lookups).
//!
//! Each case runs the twin's functions on the device over random inputs (including the
//! stress ranges each module names: magnitudes over tens of decades, grazing angles,
//! near-parallel differentials, invalid inputs) and compares with the Rust functions:
//! rng bit-exact against the pinned known-answer vectors and the core's streams; floats
//! within the bound each module states and explains (the twin is f32, the core f64).
//!
//! **Inputs are deterministic.** Random inputs come from proptest's `TestRunner` seeded
//! with a fixed name (the case's id, e.g. `twin-rng`; for a case with several random
//! checks the id and the check, e.g. `twin-footprint-pack` and `twin-footprint-gather`,
//! `twin-fresnel-reflectance`, `twin-math-acos`), its bytes zero-padded to
//! 32 for ChaCha (`proptest_batches`): the same inputs on every run and every backend, so
//! a failure reproduces. `PROPTEST_*` environment variables change neither the seed nor the
//! number of batches. A batch (thousands of
//! items) is one dispatch; there is no shrinking: the failure message names the failing
//! item, the batch and the seed.
//!
//! The kernels follow the [`crate::kernel_runner`] contract: every twin file
//! ([`arpa_core::gpu::shaders::TWIN`], composed by [`arpa_core::gpu::shaders::compose`]), a prelude
//! with the two buffers and bit-cast accessors, then the case's WGSL statements per item.

use std::cell::Cell;

use arpa_core::glam::DVec3;
use proptest::strategy::Strategy;
use proptest::test_runner::{
    Config, RngAlgorithm, TestCaseError, TestCaseResult, TestError, TestRng, TestRunner,
};

use crate::kernel_runner::{KernelJob, KernelRunner, WORKGROUP_SIZE};

pub mod differential;
pub mod emission;
pub mod footprint;
pub mod fresnel;
pub mod heuristics;
pub mod lambertian;
pub mod math;
pub mod radius;
pub mod reemission;
pub mod rng;
pub mod rng_draws;
pub mod spot_falloff;
pub mod texture;

/// `check!(condition, "format", args…)`: returns `Err(message)` from the enclosing case
/// function unless `condition` holds.
macro_rules! check {
    ($cond:expr, $($msg:tt)+) => {
        let holds: bool = $cond;
        if !holds {
            return Err(format!($($msg)+));
        }
    };
}
pub(crate) use check;

/// Declarations every kernel starts with: the two buffers and bit-cast accessors.
const PRELUDE: &str = r#"
@group(0) @binding(0) var<storage, read> input: array<u32>;
@group(0) @binding(1) var<storage, read_write> output: array<u32>;
fn in_u(i: u32) -> u32 { return input[i]; }
fn in_f(i: u32) -> f32 { return bitcast<f32>(input[i]); }
fn in_v3(i: u32) -> vec3<f32> { return vec3<f32>(in_f(i), in_f(i + 1u), in_f(i + 2u)); }
fn out_u(i: u32, x: u32) { output[i] = x; }
fn out_f(i: u32, x: f32) { output[i] = bitcast<u32>(x); }
fn out_v3(i: u32, v: vec3<f32>) { out_f(i, v.x); out_f(i + 1u, v.y); out_f(i + 2u, v.z); }
"#;

/// Runs `body` (WGSL statements with `ib`/`ob`, the first input/output word of the item)
/// once per item of `input` (`in_stride` words each) on `runner`, with every twin file and
/// then `helpers` (extra WGSL declarations) before the entry point. Returns `out_stride`
/// words per item.
pub(crate) fn run_with(
    runner: &dyn KernelRunner,
    label: &str,
    helpers: &str,
    body: &str,
    input: &[u32],
    in_stride: usize,
    out_stride: usize,
) -> Result<Vec<Vec<u32>>, String> {
    if in_stride == 0 || out_stride == 0 || !input.len().is_multiple_of(in_stride) {
        return Err(format!(
            "kernel {label:?}: {} input words are not items of {in_stride} words (output {out_stride} words)",
            input.len()
        ));
    }
    let items = input.len() / in_stride;
    let invocations =
        u32::try_from(items).map_err(|_| format!("kernel {label:?}: {items} items"))?;
    let twin = arpa_core::gpu::shaders::compose(&arpa_core::gpu::shaders::TWIN);
    let source = format!(
        "{twin}\n{PRELUDE}\n{helpers}\n@compute @workgroup_size({WORKGROUP_SIZE})\nfn main(@builtin(global_invocation_id) gid: vec3<u32>) {{\n    let item = gid.x;\n    if item >= {items}u {{ return; }}\n    let ib = item * {in_stride}u;\n    let ob = item * {out_stride}u;\n{body}\n}}\n"
    );
    let out = runner
        .run(&KernelJob {
            label,
            source: &source,
            entry: "main",
            input,
            invocations,
            output_words: items * out_stride,
        })
        .map_err(|e| format!("kernel {label:?}: {e}"))?;
    if out.len() != items * out_stride {
        return Err(format!(
            "kernel {label:?}: {} output words, expected {}",
            out.len(),
            items * out_stride
        ));
    }
    Ok(out.chunks(out_stride).map(<[u32]>::to_vec).collect())
}

/// [`run_with`] without helpers.
pub(crate) fn run(
    runner: &dyn KernelRunner,
    label: &str,
    body: &str,
    input: &[u32],
    in_stride: usize,
    out_stride: usize,
) -> Result<Vec<Vec<u32>>, String> {
    run_with(runner, label, "", body, input, in_stride, out_stride)
}

/// [`run_with`] inside a proptest body (errors become test failures).
pub(crate) fn run_prop(
    runner: &dyn KernelRunner,
    label: &str,
    helpers: &str,
    body: &str,
    input: &[u32],
    in_stride: usize,
    out_stride: usize,
) -> Result<Vec<Vec<u32>>, TestCaseError> {
    run_with(runner, label, helpers, body, input, in_stride, out_stride)
        .map_err(TestCaseError::fail)
}

/// Runs `test` on `batches` values of `strategy`, drawn by proptest's `TestRunner` from the
/// fixed seed `seed` (its bytes, zero-padded to 32; ChaCha), without shrinking and without
/// failure persistence. The error names the failing batch and the seed.
pub(crate) fn proptest_batches<S: Strategy>(
    seed: &str,
    batches: u32,
    strategy: &S,
    test: impl Fn(S::Value) -> TestCaseResult,
) -> Result<(), String> {
    let mut bytes = [0u8; 32];
    let n = seed.len().min(32);
    bytes[..n].copy_from_slice(&seed.as_bytes()[..n]);
    let config = Config {
        cases: batches,
        max_shrink_iters: 0,
        failure_persistence: None,
        ..Config::default()
    };
    let mut runner =
        TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &bytes));
    let batch = Cell::new(0u32);
    runner
        .run(strategy, |v| {
            batch.set(batch.get() + 1);
            test(v)
        })
        .map_err(|e| match e {
            TestError::Fail(reason, _) => format!(
                "{reason} (batch {} of {batches}, proptest seed {seed:?})",
                batch.get()
            ),
            TestError::Abort(reason) => format!("proptest aborted: {reason} (seed {seed:?})"),
        })
}

/// Bits of an `f32` (the kernels' input format).
pub(crate) fn fb(x: f32) -> u32 {
    x.to_bits()
}

/// Pushes the bits of three `f32`.
pub(crate) fn push3(v: &mut Vec<u32>, x: [f32; 3]) {
    v.extend(x.map(f32::to_bits));
}

/// Reads an `f32` from output bits.
pub(crate) fn f(bits: u32) -> f32 {
    f32::from_bits(bits)
}

/// Reads three `f32` starting at `i`, widened to f64.
pub(crate) fn v3(words: &[u32], i: usize) -> DVec3 {
    DVec3::new(
        f(words[i]) as f64,
        f(words[i + 1]) as f64,
        f(words[i + 2]) as f64,
    )
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use proptest::prelude::*;

    use super::proptest_batches;

    fn draw(seed: &str) -> Vec<u64> {
        let v = RefCell::new(Vec::new());
        proptest_batches(seed, 3, &any::<u64>(), |x| {
            v.borrow_mut().push(x);
            Ok(())
        })
        .expect("no failure");
        v.into_inner()
    }

    #[test]
    fn batches_come_from_the_fixed_seed() {
        let a = draw("twin-a");
        assert_eq!(a.len(), 3);
        assert_eq!(a, draw("twin-a"));
        assert_ne!(a, draw("twin-b"));
    }

    #[test]
    fn a_failure_names_its_batch_and_seed_and_is_not_shrunk() {
        let runs = RefCell::new(0);
        let e = proptest_batches("twin-c", 4, &(0u32..1000), |x| {
            *runs.borrow_mut() += 1;
            prop_assert!(*runs.borrow() < 2, "value {}", x);
            Ok(())
        })
        .expect_err("the second batch fails");
        assert!(
            e.contains("(batch 2 of 4, proptest seed \"twin-c\")"),
            "{e}"
        );
        assert_eq!(runs.into_inner(), 2, "no shrinking runs");
    }
}
