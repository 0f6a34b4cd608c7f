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
    assert!(module.functions.len() > 0, "{label}: no functions");
}

#[test]
fn each_file_validates_with_its_dependencies() {
    for (name, source) in shaders::ALL {
        let src = if name == "footprint.wgsl" { format!("{}\n{}", shaders::KERNEL, source) } else { source.to_string() };
        validate(name, &src);
    }
}

#[test]
fn all_files_together_validate() {
    let all: String = shaders::ALL.iter().map(|(_, s)| *s).collect::<Vec<_>>().join("\n");
    validate("all twin files", &all);
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
