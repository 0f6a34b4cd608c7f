//! Every WGSL file of the core validates with naga (no GPU needed): the twin files alone
//! with their dependencies and all together (no name collisions), each module of the
//! backend (the core's path-level files with the ray-query glue), and a file without its
//! dependencies or with a type error is rejected. The records the kernels exchange have
//! the layouts of their Rust twins in `arpa_core::gpu::layout` (naga's struct layout
//! against `size_of` / `offset_of`).

use arpa_core::emit::emission::PackedLight;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::gpu::layout::*;
use arpa_core::gpu::sort::{SortItem, SortStep};
use arpa_core::store::heuristics::PackedHeuristics;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::gpu::shaders::{self, WgslFile, compose};
use arpa_core::render::tracer::QueryRecord;
use std::mem::{offset_of, size_of};

fn parse(label: &str, source: &str) -> naga::Module {
    naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{label}: WGSL parse error:\n{}", e.emit_to_string_with_path(source, label)))
}

fn validate_with(label: &str, source: &str, capabilities: naga::valid::Capabilities) -> naga::Module {
    let module = parse(label, source);
    let mut validator = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), capabilities);
    if let Err(e) = validator.validate(&module) {
        panic!("{label}: naga validation error:\n{}", e.emit_to_string_with_path(source, label));
    }
    // Nothing may be silently dropped: every file defines functions or entry points.
    assert!(!module.functions.is_empty() || !module.entry_points.is_empty(), "{label}: no functions");
    module
}

fn validate(label: &str, source: &str) -> naga::Module {
    validate_with(label, source, naga::valid::Capabilities::empty())
}

#[test]
fn each_twin_file_validates_with_its_dependencies() {
    for file in shaders::TWIN {
        validate(file.name, &compose(&[file]));
    }
}

#[test]
fn all_twin_files_together_validate() {
    validate("all twin files", &compose(&shaders::TWIN));
}

#[test]
fn a_file_without_its_dependencies_is_rejected() {
    // The dependency table is needed: emission.wgsl alone does not validate.
    let alone = naga::front::wgsl::parse_str(shaders::EMISSION.source)
        .ok()
        .is_some_and(|m| naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty()).validate(&m).is_ok());
    assert!(!alone, "emission.wgsl validated without its dependencies");
}

#[test]
fn a_broken_file_is_rejected() {
    // The check itself can fail: a type error in the twin is caught.
    let broken = shaders::RADIUS.source.replace("let i = max(iteration, 1u);", "let i = max(iteration, 1.0);");
    assert_ne!(broken, shaders::RADIUS.source);
    let ok = naga::front::wgsl::parse_str(&broken)
        .ok()
        .is_some_and(|m| naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty()).validate(&m).is_ok());
    assert!(!ok, "a mistyped radius.wgsl validated");
}

/// Every module the backend compiles.
fn modules() -> Vec<(&'static str, String)> {
    use arpa_wgpu::shaders as s;
    vec![
        ("scene", s::scene()),
        ("camera pass", s::camera_pass()),
        ("photon pass", s::photon_pass()),
        ("store", s::store()),
        ("store schedule", s::schedule()),
        ("sort", s::sort()),
        ("gather", s::gather()),
        ("accumulate", s::accumulate()),
    ]
}

#[test]
fn backend_modules_validate() {
    for (label, source) in modules() {
        validate_with(label, &source, naga::valid::Capabilities::RAY_QUERY);
    }
}

#[test]
fn path_files_are_plain_wgsl_without_ray_queries() {
    // The ray casting is the backend's glue: a backend on ray-tracing pipelines supplies its own.
    for file in shaders::PATH {
        assert!(!file.source.contains("ray_query") && !file.source.contains("rayQuery") && !file.source.contains("acceleration_structure"), "{}", file.name);
    }
    let glue: [&WgslFile; 2] = [&arpa_wgpu::shaders::SCENE_RAY_QUERY, &arpa_wgpu::shaders::GATHER_RAY_QUERY];
    for file in glue {
        assert!(file.source.contains("enable wgpu_ray_query;"), "{}", file.name);
    }
}

