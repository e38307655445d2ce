//! Procedural meshes with known topology and curvature, for coarsen's demo, tests and
//! benchmarks.
//!
//! Every closed shape is a consistently oriented 2-manifold with outward normals
//! (positive signed volume); every open one is a manifold disc or perforated disc with
//! normals along +z. Output depends only on the parameters.
//!
//! | shape | topology | vertices | faces |
//! | --- | --- | --- | --- |
//! | [`icosphere`]`(r, k)` | sphere | 10·4ᵏ + 2 | 20·4ᵏ |
//! | [`uv_sphere`]`(r, n_lat, n_lon)` | sphere | 2 + (n_lat − 1)·n_lon | 2·n_lon·(n_lat − 1) |
//! | [`torus`]`(R, r, n, m)` | genus 1 | n·m | 2·n·m |
//! | [`bumpy_sphere`]`(r, k, a, f)` | sphere | as `icosphere` | as `icosphere` |
//! | [`double_torus`]`(size, res)` | genus 2 | see its docs | see its docs |
//! | [`cube`]`(size, n)` | sphere, 12 sharp edges, 8 corners | 6n² + 2 | 12n² |
//! | [`plane_grid`]`(nx, ny, size)` | disc, 1 boundary loop | (nx + 1)(ny + 1) | 2·nx·ny |
//! | [`disk_with_holes`]`(h, res, size)` | h holes, h + 1 loops | see its docs | see its docs |
//!
//! CAD-like parts with sharp edges, tessellated as a CAD program's STL export is (a plate,
//! a block, a shaft), are in `cad` (with the crate feature `cad`).
//!
//! ```
//! let m = coarsen_shapes::icosphere(1.0, 2).unwrap();
//! assert_eq!((m.n_vertices(), m.n_faces()), (162, 320));
//! assert!(m.signed_volume() > 0.0);
//! ```

use coarsen_mesh::{DVec3, Index, Mesh, Topology, topology};
use std::f64::consts::{PI, TAU};

#[cfg(feature = "cad")]
pub mod cad;

/// Why a shape could not be made: parameters that describe none, or (a bug) a failed
/// construction step.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShapeError {
    /// A parameter outside its valid range.
    #[error("{name} = {value} is invalid: expected {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value, as given.
        value: String,
        /// The valid range.
        expected: &'static str,
    },
    /// The shape would have more faces than the mesh tables support.
    #[error("{what} would have {faces} faces, more than the {max} supported")]
    TooLarge {
        /// The shape.
        what: &'static str,
        /// Its face count.
        faces: u64,
        /// The limit.
        max: u64,
    },
    /// A construction step failed on valid parameters: a broken invariant of this crate (a
    /// bug; please report it with the call).
    #[error("{what} could not be built: {reason} (a bug in coarsen-shapes)")]
    Internal {
        /// The shape.
        what: &'static str,
        /// What failed.
        reason: String,
    },
}

/// The most faces a generated shape may have (the topology tables' limit).
pub const MAX_FACES: u64 = topology::MAX_FACES as u64;

fn positive(name: &'static str, value: f64) -> Result<f64, ShapeError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ShapeError::InvalidParameter {
            name,
            value: value.to_string(),
            expected: "a finite number above 0",
        })
    }
}

fn at_least(name: &'static str, value: u32, min: u32) -> Result<u32, ShapeError> {
    if value >= min {
        Ok(value)
    } else {
        Err(ShapeError::InvalidParameter {
            name,
            value: value.to_string(),
            expected: match min {
                1 => "at least 1",
                2 => "at least 2",
                _ => "at least 3",
            },
        })
    }
}

fn fits(what: &'static str, faces: u64) -> Result<(), ShapeError> {
    if faces <= MAX_FACES {
        Ok(())
    } else {
        Err(ShapeError::TooLarge {
            what,
            faces,
            max: MAX_FACES,
        })
    }
}

/// Regular icosahedron with unit circumradius, faces counter-clockwise seen from outside.
fn icosahedron() -> Mesh {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let raw = [
        (-1.0, phi, 0.0),
        (1.0, phi, 0.0),
        (-1.0, -phi, 0.0),
        (1.0, -phi, 0.0),
        (0.0, -1.0, phi),
        (0.0, 1.0, phi),
        (0.0, -1.0, -phi),
        (0.0, 1.0, -phi),
        (phi, 0.0, -1.0),
        (phi, 0.0, 1.0),
        (-phi, 0.0, -1.0),
        (-phi, 0.0, 1.0),
    ];
    let positions = raw
        .iter()
        .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
        .collect();
    let faces = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    Mesh::new(positions, faces)
}

