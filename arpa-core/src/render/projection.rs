//! Projection maps: which part of each light's emission domain can reach geometry, and
//! which part can reach a specular (mirror, glass) object.
//!
//! **Maps.** A light's emission domain is the image of the unit square under its
//! equal-area map (the sphere of a point light, the cone of a spot, the aperture disc of a
//! directional light, the cosine-weighted hemisphere of an area light's directions). A
//! `grid` × `grid` grid over the unit square cuts it into cells of equal measure (Jensen's
//! projection maps, 1996). A cell is kept when its image can see a target: the
//! geometry is summarised by bounding spheres of [`CLUSTER_SIZE`] triangles each, in
//! Morton order, and a cell is kept when a bounding cap of its image (for directions: an
//! angular cap around the direction of its centre; for the aperture: a disc) meets the
//! cone of directions from the light towards a sphere (for an area light: from any point
//! of its bounding sphere; for a directional light: the sphere's shadow on the aperture).
//! The test is conservative: every ray from the light that hits a target triangle starts
//! in a kept cell. A cap's radius is the largest distance from the cell's centre image to
//! points of its boundary's image sampled [`EDGE_SAMPLES`] per edge, plus the largest gap
//! between neighbouring samples (the maps are smooth and the cells small, so the boundary
//! between two samples stays within a gap of them), with a relative margin.
//!
//! **Unbiased.** A light that samples only the kept cells `C` of its domain emits with
//! density `1/|C|` there instead of `1/|D|`, so each photon carries `|C|/|D|` of the
//! light's power per photon ([`crate::emit::emission::CellDomain`]); photons into the rest could
//! not have reached a target, so what they would have stored is zero.
//!
//! **Environment lights** are not projected: a photon's direction and its start on the
//! disc across it form a four-dimensional domain, and nearly every direction sees the
//! scene. Their geometry domain is whole and they have no caustic pass; their caustics
//! come from the global pass.
//!
//! The plan of a render's two photon passes built on the maps is
//! [`crate::render::emission_plan`].

use crate::emit::emission::{CellDomain, Light};
use crate::base::sampling::{cosine_hemisphere, uniform_cone, uniform_disc, uniform_sphere};
use alloc::vec::Vec;
use glam::{DVec2, DVec3};

/// Cells per side of the geometry projection grid of point, spot and directional lights:
/// coarse, because the global pass shares its photons over these cells and each cell
/// should hold many of them (its own lattice then tiles it about as evenly as one lattice
/// over the whole domain would; with a few photons a cell the footprints no longer tile
/// the domain evenly and their overlap stops following the radius schedule), and the map
/// mostly cuts away large regions (directions into the void).
pub const DELTA_GRID: u32 = 32;
/// Cells per side of the specular projection grid of point, spot and directional lights:
/// finer, since specular objects are often small in a light's view and the caustic pass
/// pays for every photon its cells send past them.
pub const SPECULAR_DELTA_GRID: u32 = 256;
/// Cells per side of the specular projection grid over an area light's directions.
pub const SPECULAR_AREA_GRID: u32 = 64;
/// Cells per side of the projection grid over an area light's directions.
pub const AREA_GRID: u32 = 32;
/// Triangles per bounding sphere of the targets.
pub const CLUSTER_SIZE: usize = 16;
/// Boundary points sampled per cell edge for its bounding cap.
pub const EDGE_SAMPLES: u32 = 6;
/// Cells per side of the blocks tested before their cells.
const BLOCK: u32 = 8;
/// A projection that keeps at least this fraction of the cells keeps the whole domain.
pub const WHOLE_ABOVE: f64 = 0.98;
/// A sphere bounding some triangles (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundingSphere {
    /// Centre (m).
    pub centre: DVec3,
    /// Radius (m).
    pub radius: f64,
}

/// Triangles a projection aims at, grouped in bounding spheres of [`CLUSTER_SIZE`]
/// triangles in the Morton order of their centroids (so that each sphere stays small).
/// A sphere that contains a point or spot light says nothing about its directions; its
/// triangles are then tested one by one (their exact spherical triangles).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Targets {
    triangles: Vec<[DVec3; 3]>,
    /// Bounding sphere and triangle index range (into `order`) of each cluster.
    clusters: Vec<(BoundingSphere, core::ops::Range<usize>)>,
    /// Triangle indices in Morton order.
    order: Vec<u32>,
}

