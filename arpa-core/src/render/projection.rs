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
use alloc::boxed::Box;
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
    /// `cos` and `sin` of `radius` (directions: the cap tests compare dot products).
    cos_sin: (f64, f64),
}

impl Cap {
    fn new(centre: DVec3, radius: f64) -> Self {
        Self { centre, radius, cos_sin: (libm::cos(radius), libm::sin(radius)) }
    }

    /// Whether two caps of unit directions meet: their centres at most the sum of their
    /// radii apart, `a·b ≥ cos(ρa + ρb)` (a margin of 1e-12 for rounding keeps the test
    /// conservative).
    fn meets_directions(&self, other: &Cap) -> bool {
        if self.radius + other.radius >= core::f64::consts::PI {
            return true;
        }
        let ((ca, sa), (cb, sb)) = (self.cos_sin, other.cos_sin);
        self.centre.dot(other.centre) >= ca * cb - sa * sb - 1e-12
    }
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
    Cap(Cap),
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
    Projector::new(scene_sphere, targets, delta_grid, area_grid).project(light)
}

/// Projects many lights onto one set of targets ([`project_on`] for each). The cells' caps
/// over the cosine-weighted hemisphere are computed once and shared by every area light:
/// each light's cells are that hemisphere turned into its frame, and angles do not change
/// under the turn, so the targets are turned into the light's frame instead of the caps
/// into the world (an emissive mesh of thousands of triangles then costs a cap test per
/// cell and target, not thousands of cap constructions).
pub struct Projector<'t> {
    scene_sphere: (DVec3, f64),
    targets: &'t Targets,
    delta_grid: u32,
    /// The caps of the area lights' grid over the cosine-weighted hemisphere, in its own
    /// frame.
    area_caps: CapGrid,
}

impl<'t> Projector<'t> {
    /// A projector onto `targets` in a scene with bounding sphere `scene_sphere` (m), with
    /// `delta_grid` cells per side for point, spot and directional lights and `area_grid` for
    /// area lights (each at most [`crate::base::sampling::MAX_CELL_GRID`]).
    pub fn new(scene_sphere: (DVec3, f64), targets: &'t Targets, delta_grid: u32, area_grid: u32) -> Self {
        let (delta_grid, area_grid) = (delta_grid.clamp(1, crate::base::sampling::MAX_CELL_GRID), area_grid.clamp(1, crate::base::sampling::MAX_CELL_GRID));
        Self { scene_sphere, targets, delta_grid, area_caps: CapGrid::new(area_grid, Space::Directions, Box::new(cosine_hemisphere)) }
    }