/// One 1-to-4 split of every face, new vertices at edge midpoints pushed onto the unit
/// sphere. Edge `e` of the old mesh becomes new vertex `n_vertices + e`.
fn subdivide_on_unit_sphere(mesh: &Mesh) -> Mesh {
    let topo = Topology::build(mesh);
    let nv = mesh.n_vertices() as Index;
    let mut positions = mesh.positions.clone();
    positions.extend(
        topo.edges()
            .iter()
            .map(|&[a, b]| (mesh.positions[a as usize] + mesh.positions[b as usize]).normalize()),
    );
    let mut faces = Vec::with_capacity(mesh.n_faces() * 4);
    for (f, &[a, b, c]) in mesh.faces.iter().enumerate() {
        let [ab, bc, ca] = topo.face_edges(f as Index).map(|e| nv + e);
        faces.push([a, ab, ca]);
        faces.push([ab, b, bc]);
        faces.push([ca, bc, c]);
        faces.push([ab, bc, ca]);
    }
    Mesh::new(positions, faces)
}

/// Unit-radius icosphere after `subdivisions` splits (parameters already checked).
fn unit_icosphere(subdivisions: u32) -> Mesh {
    (0..subdivisions).fold(icosahedron(), |m, _| subdivide_on_unit_sphere(&m))
}

/// Sphere of `radius` from an icosahedron split 1-to-4 `subdivisions` times, every vertex
/// at distance `radius` from the origin: 10·4ᵏ + 2 vertices, 20·4ᵏ faces.
pub fn icosphere(radius: f64, subdivisions: u32) -> Result<Mesh, ShapeError> {
    let radius = positive("radius", radius)?;
    fits(
        "icosphere",
        20u64.saturating_mul(4u64.saturating_pow(subdivisions)),
    )?;
    let mut m = unit_icosphere(subdivisions);
    m.positions.iter_mut().for_each(|p| *p *= radius);
    Ok(m)
}

/// Latitude–longitude sphere of `radius`: `n_lat ≥ 2` bands from pole to pole, `n_lon ≥ 3`
/// segments around; each pole is a single vertex (index 0 north at +z, last south).
pub fn uv_sphere(radius: f64, n_lat: u32, n_lon: u32) -> Result<Mesh, ShapeError> {
    let radius = positive("radius", radius)?;
    let n_lat = at_least("n_lat", n_lat, 2)?;
    let n_lon = at_least("n_lon", n_lon, 3)?;
    fits(
        "uv_sphere",
        2u64.saturating_mul(u64::from(n_lon))
            .saturating_mul(u64::from(n_lat) - 1),
    )?;
    let rings = n_lat - 1;
    let mut positions = Vec::with_capacity((2 + rings * n_lon) as usize);
    positions.push(DVec3::Z * radius);
    for i in 1..n_lat {
        let theta = PI * f64::from(i) / f64::from(n_lat);
        for j in 0..n_lon {
            let phi = TAU * f64::from(j) / f64::from(n_lon);
            positions.push(
                radius
                    * DVec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    ),
            );
        }
    }
    positions.push(-DVec3::Z * radius);
    let south = positions.len() as Index - 1;
    let ring = |i: u32, j: u32| 1 + i * n_lon + j % n_lon;
    let mut faces = Vec::with_capacity((2 * n_lon * rings) as usize);
    for j in 0..n_lon {
        faces.push([0, ring(0, j), ring(0, j + 1)]);
    }
    for i in 0..rings - 1 {
        for j in 0..n_lon {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i + 1, j),
                ring(i + 1, j + 1),
                ring(i, j + 1),
            );
            faces.push([a, b, c]);
            faces.push([a, c, d]);
        }
    }
    for j in 0..n_lon {
        faces.push([south, ring(rings - 1, j + 1), ring(rings - 1, j)]);
    }
    Ok(Mesh::new(positions, faces))
}

