//! Shared test support: the GPU context (lavapipe in CI) and a runner for WGSL test kernels
//! written against the core's twin.
#![allow(dead_code)]

use arpa_wgpu::{AdapterChoice, GpuContext, run_kernel};
use std::sync::OnceLock;

/// The device every test uses, or `None` (with a loud message) when no adapter with ray
/// queries exists outside CI. In CI (env `CI` set) a missing device fails the test.
pub fn gpu() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| match GpuContext::new(&AdapterChoice::Auto) {
        Ok(ctx) => {
            eprintln!("arpa-wgpu tests run on adapter {:?} ({:?})", ctx.info.name, ctx.info.device_type);
            Some(ctx)
        }
        Err(e) if std::env::var_os("CI").is_some() => panic!("CI needs a ray-query adapter (lavapipe): {e}"),
        Err(e) => {
            eprintln!("\n*** SKIPPING arpa-wgpu GPU tests: {e}\n*** (run `bash scripts/setup-debian.sh` to install lavapipe)\n");
            None
        }
    })
    .as_ref()
}

/// Declarations every test kernel starts with: the two buffers and bit-cast accessors.
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
/// once per item of `input` (`in_stride` words each), with every twin file included.
/// Returns `out_stride` words per item.
pub fn run(ctx: &GpuContext, label: &str, body: &str, input: &[u32], in_stride: usize, out_stride: usize) -> Vec<Vec<u32>> {
    run_with(ctx, label, "", body, input, in_stride, out_stride)
}

/// [`run`] with extra WGSL declarations (`helpers`) placed before the entry point.
pub fn run_with(ctx: &GpuContext, label: &str, helpers: &str, body: &str, input: &[u32], in_stride: usize, out_stride: usize) -> Vec<Vec<u32>> {
    assert_eq!(input.len() % in_stride, 0);
    let items = input.len() / in_stride;
    let twin = arpa_core::gpu::shaders::compose(&arpa_core::gpu::shaders::TWIN);
    let source = format!(
        "{twin}\n{PRELUDE}\n{helpers}\n@compute @workgroup_size(64)\nfn main(@builtin(global_invocation_id) gid: vec3<u32>) {{\n    let item = gid.x;\n    if item >= {items}u {{ return; }}\n    let ib = item * {in_stride}u;\n    let ob = item * {out_stride}u;\n{body}\n}}\n"
    );
    let out = run_kernel(ctx, label, &source, "main", input, items as u32, items * out_stride)
        .unwrap_or_else(|e| panic!("{e}"));
    out.chunks(out_stride).map(|c| c.to_vec()).collect()
}

/// Bits of an `f32` (the harness's input format).
pub fn fb(x: f32) -> u32 {
    x.to_bits()
}

/// Pushes the bits of three `f32`.
pub fn push3(v: &mut Vec<u32>, x: [f32; 3]) {
    v.extend(x.map(f32::to_bits));
}

/// Reads an `f32` from output bits.
pub fn f(bits: u32) -> f32 {
    f32::from_bits(bits)
}

/// Reads three `f32` starting at `i`.
pub fn v3(words: &[u32], i: usize) -> glam::DVec3 {
    glam::DVec3::new(f(words[i]) as f64, f(words[i + 1]) as f64, f(words[i + 2]) as f64)
}
