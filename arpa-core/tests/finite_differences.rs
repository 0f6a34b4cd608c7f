//! Finite-difference validation of the analytic ray differentials (Igehy 1999).
//!
//! A ray family `P(u, v) = P₀ + u ∂P/∂u + v ∂P/∂v`, `D(u, v) = normalise(w₀ + u ∂w/∂u + v ∂w/∂v)`
//! is traced in `f64` through a plane and a sphere with an *independent* tracer written
//! here (its own intersection, reflection and Snell formulas). Central differences of the
//! traced neighbouring rays must match the analytic differentials after transfer,
//! reflection and refraction (including near the critical angle, and under total internal
//! reflection) to 1e-3 relative.

use arpa_core::propagate::differential::{NormalDifferential, RayDifferential, RefractionEvent};
use arpa_core::base::rng::{Rng, StreamDomain};
use glam::DVec3;

const REL_TOL: f64 = 1e-3;

/// A traced ray: position and unit direction.
#[derive(Clone, Copy, Debug)]
struct Ray {
    p: DVec3,
    d: DVec3,
}

#[derive(Clone, Copy, Debug)]
enum Surface {
    /// `n·x = c` with unit `n`.
    Plane { n: DVec3, c: f64 },
    /// Centre and radius; outward normal.
    Sphere { centre: DVec3, radius: f64 },
}

impl Surface {
    /// Hit distance of the nearest intersection with `t > 1e-9`.
    fn hit(&self, r: &Ray) -> Option<f64> {
        match *self {
            Surface::Plane { n, c } => {
                let t = (c - n.dot(r.p)) / n.dot(r.d);
                (t > 1e-9 && t.is_finite()).then_some(t)
            }
            Surface::Sphere { centre, radius } => {
                let o = r.p - centre;
                let b = o.dot(r.d);
                let disc = b * b - (o.length_squared() - radius * radius);
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                [-b - s, -b + s].into_iter().find(|&t| t > 1e-9)
            }
        }
    }

    fn normal(&self, x: DVec3) -> DVec3 {
        match *self {
            Surface::Plane { n, .. } => n,
            Surface::Sphere { centre, radius } => (x - centre) / radius,
        }
    }

    /// Normal derivative for a positional derivative `dx` on the surface.
    fn normal_derivative(&self, dx: DVec3) -> DVec3 {
        match *self {
            Surface::Plane { .. } => DVec3::ZERO,
            Surface::Sphere { radius, .. } => dx / radius,
        }
    }
}

/// Independent specular events on traced rays.
#[derive(Clone, Copy, Debug)]
enum Event {
    Reflect,
    /// Relative index inside/outside with the surface's outward normal.
    Refract(f64),
}

fn independent_reflect(d: DVec3, n: DVec3) -> DVec3 {
    // Householder reflection written as a matrix product.
    let h = glam::DMat3::IDENTITY - 2.0 * glam::DMat3::from_cols(n * n.x, n * n.y, n * n.z);
    h * d
}

/// Snell's law from tangential components: t_tan = η d_tan, |t| = 1, same side as d.
fn independent_refract(d: DVec3, n_out: DVec3, ior: f64) -> Option<DVec3> {
    let entering = d.dot(n_out) < 0.0;
    let eta = if entering { 1.0 / ior } else { ior };
    let tan = d - n_out * d.dot(n_out);
    let t_tan = tan * eta;
    let s2 = t_tan.length_squared();
    if s2 > 1.0 {
        return None;
    }
    let sign = if entering { -1.0 } else { 1.0 };
    Some(t_tan + n_out * sign * (1.0 - s2).sqrt())
}

/// Traces a ray through surfaces, applying `events[i]` after surface `i` (no event after
/// the last); returns the ray after every hit (position at the hit, direction after the
/// event).
fn trace(mut r: Ray, surfaces: &[Surface], events: &[Event]) -> Option<Vec<(Ray, bool)>> {
    let mut out = vec![];
    for (i, s) in surfaces.iter().enumerate() {
        let t = s.hit(&r)?;
        r.p += r.d * t;
        let n = s.normal(r.p);
        let mut tir = false;
        if let Some(e) = events.get(i) {
            r.d = match *e {
                Event::Reflect => independent_reflect(r.d, n),
                Event::Refract(ior) => match independent_refract(r.d, n, ior) {
                    Some(t) => t,
                    None => {
                        tir = true;
                        independent_reflect(r.d, n)
                    }
                },
            };
        }
        out.push((r, tir));
    }
    Some(out)
}

/// The ray family and its analytic differential.
#[derive(Clone, Copy, Debug)]
struct Family {
    p0: DVec3,
    w0: DVec3,
    dp: [DVec3; 2],
    dw: [DVec3; 2],
}

impl Family {
    fn at(&self, u: f64, v: f64) -> Ray {
        Ray { p: self.p0 + self.dp[0] * u + self.dp[1] * v, d: (self.w0 + self.dw[0] * u + self.dw[1] * v).normalize() }
    }

