//! The embedded default scene: valid, with an outward-facing smooth glass sphere, a light
//! that shines down, and a camera that sees the sphere and the floor under it.

use arpa::core::glam::Vec3;
use arpa::core::render::scene::{Material, Scene, TriangleMesh};
use arpa::default_scene::*;

fn mesh<'a>(scene: &'a Scene, name: &str) -> &'a TriangleMesh {
    scene.meshes.iter().find(|m| m.name == name).unwrap_or_else(|| panic!("no mesh named '{name}'"))
}

fn triangle(m: &TriangleMesh, t: [u32; 3]) -> [Vec3; 3] {
    t.map(|i| m.positions[i as usize])
}

/// Film position (pixels, top-left origin) of world point `p`, if in front of the camera.
fn project(scene: &Scene, p: Vec3) -> Option<(f32, f32)> {
    let c = scene.camera;
    let f = c.frame().unwrap();
    let d = p - c.position;
    let z = d.dot(f.forward);
    if z <= 0.0 {
        return None;
    }
    let sx = d.dot(f.right) / (z * f.tan_half_fov * f.aspect);
    let sy = d.dot(f.up) / (z * f.tan_half_fov);
    Some(((sx + 1.0) * 0.5 * c.width as f32, (1.0 - sy) * 0.5 * c.height as f32))
}

#[test]
fn default_scene_is_valid() {
    let s = default_scene();
    s.validate().unwrap();
    assert_eq!((s.camera.width, s.camera.height), DEFAULT_RESOLUTION);
    assert!((s.camera.vertical_fov.to_degrees() - 45.0).abs() < 1e-4);
    let b = s.bounds();
    assert!(b.min.abs_diff_eq(-arpa::core::glam::DVec3::ONE, 1e-6) && b.max.abs_diff_eq(arpa::core::glam::DVec3::ONE, 1e-6), "{b:?}");
}

#[test]
fn sphere_is_smooth_glass_with_unit_outward_normals() {
    let s = default_scene();
    let m = mesh(&s, SPHERE_NAME);
    assert!(matches!(s.materials[m.material as usize], Material::Dielectric { ior, roughness, .. } if ior == 1.5 && roughness == 0.0));
    assert!((1800..=2200).contains(&m.indices.len()), "{} triangles", m.indices.len());
    let normals = m.normals.as_ref().expect("per-vertex normals");
    for (p, n) in m.positions.iter().zip(normals) {
        assert!((n.length() - 1.0).abs() < 1e-5, "normal {n} is not unit");
        assert!(((*p - SPHERE_CENTRE).length() - SPHERE_RADIUS).abs() < 1e-5);
        assert!((*p - SPHERE_CENTRE).normalize().dot(*n) > 0.9999, "normal {n} at {p} does not point outwards");
    }
    for &t in &m.indices {
        let [a, b, c] = triangle(m, t);
        let g = (b - a).cross(c - a);
        assert!(g.length() > 0.0, "degenerate triangle {t:?}");
        assert!(g.dot((a + b + c) / 3.0 - SPHERE_CENTRE) > 0.0, "triangle {t:?} winds inwards");
    }
    // Standing on the floor (y = -1).
    let lowest = m.positions.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    assert!((lowest + 1.0).abs() < 0.01 && lowest >= -1.0, "{lowest}");
}

#[test]
fn light_is_a_small_emissive_quad_facing_down() {
    let s = default_scene();
    let m = mesh(&s, LIGHT_NAME);
    assert_eq!(m.indices.len(), 2);
    assert!(m.emission.is_some_and(|e| e.min_element() > 0.0));
    for &t in &m.indices {
        let [a, b, c] = triangle(m, t);
        let n = (b - a).cross(c - a).normalize();
        assert!(n.abs_diff_eq(-Vec3::Y, 1e-6), "light triangle {t:?} faces {n}");
    }
    assert!(m.positions.iter().all(|p| p.y < 1.0 && p.y > 0.9));
    // Exactly the two emitting triangles.
    assert_eq!(s.emitters().len(), 2);
    // The walls face into the box and there are the mirror and coloured walls.
    let mirror = mesh(&s, MIRROR_NAME);
    assert!(matches!(s.materials[mirror.material as usize], Material::Conductor { roughness, .. } if roughness == 0.0));
    let floor = mesh(&s, "floor");
    let [a, b, c] = triangle(floor, floor.indices[0]);
    assert!((b - a).cross(c - a).normalize().abs_diff_eq(Vec3::Y, 1e-6));
}

#[test]
fn camera_sees_the_sphere_and_the_floor_in_front_of_it() {
    let s = default_scene();
    let (w, h) = (s.camera.width as f32, s.camera.height as f32);
    let inside = |p: Vec3| project(&s, p).is_some_and(|(x, y)| x > 0.0 && x < w && y > 0.0 && y < h);
    assert!(inside(SPHERE_CENTRE), "sphere centre projects to {:?}", project(&s, SPHERE_CENTRE));
    for d in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y] {
        assert!(inside(SPHERE_CENTRE + d * SPHERE_RADIUS), "sphere edge {d} outside the image");
    }
    // The sphere is in the right half of the image, the caustic region in front of its
    // contact point is in the lower half.
    let (x, _) = project(&s, SPHERE_CENTRE).unwrap();
    assert!(x > 0.5 * w);
    let (_, y) = project(&s, Vec3::new(SPHERE_CENTRE.x, -1.0, SPHERE_CENTRE.z + SPHERE_RADIUS)).unwrap();
    assert!(y > 0.5 * h && y < h);
}
