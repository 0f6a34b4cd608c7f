// The records the path-level kernels exchange through device buffers, each the WGSL side of
// a `#[repr(C)]` struct of arpa_core::gpu::layout (same size and field offsets; arpa-wgpu's
// tests check the sizes through naga's layouter). Self-contained.

// A raw footprint with its key (layout::KeyedFootprint, 96 bytes): what the photon pass
// appends for a photon stored as a footprint, before the heuristics.
struct ArpaKeyedFootprint {
    center: vec3<f32>,  // metres
    map: u32,           // 0 caustic, 1 global
    normal: vec3<f32>,  // unit, towards the arriving photon (flipped below the shading plane)
    pad0: u32,
    du: vec3<f32>,      // metres, tangent plane, the map's smoothing applied
    pad1: u32,
    dv: vec3<f32>,
    pad2: u32,
    flux: vec3<f32>,    // W, RGB
    pad3: u32,
    key: u32,           // photon_index * max_depth + depth, unique within the iteration
    pad4: u32,
    pad5: u32,
    pad6: u32,
}

// arpa_core::store::progressive_photon::PackedPhoton (48 bytes): a progressive photon of a sorted map.
struct ArpaPackedPhoton {
    position: vec3<f32>, // metres
    map: u32,
    normal: vec3<f32>,   // unit, towards the arrival side
    pad0: u32,
    flux: vec3<f32>,     // W, RGB
    pad1: u32,
}

// A progressive photon with its key (layout::KeyedPhoton, 64 bytes): what the photon pass
// appends for a photon stored as a progressive photon.
struct ArpaKeyedPhoton {
    position: vec3<f32>, // metres
    map: u32,
    normal: vec3<f32>,   // unit, towards the arrival side (flipped below the shading plane)
    pad0: u32,
    flux: vec3<f32>,     // W, RGB
    pad1: u32,
    key: u32,            // photon_index * max_depth + depth
    pad2: u32,
    pad3: u32,
    pad4: u32,
}

// arpa_core::render::tracer::QueryRecord (64 bytes): the camera pass's record of one pixel.
struct ArpaQueryRecord {
    position: vec3<f32>,  // metres
    pixel: u32,
    normal: vec3<f32>,    // unit, towards the viewer (flipped below the shading plane)
    valid: u32,           // 1: a diffuse query point; 0: the path ended elsewhere
    weight: vec3<f32>,    // throughput times albedo / pi (1/sr)
    pad0: u32,
    radiance: vec3<f32>,  // W/(m^2 sr) already known for the pixel
    pad1: u32,
}

// layout::SortItem (12 bytes): sorted by hi, then lo, then value.
struct ArpaSortItem {
    hi: u32,
    lo: u32,
    value: u32,
}
