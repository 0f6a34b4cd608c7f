//! The small analytic and test scenes of the suite (a few large triangles each, so every
//! backend builds them in microseconds and the core's brute-force caster can trace them).

use arpa_core::emit::emission::{Light, PointLight, TriangleLight};
use arpa_core::glam::{DVec3, Vec2, Vec3};
use arpa_core::render::scene::{Camera, Material, MaterialMaps, Scene, SceneTextures, TriangleMesh};
use arpa_core::render::texture::Texture;

pub use arpa_core::render::shapes::parallelogram as quad;

pub use arpa_core::render::shapes::cuboid;

/// A grey Lambertian material.
pub fn diffuse(albedo: f32) -> Material {
    Material::Diffuse {
        albedo: Vec3::splat(albedo),
    }
}

/// Smooth glass (IOR 1.5, clear).
pub fn glass() -> Material {
    Material::Dielectric {
        ior: 1.5,
        transmittance: Vec3::ONE,
        roughness: 0.0,
    }
}

/// A perfect mirror of reflectance 0.9.
pub fn mirror() -> Material {
    Material::Conductor {
        reflectance: Vec3::splat(0.9),
        roughness: 0.0,
    }
}

/// An isotropic point light of intensity `intensity` (W/sr, grey).
pub fn point_light(position: DVec3, intensity: f64) -> Light {
    Light::Point(PointLight {
        position,
        intensity: DVec3::splat(intensity),
    })
}

/// A square pinhole camera.
pub fn camera(
    position: Vec3,
    target: Vec3,
    up: Vec3,
    vertical_fov_degrees: f32,
    size: u32,
) -> Camera {
    Camera {
        position,
        target,
        up,
        vertical_fov: vertical_fov_degrees.to_radians(),
        width: size,
        height: size,
    }
}

fn scene(
    meshes: Vec<TriangleMesh>,
    materials: Vec<Material>,
    lights: Vec<Light>,
    camera: Camera,
) -> Scene {
    Scene { textures: Default::default(),
        meshes,
        materials,
        lights,
        camera,
        roughness_cutoff: 0.5,
        instancing: None,
    }
}

/// A floor and a back wall under a point light, with three copies of one group (a smooth
/// glass sphere, a diffuse box and a mirror panel) placed by a rotation, a non-uniform
/// scale with a rotation, and a mirroring; the copies are lifted off the floor (no
/// coincident faces, whose order no acceleration structure defines). The copies are the
/// scene's meshes and [`Scene::instancing`] records them, so a backend may instance the
/// group.
pub fn instanced_room(size: u32) -> Scene {
    use arpa_core::glam::{DAffine3, DQuat};
    use arpa_core::render::scene::Instancing;
    let mut meshes = vec![
        quad("floor", Vec3::new(-2.0, 0.0, -2.0), Vec3::new(0.0, 0.0, 4.0), Vec3::new(4.0, 0.0, 0.0), 0),
        quad("back wall", Vec3::new(-2.0, 0.0, -2.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 3.0, 0.0), 0),
    ];
    let group = [
        arpa_core::render::shapes::icosphere("glass ball", Vec3::new(0.0, 0.35, 0.0), 0.3, 2, true, 1),
        cuboid("box", Vec3::new(0.35, 0.0, -0.35), Vec3::new(0.6, 0.3, -0.1), 0),
        quad("mirror", Vec3::new(-0.5, 0.0, -0.4), Vec3::new(0.0, 0.0, 0.6), Vec3::new(-0.1, 0.6, 0.0), 2),
    ];
    let mut instancing = Instancing::default();
    let p = instancing.add_prototype("group", &group);
    for (scale, angle, at) in [
        (DVec3::ONE, 0.4, DVec3::new(-1.1, 0.02, 0.2)),
        (DVec3::new(1.3, 0.8, 1.1), -0.9, DVec3::new(0.9, 0.01, 0.3)),
        (DVec3::new(-1.0, 1.1, 1.0), 2.5, DVec3::new(0.0, 0.03, -1.0)),
    ] {
        instancing.place(&mut meshes, &group, p, DAffine3::from_scale_rotation_translation(scale, DQuat::from_rotation_y(angle), at));
    }
    let mut s = scene(
        meshes,
        vec![diffuse(0.6), glass(), mirror()],
        vec![point_light(DVec3::new(0.2, 1.8, 0.6), 4.0)],
        camera(Vec3::new(0.0, 1.4, 3.5), Vec3::new(0.0, 0.3, 0.0), Vec3::Y, 50.0, size),
    );
    s.instancing = Some(instancing);
    s
}

