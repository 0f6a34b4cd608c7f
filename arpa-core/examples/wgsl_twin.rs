//! The core's WGSL twin in one's own wgpu compute shader: emit photons from a point light,
//! move them onto a floor and build their footprint records on the GPU, with the core's
//! WGSL files composed by [`arpa_core::gpu::shaders::compose_with`] under a small user kernel, and
//! check every photon against the Rust core.
//!
//! The host prepares the light once per iteration (`Light::prepare`) and uploads its
//! 160-byte record (`PreparedLight::pack`, the WGSL `ArpaLight`). Invocation `i` of the user
//! kernel then does what a renderer's photon pass does for a point light over the floor
//! `z = 0`: `arpa_emit` photon `i` (its own stream `arpa_rng_new(seed, iteration, i,
//! ARPA_DOMAIN_PHOTON)`), `arpa_diff_transfer` it to the floor (`t = −p.z/d.z`, computed
//! here), `arpa_footprint_pack` its footprint, and evaluates the footprint's irradiance
//! at one floor point (`arpa_footprint_irradiance`, Silverman kernel). The Rust side runs
//! `PreparedLight::emit`, `RayDifferential::transfer`, `Footprint::from_hit`,
//! `Footprint::pack` and `PackedFootprint::irradiance` on the same photon.
//!
//! Tolerance: WGSL is `f32` where the core is `f64`, and the twin's lattice point differs
//! from the core's by a few `f32` ulps, which moves a direction by that much times the
//! sphere map's Jacobian (large next to the poles). Photons leaving within `MIN_COS_DOWN`
//! of the horizon are left out (the transfer's error grows like `1/|d.z|` and they land far
//! away). The landing point must agree to `TOL` times `max(|p|, 1 m)`, the filter rows and
//! the flux density to `TOL` relative, the irradiance at the query point to `TOL` times the
//! footprint's flux density, and the status (heads up, or stored) exactly. `TOL` is some
//! hundred `f32` ulps: far above the twin's rounding (a few ulps times the step's
//! condition, see `arpa_core::gpu::shaders`), far below any real mismatch (a wrong layout field,
//! differential or lattice index moves results by whole percent).
//!
//! Without a wgpu adapter (no Vulkan driver) it prints that it skipped and exits 0, or 1
//! when the environment variable `CI` is set (CI must run it). Lavapipe is enough.
//! Run: `cargo run -p arpa-core --example wgsl_twin`.

use arpa_core::emit::emission::{EmissionParams, Light, PointLight};
use arpa_core::store::footprint::{Footprint, FootprintError, PhotonMap};
use arpa_core::glam::{DVec3, Vec3};
use arpa_core::gather::kernel::Kernel;
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::gpu::shaders::{compose_with, EMISSION, FOOTPRINT};

const PHOTONS: u32 = 4096;
const SEED: u32 = 7;
const ITERATION: u32 = 3;
/// Slab limit of the records (the map's progressive radius in a renderer), metres.
const RADIUS: f32 = 0.05;
/// Photons heading down more steeply than this cosine are compared.
const MIN_COS_DOWN: f64 = 0.2;
const TOL: f64 = 2e-5;
const QUERY: Vec3 = Vec3::new(0.3, -0.2, 0.0);

/// One photon's result, as the user kernel writes it (48 bytes, WGSL `UserResult`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct UserResult {
    p: [f32; 3],
    /// 0 stored, 1 heads up (no floor), 10 + code: emission, 20 + code: transfer,
    /// 30 + code: packing failed (the WGSL files' status codes).
    status: u32,
    row_u: [f32; 3],
    density: f32,
    row_v: [f32; 3],
    irradiance: f32,
}

/// The user kernel: one invocation per photon. It needs the emission and footprint files
/// (and, through them, rng, frame, sampling, differential and kernel); `compose_with` puts them
/// first (`compose_with`). Seed, iteration, slab limit and query point are constants `main`
/// writes before it.
const USER_KERNEL: &str = r#"
@group(0) @binding(0) var<storage, read> user_light: ArpaLight;
@group(0) @binding(1) var<storage, read_write> user_results: array<UserResult>;