impl Targets {
    /// Clusters `triangles` (vertices in metres) as one group.
    pub fn new(triangles: Vec<[DVec3; 3]>) -> Self {
        let n = triangles.len();
        Self::grouped(triangles, &[n])
    }

    /// Clusters `triangles` (vertices in metres) within each group of consecutive
    /// triangles of sizes `groups` (meshes: a cluster never spans two, so that a small
    /// mirror does not share a sphere with a distant glass object).
    pub fn grouped(triangles: Vec<[DVec3; 3]>, groups: &[usize]) -> Self {
        let centroid = |t: &[DVec3; 3]| (t[0] + t[1] + t[2]) / 3.0;
        let mut order: Vec<u32> = Vec::with_capacity(triangles.len());
        let mut clusters = Vec::new();
        let mut first = 0usize;
        for &len in groups {
            let end = (first + len).min(triangles.len());
            if end <= first {
                continue;
            }
            let group = first..end;
            first = end;
            let bounds = crate::base::aabb::Aabb::from_points(triangles[group.clone()].iter().map(centroid));
            let (lo, hi) = (bounds.min.as_vec3().to_array(), bounds.max.as_vec3().to_array());
            let inv = crate::base::morton::inverse_extent(lo, hi);
            let mut keyed: Vec<(u32, u32)> = group.map(|i| (crate::base::morton::morton_code(centroid(&triangles[i]).as_vec3().to_array(), lo, inv), i as u32)).collect();
            keyed.sort_unstable();
            let start = order.len();
            order.extend(keyed.into_iter().map(|(_, i)| i));
            for c in (start..order.len()).step_by(CLUSTER_SIZE) {
                let range = c..(c + CLUSTER_SIZE).min(order.len());
                let points = || order[range.clone()].iter().flat_map(|&i| triangles[i as usize]);
                let centre = crate::base::aabb::Aabb::from_points(points()).centre();
                let r = points().map(|p| (p - centre).length()).fold(0.0, f64::max);
                // f32 vertices in the ray casts: a relative margin covers their rounding.
                clusters.push((BoundingSphere { centre, radius: r * (1.0 + 1e-6) + 1e-6 * (1.0 + centre.abs().max_element()) }, range));
            }
        }
        Self { triangles, clusters, order }
    }

    /// The clusters' bounding spheres.
    pub fn spheres(&self) -> impl Iterator<Item = BoundingSphere> + '_ {
        self.clusters.iter().map(|c| c.0)
    }

    /// Whether there is no target.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    fn cluster_triangles(&self, c: usize) -> impl Iterator<Item = &[DVec3; 3]> + '_ {
        self.order[self.clusters[c].1.clone()].iter().map(|&i| &self.triangles[i as usize])
    }
}

/// The cells of a light's emission domain that a projection keeps.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DomainCells {
    /// Cells per side of the grid; 0: the whole domain (every cell kept, no list).
    pub grid: u32,
    /// The kept cells, `ix + iy · grid`, ascending (empty with `grid` 0).
    pub cells: Vec<u32>,
}

impl DomainCells {
    /// The whole domain.
    pub const fn whole() -> Self {
        Self { grid: 0, cells: Vec::new() }
    }

    /// No cell: the light reaches no target ([`DomainCells::is_empty`]).
    pub const fn none() -> Self {
        Self { grid: 1, cells: Vec::new() }
    }

    /// The domain the emission samples ([`CellDomain`]).
    pub fn domain(&self) -> CellDomain {
        CellDomain { grid: self.grid, count: self.cells.len() as u32 }
    }

    /// Fraction of the domain's measure kept.
    pub fn fraction(&self) -> f64 {
        self.domain().fraction()
    }

    /// Whether no cell is kept (the light cannot reach any target).
    pub fn is_empty(&self) -> bool {
        self.grid != 0 && self.cells.is_empty()
    }
}

/// A light's two projections.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LightProjection {
    /// Cells that see any geometry (the global pass).
    pub geometry: DomainCells,
    /// Cells that see a mirror or glass object (the caustic pass).
    pub specular: DomainCells,
}

