//! The `simplify.qem` stage: Garland & Heckbert (1997) quadric edge collapse down to the
//! run target — the baseline both papers compare to.
//!
//! The work is done by the shared collapse engine (`coarsen-collapse`), with its
//! [`QuadricModel`]: per-vertex quadrics from the face planes (area-weighted by default),
//! boundary constraint planes, optimal placement with guarded fall-backs, and the engine's
//! validity checks (link condition, flips, degenerate faces, optional quality guard) and
//! boundary rules. Non-manifold vertices are locked in place rather than refused, so the
//! stage does not need a manifold input.
//!
//! | parameter | default | meaning |
//! | --- | --- | --- |
//! | `max_error` | `0` (none) | stop before the first collapse costing more (cost of the mesh scaled to a unit diagonal) |
//! | `boundary_weight` | `1000` | weight of the boundary constraint planes relative to the face planes |
//! | `min_quality` | `0` (off) | refuse collapses leaving a triangle below this quality and below its previous quality |
//! | `area_weighted` | `true` | weight each face plane by its area |
//! | `facing_guard` | `true` | refuse collapses turning a face away from the run input's surface nearest it (see below) |
//! | `parallel` | `true` | on meshes of 2¹⁹ faces or more, make most collapses in parts of the mesh side by side (see below) |
//! | `unit` | `"edge"` | `edge`, or `triangle`: triangle collapses (the three vertex quadrics summed), then a few edge collapses to meet the target — paper 2's baseline \[8\] with `area_weighted = false` (its \[3\] is the edge unit with `area_weighted = false`) |
//! | `sve_weighted` | `false` | also report `sve_weighted`, the swept squared volumes weighted as paper 2's Eq. (4) (to compare with `simplify.svec`) |
//!
//! The run is the collapse stages' shared skeleton (`coarsen_collapse::stage`): the target
//! from the run (`--vertices`, `--faces`, `--ratio` or the pipeline's; a vertex count met
//! exactly, a face count or ratio too where the mesh has a boundary, on a closed mesh to
//! within one face), the progressive record, the **facing guard** (`facing_guard`: a
//! collapse is refused, `refused.facing`, when a face it reshapes would point away from
//! the run input's surface nearest it; on the cow's thin legs, ears and tail this removes
//! the faces that ended nearest to the part's other side), progress, attribute carrying,
//! and the report's figures (`collapses`, `parallel_collapses`, `refused` by reason,
//! `facing_tests`, `sve`, `sve_max`, `max_cost`, `cost_curve` (`[collapses, largest cost]`
//! bins, for the HTML report's plot), the final `vertices` and `faces`, `stop`, the
//! `locked_vertices` and the `boundary_loops` before and after) and warnings (a target not
//! reached, locked and dropped vertices).
//!
//! **Beside `simplify.svec`**, which runs the same skeleton: QEM collapses edges (SVEC
//! triangles, then a few edges to meet the target exactly); its quadrics are summed per
//! vertex as the collapses merge them, so only the candidates at the new vertex are
//! re-costed (SVEC measures from the current faces and re-costs a ring); the new vertex
//! goes where its quadric is least, kept on the boundary by constraint planes that are on
//! by default (SVEC: the paper's placement rules with a feature filter, no boundary planes
//! by default); the parallel phase's second round makes one step (SVEC up to 16); no
//! `target_scale`, and no figures of its own.
//!
//! **Parallel phase** (`parallel`): on a mesh of 2¹⁹ faces or more, the engine first cuts
//! the mesh into parts of about 2¹⁷ faces and collapses them side by side, up to nine tenths
//! of the collapses needed, then once more with the cuts moved halfway (up to the cost that
//! the collapses still needed reach), and leaves the rest to one greedy order
//! (`LiveMesh::collapse_in_parts`). The output does not depend on the thread count, but it
//! is not the purely serial one; with `--progressive` the run is serial (the record needs
//! every collapse made on the whole mesh), so its output may differ from a run without. On
//! the bunny subdivided three times (4.4M faces) to 60,000 faces the stage took 9.8 s
//! instead of 14.1 s, its Hausdorff distance 0.052 % of the diagonal instead of 0.047 %,
//! Q_avg 0.694 against 0.695; with noise added, 31 s instead of 71 s, `sve` +2 %.
//!
//! ```
//! use coarsen_stage::{Context, Stage, StageReport, Target};
//! use coarsen_stage_qem::{QemParams, SimplifyQem};
//! # use coarsen_mesh::{DVec3, Mesh};
//! # let p = [DVec3::X, DVec3::Y, -DVec3::X, -DVec3::Y, DVec3::Z, -DVec3::Z];
//! # let faces = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4],
//! #                  [1, 0, 5], [2, 1, 5], [3, 2, 5], [0, 3, 5]];
//! let octahedron = Mesh::new(p.to_vec(), faces);
//! let mut report = StageReport::default();
//! let mut cx = Context::new(&octahedron, &mut report);
//! cx.target = Some(Target::Vertices(5));
//! let out = SimplifyQem::new(QemParams::default()).run(octahedron.clone(), &mut cx)?;
//! assert_eq!(out.n_vertices(), 5);
//! assert_eq!(report.get("collapses"), Some(&1.into()));
//! # Ok::<(), coarsen_stage::StageError>(())
//! ```