/// Floor (4 × 4), back wall, a glass slab floating above the floor and a mirror at the
/// side, lit by a point light above the slab: every photon-path event (diffuse storage,
/// Fresnel reflection, refraction in and out, mirror reflection, diffuse bounce) occurs,
/// and both maps receive footprints.
pub fn glass_mirror_room(size: u32) -> Scene {
    let floor = quad(
        "floor",
        Vec3::new(-2.0, 0.0, -2.0),
        Vec3::new(0.0, 0.0, 4.0),
        Vec3::new(4.0, 0.0, 0.0),
        0,
    );
    let wall = quad(
        "back wall",
        Vec3::new(-2.0, 0.0, -2.0),
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 3.0, 0.0),
        0,
    );
    let slab = cuboid(
        "glass slab",
        Vec3::new(-0.6, 0.5, -0.6),
        Vec3::new(0.6, 0.7, 0.6),
        1,
    );
    let mirror_quad = quad(
        "mirror",
        Vec3::new(1.6, 0.0, -1.0),
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::new(-0.3, 1.5, 0.0),
        2,
    );
    scene(
        vec![floor, wall, slab, mirror_quad],
        vec![diffuse(0.6), glass(), mirror()],
        vec![point_light(DVec3::new(0.2, 1.6, 0.1), 3.0)],
        camera(
            Vec3::new(0.0, 1.2, 3.5),
            Vec3::new(0.0, 0.4, 0.0),
            Vec3::Y,
            50.0,
            size,
        ),
    )
}

/// Floor, back wall, a thin one-sided-geometry shelf (a single quad) above the floor, a
/// small glass block on the floor and a point light above the shelf. The camera sits
/// below the shelf's height, so it sees the shelf's underside, where query points lie in
/// the very plane of the footprints stored on the shelf's lit top: inside their slabs but
/// back-facing, so they must contribute nothing.
pub fn shelf_room(size: u32) -> Scene {
    let floor = quad(
        "floor",
        Vec3::new(-2.0, 0.0, -2.0),
        Vec3::new(0.0, 0.0, 4.0),
        Vec3::new(4.0, 0.0, 0.0),
        0,
    );
    let wall = quad(
        "back wall",
        Vec3::new(-2.0, 0.0, -2.0),
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 3.0, 0.0),
        0,
    );
    let shelf = quad(
        "shelf",
        Vec3::new(-0.6, 0.6, -0.6),
        Vec3::new(0.0, 0.0, 1.2),
        Vec3::new(1.2, 0.0, 0.0),
        0,
    );
    let block = cuboid(
        "glass block",
        Vec3::new(0.7, 0.0, -0.2),
        Vec3::new(1.2, 0.4, 0.3),
        1,
    );
    scene(
        vec![floor, wall, shelf, block],
        vec![diffuse(0.7), glass()],
        vec![point_light(DVec3::new(0.25, 1.3, 0.15), 3.0)],
        camera(
            Vec3::new(0.0, 0.35, 2.8),
            Vec3::new(0.0, 0.45, 0.0),
            Vec3::Y,
            55.0,
            size,
        ),
    )
}

/// Height of the plane scene's point light above the plane (m).
pub const PLANE_LIGHT_HEIGHT: f64 = 1.0;
/// Intensity of the plane scene's point light (W/sr).
pub const PLANE_INTENSITY: f64 = 2.0;
/// Albedo of the plane.
pub const PLANE_ALBEDO: f64 = 0.5;