    fn differential(&self) -> RayDifferential {
        RayDifferential::from_unnormalised(self.p0, self.w0, self.dp[0], self.dp[1], self.dw[0], self.dw[1]).unwrap()
    }
}

/// Propagates the analytic differential through the same chain. Returns per hit the
/// differential after the event and whether TIR happened.
fn propagate(f: &Family, surfaces: &[Surface], events: &[Event]) -> Vec<(RayDifferential, bool)> {
    let mut rd = f.differential();
    let mut out = vec![];
    for (i, s) in surfaces.iter().enumerate() {
        let r = Ray { p: rd.p, d: rd.d };
        let t = s.hit(&r).expect("central ray hits");
        let x = rd.p + rd.d * t;
        let n = s.normal(x);
        rd = rd.transfer(t, n).expect("transfer");
        let nd = NormalDifferential { n, dn_du: s.normal_derivative(rd.dp_du), dn_dv: s.normal_derivative(rd.dp_dv) };
        let mut tir = false;
        if let Some(e) = events.get(i) {
            rd = match *e {
                Event::Reflect => rd.reflect(&nd).expect("reflect"),
                Event::Refract(ior) => {
                    let (r, ev) = rd.refract(&nd, ior).expect("refract");
                    tir = ev == RefractionEvent::TotalInternalReflection;
                    r
                }
            };
        }
        out.push((rd, tir));
    }
    out
}

fn assert_close(analytic: DVec3, fd: DVec3, what: &str) {
    let err = (analytic - fd).length();
    let scale = fd.length().max(analytic.length());
    assert!(err <= REL_TOL * scale + 1e-12, "{what}: analytic {analytic} vs finite difference {fd} (rel err {:.2e})", err / scale);
}

/// Checks every hit of the chain against central differences with step `h`.
fn check_chain(f: &Family, surfaces: &[Surface], events: &[Event], h: f64, label: &str) -> Vec<bool> {
    let analytic = propagate(f, surfaces, events);
    let mut tirs = vec![];
    for (k, (param, name)) in [(0usize, "u"), (1, "v")].into_iter().enumerate() {
        let (du, dv) = if param == 0 { (h, 0.0) } else { (0.0, h) };
        let plus = trace(f.at(du, dv), surfaces, events).expect("neighbour +h hits");
        let minus = trace(f.at(-du, -dv), surfaces, events).expect("neighbour -h hits");
        let centre = trace(f.at(0.0, 0.0), surfaces, events).unwrap();
        for (i, ((rd, tir), ((p, _), (m, _)))) in analytic.iter().zip(plus.iter().zip(&minus)).enumerate() {
            assert_eq!(*tir, centre[i].1, "{label}: TIR classification differs at hit {i}");
            if k == 0 {
                tirs.push(*tir);
            }
            let fd_p = (p.p - m.p) / (2.0 * h);
            let fd_d = (p.d - m.d) / (2.0 * h);
            let (ap, ad) = if param == 0 { (rd.dp_du, rd.dd_du) } else { (rd.dp_dv, rd.dd_dv) };
            assert_close(ap, fd_p, &format!("{label}: dP/d{name} at hit {i}"));
            assert_close(ad, fd_d, &format!("{label}: dD/d{name} at hit {i}"));
        }
    }
    tirs
}

fn random_family(rng: &mut Rng, target: DVec3, from: DVec3) -> Family {
    let mut r = || 2.0 * rng.next_f64() - 1.0;
    let w0 = (target - from).normalize() + DVec3::new(r(), r(), r()) * 0.02;
    Family {
        p0: from,
        w0,
        dp: [DVec3::new(r(), r(), r()) * 0.05, DVec3::new(r(), r(), r()) * 0.05],
        dw: [DVec3::new(r(), r(), r()) * 0.1, DVec3::new(r(), r(), r()) * 0.1],
    }
}

#[test]
fn plane_transfer_and_reflection() {
    let mut rng = Rng::new(11, 0, 0, StreamDomain::User);
    for case in 0..200 {
        let n = DVec3::new(0.1 * rng.next_f64(), 1.0, -0.2 * rng.next_f64()).normalize();
        let plane = Surface::Plane { n, c: 0.3 };
        let from = DVec3::new(rng.next_f64() * 4.0 - 2.0, 3.0 + rng.next_f64(), rng.next_f64() * 4.0 - 2.0);
        let target = DVec3::new(rng.next_f64() - 0.5, 0.3, rng.next_f64() - 0.5);
        let f = random_family(&mut rng, target, from);
        let second = Surface::Plane { n: DVec3::new(0.0, -1.0, 0.1).normalize(), c: -6.0 };
        check_chain(&f, &[plane, second], &[Event::Reflect], 1e-6, &format!("plane reflect case {case}"));
    }
}