use coarsen_collapse::stage::{Collapsed, Simplifier, triangles_then_edges};
use coarsen_collapse::{
    FaceGuard, Goal, LiveMesh, Options, PartOptions, QemOptions, QuadricModel, Unit,
};
use coarsen_stage::params::{check_finite_min, check_range};
use coarsen_stage::{
    Context, Contract, Mesh, ParamIssue, Params, Stage, StageError, TargetCount, params,
};

params! {
    /// Parameters of `simplify.qem`.
    pub struct QemParams {
        /// Largest collapse cost allowed, as the quadric error of the mesh scaled to a unit
        /// bounding-box diagonal (area × squared distance when `area_weighted`); the run stops
        /// before the first collapse costing more. 0 means no limit.
        pub max_error: f64 = 0.0,
        /// Weight of the boundary constraint planes (through each boundary edge,
        /// perpendicular to its face) relative to the face planes; 0 drops them.
        pub boundary_weight: f64 = 1000.0,
        /// Refuse collapses that leave a triangle below this Frey–Borouchaki quality (and
        /// below its quality before); 0 turns the guard off.
        pub min_quality: f64 = 0.0,
        /// Weight each face plane by the face's area (else every face counts 1).
        pub area_weighted: bool = true,
        /// Refuse collapses that would turn a face away from the run input's surface
        /// nearest it (the metrics' flipped-face test), tested where the engine's gate says
        /// a face could fail (thin parts, sharp turns); `false` leaves only the engine's own
        /// flip checks.
        pub facing_guard: bool = true,
        /// On meshes of 2¹⁹ faces or more, make most collapses on parts of the mesh side
        /// by side (`coarsen_collapse::LiveMesh::collapse_in_parts`) before the last ones
        /// in one greedy order; `false` makes them all in that order.
        pub parallel: bool = true,
        /// What one collapse merges: `edge` (Garland–Heckbert) or `triangle` — the three
        /// vertices' quadrics summed, then a few edge collapses to meet the target exactly
        /// (paper 2's baseline [8], Zhou, Pan & Shi 1998: "a triangle constriction method
        /// based on QEM"; its cost transmission to related triangles is not described and
        /// not done).
        pub unit: String = "edge".to_string(),
        /// Also report `sve_weighted`: each collapse's squared volume weighted as paper 2's
        /// Eq. (4) quadrics (Wᵢ·Nᵢ per face), to compare with `simplify.svec` runs.
        pub sve_weighted: bool = false,
        /// Keep the input's sharp features (`coarsen-features`): its corners (where three or
        /// more sharp or boundary curves meet or one turns sharply) as they are, no collapse
        /// merging or moving them; the vertices of sharp curves between two surface patches
        /// where they are, merged along their curve only.
        pub features: bool = false,
        /// An input edge is sharp when its two faces' normals differ by more than this
        /// (degrees), for `features`.
        pub feature_angle_deg: f64 = 40.0,
        /// Where a collapse puts the vertex it keeps: `optimal` (the point of least quadric
        /// error) or `vertices` (the cheaper of the edge's two vertices, where it is:
        /// Garland–Heckbert's subset placement, as meshoptimizer's simplifier does), so
        /// that every output vertex is an input vertex at its place — a level of detail
        /// can share the input's vertex buffer, and its UVs are exact at the vertices.
        /// `vertices` needs `unit = "edge"`. `surface`: the point of least error, then,
        /// after the last collapse, the nearest point of the input faces the vertex stands
        /// for, where that spoils no face — every output vertex on the input surface, its
        /// UVs exact there as at an input vertex (`coarsen_collapse`'s settling; the report
        /// gives `settled_vertices` and `settle_refused`). `auto`: `surface` when the mesh
        /// has texture coordinates, else `optimal`.
        pub placement: String = "auto".to_string(),
        /// Weight of the texture coordinates in the cost: Hoppe's (1999) attribute terms,
        /// how far the merged faces' UV fields are from one linear map, UVs scaled so that
        /// the texture's width weighs as the bounding-box diagonal (`coarsen_collapse`'s
        /// `QuadricModel`). 0: a geometric cost; only on meshes with UVs.
        pub uv_weight: f64 = 0.0,
    }
}

