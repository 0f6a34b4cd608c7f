//! Every WGSL file of the core's twin parses and validates with naga (no GPU needed), alone
//! with its dependencies and all together (no name collisions), and a module that uses it
//! from an entry point validates too.

use arpa_core::shaders;

fn validate(label: &str, source: &str) {
    let module = match naga::front::wgsl::parse_str(source) {
        Ok(m) => m,
        Err(e) => panic!("{label}: WGSL parse error:\n{}", e.emit_to_string_with_path(source, label)),
    };
    let mut validator = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty());
    if let Err(e) = validator.validate(&module) {
        panic!("{label}: naga validation error:\n{}", e.emit_to_string_with_path(source, label));
    }
    // Nothing may be silently dropped: every file defines functions.
    assert!(!module.functions.is_empty(), "{label}: no functions");
}

#[test]
fn each_file_validates_with_its_dependencies() {
    for (name, source) in shaders::ALL {
        let deps: Vec<&str> = shaders::dependencies(name)
            .iter()
            .map(|d| shaders::ALL.iter().find(|(n, _)| n == d).unwrap_or_else(|| panic!("{name}: unknown dependency {d}")).1)
            .collect();
        validate(name, &format!("{}\n{}", deps.join("\n"), source));
    }
}

#[test]
fn all_files_together_validate() {
    let all: String = shaders::ALL.iter().map(|(_, s)| *s).collect::<Vec<_>>().join("\n");
    validate("all twin files", &all);
}

#[test]
fn dependencies_come_first_in_all() {
    for (i, (name, _)) in shaders::ALL.iter().enumerate() {
        for d in shaders::dependencies(name) {
            let j = shaders::ALL.iter().position(|(n, _)| n == d).expect("dependency listed in ALL");
            assert!(j < i, "{name} needs {d}, which comes after it in ALL");
        }
    }
}

#[test]
fn a_file_without_its_dependencies_is_rejected() {
    // The dependency list is needed: emission.wgsl alone does not validate.
    assert!(naga::front::wgsl::parse_str(shaders::EMISSION).is_err() || {
        let m = naga::front::wgsl::parse_str(shaders::EMISSION).unwrap();
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty()).validate(&m).is_err()
    });
}

#[test]
fn gather_kernel_validates() {
    let src = format!("enable wgpu_ray_query;\n{}\n{}\n{}", shaders::KERNEL, shaders::FOOTPRINT, arpa_wgpu::gather::GATHER_WGSL);
    let module = naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("gather.wgsl: {}", e.emit_to_string(&src)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::RAY_QUERY)
        .validate(&module)
        .unwrap_or_else(|e| panic!("gather.wgsl: {}", e.emit_to_string(&src)));
}

#[test]
fn ray_cast_kernel_validates() {
    let src = format!("enable wgpu_ray_query;\n{}", arpa_wgpu::scene::RAY_CAST_WGSL);
    let module = naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("ray_cast.wgsl: {}", e.emit_to_string(&src)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::RAY_QUERY)
        .validate(&module)
        .unwrap_or_else(|e| panic!("ray_cast.wgsl: {}", e.emit_to_string(&src)));
}

#[test]
fn store_kernel_validates() {
    let src = format!("{}\n{}\n{}\n{}", shaders::KERNEL, shaders::FOOTPRINT, shaders::HEURISTICS, arpa_wgpu::store::STORE_WGSL);
    validate("store.wgsl", &src);
}

#[test]
fn a_broken_file_is_rejected() {
    // The check itself can fail: a type error in the twin is caught.
    let broken = shaders::RADIUS.replace("let i = max(iteration, 1u);", "let i = max(iteration, 1.0);");
    assert_ne!(broken, shaders::RADIUS);
    let ok = naga::front::wgsl::parse_str(&broken)
        .ok()
        .is_some_and(|m| naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty()).validate(&m).is_ok());
    assert!(!ok, "a mistyped radius.wgsl validated");
}

#[test]
fn scene_wgsl_validates() {
    let src = format!("enable wgpu_ray_query;\n{}", arpa_wgpu::scene::SCENE_WGSL);
    let module = naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("scene.wgsl: {}", e.emit_to_string(&src)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::RAY_QUERY)
        .validate(&module)
        .unwrap_or_else(|e| panic!("scene.wgsl: {}", e.emit_to_string(&src)));
}