/// A point light at height 1 over a 20 × 20 diffuse plane of albedo 0.5; the camera looks
/// straight down from height 3 and sees the square `|x|, |z| ≤ 1.5`. Nothing is above the
/// plane, so photons reflected by it leave the scene: with direct lighting off the radiance
/// is exactly `ρ/π · I cos θ / d²`.
pub fn lit_plane(size: u32) -> Scene {
    let floor = quad(
        "plane",
        Vec3::new(-10.0, 0.0, -10.0),
        Vec3::new(0.0, 0.0, 20.0),
        Vec3::new(20.0, 0.0, 0.0),
        0,
    );
    scene(
        vec![floor],
        vec![diffuse(PLANE_ALBEDO as f32)],
        vec![point_light(
            DVec3::new(0.0, PLANE_LIGHT_HEIGHT, 0.0),
            PLANE_INTENSITY,
        )],
        Camera {
            position: Vec3::new(0.0, 3.0, 0.0),
            target: Vec3::ZERO,
            up: Vec3::new(0.0, 0.0, -1.0),
            vertical_fov: 2.0 * 0.5f32.atan(),
            width: size,
            height: size,
        },
    )
}

/// [`lit_plane`] with albedo 1 and texture coordinates `u = (x + 10)/20`, `v = (z + 10)/20`
/// on its 20 × 20 square (so `∂p/∂u = 20 x̂`, `∂p/∂v = 20 ẑ`), the textures and maps
/// `textures` (material 0 reading `maps`).
pub fn lit_plane_textured(size: u32, textures: Vec<Texture>, maps: MaterialMaps) -> Scene {
    let mut scene = lit_plane(size);
    for m in &mut scene.meshes {
        m.uvs = Some(m.positions.iter().map(|p| Vec2::new((p.x + 10.0) / 20.0, (p.z + 10.0) / 20.0)).collect());
    }
    scene.materials[0] = diffuse(1.0);
    scene.textures = SceneTextures { textures, maps: vec![maps], emission: vec![], environment: None };
    scene
}

/// A triangle light whose three corners are collinear (zero area).
pub fn zero_area_triangle_light() -> Light {
    Light::Triangle(TriangleLight {
        p: [
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
        ],
        radiance: DVec3::splat(5.0),
    })
}

/// An icosphere of radius `radius` around `centre` with flat facets
/// ([`arpa_core::render::shapes::icosphere`]).
pub fn icosphere(centre: Vec3, radius: f32, subdivisions: u32, material: u32) -> TriangleMesh {
    arpa_core::render::shapes::icosphere("icosphere", centre, radius, subdivisions, false, material)
}

/// Intensity of the furnace's point light (W/sr).
pub const FURNACE_INTENSITY: f64 = 1.5;
/// Albedo of the furnace's wall.
pub const FURNACE_ALBEDO: f64 = 0.5;

/// A point light at the centre of a closed unit icosphere (1280 triangles) of albedo 0.5,
/// seen from the centre: a closed furnace with all bounces.
pub fn furnace(size: u32) -> Scene {
    scene(
        vec![icosphere(Vec3::ZERO, 1.0, 3, 0)],
        vec![diffuse(FURNACE_ALBEDO as f32)],
        vec![point_light(DVec3::ZERO, FURNACE_INTENSITY)],
        camera(Vec3::ZERO, Vec3::new(0.3, 0.2, 1.0), Vec3::Y, 60.0, size),
    )
}