/// Torus around the z axis: tube centre at distance `major` from the axis, tube radius
/// `minor` (`0 < minor < major`), `n_major ≥ 3` segments around the axis and
/// `n_minor ≥ 3` around the tube. Gaussian curvature `cos w / (minor·(major + minor·cos w))`
/// at tube angle `w`: positive outside, negative inside.
pub fn torus(major: f64, minor: f64, n_major: u32, n_minor: u32) -> Result<Mesh, ShapeError> {
    let major = positive("major", major)?;
    let minor = positive("minor", minor)?;
    if minor >= major {
        return Err(ShapeError::InvalidParameter {
            name: "minor",
            value: minor.to_string(),
            expected: "less than major",
        });
    }
    let n = at_least("n_major", n_major, 3)?;
    let m = at_least("n_minor", n_minor, 3)?;
    fits(
        "torus",
        2u64.saturating_mul(u64::from(n))
            .saturating_mul(u64::from(m)),
    )?;
    let id = |i: u32, j: u32| (i % n) * m + j % m;
    let mut positions = Vec::with_capacity((n * m) as usize);
    for i in 0..n {
        let u = TAU * f64::from(i) / f64::from(n);
        for j in 0..m {
            let w = TAU * f64::from(j) / f64::from(m);
            let r = major + minor * w.cos();
            positions.push(DVec3::new(r * u.cos(), r * u.sin(), minor * w.sin()));
        }
    }
    let mut faces = Vec::with_capacity((2 * n * m) as usize);
    for i in 0..n {
        for j in 0..m {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            faces.push([a, b, c]);
            faces.push([a, c, d]);
        }
    }
    Ok(Mesh::new(positions, faces))
}

/// The radial factor of [`bumpy_sphere`] at unit direction `u`.
fn bump(u: DVec3, amplitude: f64, frequency: f64) -> f64 {
    let weight = ((1.0 + u.z) / 2.0).powi(2);
    let wave = (frequency * u.x).sin() * (frequency * u.y).sin() * (frequency * u.z).sin();
    1.0 + amplitude * weight * wave
}

/// Icosphere whose vertices are pushed radially to
/// `r(u) = radius · (1 + amplitude · w(u) · sin(f·uₓ) · sin(f·u_y) · sin(f·u_z))`
/// with `w(u) = ((1 + u_z) / 2)²` and `f = frequency`, for each unit direction `u`.
///
/// The weight makes the bumps grow from nothing at the south pole to full height at the
/// north pole, so the surface has flat-ish, gently curved and sharply curved regions.
/// `0 ≤ amplitude < 1` keeps `r > 0`: the surface stays star-shaped around the origin,
/// hence embedded and outward oriented. Counts as [`icosphere`].
pub fn bumpy_sphere(
    radius: f64,
    subdivisions: u32,
    amplitude: f64,
    frequency: f64,
) -> Result<Mesh, ShapeError> {
    let radius = positive("radius", radius)?;
    if !(amplitude.is_finite() && (0.0..1.0).contains(&amplitude)) {
        return Err(ShapeError::InvalidParameter {
            name: "amplitude",
            value: amplitude.to_string(),
            expected: "0 ≤ amplitude < 1",
        });
    }
    if !(frequency.is_finite() && frequency >= 0.0) {
        return Err(ShapeError::InvalidParameter {
            name: "frequency",
            value: frequency.to_string(),
            expected: "a finite number ≥ 0",
        });
    }
    fits(
        "bumpy_sphere",
        20u64.saturating_mul(4u64.saturating_pow(subdivisions)),
    )?;
    Ok(bumpy(radius, subdivisions, amplitude, frequency))
}

fn bumpy(radius: f64, subdivisions: u32, amplitude: f64, frequency: f64) -> Mesh {
    let mut m = unit_icosphere(subdivisions);
    m.positions
        .iter_mut()
        .for_each(|p| *p *= radius * bump(*p, amplitude, frequency));
    m
}

/// The built-in demo mesh (`coarsen run` without input): a bumpy sphere of radius 1,
/// 10,242 vertices and 20,480 faces, with bumps of amplitude 0.25 at frequency 7 that
/// fade out towards the south pole (see [`bumpy_sphere`]).
pub fn demo() -> Mesh {
    bumpy(1.0, 5, 0.25, 7.0)
}

/// Keeps only the vertices that faces use, in their original order.
fn compact(positions: Vec<DVec3>, faces: Vec<[Index; 3]>) -> Mesh {
    let mut new_index = vec![Index::MAX; positions.len()];
    for f in &faces {
        for &v in f {
            new_index[v as usize] = 0;
        }
    }
    let mut kept = Vec::new();
    for (v, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = kept.len() as Index;
            kept.push(positions[v]);
        }
    }
    let faces = faces
        .into_iter()
        .map(|f| f.map(|v| new_index[v as usize]))
        .collect();
    Mesh::new(kept, faces)
}