/// Where a light's cell images live: unit directions (distances are angles) or the
/// aperture plane (distances in metres).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Space {
    Directions,
    Aperture,
}

/// A cap bounding the image of a cell or block: its centre and radius (radians or metres).
#[derive(Clone, Copy, Debug)]
struct Cap {
    centre: DVec3,
    radius: f64,
}

/// Angle between unit vectors (radians), accurate also for small angles.
fn angle(a: DVec3, b: DVec3) -> f64 {
    libm::atan2(a.cross(b).length(), a.dot(b))
}

/// A target as the light sees it.
#[derive(Clone, Copy, Debug)]
enum Seen {
    /// Directions within `radius` of `centre` (unit; radians), or aperture points within
    /// `radius` of `centre` (metres).
    Cap { centre: DVec3, radius: f64 },
    /// Directions through the spherical triangle of these unit vertex directions.
    Triangle([DVec3; 3]),
    /// Every cell may see it.
    All,
}

/// The projection of the light `light` in a scene with bounding sphere `scene_sphere`
/// onto `targets` on the grids [`DELTA_GRID`] and [`AREA_GRID`]: the kept cells (nearly all
/// cells give [`DomainCells::whole`]).
pub fn project(light: &Light, scene_sphere: (DVec3, f64), targets: &Targets) -> DomainCells {
    project_on(light, scene_sphere, targets, DELTA_GRID, AREA_GRID)
}

/// [`project`] with `delta_grid` cells per side for point, spot and directional lights and
/// `area_grid` for area lights (at most [`crate::base::sampling::MAX_CELL_GRID`]).
pub fn project_on(light: &Light, scene_sphere: (DVec3, f64), targets: &Targets, delta_grid: u32, area_grid: u32) -> DomainCells {
    let (delta_grid, area_grid) = (delta_grid.clamp(1, crate::base::sampling::MAX_CELL_GRID), area_grid.clamp(1, crate::base::sampling::MAX_CELL_GRID));
    match light {
        Light::Point(l) => {
            let o = l.position;
            project_with(delta_grid, Space::Directions, &|u| uniform_sphere(u), targets, |t| seen_from_point(o, t))
        }
        Light::Spot(l) => {
            let frame = light.frame();
            let cos_cutoff = libm::cos(l.cutoff);
            let o = l.position;
            project_with(delta_grid, Space::Directions, &move |u| frame.to_world(uniform_cone(u, cos_cutoff)), targets, |t| seen_from_point(o, t))
        }
        // Every direction of an environment may reach the scene: it is not projected.
        Light::Environment(_) => DomainCells::whole(),
        Light::Directional(_) => {
            let frame = light.frame();
            let (centre, radius) = scene_sphere;
            let map = move |u: DVec2| {
                let d = uniform_disc(u) * radius;
                DVec3::new(d.x, d.y, 0.0)
            };
            project_with(delta_grid, Space::Aperture, &map, targets, |t: Target| match t {
                Target::Sphere(s) => {
                    let rel = s.centre - centre;
                    Seen::Cap { centre: DVec3::new(rel.dot(frame.t), rel.dot(frame.b), 0.0), radius: s.radius }
                }
                Target::Triangle(_) => Seen::All,
            })
        }
        Light::Triangle(_) | Light::Quad(_) => {
            let frame = light.frame();
            let corners: Vec<DVec3> = match light {
                Light::Triangle(l) => l.p.to_vec(),
                Light::Quad(l) => alloc::vec![l.origin, l.origin + l.edge_u, l.origin + l.edge_v, l.origin + l.edge_u + l.edge_v],
                _ => unreachable!(),
            };
            let c = crate::base::aabb::Aabb::from_points(corners.iter().copied()).centre();
            let r = corners.iter().map(|p| (*p - c).length()).fold(0.0, f64::max);
            // From any point of the emitter's bounding ball: the cone towards the sphere
            // grown by the ball's radius; a cluster that overlaps the ball sees everything.
            project_with(area_grid, Space::Directions, &move |u| frame.to_world(cosine_hemisphere(u)), targets, |t: Target| match t {
                Target::Sphere(s) => cone(c, r, s).unwrap_or(Seen::All),
                Target::Triangle(_) => Seen::All,
            })
        }
    }
}