/// Bottom of the slab scene's glass slab (m).
pub const SLAB_BOTTOM: f64 = 0.5;
/// Thickness of the slab scene's glass slab (m).
pub const SLAB_THICKNESS: f64 = 1.0;
/// Half side of the slab scene's glass slab (m).
pub const SLAB_HALF_SIDE: f64 = 4.0;
/// IOR of the slab (and of [`glass`]).
pub const SLAB_IOR: f64 = 1.5;
/// Albedo of the slab scene's floor.
pub const SLAB_FLOOR_ALBEDO: f64 = 0.5;
/// Position of the slab scene's point light (m): on the y axis above the slab.
pub const SLAB_LIGHT: DVec3 = DVec3::new(0.0, 2.5, 0.0);
/// Intensity of the slab scene's point light (W/sr).
pub const SLAB_INTENSITY: f64 = 3.0;
/// The slab scene's camera position (m).
pub const SLAB_CAMERA: Vec3 = Vec3::new(0.0, 4.0, 2.0);
/// The slab scene's vertical field of view (degrees).
pub const SLAB_FOV_DEGREES: f32 = 24.0;

/// A 12 × 12 diffuse floor at y = 0 (albedo [`SLAB_FLOOR_ALBEDO`]) under a clear glass
/// slab `|x|, |z| ≤ 4`, `y ∈ [0.5, 1.5]` (IOR 1.5), a point light above the slab at
/// [`SLAB_LIGHT`], and a camera at [`SLAB_CAMERA`] looking at the origin, so that every
/// camera ray enters the slab through its top face and the floor is seen only through
/// the glass. The slab's faces are parallel: every chain top–bottom has a closed form.
pub fn glass_slab(size: u32) -> Scene {
    slab_scene(size, SLAB_THICKNESS)
}

/// Thickness of [`thin_sheet`]'s glass (m): a twelfth of the ray-origin offset the paths
/// once used (`1e-5 (1 + |p|)`, 5e-5 m at the sheet's corners), 8 times the `t_min` of a
/// ray leaving it ([`arpa_core::render::ray_cast::leave_t_min`] at `|p| = 4`).
pub const THIN_SHEET_THICKNESS: f64 = 4e-6;

/// [`glass_slab`] with the slab only [`THIN_SHEET_THICKNESS`] thick (its top at
/// `0.5 + 4e-6` rounded to `f32`, see [`thin_sheet_thickness`]).
pub fn thin_sheet(size: u32) -> Scene {
    slab_scene(size, THIN_SHEET_THICKNESS)
}

/// The thickness of [`thin_sheet`]'s glass as its `f32` vertices have it (m).
pub fn thin_sheet_thickness() -> f64 {
    (SLAB_BOTTOM + THIN_SHEET_THICKNESS) as f32 as f64 - SLAB_BOTTOM
}

fn slab_scene(size: u32, thickness: f64) -> Scene {
    let floor = quad(
        "floor",
        Vec3::new(-6.0, 0.0, -6.0),
        Vec3::new(0.0, 0.0, 12.0),
        Vec3::new(12.0, 0.0, 0.0),
        0,
    );
    let h = SLAB_HALF_SIDE as f32;
    let slab = cuboid(
        "glass slab",
        Vec3::new(-h, SLAB_BOTTOM as f32, -h),
        Vec3::new(h, (SLAB_BOTTOM + thickness) as f32, h),
        1,
    );
    scene(
        vec![floor, slab],
        vec![diffuse(SLAB_FLOOR_ALBEDO as f32), glass()],
        vec![point_light(SLAB_LIGHT, SLAB_INTENSITY)],
        camera(SLAB_CAMERA, Vec3::ZERO, Vec3::Y, SLAB_FOV_DEGREES, size),
    )
}