/// [`QemParams::unit`] as the engine's unit, `None` when it names neither.
fn unit_named(name: &str) -> Option<Unit> {
    match name {
        "edge" => Some(Unit::Edge),
        "triangle" => Some(Unit::Triangle),
        _ => None,
    }
}

impl Params for QemParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut issues = Vec::new();
        check_finite_min(&mut issues, "max_error", self.max_error, 0.0);
        check_finite_min(&mut issues, "boundary_weight", self.boundary_weight, 0.0);
        check_finite_min(&mut issues, "uv_weight", self.uv_weight, 0.0);
        check_range(&mut issues, "min_quality", self.min_quality, 0.0, 1.0);
        check_range(
            &mut issues,
            "feature_angle_deg",
            self.feature_angle_deg,
            0.0,
            180.0,
        );
        if unit_named(&self.unit).is_none() {
            issues.push(ParamIssue {
                field: "unit",
                message: format!("`{}` is neither `edge` nor `triangle`", self.unit),
            });
        }
        match self.placement.as_str() {
            "optimal" | "surface" | "auto" => {}
            "vertices" if self.unit == "edge" => {}
            "vertices" => issues.push(ParamIssue {
                field: "placement",
                message: "`vertices` needs `unit = \"edge\"`".into(),
            }),
            other => issues.push(ParamIssue {
                field: "placement",
                message: format!(
                    "`{other}` is none of `optimal`, `vertices`, `surface` and `auto`"
                ),
            }),
        }
        issues
    }
}

/// Garland–Heckbert quadric edge collapse to the run target.
pub struct SimplifyQem(QemParams);

impl Stage for SimplifyQem {
    type Params = QemParams;
    const KIND: &'static str = "simplify.qem";
    const SUMMARY: &'static str =
        "Garland–Heckbert quadric edge collapse down to the run target (the QEM baseline).";

    const RECORDS_COLLAPSES: bool = true;

    fn new(params: QemParams) -> Self {
        SimplifyQem(params)
    }

    fn contract(&self) -> Contract {
        coarsen_collapse::stage::contract()
    }

    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        coarsen_collapse::stage::run(Self::KIND, &mut Qem(&self.0), mesh, cx)
    }
}

/// The QEM side of the collapse-stage skeleton: edge (or triangle) collapses under the
/// quadric model, in parts first on big meshes, then in one greedy order.
struct Qem<'a>(&'a QemParams);

impl Qem<'_> {
    fn unit(&self) -> Unit {
        unit_named(&self.0.unit).unwrap_or(Unit::Edge)
    }
}