/// Pushes the quad `q` (counter-clockwise seen from its front) as two triangles.
fn push_quad(faces: &mut Vec<[Index; 3]>, q: [Index; 4]) {
    faces.push([q[0], q[1], q[2]]);
    faces.push([q[0], q[2], q[3]]);
}

/// A cube of side `size` centred at the origin, each side an `n × n` grid of squares
/// split into two triangles: the smallest CAD part, with sharp edges and corners. Lattice
/// point `(i, j, k)` (each in `0..=n`, at least one at 0 or `n`) lies at
/// `(i, j, k) · size / n − size / 2`; vertices are numbered in the order the sides first
/// use them (−x, +x, −y, +y, −z, +z).
pub fn cube(size: f64, n: u32) -> Result<Mesh, ShapeError> {
    let size = positive("size", size)?;
    let n = at_least("n", n, 1)?;
    fits("cube", 12u64.saturating_mul(u64::from(n).pow(2)))?;
    let mut index = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let mut id = |p: [u32; 3]| -> Index {
        *index.entry(p).or_insert_with(|| {
            positions.push(
                DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
                    * (size / f64::from(n))
                    - DVec3::splat(size / 2.0),
            );
            (positions.len() - 1) as Index
        })
    };
    let mut faces = Vec::with_capacity(12 * (n * n) as usize);
    for axis in 0..3 {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, n] {
            for u in 0..n {
                for v in 0..n {
                    let at = |du: u32, dv: u32| {
                        let mut p = [0; 3];
                        p[axis] = side;
                        p[b] = u + du;
                        p[c] = v + dv;
                        p
                    };
                    // Counter-clockwise about +axis; the side at 0 faces the other way.
                    let mut q = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)].map(&mut id);
                    if side == 0 {
                        q.reverse();
                    }
                    push_quad(&mut faces, q);
                }
            }
        }
    }
    Ok(Mesh::new(positions, faces))
}

/// A genus-2 solid: a block `5·size × 3·size × size` (centred at the origin) pierced along
/// z by two square holes of side `size`, built from cubic cells of side
/// `size / resolution` and triangulated on its surface.
///
/// It is a voxel surface, not a smooth double torus: curvature sits on its edges and
/// corners (flat faces elsewhere), which makes it a test of sharp features as much as of
/// topology. With `r = resolution` it has `100·r²` triangles: two per cell side on the
/// surface, which has `13·r²` cell sides on top, as many below, `16·r²` on the outer walls
/// and `8·r²` on the hole walls.
pub fn double_torus(size: f64, resolution: u32) -> Result<Mesh, ShapeError> {
    let size = positive("size", size)?;
    let r = at_least("resolution", resolution, 1)?;
    fits("double_torus", 100u64.saturating_mul(u64::from(r).pow(2)))?;
    let (nx, ny, nz) = (5 * r, 3 * r, r);
    // The block is the plan `solid` extruded along z.
    let solid = |i: i64, j: i64| {
        let r = i64::from(r);
        let inside = (0..5 * r).contains(&i) && (0..3 * r).contains(&j);
        let in_hole =
            (r..2 * r).contains(&j) && ((r..2 * r).contains(&i) || (3 * r..4 * r).contains(&i));
        inside && !in_hole
    };
    let mut lattice = Lattice {
        px: nx + 1,
        nz,
        h: size / f64::from(r),
        centre: DVec3::new(2.5 * size, 1.5 * size, 0.5 * size),
        bottom: vec![Index::MAX; ((nx + 1) * (ny + 1)) as usize],
        top: vec![Index::MAX; ((nx + 1) * (ny + 1)) as usize],
        column: vec![Index::MAX; ((nx + 1) * (ny + 1)) as usize],
        positions: Vec::new(),
    };
    let mut faces = Vec::with_capacity(100 * (r * r) as usize);
    for j in 0..ny {
        for i in 0..nx {
            let (si, sj) = (i64::from(i), i64::from(j));
            if !solid(si, sj) {
                continue;
            }
            let mut quad = |faces: &mut Vec<[Index; 3]>, k: u32, q: [(u32, u32, u32); 4]| {
                let q = q.map(|(di, dj, dk)| lattice.vertex(i + di, j + dj, k + dk));
                push_quad(faces, q);
            };
            // Corners counter-clockwise seen from outside.
            quad(&mut faces, 0, [(0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0)]);
            quad(
                &mut faces,
                nz - 1,
                [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
            );
            for k in 0..nz {
                if !solid(si + 1, sj) {
                    quad(&mut faces, k, [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)]);
                }
                if !solid(si - 1, sj) {
                    quad(&mut faces, k, [(0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0)]);
                }
                if !solid(si, sj + 1) {
                    quad(&mut faces, k, [(0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0)]);
                }
                if !solid(si, sj - 1) {
                    quad(&mut faces, k, [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]);
                }
            }
        }
    }
    Ok(Mesh::new(lattice.positions, faces))
}

