//! The `normals` stage: recomputes the mesh's normals from its faces, per corner, so that a
//! coarse mesh is shaded as its own faces say (a carried normal describes the input's
//! surface where the vertex stood, not the coarse faces around it).
//!
//! Each face corner's normal is the weighted sum of the unit normals of the faces in its
//! *smoothing group*: the corners around its vertex that meet across edges whose faces turn
//! by at most `crease_deg` (an edge of more or fewer than two faces separates groups). The
//! weight is each face's angle at the vertex (`weighting = "angle"`, Thürmer and Wüthrich's
//! mean weighted by angle: independent of how a flat region is triangulated) or its area
//! (`"area"`). A vertex on a hard edge thus gets one normal per side, as a wedge; the
//! normals that agree at every vertex are a vertex column. Other per-corner columns (UVs)
//! are kept as they are. The geometry is not touched.

use coarsen_geom::DVec3;
use coarsen_mesh::{AttrValues, Index, Mesh};
use coarsen_stage::{Context, Contract, ParamIssue, Params, Stage, StageError, params};

params! {
    /// Parameters of `normals`.
    pub struct NormalsParams {
        /// Two faces meeting at an edge are shaded as one smooth surface when their normals
        /// differ by at most this (degrees); 0 shades every face flat, 180 smooths across
        /// every edge of two faces.
        pub crease_deg: f64 = 60.0,
        /// How the faces around a vertex weigh: `angle` (their angle at the vertex) or
        /// `area`.
        pub weighting: String = "angle".to_string(),
    }
}

impl Params for NormalsParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut v = Vec::new();
        coarsen_stage::params::check_range(&mut v, "crease_deg", self.crease_deg, 0.0, 180.0);
        if !matches!(self.weighting.as_str(), "angle" | "area") {
            v.push(ParamIssue::new(
                "weighting",
                format!("`{}`: expected `angle` or `area`", self.weighting),
            ));
        }
        v
    }
}

/// The `normals` stage.
pub struct Normals(NormalsParams);

/// The column the normals are written to.
pub const NORMAL: &str = "normal";

impl Stage for Normals {
    type Params = NormalsParams;
    const KIND: &'static str = "normals";
    const SUMMARY: &'static str = "Per-corner normals recomputed from the faces (angle- or area-weighted), split at hard edges above a crease angle.";

    fn new(params: NormalsParams) -> Self {
        Normals(params)
    }

    fn contract(&self) -> Contract {
        Contract {
            carries_wedges: true,
            ..Contract::default()
        }
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let by_area = self.0.weighting == "area";
        let normals = corner_normals(&mesh, self.0.crease_deg, by_area);
        mesh.vertex_attrs.remove(NORMAL);
        let mut columns = mesh.wedges.corner_values();
        columns.insert(NORMAL, AttrValues::Vec3(normals));
        mesh = mesh.with_corner_attributes(columns);
        let split = match mesh.wedges.attrs().get(NORMAL) {
            Some(_) => mesh.wedges.split_vertices(),
            None => 0,
        };
        cx.report.figure("hard_edge_vertices", split);
        Ok(mesh)
    }
}

/// Each face corner's normal (`3 · face + k`): the weighted unit normals of the faces of
/// its smoothing group (module docs), unit length; zero where they cancel or every face is
/// degenerate.
pub fn corner_normals(mesh: &Mesh, crease_deg: f64, by_area: bool) -> Vec<DVec3> {
    let n_faces = mesh.n_faces();
    let unit: Vec<DVec3> = (0..n_faces).map(|f| mesh.face_normal(f)).collect();
    // Corners joined across smooth edges, as a union-find over corners.
    let mut parent: Vec<Index> = (0..3 * n_faces as Index).collect();
    let cos_crease = crease_deg.to_radians().cos();
    let mut edges: Vec<(Index, Index, Index)> = Vec::with_capacity(3 * n_faces);
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b), (3 * f + k) as Index));
        }
    }
    edges.sort_unstable();
    for run in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        let [(_, _, c1), (_, _, c2)] = run else {
            continue;
        };
        let (f1, f2) = (*c1 as usize / 3, *c2 as usize / 3);
        let smooth = unit[f1] != DVec3::ZERO
            && unit[f2] != DVec3::ZERO
            && (crease_deg >= 180.0 || unit[f1].dot(unit[f2]) >= cos_crease);
        if !smooth {
            continue;
        }
        // The corners at each end of the shared edge, in each face.
        for v in [run[0].0, run[0].1] {
            let at = |f: usize| (3 * f + corner_of(mesh.faces[f], v)) as Index;
            union(&mut parent, at(f1), at(f2));
        }
    }
    let weight = |f: usize, k: usize| -> f64 {
        let [a, b, c] = mesh.faces[f].map(|v| mesh.positions[v as usize]);
        if by_area {
            return 0.5 * (b - a).cross(c - a).length();
        }
        let (p, q, r) = match k {
            0 => (a, b, c),
            1 => (b, c, a),
            _ => (c, a, b),
        };
        (q - p).angle_between(r - p)
    };
    let mut sum = vec![DVec3::ZERO; 3 * n_faces];
    for c in 0..3 * n_faces {
        let root = find(&mut parent, c as Index) as usize;
        let w = weight(c / 3, c % 3);
        if w.is_finite() {
            sum[root] += w * unit[c / 3];
        }
    }
    (0..3 * n_faces)
        .map(|c| sum[find(&mut parent, c as Index) as usize].normalize_or_zero())
        .collect()
}