/// What [`project_with`]'s callback is asked about: a cluster's sphere, or (when the
/// sphere answered [`Seen::All`] for a point or spot light) one of its triangles.
#[derive(Clone, Copy, Debug)]
enum Target<'a> {
    Sphere(&'a BoundingSphere),
    Triangle(&'a [DVec3; 3]),
}

/// The cone of directions from a ball (centre `o`, radius `r_o`) towards the sphere
/// `t`; `None` when the two overlap (every direction may reach it).
fn cone(o: DVec3, r_o: f64, t: &BoundingSphere) -> Option<Seen> {
    let v = t.centre - o;
    let d = v.length();
    let r = t.radius + r_o;
    if !(d > r) || !d.is_finite() {
        return None;
    }
    Some(Seen::Cap { centre: v / d, radius: libm::asin((r / d).min(1.0)) })
}

/// What a point light at `o` sees of a target: the cone towards a sphere, or, for a
/// sphere around the light, nothing yet ([`Seen::All`]: its triangles are asked next),
/// and the exact spherical triangle of a triangle (every direction when the light lies
/// in the triangle's plane).
fn seen_from_point(o: DVec3, t: Target) -> Seen {
    match t {
        Target::Sphere(s) => cone(o, 0.0, s).unwrap_or(Seen::All),
        Target::Triangle(tri) => {
            let v = tri.map(|p| p - o);
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            let plane = n.dot(v[0]);
            // In (or within rounding of) the plane: no cone bounds it.
            let scale = n.length() * v.iter().map(|x| x.length()).fold(0.0, f64::max);
            if !(plane.abs() > 1e-9 * scale) || v.iter().any(|x| !(x.length() > 0.0)) {
                return Seen::All;
            }
            Seen::Triangle(v.map(|x| x.normalize()))
        }
    }
}

/// Whether the cap (unit `x`, angular radius `rho`) meets the spherical triangle `t`
/// (unit vertices): `x` inside it, or within `rho` of one of its edges.
fn cap_meets_spherical_triangle(x: DVec3, rho: f64, t: &[DVec3; 3]) -> bool {
    let orient = t[0].dot(t[1].cross(t[2]));
    if orient == 0.0 || !orient.is_finite() {
        return true;
    }
    let sign = orient.signum();
    let edges = [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])];
    if edges.iter().all(|(p, q)| sign * p.cross(*q).dot(x) >= 0.0) {
        return true;
    }
    edges.iter().any(|&(p, q)| {
        let n = p.cross(q);
        let len = n.length();
        if !(len > 0.0) {
            return angle(x, p) <= rho;
        }
        let n = n / len;
        let s = x.dot(n);
        let xp = x - n * s;
        // The foot of x on the great circle lies on the arc p..q (the short arc).
        let on_arc = p.cross(xp).dot(n) >= 0.0 && xp.cross(q).dot(n) >= 0.0;
        if on_arc {
            libm::asin(s.abs().min(1.0)) <= rho
        } else {
            angle(x, p).min(angle(x, q)) <= rho
        }
    })
}