/// Surface vertices of an extruded cell block, numbered on first use: full grids on the
/// bottom and top layers, one column of in-between vertices per wall corner.
struct Lattice {
    px: u32,
    nz: u32,
    h: f64,
    centre: DVec3,
    bottom: Vec<Index>,
    top: Vec<Index>,
    column: Vec<Index>,
    positions: Vec<DVec3>,
}

impl Lattice {
    fn vertex(&mut self, i: u32, j: u32, k: u32) -> Index {
        let cell = (i + self.px * j) as usize;
        let (h, centre) = (self.h, self.centre);
        let point = |k: u32| h * DVec3::new(f64::from(i), f64::from(j), f64::from(k)) - centre;
        let positions = &mut self.positions;
        let mut new = |p: DVec3| {
            positions.push(p);
            (positions.len() - 1) as Index
        };
        if k == 0 || k == self.nz {
            let slot = if k == 0 {
                &mut self.bottom[cell]
            } else {
                &mut self.top[cell]
            };
            if *slot == Index::MAX {
                *slot = new(point(k));
            }
            *slot
        } else {
            let slot = &mut self.column[cell];
            if *slot == Index::MAX {
                *slot = new(point(1));
                for kk in 2..self.nz {
                    new(point(kk));
                }
            }
            *slot + (k - 1)
        }
    }
}