struct UserResult {
    p: vec3<f32>,
    status: u32,
    row_u: vec3<f32>,
    density: f32,
    row_v: vec3<f32>,
    irradiance: f32,
}

@compute @workgroup_size(64)
fn user_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= user_light.photon_count {
        return;
    }
    var r: UserResult;
    var rng = arpa_rng_new(USER_SEED, USER_ITERATION, i, ARPA_DOMAIN_PHOTON);
    let e = arpa_emit(user_light, i, &rng);
    let up = vec3<f32>(0.0, 0.0, 1.0);
    if e.status != ARPA_DIFF_OK {
        r.status = 10u + e.status;
    } else if e.ray.d.z >= 0.0 {
        r.status = 1u;
    } else {
        let hit = arpa_diff_transfer(e.ray, -e.ray.p.z / e.ray.d.z, up);
        if hit.status != ARPA_DIFF_OK {
            r.status = 20u + hit.status;
        } else {
            // The floor's normal faces the arriving photon: +z.
            let packed = arpa_footprint_pack(hit.ray.p, up, hit.ray.dp_du, hit.ray.dp_dv, e.flux, 1u, USER_RADIUS);
            r.p = hit.ray.p;
            r.status = select(30u + packed.status, 0u, packed.status == ARPA_FOOTPRINT_OK);
            r.row_u = packed.fp.row_u;
            r.row_v = packed.fp.row_v;
            r.density = packed.fp.flux_density_r;
            r.irradiance = arpa_footprint_irradiance(packed.fp, USER_QUERY, up, ARPA_KERNEL_SILVERMAN).x;
        }
    }
    user_results[i] = r;
}
"#;

/// The same photon by the Rust core, with the kernel's status codes.
fn core_result(light: &arpa_core::emit::emission::PreparedLight, i: u32) -> UserResult {
    let mut rng = Rng::new(SEED, ITERATION, i, StreamDomain::Photon);
    let e = light.emit(i, &mut rng).expect("a point light always emits");
    if e.ray.d.z >= 0.0 {
        return UserResult { status: 1, ..Default::default() };
    }
    let hit = match e.ray.transfer(-e.ray.p.z / e.ray.d.z, DVec3::Z) {
        Ok(hit) => hit,
        Err(_) => return UserResult { status: 20, ..Default::default() },
    };
    let fp = Footprint::from_hit(&hit, DVec3::Z, e.flux, PhotonMap::Global).expect("the floor normal is valid");
    let packed = match fp.pack(RADIUS as f64) {
        Ok(packed) => packed,
        Err(FootprintError::Degenerate) => return UserResult { status: 31, ..Default::default() },
        Err(FootprintError::Unrepresentable) => return UserResult { status: 32, ..Default::default() },
        Err(FootprintError::InvalidNormal) => return UserResult { status: 33, ..Default::default() },
    };
    UserResult {
        p: hit.p.as_vec3().to_array(),
        status: 0,
        row_u: packed.row_u,
        density: packed.flux_density_r,
        row_v: packed.row_v,
        irradiance: packed.irradiance(QUERY, Vec3::Z, Kernel::Silverman).x,
    }
}

/// Runs the composed module on the first adapter wgpu finds; `None` when there is none.
fn run_on_gpu(source: &str, light: &arpa_core::emit::emission::PackedLight) -> Option<(String, Vec<UserResult>)> {
    use wgpu::util::DeviceExt;
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::PRIMARY,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY)).into_iter().next()?;
    let name = adapter.get_info().name;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor::default())).expect("a device");
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("user"), source: wgpu::ShaderSource::Wgsl(source.into()) });
    // The layout comes from the shader (bindings 0 and 1 of group 0).
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("user"),
        layout: None,
        module: &module,
        entry_point: Some("user_main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let storage = wgpu::BufferUsages::STORAGE;
    let light_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some("light"), contents: bytemuck::bytes_of(light), usage: storage });
    let bytes = (PHOTONS as usize * size_of::<UserResult>()) as u64;
    let buffer = |usage| device.create_buffer(&wgpu::BufferDescriptor { label: None, size: bytes, usage, mapped_at_creation: false });
    let results = buffer(storage | wgpu::BufferUsages::COPY_SRC);
    let staging = buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: light_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: results.as_entire_binding() },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(PHOTONS.div_ceil(64), 1, 1);
    }
    encoder.copy_buffer_to_buffer(&results, 0, &staging, 0, bytes);
    queue.submit([encoder.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |r| r.expect("mapping the results"));
    device.poll(wgpu::PollType::wait_indefinitely()).expect("the device finishes");
    let out = bytemuck::pod_collect_to_vec(&staging.get_mapped_range(..).expect("mapped results"));
    Some((name, out))
}