/// The corner of `face` at vertex `v`.
fn corner_of(face: [Index; 3], v: Index) -> usize {
    face.iter().position(|&u| u == v).unwrap_or(0)
}

fn find(parent: &mut [Index], mut x: Index) -> Index {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

/// Joins the groups of `a` and `b` (the smaller root names the group).
fn union(parent: &mut [Index], a: Index, b: Index) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
}

coarsen_stage::export_stage!(Normals);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_stage::StageReport;

    fn run(mesh: &Mesh, params: NormalsParams) -> (Mesh, StageReport) {
        let mut report = StageReport::default();
        let mut cx = Context::new(mesh, &mut report);
        let out = Normals::new(params).run(mesh.clone(), &mut cx).unwrap();
        (out, report)
    }

    fn cube() -> Mesh {
        coarsen_shapes::cube(1.0, 1).unwrap()
    }

    #[test]
    fn a_cube_gets_one_normal_per_side_and_a_sphere_one_per_vertex() {
        let (out, report) = run(&cube(), NormalsParams::default());
        assert_eq!(out.positions, cube().positions);
        // Every corner of the cube is on three hard edges: three wedges each, axis normals.
        assert_eq!(report.get("hard_edge_vertices"), Some(&8.into()));
        let Some(AttrValues::Vec3(n)) = out.corner_column(NORMAL) else {
            panic!("corner normals")
        };
        for (c, &v) in out.faces.iter().flatten().enumerate() {
            let face = c / 3;
            assert!(
                (n[c] - out.face_normal(face)).length() < 1e-12,
                "corner {c} of {v}"
            );
        }
        // Smooth across every edge (180°): one normal per vertex, a vertex column.
        let smooth = NormalsParams {
            crease_deg: 180.0,
            ..Default::default()
        };
        let sphere = coarsen_shapes::icosphere(1.0, 2).unwrap();
        let (out, report) = run(&sphere, smooth);
        assert_eq!(report.get("hard_edge_vertices"), Some(&0.into()));
        assert!(out.wedges.is_empty());
        let n = out.vertex_attrs.vec3(NORMAL).expect("vertex normals");
        for (p, n) in out.positions.iter().zip(n) {
            assert!(p.normalize().dot(*n) > 0.99, "a sphere's normals point out");
        }
    }

    #[test]
    fn uvs_stay_and_weighting_by_angle_ignores_how_a_flat_side_is_cut() {
        // A roof ridge along x through vertex 0: one triangle on the side y > 0, three of
        // uneven sizes on the side y < 0, each side a right angle at vertex 0.
        let t = 0.5;
        let side = |deg: f64| {
            let a = deg.to_radians();
            DVec3::new(a.cos(), -a.sin(), -a.sin() * t)
        };
        let m = coarsen_shapes::with_planar_uvs(Mesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::new(0.0, 1.0, -t),
                side(90.0),
                side(60.0),
                side(20.0),
            ],
            vec![[0, 1, 2], [0, 3, 4], [0, 4, 5], [0, 5, 1]],
        ));
        let Some(AttrValues::Vec2(uv)) = m.corner_column("uv") else {
            unreachable!("planar UVs")
        };
        let at_ridge = |weighting: &str| {
            let p = NormalsParams {
                crease_deg: 180.0,
                weighting: weighting.into(),
            };
            let (out, _) = run(&m, p);
            assert_eq!(out.corner_column("uv"), Some(AttrValues::Vec2(uv.clone())));
            out.vertex_attrs.vec3(NORMAL).expect("smooth: per vertex")[0]
        };
        // By angle, the two sides weigh alike: straight up. By area, the cut side leans.
        assert!((at_ridge("angle") - DVec3::Z).length() < 1e-12);
        assert!((at_ridge("area") - DVec3::Z).length() > 1e-3);
    }

    #[test]
    fn bad_parameters_are_named() {
        let p = NormalsParams {
            crease_deg: 200.0,
            weighting: "size".into(),
        };
        let issues = p.validate();
        assert_eq!(issues.len(), 2, "{issues:?}");
    }
}