/// `mesh` with texture coordinates per corner from longitude and latitude about the z axis
/// through the origin: u = longitude / 2π, v = colatitude / π. A face across the meridian
/// where the longitude wraps takes its corners past 1 there, so that meridian is a UV seam;
/// a vertex on the axis takes each face's own longitude (at its centroid).
pub fn with_spherical_uvs(mesh: Mesh) -> Mesh {
    let lon = |p: DVec3| (p.y.atan2(p.x) / TAU).rem_euclid(1.0);
    let mut uv = Vec::with_capacity(3 * mesh.n_faces());
    for face in &mesh.faces {
        let ps = face.map(|v| mesh.positions[v as usize]);
        let centroid = (ps[0] + ps[1] + ps[2]) / 3.0;
        let mut u = ps.map(|p| {
            if p.x.hypot(p.y) < 1e-12 {
                lon(centroid)
            } else {
                lon(p)
            }
        });
        let (lo, hi) = u
            .iter()
            .fold((1.0f64, 0.0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
        if hi - lo > 0.5 {
            u.iter_mut().filter(|x| **x < 0.5).for_each(|x| *x += 1.0);
        }
        for (k, p) in ps.iter().enumerate() {
            let colatitude = (p.z / p.length().max(f64::MIN_POSITIVE))
                .clamp(-1.0, 1.0)
                .acos();
            uv.push(coarsen_mesh::DVec2::new(u[k], colatitude / PI));
        }
    }
    let mut cols = coarsen_mesh::Attributes::default();
    cols.insert("uv", coarsen_mesh::AttrValues::Vec2(uv));
    let wedges = coarsen_mesh::Wedges::from_corners(&mesh.faces, cols);
    Mesh { wedges, ..mesh }
}

/// `mesh` with texture coordinates per corner cut into `charts` islands by face (face `f`
/// in island `(f · stride) mod charts`, each island its own (x, y + z/2) shifted along u):
/// seams of any shape, islands of single faces, seams that meet and end anywhere — a test
/// of whatever keeps seams.
pub fn with_uv_islands(mesh: Mesh, charts: u32, stride: u32) -> Mesh {
    let charts = charts.max(1);
    let mut uv = Vec::with_capacity(3 * mesh.n_faces());
    for (f, face) in mesh.faces.iter().enumerate() {
        let island = (f as u32).wrapping_mul(stride) % charts;
        for &v in face {
            let p = mesh.positions[v as usize];
            uv.push(coarsen_mesh::DVec2::new(
                p.x + 3.0 * island as f64,
                p.y + 0.5 * p.z,
            ));
        }
    }
    let mut cols = coarsen_mesh::Attributes::default();
    cols.insert("uv", coarsen_mesh::AttrValues::Vec2(uv));
    let wedges = coarsen_mesh::Wedges::from_corners(&mesh.faces, cols);
    Mesh { wedges, ..mesh }
}

/// The unit square in the z = 0 plane as two triangles (corners 0, x, x + y, y), with
/// texture coordinates per corner equal to each corner's (x, y): the smallest textured mesh.
pub fn uv_square() -> Mesh {
    with_planar_uvs(Mesh::new(
        vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
        vec![[0, 1, 2], [0, 2, 3]],
    ))
}

/// `mesh` with texture coordinates per corner equal to each corner's (x, y): a projection
/// along z, no seam.
pub fn with_planar_uvs(mesh: Mesh) -> Mesh {
    let uv = mesh
        .faces
        .iter()
        .flatten()
        .map(|&v| mesh.positions[v as usize].truncate())
        .collect();
    let mut cols = coarsen_mesh::Attributes::default();
    cols.insert("uv", coarsen_mesh::AttrValues::Vec2(uv));
    let wedges = coarsen_mesh::Wedges::from_corners(&mesh.faces, cols);
    Mesh { wedges, ..mesh }
}

/// Flat grid in the z = 0 plane, normal +z: `nx × ny` square cells, `size` wide along x
/// (so `size · ny / nx` along y), centred at the origin; each cell split along its
/// diagonal from `(i, j)` to `(i + 1, j + 1)`. One boundary loop.
pub fn plane_grid(nx: u32, ny: u32, size: f64) -> Result<Mesh, ShapeError> {
    let size = positive("size", size)?;
    let nx = at_least("nx", nx, 1)?;
    let ny = at_least("ny", ny, 1)?;
    fits(
        "plane_grid",
        2u64.saturating_mul(u64::from(nx))
            .saturating_mul(u64::from(ny)),
    )?;
    Ok(masked_grid(nx, ny, size / f64::from(nx), |_, _| true))
}

/// Grid of `nx × ny` cells of side `h`, keeping the cells where `keep(i, j)`; unused
/// vertices are dropped.
fn masked_grid(nx: u32, ny: u32, h: f64, keep: impl Fn(u32, u32) -> bool) -> Mesh {
    let id = |i: u32, j: u32| i + (nx + 1) * j;
    let offset = DVec3::new(f64::from(nx), f64::from(ny), 0.0) * (h / 2.0);
    let mut positions = Vec::with_capacity(((nx + 1) * (ny + 1)) as usize);
    for j in 0..=ny {
        for i in 0..=nx {
            positions.push(DVec3::new(f64::from(i), f64::from(j), 0.0) * h - offset);
        }
    }
    let mut faces = Vec::with_capacity((2 * nx * ny) as usize);
    for j in 0..ny {
        for i in 0..nx {
            if keep(i, j) {
                push_quad(
                    &mut faces,
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)],
                );
            }
        }
    }
    compact(positions, faces)
}