fn project_with(grid: u32, space: Space, map: &dyn Fn(DVec2) -> DVec3, targets: &Targets, seen: impl Fn(Target) -> Seen) -> DomainCells {
    let dist = |a: DVec3, b: DVec3| match space {
        Space::Directions => angle(a, b),
        Space::Aperture => (a - b).length(),
    };
    let meets = |c: &Cap, s: &Seen| match s {
        Seen::Cap { centre, radius } => dist(c.centre, *centre) <= c.radius + radius,
        Seen::Triangle(t) => cap_meets_spherical_triangle(c.centre, c.radius, t),
        Seen::All => true,
    };
    let cap = |x0: u32, y0: u32, size: u32| -> Cap {
        let g = grid as f64;
        let (u0, v0) = (x0 as f64 / g, y0 as f64 / g);
        let side = size as f64 / g;
        let centre = map(DVec2::new(u0 + 0.5 * side, v0 + 0.5 * side));
        // `n` points per edge, around the square from its corner (u0, v0).
        let n = EDGE_SAMPLES * size.min(4);
        let edges = [
            (DVec2::new(u0, v0), DVec2::new(side, 0.0)),
            (DVec2::new(u0 + side, v0), DVec2::new(0.0, side)),
            (DVec2::new(u0 + side, v0 + side), DVec2::new(-side, 0.0)),
            (DVec2::new(u0, v0 + side), DVec2::new(0.0, -side)),
        ];
        let boundary: Vec<DVec3> = edges.iter().flat_map(|&(start, along)| (0..n).map(move |k| start + along * (k as f64 / n as f64))).map(map).collect();
        let far = boundary.iter().map(|&b| dist(centre, b)).fold(0.0, f64::max);
        let gap = (0..boundary.len()).map(|i| dist(boundary[i], boundary[(i + 1) % boundary.len()])).fold(0.0, f64::max);
        Cap { centre, radius: (far + gap) * 1.01 + 1e-9 }
    };
    let blocks = grid.div_ceil(BLOCK);
    let block_caps: Vec<Cap> = (0..blocks * blocks).map(|b| cap((b % blocks) * BLOCK, (b / blocks) * BLOCK, BLOCK)).collect();
    let mut cell_caps: Vec<Option<Cap>> = alloc::vec![None; (grid * grid) as usize];
    let mut kept = alloc::vec![false; (grid * grid) as usize];
    let mut mark = |s: &Seen, kept: &mut Vec<bool>| {
        for (b, bc) in block_caps.iter().enumerate() {
            if !meets(bc, s) {
                continue;
            }
            let (bx, by) = ((b as u32 % blocks) * BLOCK, (b as u32 / blocks) * BLOCK);
            for y in by..(by + BLOCK).min(grid) {
                for x in bx..(bx + BLOCK).min(grid) {
                    let i = (x + y * grid) as usize;
                    if kept[i] {
                        continue;
                    }
                    let c = *cell_caps[i].get_or_insert_with(|| cap(x, y, 1));
                    if meets(&c, s) {
                        kept[i] = true;
                    }
                }
            }
        }
    };
    for (k, (sphere, _)) in targets.clusters.iter().enumerate() {
        match seen(Target::Sphere(sphere)) {
            Seen::All => {
                for t in targets.cluster_triangles(k) {
                    match seen(Target::Triangle(t)) {
                        Seen::All => return DomainCells::whole(),
                        s => mark(&s, &mut kept),
                    }
                }
            }
            s => mark(&s, &mut kept),
        }
    }
    // Nearly every cell: the whole domain (the same photons as without projection; the
    // few left out would save next to nothing).
    if kept.iter().filter(|&&k| k).count() as f64 >= WHOLE_ABOVE * kept.len() as f64 {
        return DomainCells::whole();
    }
    DomainCells { grid, cells: (0..grid * grid).filter(|&i| kept[i as usize]).collect() }
}

/// `total` shared in proportion to `weights` by largest remainders, at least one each for
/// a positive weight while `total` allows ([`crate::render::prepared_scene::PreparedScene::photon_allocation`]'s rule).
pub fn allocate(weights: &[f64], total: u32) -> Vec<u32> {
    let n = weights.len();
    let sum: f64 = weights.iter().sum();
    if n == 0 || total == 0 || !(sum > 0.0) {
        return alloc::vec![0; n];
    }
    let mut counts: Vec<u32> = Vec::with_capacity(n);
    let mut remainders: Vec<(f64, usize)> = Vec::with_capacity(n);
    for (i, p) in weights.iter().enumerate() {
        let exact = total as f64 * p / sum;
        let floor = libm::floor(exact);
        counts.push(floor as u32);
        remainders.push((exact - floor, i));
    }
    let mut left = total.saturating_sub(counts.iter().sum());
    remainders.sort_by(|a, b| {
        let za = counts[a.1] == 0 && weights[a.1] > 0.0;
        let zb = counts[b.1] == 0 && weights[b.1] > 0.0;
        zb.cmp(&za).then(b.0.total_cmp(&a.0)).then(a.1.cmp(&b.1))
    });
    for &(_, i) in &remainders {
        if left == 0 {
            break;
        }
        if weights[i] > 0.0 {
            counts[i] += 1;
            left -= 1;
        }
    }
    counts
}