/// The mirror scene's mirror plane `x = MIRROR_X` (m).
pub const MIRROR_X: f64 = 1.0;
/// Height of the mirror (m); it spans `y ∈ [0, MIRROR_HEIGHT]`, `|z| ≤ MIRROR_HALF_WIDTH`.
pub const MIRROR_HEIGHT: f64 = 1.2;
/// Half width of the mirror (m).
pub const MIRROR_HALF_WIDTH: f64 = 0.5;
/// Reflectance of [`mirror`].
pub const MIRROR_REFLECTANCE: f64 = 0.9;
/// Albedo of the mirror scene's floor.
pub const MIRROR_FLOOR_ALBEDO: f64 = 0.5;
/// Position of the mirror scene's point light (m).
pub const MIRROR_LIGHT: DVec3 = DVec3::new(-0.3, 0.6, 0.0);
/// Intensity of the mirror scene's point light (W/sr).
pub const MIRROR_INTENSITY: f64 = 2.0;
/// The mirror scene's camera position (m).
pub const MIRROR_CAMERA: Vec3 = Vec3::new(-2.0, 2.2, 0.0);
/// The mirror scene's camera target (m).
pub const MIRROR_TARGET: Vec3 = Vec3::new(0.6, 0.2, 0.0);
/// The mirror scene's vertical field of view (degrees).
pub const MIRROR_FOV_DEGREES: f32 = 50.0;

/// A diffuse floor `x ∈ [−3, 1]`, `|z| ≤ 3` at y = 0 ending at a vertical mirror (plane
/// `x = 1`, `y ∈ [0, 1.2]`, `|z| ≤ 0.5`, reflectance 0.9) and a point light in front of the
/// mirror. The camera looks at the mirror over the floor: it sees the floor directly and
/// reflected, and rays above or beside the mirror leave the scene. The mirror's caustic on
/// the floor is the light of the image source mirrored in `x = 1`, through the mirror's
/// rectangle.
pub fn mirror_wall(size: u32) -> Scene {
    let floor = quad(
        "floor",
        Vec3::new(-3.0, 0.0, -3.0),
        Vec3::new(0.0, 0.0, 6.0),
        Vec3::new(4.0, 0.0, 0.0),
        0,
    );
    let (x, w, h) = (
        MIRROR_X as f32,
        MIRROR_HALF_WIDTH as f32,
        MIRROR_HEIGHT as f32,
    );
    let mirror_quad = quad(
        "mirror",
        Vec3::new(x, 0.0, -w),
        Vec3::new(0.0, h, 0.0),
        Vec3::new(0.0, 0.0, 2.0 * w),
        1,
    );
    scene(
        vec![floor, mirror_quad],
        vec![diffuse(MIRROR_FLOOR_ALBEDO as f32), mirror()],
        vec![point_light(MIRROR_LIGHT, MIRROR_INTENSITY)],
        camera(
            MIRROR_CAMERA,
            MIRROR_TARGET,
            Vec3::Y,
            MIRROR_FOV_DEGREES,
            size,
        ),
    )
}

/// Height of [`knife_edge`]'s wedge bottom (m).
pub const WEDGE_BOTTOM: f64 = 0.5;
/// Slope of [`knife_edge`]'s top face: thickness per metre from the knife edge (rad, ≈).
pub const WEDGE_SLOPE: f64 = 0.05;
/// Length of the wedge from its knife edge at `x = 0` (m).
pub const WEDGE_LENGTH: f64 = 1.0;
/// Half width of the wedge along z (m).
pub const WEDGE_HALF_WIDTH: f64 = 1.0;
/// [`knife_edge`]'s camera position (m).
pub const WEDGE_CAMERA: Vec3 = Vec3::new(-0.625, 1.5, 0.25);
/// [`knife_edge`]'s camera target (m): on the wedge's bottom plane, 0.5 mm in from the edge.
pub const WEDGE_TARGET: Vec3 = Vec3::new(0.0005, 0.5, 0.0);
/// [`knife_edge`]'s vertical field of view (degrees): about 2 mm across at the target.
pub const WEDGE_FOV_DEGREES: f32 = 0.07;