/// Flat open patch with `n_holes ≥ 1` square holes in a row: `n_holes` blocks of
/// `3·resolution × 3·resolution` square cells, each with its central
/// `resolution × resolution` cells removed; `size` wide along x, centred at the origin,
/// normal +z. Boundary loops: `n_holes + 1`; Euler characteristic `1 − n_holes`.
/// Faces: `16 · n_holes · resolution²`.
pub fn disk_with_holes(n_holes: u32, resolution: u32, size: f64) -> Result<Mesh, ShapeError> {
    let size = positive("size", size)?;
    let holes = at_least("n_holes", n_holes, 1)?;
    let r = at_least("resolution", resolution, 1)?;
    fits(
        "disk_with_holes",
        16u64
            .saturating_mul(u64::from(holes))
            .saturating_mul(u64::from(r).pow(2)),
    )?;
    let (nx, ny) = (3 * r * holes, 3 * r);
    let in_hole =
        move |i: u32, j: u32| (r..2 * r).contains(&(i % (3 * r))) && (r..2 * r).contains(&j);
    Ok(masked_grid(nx, ny, size / f64::from(nx), |i, j| {
        !in_hole(i, j)
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::topology::TopologySummary;

    fn summary(m: &Mesh) -> TopologySummary {
        Topology::build(m).summary(m)
    }

    /// Closed, manifold, consistently oriented, outward, one component of genus `g`.
    fn assert_closed_surface(m: &Mesh, g: i64) {
        let s = summary(m);
        assert!(s.manifold, "{s:?}");
        assert!(s.consistently_oriented, "{s:?}");
        assert_eq!(s.n_boundary_edges, 0);
        assert_eq!(s.n_components, 1);
        assert_eq!(s.euler, 2 - 2 * g);
        assert_eq!(s.genus, vec![Some(g)]);
        assert_eq!(s.n_degenerate_faces, 0);
        assert!(m.signed_volume() > 0.0, "outward orientation");
        assert!(m.validate_indices().is_ok());
    }

    #[test]
    fn icosahedron_faces_point_outward() {
        let m = icosahedron();
        for f in 0..m.n_faces() {
            assert!(m.face_normal(f).dot(m.face_centroid(f)) > 0.0, "face {f}");
        }
    }

    #[test]
    fn icosphere_counts_radius_and_topology() {
        for k in 0..4 {
            let m = icosphere(2.5, k).unwrap();
            let p = 4usize.pow(k);
            assert_eq!((m.n_vertices(), m.n_faces()), (10 * p + 2, 20 * p));
            assert!(m.positions.iter().all(|v| (v.length() - 2.5).abs() < 1e-12));
            assert_closed_surface(&m, 0);
        }
        let fine = icosphere(1.0, 5).unwrap();
        // Inscribed polyhedron: volume just under 4π/3.
        let v = fine.signed_volume();
        assert!(v < 4.0 / 3.0 * PI && v > 0.99 * 4.0 / 3.0 * PI, "{v}");
    }

    #[test]
    fn uv_sphere_has_single_pole_vertices() {
        let m = uv_sphere(3.0, 6, 8).unwrap();
        assert_eq!((m.n_vertices(), m.n_faces()), (2 + 5 * 8, 2 * 8 * 5));
        assert_eq!(m.positions[0], DVec3::new(0.0, 0.0, 3.0));
        assert_eq!(*m.positions.last().unwrap(), DVec3::new(0.0, 0.0, -3.0));
        assert!(m.positions.iter().all(|v| (v.length() - 3.0).abs() < 1e-12));
        assert_closed_surface(&m, 0);
        // The smallest case: two bands, a double cone.
        assert_closed_surface(&uv_sphere(1.0, 2, 3).unwrap(), 0);
    }

    #[test]
    fn a_cube_is_a_closed_box_of_its_size() {
        for n in [1, 3] {
            let m = cube(2.0, n).unwrap();
            let k = (n * n) as usize;
            assert_eq!((m.n_vertices(), m.n_faces()), (6 * k + 2, 12 * k));
            assert_closed_surface(&m, 0);
            assert!((m.signed_volume() - 8.0).abs() < 1e-12);
            assert!(m.positions.iter().all(|p| p.abs().max_element() == 1.0));
        }
        assert!(cube(0.0, 1).is_err() && cube(1.0, 0).is_err());
    }

    #[test]
    fn torus_has_genus_one() {
        let m = torus(3.0, 1.0, 24, 12).unwrap();
        assert_eq!((m.n_vertices(), m.n_faces()), (288, 576));
        assert_closed_surface(&m, 1);
        for p in &m.positions {
            let ring = DVec3::new(p.x, p.y, 0.0).normalize() * 3.0;
            assert!(((*p - ring).length() - 1.0).abs() < 1e-12);
        }
        assert_closed_surface(&torus(1.0, 0.5, 3, 3).unwrap(), 1);
    }

    #[test]
    fn bumpy_sphere_follows_its_formula() {
        let (a, f) = (0.3, 5.0);
        let m = bumpy_sphere(2.0, 3, a, f).unwrap();
        assert_eq!((m.n_vertices(), m.n_faces()), (642, 1280));
        assert_closed_surface(&m, 0);
        let unit = icosphere(1.0, 3).unwrap();
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for (p, u) in m.positions.iter().zip(&unit.positions) {
            let expect = 2.0 * bump(*u, a, f);
            assert!((p.length() - expect).abs() < 1e-12);
            lo = lo.min(p.length());
            hi = hi.max(p.length());
        }
        assert!(
            lo < 1.7 && hi > 2.3,
            "bumps reach well off the sphere: {lo}..{hi}"
        );
        // Amplitude 0 is the plain icosphere.
        assert_eq!(
            bumpy_sphere(2.0, 3, 0.0, f).unwrap(),
            icosphere(2.0, 3).unwrap()
        );
    }

    #[test]
    fn demo_is_a_bumpy_sphere_of_twenty_thousand_faces() {
        let m = demo();
        assert_eq!((m.n_vertices(), m.n_faces()), (10_242, 20_480));
        assert_closed_surface(&m, 0);
        assert_eq!(m, demo(), "deterministic");
        // Curvature varies: dihedral angles are tiny near the south pole, large up north.
        let t = Topology::build(&m);
        let normals: Vec<DVec3> = (0..m.n_faces()).map(|f| m.face_normal(f)).collect();
        let (mut south, mut north) = (0.0f64, 0.0f64);
        for e in 0..t.n_edges() as u32 {
            let [f, g] = [t.edge_faces(e)[0], t.edge_faces(e)[1]];
            let bend = normals[f as usize].angle_between(normals[g as usize]);
            let z = m.positions[t.edge(e)[0] as usize].z;
            if z < -0.9 {
                south = south.max(bend);
            } else if z > 0.5 {
                north = north.max(bend);
            }
        }
        assert!(north > 4.0 * south, "north {north} vs south {south}");
    }

    #[test]
    fn double_torus_has_genus_two() {
        for r in 1..4 {
            let m = double_torus(1.0, r).unwrap();
            assert_eq!(m.n_faces() as u32, 100 * r * r);
            assert_closed_surface(&m, 2);
            let volume = 5.0 * 3.0 - 2.0;
            assert!((m.signed_volume() - volume).abs() < 1e-9);
        }
    }

    #[test]
    fn plane_grid_is_a_disc_with_one_loop() {
        let m = plane_grid(4, 3, 2.0).unwrap();
        assert_eq!((m.n_vertices(), m.n_faces()), (20, 24));
        let t = Topology::build(&m);
        let s = t.summary(&m);
        assert_eq!((s.n_boundary_loops, s.euler), (1, 1));
        assert_eq!(s.genus, vec![Some(0)]);
        assert!(s.manifold && s.consistently_oriented);
        assert_eq!(t.boundary_loop(0).len(), 2 * (4 + 3));
        assert!((0..m.n_faces()).all(|f| m.face_normal(f) == DVec3::Z));
        assert!((m.area() - 2.0 * 1.5).abs() < 1e-12);
    }

    #[test]
    fn disk_with_holes_has_one_loop_per_hole_plus_the_rim() {
        for (holes, r) in [(1, 1), (3, 2)] {
            let m = disk_with_holes(holes, r, 6.0).unwrap();
            assert_eq!(m.n_faces() as u32, 16 * holes * r * r);
            let s = summary(&m);
            assert_eq!(s.n_boundary_loops as u32, holes + 1);
            assert_eq!(s.euler, 1 - i64::from(holes));
            assert_eq!(s.genus, vec![Some(0)]);
            assert!(s.manifold && s.consistently_oriented);
            assert_eq!(s.n_isolated_vertices, 0);
        }
    }

    #[test]
    fn bad_parameters_are_named() {
        let err = |r: Result<Mesh, ShapeError>| match r {
            Err(ShapeError::InvalidParameter { name, .. }) => name,
            other => panic!("expected an invalid parameter, got {other:?}"),
        };
        assert_eq!(err(icosphere(f64::NAN, 1)), "radius");
        assert_eq!(err(uv_sphere(1.0, 1, 8)), "n_lat");
        assert_eq!(err(torus(1.0, 1.0, 8, 8)), "minor");
        assert_eq!(err(bumpy_sphere(1.0, 1, 1.0, 3.0)), "amplitude");
        assert_eq!(err(bumpy_sphere(1.0, 1, 0.5, f64::INFINITY)), "frequency");
        assert_eq!(err(plane_grid(0, 3, 1.0)), "nx");
        assert_eq!(err(disk_with_holes(2, 0, 1.0)), "resolution");
        assert_eq!(err(double_torus(-1.0, 2)), "size");
        assert!(matches!(
            icosphere(1.0, 40),
            Err(ShapeError::TooLarge {
                what: "icosphere",
                ..
            })
        ));
        assert!(matches!(
            torus(2.0, 1.0, u32::MAX, u32::MAX),
            Err(ShapeError::TooLarge { .. })
        ));
    }
}