impl Simplifier for Qem<'_> {
    fn unit(&self) -> Unit {
        Qem::unit(self)
    }

    fn goal(&self, count: TargetCount) -> Goal {
        match count {
            TargetCount::Vertices(n) => Goal::Vertices(usize::try_from(n).unwrap_or(usize::MAX)),
            TargetCount::Faces(n) => Goal::Faces(usize::try_from(n).unwrap_or(usize::MAX)),
        }
    }

    fn facing_guard(&self) -> bool {
        self.0.facing_guard
    }

    fn kept_corners(&self) -> Option<f64> {
        self.0.features.then_some(self.0.feature_angle_deg)
    }

    fn max_error(&self) -> f64 {
        self.0.max_error
    }

    fn settles(&self, mesh: &Mesh) -> bool {
        match self.0.placement.as_str() {
            "surface" => true,
            "auto" => coarsen_collapse::stage::has_uvs(mesh),
            _ => false,
        }
    }

    fn weighted_sve(&self) -> bool {
        self.0.sve_weighted
    }

    fn collapse<G: FaceGuard + Send>(
        &mut self,
        live: &mut LiveMesh,
        goal: Goal,
        new_guard: impl Fn() -> G + Sync,
        progress: &mut dyn FnMut(usize),
    ) -> Collapsed {
        let p = self.0;
        let unit = Qem::unit(self);
        if p.placement == "vertices" {
            live.keep_input_positions();
        }
        let mut model = QuadricModel::new(
            live,
            &QemOptions {
                area_weighted: p.area_weighted,
                boundary_weight: p.boundary_weight,
                unit,
                uv_weight: p.uv_weight,
            },
        );
        let opts = Options {
            goal,
            max_error: (p.max_error > 0.0).then_some(p.max_error),
            min_quality: p.min_quality,
            keep_log: false,
            weighted_sve: p.sve_weighted,
            ..Options::new(goal)
        };
        let parts = PartOptions::when(p.parallel);
        if unit == Unit::Edge {
            return live
                .collapse_parted(&mut model, new_guard, &opts, &parts, progress)
                .into();
        }
        // Triangle collapses stop short of the goal; edge collapses finish.
        let to_edges = |m: &mut QuadricModel| m.set_unit(Unit::Edge);
        let (run, _) = triangles_then_edges(
            live, &mut model, new_guard, &opts, &parts, to_edges, progress,
        );
        run.into()
    }
}