/// The struct `name` of `module`: its size and the offsets of its members by name.
fn wgsl_struct(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
    let ty = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(name)).unwrap_or_else(|| panic!("no WGSL struct {name}"));
    match &ty.1.inner {
        naga::TypeInner::Struct { members, span } => (*span, members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect()),
        other => panic!("{name} is not a struct: {other:?}"),
    }
}

#[test]
fn records_have_the_layouts_of_their_rust_twins() {
    let parsed: Vec<naga::Module> = modules().iter().map(|(l, s)| parse(l, s)).collect();
    // (WGSL name, Rust size, [(WGSL member, Rust offset)])
    type Check = (&'static str, usize, Vec<(&'static str, usize)>);
    let checks: Vec<Check> = vec![
        ("ArpaKeyedFootprint", size_of::<KeyedFootprint>(), vec![("center", 0), ("map", 12), ("normal", 16), ("du", 32), ("dv", 48), ("flux", 64), ("key", offset_of!(KeyedFootprint, key))]),
        ("ArpaKeyedPhoton", size_of::<KeyedPhoton>(), vec![("position", 0), ("map", 12), ("normal", 16), ("flux", 32), ("key", offset_of!(KeyedPhoton, key))]),
        ("ArpaPackedPhoton", size_of::<PackedPhoton>(), vec![("position", offset_of!(PackedPhoton, position)), ("map", offset_of!(PackedPhoton, map)), ("normal", offset_of!(PackedPhoton, normal)), ("flux", offset_of!(PackedPhoton, flux))]),
        ("ArpaPackedFootprint", size_of::<PackedFootprint>(), vec![]),
        ("ArpaQueryRecord", size_of::<QueryRecord>(), vec![("position", offset_of!(QueryRecord, position)), ("pixel", offset_of!(QueryRecord, pixel)), ("normal", offset_of!(QueryRecord, normal)), ("valid", offset_of!(QueryRecord, valid)), ("weight", offset_of!(QueryRecord, weight)), ("radiance", offset_of!(QueryRecord, radiance))]),
        ("ArpaSortItem", size_of::<SortItem>(), vec![("hi", 0), ("lo", 4), ("value", 8)]),
        ("SortStep", 16, vec![("k", offset_of!(SortStep, k)), ("j", offset_of!(SortStep, j))]),
        ("PhotonParams", size_of::<PhotonParams>(), vec![("photon_count", 0), ("first_photon", offset_of!(PhotonParams, first_photon)), ("smoothing", offset_of!(PhotonParams, smoothing))]),
        ("PhotonEmitterRange", size_of::<EmitterRange>(), vec![("first_index", 0), ("count", 4), ("valid", 8)]),
        ("PhotonCounters", size_of::<PhotonCounters>(), vec![("emitted", 0), ("differential_lost", offset_of!(PhotonCounters, differential_lost)), ("photon_overflowed", offset_of!(PhotonCounters, photon_overflowed))]),
        ("ArpaLight", size_of::<PackedLight>(), vec![("cell_offset", offset_of!(PackedLight, cell_offset)), ("emission_record", offset_of!(PackedLight, emission_record))]),
        ("ArpaHeuristics", size_of::<PackedHeuristics>(), vec![]),
        ("StoreParams", size_of::<StoreParams>(), vec![("radii", offset_of!(StoreParams, radii)), ("scene_lo", offset_of!(StoreParams, scene_lo)), ("raw_count", offset_of!(StoreParams, raw_count)), ("scene_inv", offset_of!(StoreParams, scene_inv)), ("photon_count", offset_of!(StoreParams, photon_count)), ("fp_sorted", offset_of!(StoreParams, fp_sorted)), ("ph_sorted", offset_of!(StoreParams, ph_sorted))]),
        ("ArpaScheduleCounters", size_of::<PhotonCounters>(), vec![("footprint_appends", offset_of!(PhotonCounters, footprint_appends)), ("photon_appends", offset_of!(PhotonCounters, photon_appends)), ("footprint_overflowed", offset_of!(PhotonCounters, footprint_overflowed)), ("photon_overflowed", offset_of!(PhotonCounters, photon_overflowed))]),
        ("ArpaScheduleStoreParams", size_of::<StoreParams>(), vec![("radii", offset_of!(StoreParams, radii)), ("scene_lo", offset_of!(StoreParams, scene_lo)), ("raw_count", offset_of!(StoreParams, raw_count)), ("scene_inv", offset_of!(StoreParams, scene_inv)), ("photon_count", offset_of!(StoreParams, photon_count)), ("fp_sorted", offset_of!(StoreParams, fp_sorted)), ("ph_sorted", offset_of!(StoreParams, ph_sorted))]),
        ("ArpaGatherResult", size_of::<GatherResult>(), vec![("caustic", 0), ("caustic_count", 12), ("global", 16), ("global_count", 28), ("candidates", 32), ("pad", 40), ("scaled", offset_of!(GatherResult, scaled))]),
        ("GatherImageParams", size_of::<GatherImageParams>(), vec![("radii", 0), ("kernel", 8), ("pixels", 12), ("batch", 16), ("scales", offset_of!(GatherImageParams, scales))]),
        ("AccumPixel", size_of::<AccumPixel>(), vec![("sum", 0), ("rejected", 12), ("compensation", 16)]),
        ("ArpaCameraParams", size_of::<CameraParams>(), vec![("position", 0), ("width", 12), ("forward", 16), ("height", 28), ("right", 32), ("tan_half_fov", 44), ("up", 48), ("aspect", 60), ("seed", 64), ("iteration", 68), ("max_depth", 72), ("direct_lighting", 76), ("pixel_count", 80), ("row_invocations", 84)]),
        ("ArpaSceneInfo", size_of::<SceneInfo>(), vec![("mesh_count", 0), ("delta_count", 4), ("area_count", 8), ("has_masks", 12), ("sphere_centre", 16), ("sphere_radius", 28)]),
        ("ArpaSceneMesh", size_of::<SceneMesh>(), vec![("first_triangle", 0), ("kind", 8), ("color", 16), ("ior", 28), ("emission", 32), ("has_normals", 44), ("color_texture", 48), ("opacity_texture", 52), ("opacity", 56), ("uv_first", 60), ("emission_texture", 64)]),
        ("ArpaSceneTriangle", size_of::<SceneTriangle>(), vec![("p0", 0), ("flags", 12), ("p1", 16), ("blas_triangle", 28), ("p2", 32), ("normal", 48), ("n0", 64), ("n1", 80), ("n2", 96)]),
        ("ArpaSceneEmitter", size_of::<SceneEmitter>(), vec![("kind", 0), ("falloff", 4), ("cutoff", 8), ("beam_width", 12), ("p0", 16), ("cdf", 28), ("p1", 32), ("probability", 44), ("p2", 48), ("emission_record", 60), ("color", 64)]),
    ];
    for (name, size, members) in checks {
        let module = parsed.iter().find(|m| m.types.iter().any(|(_, t)| t.name.as_deref() == Some(name))).unwrap_or_else(|| panic!("no module declares {name}"));
        let (span, offsets) = wgsl_struct(module, name);
        assert_eq!(span as usize, size, "{name}: WGSL size {span}, Rust {size}");
        for (member, offset) in members {
            let got = offsets.iter().find(|(n, _)| n == member).unwrap_or_else(|| panic!("{name} has no member {member}")).1;
            assert_eq!(got as usize, offset, "{name}.{member}");
        }
    }
}

/// `bandwidth.wgsl`'s ladder constants are the core's (`arpa_core::gather::scales`).
#[test]
fn bandwidth_constants_are_the_cores() {
    use arpa_core::gather::scales::{MOMENT_PLANES, PLANES, SCALES};
    let module = parse("bandwidth", &compose(&[&shaders::BANDWIDTH]));
    for (name, want) in [("ARPA_SCALES", SCALES), ("ARPA_MOMENT_PLANES", MOMENT_PLANES), ("ARPA_PLANES", PLANES)] {
        let (_, c) = module.constants.iter().find(|(_, c)| c.name.as_deref() == Some(name)).unwrap_or_else(|| panic!("no constant {name}"));
        match module.global_expressions[c.init] {
            naga::Expression::Literal(naga::Literal::U32(v)) => assert_eq!(v as usize, want, "{name}"),
            ref other => panic!("{name} = {other:?}"),
        }
    }
}