    /// The cells of `light`'s emission domain that may reach a target.
    pub fn project(&mut self, light: &Light) -> DomainCells {
        let targets = self.targets;
        match light {
            Light::Point(l) => {
                let o = l.position;
                project_with(&mut CapGrid::new(self.delta_grid, Space::Directions, Box::new(uniform_sphere)), &|v| v, targets, |t| seen_from_point(o, t))
            }
            Light::Spot(l) => {
                let frame = light.frame();
                let cos_cutoff = libm::cos(l.cutoff);
                let o = l.position;
                let mut caps = CapGrid::new(self.delta_grid, Space::Directions, Box::new(move |u| uniform_cone(u, cos_cutoff)));
                project_with(&mut caps, &|v| frame.to_local(v), targets, |t| seen_from_point(o, t))
            }
            // Every direction of an environment may reach the scene: it is not projected.
            Light::Environment(_) => DomainCells::whole(),
            Light::Directional(_) => {
                let frame = light.frame();
                let (centre, radius) = self.scene_sphere;
                let map = move |u: DVec2| {
                    let d = uniform_disc(u) * radius;
                    DVec3::new(d.x, d.y, 0.0)
                };
                project_with(&mut CapGrid::new(self.delta_grid, Space::Aperture, Box::new(map)), &|v| v, targets, |t: Target| match t {
                    Target::Sphere(s) => {
                        let rel = s.centre - centre;
                        Seen::Cap(Cap::new(DVec3::new(rel.dot(frame.t), rel.dot(frame.b), 0.0), s.radius))
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
                project_with(&mut self.area_caps, &|v| frame.to_local(v), targets, |t: Target| match t {
                    Target::Sphere(s) => cone(c, r, s).unwrap_or(Seen::All),
                    Target::Triangle(_) => Seen::All,
                })
            }
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
    Some(Seen::Cap(Cap::new(v / d, libm::asin((r / d).min(1.0)))))
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

/// The bounding caps of a `grid` × `grid` grid's cells under the map `map` from the unit
/// square, in the map's own frame, as a quadtree: one node over the whole grid (its side
/// the next power of two), each split in four down to single cells (nodes at the grid's
/// edge clipped to it). A cell is kept when its cap and every enclosing node's cap meet
/// what the light sees of a target; each cap bounds its node's image, so the test stays
/// conservative. A node's cap is computed when a test first needs it and kept for the next
/// target and light.
struct CapGrid {
    grid: u32,
    space: Space,
    map: Box<dyn Fn(DVec2) -> DVec3>,
    /// Per level, from the root to the cells (side 1): the nodes' side in cells, nodes per
    /// grid side, and their caps (row-major).
    levels: Vec<(u32, u32, Vec<Option<Cap>>)>,
}

impl CapGrid {
    fn new(grid: u32, space: Space, map: Box<dyn Fn(DVec2) -> DVec3>) -> Self {
        let mut levels = Vec::new();
        let mut side = grid.next_power_of_two();
        loop {
            let nodes = grid.div_ceil(side);
            levels.push((side, nodes, alloc::vec![None; (nodes * nodes) as usize]));
            if side == 1 {
                break;
            }
            side /= 2;
        }
        Self { grid, space, map, levels }
    }

    /// Distance between two points of the map's image (radians or metres).
    fn dist(&self, a: DVec3, b: DVec3) -> f64 {
        match self.space {
            Space::Directions => angle(a, b),
            Space::Aperture => (a - b).length(),
        }
    }

    /// The cap of the `w` × `h` cells from cell `(x0, y0)`.
    fn cap(&self, x0: u32, y0: u32, w: u32, h: u32) -> Cap {
        let g = self.grid as f64;
        let (u0, v0) = (x0 as f64 / g, y0 as f64 / g);
        let (su, sv) = (w as f64 / g, h as f64 / g);
        let centre = (self.map)(DVec2::new(u0 + 0.5 * su, v0 + 0.5 * sv));
        // `n` points per edge, around the rectangle from its corner (u0, v0).
        let n = EDGE_SAMPLES * w.max(h).min(4);
        let edges = [
            (DVec2::new(u0, v0), DVec2::new(su, 0.0)),
            (DVec2::new(u0 + su, v0), DVec2::new(0.0, sv)),
            (DVec2::new(u0 + su, v0 + sv), DVec2::new(-su, 0.0)),
            (DVec2::new(u0, v0 + sv), DVec2::new(0.0, -sv)),
        ];
        let boundary: Vec<DVec3> = edges.iter().flat_map(|&(start, along)| (0..n).map(move |k| start + along * (k as f64 / n as f64))).map(|u| (self.map)(u)).collect();
        let far = boundary.iter().map(|&b| self.dist(centre, b)).fold(0.0, f64::max);
        let gap = (0..boundary.len()).map(|i| self.dist(boundary[i], boundary[(i + 1) % boundary.len()])).fold(0.0, f64::max);
        let radius = (far + gap) * 1.01 + 1e-9;
        // A cap of directions bounds its node by its boundary only while the boundary stays
        // within a right angle of the centre (only then can the node not enclose the
        // centre's antipode, the one point farther than its boundary); a larger one is
        // taken as the whole sphere.
        match self.space {
            Space::Directions if radius >= core::f64::consts::FRAC_PI_2 => Cap::new(centre, core::f64::consts::PI),
            _ => Cap::new(centre, radius),
        }
    }

    /// Whether the cap `c` meets what the light sees of a target (in the map's frame).
    fn meets(&self, c: &Cap, s: &Seen) -> bool {
        match s {
            Seen::Cap(t) => match self.space {
                Space::Directions => c.meets_directions(t),
                Space::Aperture => self.dist(c.centre, t.centre) <= c.radius + t.radius,
            },
            Seen::Triangle(t) => cap_meets_spherical_triangle(c.centre, c.radius, t),
            Seen::All => true,
        }
    }

    /// Marks in `kept` every cell whose cap, and its enclosing nodes' caps, meet `s`.
    fn mark(&mut self, s: &Seen, kept: &mut [bool]) {
        self.mark_node(0, 0, 0, s, kept);
    }

    /// [`CapGrid::mark`] below node `(x, y)` of `level`.
    fn mark_node(&mut self, level: usize, x: u32, y: u32, s: &Seen, kept: &mut [bool]) {
        let (side, nodes) = (self.levels[level].0, self.levels[level].1);
        let (x0, y0) = (x * side, y * side);
        if x0 >= self.grid || y0 >= self.grid {
            return;
        }
        let leaf = level + 1 == self.levels.len();
        if leaf && kept[(x0 + y0 * self.grid) as usize] {
            return;
        }
        let i = (x + y * nodes) as usize;
        let cap = match self.levels[level].2[i] {
            Some(c) => c,
            None => {
                let c = self.cap(x0, y0, side.min(self.grid - x0), side.min(self.grid - y0));
                self.levels[level].2[i] = Some(c);
                c
            }
        };
        if !self.meets(&cap, s) {
            return;
        }
        if leaf {
            kept[(x0 + y0 * self.grid) as usize] = true;
            return;
        }
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            self.mark_node(level + 1, 2 * x + dx, 2 * y + dy, s, kept);
        }
    }
}

/// The cells of `caps` that see a target: `seen` says what the light sees of each target
/// (in world space), `to_local` turns that into the caps' frame (a rotation, so distances
/// and angles stay as they are).
fn project_with(caps: &mut CapGrid, to_local: &dyn Fn(DVec3) -> DVec3, targets: &Targets, seen: impl Fn(Target) -> Seen) -> DomainCells {
    let local = |s: Seen| match s {
        Seen::Cap(c) => Seen::Cap(Cap { centre: to_local(c.centre), ..c }),
        Seen::Triangle(t) => Seen::Triangle(t.map(to_local)),
        Seen::All => Seen::All,
    };
    // What the light sees of every target first: one that every direction may reach
    // makes the domain whole before any cell is tested (an emissive mesh's own clusters
    // overlap each of its triangles' balls).
    let mut all_seen = Vec::with_capacity(targets.clusters.len());
    for (k, (sphere, _)) in targets.clusters.iter().enumerate() {
        match seen(Target::Sphere(sphere)) {
            Seen::All => {
                for t in targets.cluster_triangles(k) {
                    match seen(Target::Triangle(t)) {
                        Seen::All => return DomainCells::whole(),
                        s => all_seen.push(local(s)),
                    }
                }
            }
            s => all_seen.push(local(s)),
        }
    }
    let grid = caps.grid;
    let mut kept = alloc::vec![false; (grid * grid) as usize];
    for s in &all_seen {
        caps.mark(s, &mut kept);
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