#[test]
fn plane_refraction_both_ways() {
    let mut rng = Rng::new(12, 0, 0, StreamDomain::User);
    for case in 0..200 {
        // A glass slab between y = 0 and y = 1: enter through the top, leave at the bottom.
        let top = Surface::Plane { n: DVec3::Y, c: 1.0 };
        let bottom = Surface::Plane { n: DVec3::Y, c: 0.0 };
        let floor = Surface::Plane { n: DVec3::Y, c: -2.0 };
        let from = DVec3::new(rng.next_f64() * 2.0 - 1.0, 3.0, rng.next_f64() * 2.0 - 1.0);
        let f = random_family(&mut rng, DVec3::new(0.0, 1.0, 0.0), from);
        let ior = 1.2 + 0.6 * rng.next_f64();
        // The bottom face's normal points out of the slab (−y); its Plane normal is +y, so
        // give it as the outward −y plane instead.
        let bottom_out = Surface::Plane { n: -DVec3::Y, c: 0.0 };
        let _ = bottom;
        check_chain(&f, &[top, bottom_out, floor], &[Event::Refract(ior), Event::Refract(ior)], 1e-6, &format!("slab case {case}"));
    }
}

#[test]
fn sphere_transfer_reflection_refraction() {
    let mut rng = Rng::new(13, 0, 0, StreamDomain::User);
    let sphere = Surface::Sphere { centre: DVec3::new(0.0, 1.0, 0.0), radius: 1.0 };
    let floor = Surface::Plane { n: DVec3::Y, c: -0.5 };
    let mut refracted = 0;
    for case in 0..300 {
        let from = DVec3::new(rng.next_f64() * 0.4 - 0.2, 5.0, rng.next_f64() * 0.4 - 0.2);
        // Aim at points across the sphere's silhouette, avoiding the exact rim.
        let target = DVec3::new(rng.next_f64() * 1.4 - 0.7, 1.0, rng.next_f64() * 1.4 - 0.7);
        let f = random_family(&mut rng, target, from);
        let hit = sphere.hit(&f.at(0.0, 0.0));
        if hit.is_none() {
            continue;
        }
        // Mirror ball, then the floor (or a far plane for rays reflected upwards).
        let far = Surface::Plane { n: DVec3::Y, c: 20.0 };
        let r = trace(f.at(0.0, 0.0), &[sphere], &[Event::Reflect]).unwrap()[0].0;
        let next = if r.d.y < -0.05 { floor } else if r.d.y > 0.05 { far } else { continue };
        check_chain(&f, &[sphere, next], &[Event::Reflect], 1e-7, &format!("mirror ball case {case}"));
        // Glass ball: refract in, transfer across the inside, refract out (or TIR), floor.
        let ior = 1.3 + 0.4 * rng.next_f64();
        let chain = [sphere, sphere];
        let events = [Event::Refract(ior), Event::Refract(ior)];
        let Some(path) = trace(f.at(0.0, 0.0), &chain, &events) else { continue };
        let out = path[1].0;
        let last = if out.d.y < -0.05 { floor } else { continue };
        let Some(_) = trace(f.at(1e-7, 0.0), &[sphere, sphere, last], &events) else { continue };
        check_chain(&f, &[sphere, sphere, last], &events, 1e-7, &format!("glass ball case {case}"));
        refracted += 1;
    }
    assert!(refracted > 100, "too few glass-ball cases exercised: {refracted}");
}

/// Rays leaving glass (ior 1.5) at angles just below and just above the critical angle
/// `asin(1/1.5) ≈ 41.81°`: refraction differentials (which grow like `1/√k`) and the TIR
/// fallback both match finite differences.
#[test]
fn near_critical_angle_and_tir() {
    let ior = 1.5;
    let critical = (1.0f64 / ior).asin();
    let exit = Surface::Plane { n: DVec3::Y, c: 0.0 }; // outward normal +y, glass below
    let screen_up = Surface::Plane { n: DVec3::Y, c: 1.0 };
    let screen_down = Surface::Plane { n: DVec3::Y, c: -1.0 };
    let mut saw_tir = false;
    let mut saw_near = false;
    for (i, offset_deg) in [-3.0f64, -1.0, -0.3, -0.1, 0.1, 0.3, 1.0, 3.0].into_iter().enumerate() {
        let theta = critical + offset_deg.to_radians();
        let d = DVec3::new(theta.sin(), theta.cos(), 0.0);
        let f = Family {
            p0: -d,
            w0: d,
            dp: [DVec3::new(0.0, 0.0, 1e-2), DVec3::new(1e-2, 0.0, 0.0)],
            dw: [DVec3::new(0.0, 0.0, 2e-2), DVec3::new(-1e-2 * theta.cos(), 1e-2 * theta.sin(), 0.0)],
        };
        let tir = offset_deg > 0.0;
        let screen = if tir { screen_down } else { screen_up };
        // Steps well below the angular distance to the critical angle.
        let h = 1e-4 * offset_deg.abs().to_radians().min(1.0);
        let tirs = check_chain(&f, &[exit, screen], &[Event::Refract(ior)], h, &format!("critical offset {offset_deg}° (#{i})"));
        assert_eq!(tirs[0], tir);
        saw_tir |= tir;
        saw_near |= !tir && offset_deg.abs() < 0.2;
    }
    assert!(saw_tir && saw_near);
}