/// A glass wedge (prism, IOR 1.5) with a knife edge along z at `x = 0`, `y = 0.5`: bottom
/// face `y = 0.5`, top face rising by [`WEDGE_SLOPE`] per metre to `x = 1`, so it is
/// thinner than `1e-5 m` for the first 0.2 mm; a diffuse floor at `y = 0` (albedo
/// [`SLAB_FLOOR_ALBEDO`]), a point light above, and a camera zoomed on the first 2 mm of
/// the wedge (the rim of a lens, seen closely), looking down at it from the knife-edge
/// side. Flat faces: every chain has a closed form.
pub fn knife_edge(size: u32) -> Scene {
    let floor = quad(
        "floor",
        Vec3::new(-3.0, 0.0, -3.0),
        Vec3::new(0.0, 0.0, 6.0),
        Vec3::new(6.0, 0.0, 0.0),
        0,
    );
    let (y0, l, w) = (WEDGE_BOTTOM as f32, WEDGE_LENGTH as f32, WEDGE_HALF_WIDTH as f32);
    let y1 = (WEDGE_BOTTOM + WEDGE_SLOPE * WEDGE_LENGTH) as f32;
    // Edge a0-a1, far bottom b0-b1, far top c0-c1; every face wound outwards.
    let positions = vec![
        Vec3::new(0.0, y0, -w),
        Vec3::new(0.0, y0, w),
        Vec3::new(l, y0, -w),
        Vec3::new(l, y0, w),
        Vec3::new(l, y1, -w),
        Vec3::new(l, y1, w),
    ];
    let (a0, a1, b0, b1, c0, c1) = (0, 1, 2, 3, 4, 5);
    let wedge = TriangleMesh { uvs: None,
        name: "glass wedge".into(),
        positions,
        normals: None,
        indices: vec![
            [a0, b0, b1],
            [a0, b1, a1], // bottom, -y
            [a0, a1, c1],
            [a0, c1, c0], // top
            [b0, c0, c1],
            [b0, c1, b1], // far end, +x
            [a0, c0, b0], // side, -z
            [a1, b1, c1], // side, +z
        ],
        material: 1,
        emission: None,
    };
    scene(
        vec![floor, wedge],
        vec![diffuse(SLAB_FLOOR_ALBEDO as f32), glass()],
        vec![point_light(DVec3::new(-0.5, 2.5, 0.0), SLAB_INTENSITY)],
        camera(WEDGE_CAMERA, WEDGE_TARGET, Vec3::Y, WEDGE_FOV_DEGREES, size),
    )
}

/// Position of [`open_mirror`]'s point light (m).
pub const OPEN_LIGHT: DVec3 = DVec3::new(0.0, 1.0, 0.0);
/// Intensity of [`open_mirror`]'s point light (W/sr).
pub const OPEN_INTENSITY: f64 = 2.0;
/// Albedo of [`open_mirror`]'s floor.
pub const OPEN_FLOOR_ALBEDO: f64 = 0.5;
/// Half side of [`open_mirror`]'s floor (m): far beyond the caustic, so every photon the
/// mirror reflects lands on it.
pub const OPEN_FLOOR_HALF_SIDE: f32 = 10.0;
/// Centre of [`open_mirror`]'s mirror (m).
pub const OPEN_MIRROR_CENTRE: DVec3 = DVec3::new(0.3, 0.7, 0.1);
/// The floor point the light's ray through the mirror's centre is reflected to (m): it
/// fixes the mirror's tilt.
pub const OPEN_MIRROR_AIM: DVec3 = DVec3::new(-0.2, 0.0, -0.1);
/// Side of [`open_mirror`]'s square mirror (m).
pub const OPEN_MIRROR_SIDE: f64 = 0.2;
/// Rotation of the mirror's square about its normal (degrees), so that no edge is
/// horizontal.
pub const OPEN_MIRROR_TWIST_DEGREES: f64 = 20.0;
/// [`open_mirror`]'s camera: straight above this floor point (m) …
pub const OPEN_VIEW_CENTRE: Vec3 = Vec3::new(-0.35, 0.0, -0.17);
/// … at this height (m) …
pub const OPEN_CAMERA_HEIGHT: f32 = 3.0;
/// … with this vertical field of view (degrees): it sees the floor
/// `|x + 0.35|, |z + 0.17| ≤ 0.53`, the whole caustic and some floor beside it, and not
/// the mirror.
pub const OPEN_FOV_DEGREES: f32 = 20.0;