coarsen_stage::export_stage!(SimplifyQem);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::DVec3;
    use coarsen_shapes::{disk_with_holes, icosphere, plane_grid};
    use coarsen_stage::{StageReport, Target};

    fn run(
        mesh: &Mesh,
        target: Option<Target>,
        params: QemParams,
    ) -> (Result<Mesh, StageError>, StageReport) {
        let mut report = StageReport::default();
        let mut cx = Context::new(mesh, &mut report);
        cx.target = target;
        let out = SimplifyQem::new(params).run(mesh.clone(), &mut cx);
        (out, report)
    }

    #[test]
    fn per_vertex_uvs_take_the_value_where_each_vertex_lands() {
        // A bumpy sheet whose UV is its (x, y): a vertex's UV must name its own place.
        let mut mesh = plane_grid(30, 30, 1.0).unwrap();
        for p in &mut mesh.positions {
            p.z = 0.05 * (6.0 * p.x).sin() * (5.0 * p.y).cos();
        }
        let uv = mesh.positions.iter().map(|p| p.truncate()).collect();
        mesh.vertex_attrs
            .insert("uv", coarsen_mesh::AttrValues::Vec2(uv));
        let (out, report) = run(&mesh, Some(Target::Vertices(80)), QemParams::default());
        let out = out.unwrap();
        assert!(out.wedges.is_empty(), "per vertex in, per vertex out");
        let uv = out.vertex_attrs.vec2("uv").expect("uv carried");
        let t = coarsen_metrics::texture(&mesh, &out, 2f64.sqrt()).unwrap();
        assert_eq!(t.uv_flipped + t.uv_degenerate, 0, "{t:?}");
        // Each UV lands within the vertex's distance from the sheet (far under a blend of
        // the merged vertices' UVs, a cluster's width).
        let h = coarsen_metrics::measure(Some(&mesh), &out, &Default::default())
            .unwrap()
            .fidelity
            .unwrap()
            .hausdorff_pct;
        assert!(t.distortion_max_pct <= h, "{t:?}, Hausdorff {h}");
        assert!(
            uv.iter()
                .zip(&out.positions)
                .all(|(t, p)| t.distance(p.truncate()) < 0.02)
        );
        assert_eq!(report.get("seam_vertices_in"), Some(&0.into()));
    }

    #[test]
    fn placement_at_vertices_keeps_input_vertices_and_exact_uvs() {
        // A sphere with a UV seam along a meridian, and a disk with holes (boundaries).
        let sphere = coarsen_shapes::with_spherical_uvs(icosphere(1.0, 4).unwrap());
        let disk = coarsen_shapes::with_uv_islands(disk_with_holes(3, 24, 1.0).unwrap(), 1, 1);
        for (mesh, n, curved) in [(sphere, 300, true), (disk, 150, false)] {
            let params = QemParams {
                placement: "vertices".into(),
                ..QemParams::default()
            };
            let (out, _) = run(&mesh, Some(Target::Vertices(n)), params);
            let out = out.unwrap();
            assert_eq!(out.n_vertices() as u64, n);
            let mut input: Vec<[u64; 3]> = mesh
                .positions
                .iter()
                .map(|p| p.to_array().map(f64::to_bits))
                .collect();
            input.sort_unstable();
            for p in &out.positions {
                let bits = p.to_array().map(f64::to_bits);
                assert!(input.binary_search(&bits).is_ok(), "{p} is no input vertex");
            }
            let t = coarsen_metrics::texture(&mesh, &out, 2.0 * 3f64.sqrt()).unwrap();
            assert_eq!(t.distortion_max_pct, 0.0, "{t:?}");
            assert_eq!(t.uv_flipped + t.uv_degenerate, 0, "{t:?}");
            // On the sphere the optimal placement moves vertices off the input surface.
            let optimal = QemParams {
                placement: "optimal".into(),
                ..QemParams::default()
            };
            let (moved, _) = run(&mesh, Some(Target::Vertices(n)), optimal);
            let t = coarsen_metrics::texture(&mesh, &moved.unwrap(), 2.0 * 3f64.sqrt()).unwrap();
            assert_eq!(t.distortion_max_pct > 0.0, curved, "{t:?}");
        }
        let issues = QemParams {
            placement: "vertices".into(),
            unit: "triangle".into(),
            ..QemParams::default()
        }
        .validate();
        assert_eq!(issues.len(), 1, "{issues:?}");
        assert_eq!(
            issues[0].to_string(),
            "placement: `vertices` needs `unit = \"edge\"`"
        );
    }

    /// The vertices of `m` where faces of two materials meet.
    #[test]
    fn automatic_placement_settles_textured_meshes_on_the_input() {
        let bare = icosphere(1.0, 4).unwrap();
        let textured = coarsen_shapes::with_spherical_uvs(bare.clone());
        let target = Some(Target::Vertices(300));
        let with = |placement: &str| QemParams {
            placement: placement.into(),
            ..QemParams::default()
        };
        // With UVs: every moved vertex on the input, its UVs exact there.
        let (out, report) = run(&textured, target, QemParams::default());
        let out = out.unwrap();
        let settled = report
            .get("settled_vertices")
            .and_then(|v| v.as_u64())
            .unwrap();
        assert!(settled > 250, "{settled}");
        assert_eq!(report.get("settle_refused"), Some(&0.into()));
        let t = coarsen_metrics::texture(&textured, &out, 2.0 * 3f64.sqrt()).unwrap();
        assert!(t.distortion_max_pct < 1e-9, "{t:?}");
        assert_eq!(t.uv_flipped + t.uv_degenerate, 0, "{t:?}");
        // The same collapses as the optimal placement, the vertices moved after them.
        let (optimal, _) = run(&textured, target, with("optimal"));
        assert_eq!(out.faces, optimal.unwrap().faces);
        let (surface, _) = run(&textured, target, with("surface"));
        assert_eq!(surface.unwrap().positions, out.positions);
        // Without UVs: the optimal placement, to the bit.
        let (auto, report) = run(&bare, target, QemParams::default());
        let (optimal, _) = run(&bare, target, with("optimal"));
        assert_eq!(auto.unwrap().positions, optimal.unwrap().positions);
        assert!(report.get("settled_vertices").is_none());
    }

    fn material_border(m: &Mesh) -> Vec<[u64; 3]> {
        let material = m
            .face_attrs
            .label(coarsen_mesh::material::MATERIAL)
            .unwrap();
        let mut first = vec![u32::MAX; m.n_vertices()];
        let mut border = vec![false; m.n_vertices()];
        for (face, &k) in m.faces.iter().zip(material) {
            for &v in face {
                let f = &mut first[v as usize];
                border[v as usize] |= *f != u32::MAX && *f != k;
                *f = k;
            }
        }
        let mut out: Vec<[u64; 3]> = (0..m.n_vertices())
            .filter(|&v| border[v])
            .map(|v| m.positions[v].to_array().map(f64::to_bits))
            .collect();
        out.sort_unstable();
        out
    }

    #[test]
    fn borders_between_materials_stay_where_they_were() {
        // A sphere in three materials by latitude bands, without UVs.
        let mut mesh = icosphere(1.0, 4).unwrap();
        let material = (0..mesh.n_faces())
            .map(|f| {
                let z = mesh.faces[f]
                    .iter()
                    .map(|&v| mesh.positions[v as usize].z)
                    .sum::<f64>();
                u32::from(z > -0.6) + u32::from(z > 1.2)
            })
            .collect();
        mesh.face_attrs.insert(
            coarsen_mesh::material::MATERIAL,
            coarsen_mesh::AttrValues::Label(material),
        );
        let border_in = material_border(&mesh);
        assert!(border_in.len() > 40);
        let (out, report) = run(&mesh, Some(Target::Vertices(150)), QemParams::default());
        let out = out.unwrap();
        assert_eq!(out.n_vertices(), 150);
        assert!(out.wedges.is_empty(), "no column added to the output");
        assert!(
            report
                .get("seam_vertices_in")
                .is_some_and(|n| n.as_u64() > Some(40))
        );
        // Every border vertex of the output is one of the input's, where it was.
        let border_out = material_border(&out);
        assert!(border_out.len() >= 12, "{}", border_out.len());
        for p in &border_out {
            assert!(border_in.binary_search(p).is_ok(), "{p:?} left the border");
        }
    }

    #[test]
    fn hands_back_its_progressive_record_only_when_asked() {
        let mesh = icosphere(1.0, 2).unwrap();
        let mut report = StageReport::default();
        let mut slot = None;
        let mut cx = Context::new(&mesh, &mut report);
        cx.target = Some(Target::Vertices(50));
        cx.progressive = Some(&mut slot);
        let out = SimplifyQem::new(QemParams::default())
            .run(mesh.clone(), &mut cx)
            .unwrap();
        let record = slot
            .expect("a record")
            .downcast::<coarsen_collapse::Progressive>()
            .expect("the engine's record");
        assert_eq!(record.steps.len(), mesh.n_vertices() - 50);
        assert_eq!(record.coarse, coarsen_collapse::fingerprint(&out));
        let (plain, _) = run(&mesh, Some(Target::Vertices(50)), QemParams::default());
        assert_eq!(plain.unwrap(), out, "recording changes nothing");
    }

    #[test]
    fn needs_a_target_and_says_so() {
        let stage = SimplifyQem::new(QemParams::default());
        assert!(stage.contract().needs.target);
        assert!(
            !stage.contract().needs.manifold,
            "non-manifold vertices are locked instead"
        );
        let (out, _) = run(&icosphere(1.0, 1).unwrap(), None, QemParams::default());
        let e = out.unwrap_err().to_string();
        assert!(e.contains("`simplify.qem` needs a target"), "{e}");
    }

    #[test]
    fn parameters_out_of_range_are_named() {
        let bad = QemParams {
            max_error: -1.0,
            boundary_weight: f64::NAN,
            min_quality: 1.5,
            area_weighted: true,
            facing_guard: true,
            parallel: true,
            unit: "vertex".into(),
            sve_weighted: false,
            features: true,
            feature_angle_deg: 200.0,
            placement: "nearest".into(),
            uv_weight: -1.0,
        };
        let fields: Vec<_> = bad.validate().iter().map(|i| i.field).collect();
        assert_eq!(
            fields,
            [
                "max_error",
                "boundary_weight",
                "uv_weight",
                "min_quality",
                "feature_angle_deg",
                "unit",
                "placement"
            ]
        );
        assert!(QemParams::default().validate().is_empty());
    }

    #[test]
    fn example_table_builds_through_the_registry() {
        let d = descriptor();
        let mut table: toml::Table =
            toml::from_str(&d.example_toml().replace("[[stage]]\n", "")).unwrap();
        assert_eq!(table.remove("kind"), Some("simplify.qem".into()));
        let stage = (d.build)(&table).ok().unwrap();
        assert_eq!(stage.kind(), "simplify.qem");
        assert_eq!(stage.params()["boundary_weight"].as_float(), Some(1000.0));
    }

    #[test]
    fn vertex_target_is_exact_and_the_report_has_every_figure() {
        let sphere = icosphere(2.0, 3).unwrap();
        let (out, report) = run(&sphere, Some(Target::Vertices(123)), QemParams::default());
        let out = out.unwrap();
        assert_eq!(out.n_vertices(), 123);
        assert_eq!(report.get("vertices"), Some(&123.into()));
        assert_eq!(report.get("stop"), Some(&"reached".into()));
        assert_eq!(report.get("collapses"), Some(&(642 - 123).into()));
        for name in [
            "refused",
            "sve",
            "max_cost",
            "faces",
            "boundary_loops",
            "locked_vertices",
        ] {
            assert!(report.get(name).is_some(), "missing figure {name}");
        }
        assert!(report.get("sve").unwrap().as_f64().unwrap() > 0.0);
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    }

    #[test]
    fn triangle_collapses_meet_the_target_with_a_few_edges() {
        let sphere = coarsen_shapes::bumpy_sphere(1.0, 3, 0.1, 5.0).unwrap();
        let params = |unit: &str| QemParams {
            unit: unit.into(),
            area_weighted: false,
            sve_weighted: true,
            ..QemParams::default()
        };
        let (edges, by_edge) = run(&sphere, Some(Target::Vertices(123)), params("edge"));
        let (tris, by_triangle) = run(&sphere, Some(Target::Vertices(123)), params("triangle"));
        let (edges, tris) = (edges.unwrap(), tris.unwrap());
        assert_eq!((edges.n_vertices(), tris.n_vertices()), (123, 123));
        assert_ne!(edges.positions, tris.positions);
        let figure = |r: &StageReport, name: &str| r.get(name).and_then(|x| x.as_f64()).unwrap();
        // A triangle collapse removes two vertices: about half as many collapses.
        let (e, t) = (
            figure(&by_edge, "collapses"),
            figure(&by_triangle, "collapses"),
        );
        assert!(
            t < 0.6 * e,
            "{t} triangle-run collapses, {e} edge collapses"
        );
        for r in [&by_edge, &by_triangle] {
            let (sve, max, w) = (
                figure(r, "sve"),
                figure(r, "sve_max"),
                figure(r, "sve_weighted"),
            );
            assert!(
                0.0 < max && max < sve && 0.0 < w && w < sve,
                "{sve} {max} {w}"
            );
        }
        let (_, plain) = run(&sphere, Some(Target::Vertices(123)), QemParams::default());
        assert!(plain.get("sve_max").is_some() && plain.get("sve_weighted").is_none());
    }

    #[test]
    fn ratio_target_removes_that_share_of_faces() {
        let sphere = icosphere(1.0, 3).unwrap();
        let (out, _) = run(&sphere, Some(Target::Ratio(0.7)), QemParams::default());
        // 1280 faces · 0.3 = 384.
        assert_eq!(out.unwrap().n_faces(), 384);
    }

    #[test]
    fn unreachable_target_is_a_warning_not_an_error() {
        // A tetrahedron cannot lose a vertex and stay a closed manifold.
        let tet = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
        );
        let (out, report) = run(&tet, Some(Target::Vertices(3)), QemParams::default());
        assert_eq!(out.unwrap(), tet);
        assert_eq!(report.get("stop"), Some(&"exhausted".into()));
        assert!(
            report.warnings[0].contains("target (3 vertices) not reached"),
            "{:?}",
            report.warnings
        );
    }

    #[test]
    fn max_error_stops_early_with_a_warning() {
        let sphere = icosphere(1.0, 3).unwrap();
        let params = QemParams {
            max_error: 1e-12,
            ..QemParams::default()
        };
        let (out, report) = run(&sphere, Some(Target::Vertices(12)), params);
        assert!(out.unwrap().n_vertices() > 12);
        assert_eq!(report.get("stop"), Some(&"max_error".into()));
        assert!(
            report.warnings[0].contains("above max_error"),
            "{:?}",
            report.warnings
        );
    }

    #[test]
    fn holes_stay_open() {
        let disk = disk_with_holes(2, 4, 1.0).unwrap();
        let (out, report) = run(&disk, Some(Target::Vertices(60)), QemParams::default());
        assert_eq!(out.unwrap().n_vertices(), 60);
        assert_eq!(report.get("boundary_loops_in"), Some(&3.into()));
        assert_eq!(report.get("boundary_loops"), Some(&3.into()));
    }

    #[test]
    fn flat_grid_keeps_its_border_and_corners() {
        let grid = plane_grid(12, 12, 1.0).unwrap();
        let (out, report) = run(&grid, Some(Target::Vertices(20)), QemParams::default());
        let out = out.unwrap();
        assert_eq!(out.n_vertices(), 20);
        assert_eq!(report.get("boundary_loops"), Some(&1.into()));
        let bbox = out.bbox();
        assert_eq!((bbox.min, bbox.max), (grid.bbox().min, grid.bbox().max));
        assert!((out.area() - grid.area()).abs() < 1e-9 * grid.area());
    }
}