fn main() {
    let light = Light::Point(PointLight { position: DVec3::new(0.0, 0.0, 1.0), intensity: DVec3::splat(2.0) });
    let prepared = light.prepare(&EmissionParams::new(PHOTONS).for_iteration(SEED, ITERATION, 0)).expect("a valid light");
    // The module: the core files the kernel calls (with everything they need, in order),
    // then the user's constants and kernel.
    let constants = format!(
        "const USER_SEED: u32 = {SEED}u;\nconst USER_ITERATION: u32 = {ITERATION}u;\nconst USER_RADIUS: f32 = {RADIUS:?};\nconst USER_QUERY: vec3<f32> = vec3<f32>({:?}, {:?}, {:?});\n",
        QUERY.x, QUERY.y, QUERY.z
    );
    let source = compose_with(&[&EMISSION, &FOOTPRINT], &(constants + USER_KERNEL));

    let Some((adapter, gpu)) = run_on_gpu(&source, &prepared.pack()) else {
        println!("!!! skipped: no wgpu adapter (install a Vulkan driver, e.g. lavapipe) !!!");
        std::process::exit(if std::env::var_os("CI").is_some() { 1 } else { 0 });
    };
    let (mut compared, mut worst, mut bad) = (0u32, 0.0f64, 0u32);
    let (mut sum_gpu, mut sum_core) = (0.0f64, 0.0f64);
    for (i, g) in gpu.iter().enumerate() {
        let i = i as u32;
        let d = prepared.emit(i, &mut Rng::new(SEED, ITERATION, i, StreamDomain::Photon)).expect("a point light always emits").ray.d;
        if d.z < 0.0 && -d.z < MIN_COS_DOWN {
            continue; // near the horizon: see the module docs
        }
        let c = core_result(&prepared, i);
        compared += 1;
        let v = |a: [f32; 3]| Vec3::from_array(a).as_dvec3();
        let rel = |a: [f32; 3], b: [f32; 3], scale: f64| (v(a) - v(b)).length() / scale;
        let errors = if g.status != c.status {
            vec![f64::INFINITY]
        } else if c.status != 0 {
            vec![]
        } else {
            let density = c.density as f64;
            vec![
                rel(g.p, c.p, v(c.p).length().max(1.0)),
                rel(g.row_u, c.row_u, v(c.row_u).length()),
                rel(g.row_v, c.row_v, v(c.row_v).length()),
                (g.density as f64 - density).abs() / density,
                (g.irradiance as f64 - c.irradiance as f64).abs() / density,
            ]
        };
        let e = errors.into_iter().fold(0.0, f64::max);
        sum_gpu += g.irradiance as f64;
        sum_core += c.irradiance as f64;
        worst = worst.max(e);
        if e > TOL {
            bad += 1;
            if bad <= 5 {
                println!("photon {i}: GPU {g:?}\n          core {c:?}");
            }
        }
    }
    println!("adapter {adapter:?}: {compared} of {PHOTONS} photons compared, largest relative difference {worst:.2e} (tolerance {TOL:.0e})");
    println!("irradiance at {QUERY} from this iteration's footprints: GPU {sum_gpu:.6} W/m², core {sum_core:.6} W/m²");
    if bad > 0 || compared == 0 {
        println!("FAILED: {bad} photons differ");
        std::process::exit(1);
    }
}