/// The corners of [`open_mirror`]'s mirror before rounding to `f32` (m), in order around
/// the square, wound so that `(p₁ − p₀) × (p₃ − p₀)` faces the light. The mirror's normal
/// bisects the directions from its centre back to the light and on to
/// [`OPEN_MIRROR_AIM`].
pub fn open_mirror_corners() -> [DVec3; 4] {
    let c = OPEN_MIRROR_CENTRE;
    let n = ((OPEN_MIRROR_AIM - c).normalize() - (c - OPEN_LIGHT).normalize()).normalize();
    let e1 = n.cross(DVec3::Y).normalize();
    let e2 = n.cross(e1);
    let (s, co) = OPEN_MIRROR_TWIST_DEGREES.to_radians().sin_cos();
    let (a, b) = (
        (e1 * co + e2 * s) * OPEN_MIRROR_SIDE,
        (e2 * co - e1 * s) * OPEN_MIRROR_SIDE,
    );
    let origin = c - (a + b) * 0.5;
    [origin, origin + a, origin + a + b, origin + b]
}

/// A point light ([`OPEN_LIGHT`], [`OPEN_INTENSITY`]) 1 m above a 20 × 20 diffuse floor
/// (albedo [`OPEN_FLOOR_ALBEDO`]) and a 0.2 m square mirror (reflectance
/// [`MIRROR_REFLECTANCE`]) tilted beside and below the light, 0.44 m from it, and nothing
/// else: an open scene in which the mirror subtends 1 % of the light's sphere of
/// directions. The mirror's caustic on the floor is the light of the image source (the
/// light mirrored in the mirror's plane) through the mirror's square; the camera looks
/// straight down at it. The mirror is mesh 1, its vertices `p₀, p₁, p₁ + p₃ − p₀, p₃` in
/// `f32`.
pub fn open_mirror(size: u32) -> Scene {
    let h = OPEN_FLOOR_HALF_SIDE;
    let floor = quad(
        "floor",
        Vec3::new(-h, 0.0, -h),
        Vec3::new(0.0, 0.0, 2.0 * h),
        Vec3::new(2.0 * h, 0.0, 0.0),
        0,
    );
    let [p0, p1, _, p3] = open_mirror_corners().map(|p| p.as_vec3());
    let mirror_quad = quad("mirror", p0, p1 - p0, p3 - p0, 1);
    let v = OPEN_VIEW_CENTRE;
    scene(
        vec![floor, mirror_quad],
        vec![diffuse(OPEN_FLOOR_ALBEDO as f32), mirror()],
        vec![point_light(OPEN_LIGHT, OPEN_INTENSITY)],
        camera(
            Vec3::new(v.x, OPEN_CAMERA_HEIGHT, v.z),
            v,
            Vec3::new(0.0, 0.0, -1.0),
            OPEN_FOV_DEGREES,
            size,
        ),
    )
}

/// Irradiance of the bandwidth scenes' directional light on a plane perpendicular to it
/// (W/m²).
pub const BANDWIDTH_IRRADIANCE: f64 = 2.0;
/// Albedo of the bandwidth scenes' floor.
pub const BANDWIDTH_ALBEDO: f64 = 0.5;
/// Height of the bandwidth scene's black occluder (metres).
pub const BANDWIDTH_OCCLUDER_HEIGHT: f32 = 0.5;

/// A 2 × 2 diffuse floor (`y = 0`, albedo [`BANDWIDTH_ALBEDO`]) under a directional light
/// travelling along `(1, −1, 0)/√2`, so the floor's irradiance is `E/√2` and, with direct
/// lighting off, its radiance `ρ/π · E/√2` wherever the light reaches it; the camera looks
/// straight down from height 3 at the square `|x|, |z| ≤ 0.5`. With `occluded`, a black
/// (albedo 0) half-plane at height [`BANDWIDTH_OCCLUDER_HEIGHT`] over `x ≤ −0.5`, outside the
/// camera's view, casts a hard shadow whose edge is the line `x = 0` of the floor: irradiance
/// `E/√2` for `x > 0` and exactly 0 for `x < 0` (photons the floor reflects leave the scene
/// or end on the occluder's black underside).
pub fn bandwidth_plane(size: u32, occluded: bool) -> Scene {
    let mut meshes = vec![quad("floor", Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 2.0), Vec3::new(2.0, 0.0, 0.0), 0)];
    if occluded {
        let y = BANDWIDTH_OCCLUDER_HEIGHT;
        meshes.push(quad("occluder", Vec3::new(-2.5, y, -1.5), Vec3::new(0.0, 0.0, 3.0), Vec3::new(2.0, 0.0, 0.0), 1));
    }
    let light = Light::Directional(arpa_core::emit::emission::DirectionalLight {
        direction: DVec3::new(1.0, -1.0, 0.0).normalize(),
        irradiance: DVec3::splat(BANDWIDTH_IRRADIANCE),
    });
    scene(
        meshes,
        vec![diffuse(BANDWIDTH_ALBEDO as f32), diffuse(0.0)],
        vec![light],
        Camera {
            position: Vec3::new(0.0, 3.0, 0.0),
            target: Vec3::ZERO,
            up: Vec3::new(0.0, 0.0, -1.0),
            vertical_fov: 2.0 * (0.5f32 / 3.0).atan(),
            width: size,
            height: size,
        },
    )
}

/// Radiance of the environment-lit plane's constant environment (W/(m²·sr), grey).
pub const ENVIRONMENT_RADIANCE: f64 = 0.8;

/// A diffuse plane (2 × 2, albedo [`PLANE_ALBEDO`]) under a constant environment of
/// radiance [`ENVIRONMENT_RADIANCE`] and nothing else, seen obliquely so that the top of
/// the image shows the environment itself.
pub fn environment_plane(size: u32) -> Scene {
    let floor = quad("plane", Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 2.0), Vec3::new(2.0, 0.0, 0.0), 0);
    scene(
        vec![floor],
        vec![diffuse(PLANE_ALBEDO as f32)],
        vec![Light::Environment(arpa_core::emit::emission::EnvironmentLight { radiance: DVec3::splat(ENVIRONMENT_RADIANCE), mean: DVec3::ONE })],
        camera(Vec3::new(0.0, 2.2, 2.2), Vec3::new(0.0, 0.0, -0.4), Vec3::Y, 40.0, size),
    )
}

/// The environment-lit plane ([`environment_plane`]) under an environment map in place of
/// the constant: 16 × 8 texels, a sky that brightens towards the horizon with a bright
/// patch of 2 × 2 texels, turned 20° about x; scale [`ENVIRONMENT_RADIANCE`].
pub fn environment_map_plane(size: u32) -> Scene {
    use arpa_core::render::environment::EnvironmentMap;
    use arpa_core::render::texture::{Bitmap, Texels, TextureFilter, TextureWrap, UvTransform};
    let (w, h) = (16u32, 8u32);
    let texels = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| if (5..7).contains(&i) && (2..4).contains(&j) { [6.0, 5.0, 4.0] } else { [0.3 + 0.1 * j as f32, 0.4 + 0.05 * j as f32, 0.8 - 0.02 * i as f32] })
        .collect();
    let map = EnvironmentMap {
        bitmap: Bitmap { width: w, height: h, texels: Texels::Float(texels), filter: TextureFilter::Bilinear, wrap: TextureWrap::Repeat, to_uv: UvTransform::default() },
        to_world: arpa_core::glam::DMat3::from_rotation_x(20f64.to_radians()),
    };
    let mean = map.mean().expect("a valid map");
    let mut s = environment_plane(size);
    s.lights = vec![Light::Environment(arpa_core::emit::emission::EnvironmentLight { radiance: DVec3::splat(ENVIRONMENT_RADIANCE), mean })];
    s.textures.environment = Some(map);
    s
}
