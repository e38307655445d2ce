//! `density.sharp`: a coarsen stage that lives outside coarsen's tree — the template for
//! writing your own (`docs/writing-a-stage.md` walks through it).
//!
//! It writes a vertex scalar that is `weight` at the ends of sharp edges and 1 elsewhere.
//! `cluster.cvt` with `energy = "valette2004"` takes it as its density, so the clusters,
//! and the output's vertices, crowd along creases and corners (`sharp-cvt.toml`).
//!
//! An edge is sharp when the normals of its two faces differ by more than `angle_deg`, when
//! it bounds a single face (with `boundary`), or when three or more faces share it.

use coarsen::plugin::{
    AttrKind, AttrRef, AttrValues, Context, Contract, DVec3, Mesh, ParamIssue, Params, Stage,
    StageError, check_range, export_stage, params,
};
use std::collections::HashMap;

params! {
    /// Parameters of `density.sharp`.
    pub struct SharpParams {
        /// Name of the vertex scalar written.
        pub name: String = "sharpness".to_string(),
        /// An edge is sharp when its two faces' normals differ by more than this angle, in degrees.
        pub angle_deg: f64 = 40.0,
        /// Value at the vertices of sharp edges (1 elsewhere).
        pub weight: f64 = 2.0,
        /// Count the edges of the mesh's boundary as sharp.
        pub boundary: bool = true,
    }
}

impl Params for SharpParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut issues = Vec::new();
        if self.name.is_empty() {
            issues.push(ParamIssue::new("name", "must not be empty"));
        }
        check_range(&mut issues, "angle_deg", self.angle_deg, 0.0, 180.0);
        check_range(&mut issues, "weight", self.weight, 1.0, 1e6);
        issues
    }
}

/// The `density.sharp` stage.
pub struct Sharp(SharpParams);

impl Stage for Sharp {
    type Params = SharpParams;
    const KIND: &'static str = "density.sharp";
    const SUMMARY: &'static str = "Vertex density, high along sharp edges, for cluster.cvt's valette2004 energy (template plug-in).";

    fn new(params: SharpParams) -> Self {
        Sharp(params)
    }

    // Declares the column it writes: a later stage that reads it (`cluster.cvt` with
    // `density = "sharpness"`) passes the pipeline check only when this stage comes first.
    fn contract(&self) -> Contract {
        Contract {
            writes: vec![AttrRef::vertex(self.0.name.clone(), AttrKind::Scalar)],
            ..Contract::default()
        }
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let p = &self.0;
        let sharp = sharp_vertices(&mesh, p.angle_deg.to_radians().cos(), p.boundary);
        let density = sharp
            .iter()
            .map(|&s| if s { p.weight } else { 1.0 })
            .collect();
        mesh.vertex_attrs
            .insert(p.name.clone(), AttrValues::Scalar(density));
        cx.report
            .figure("sharp_vertices", sharp.iter().filter(|&&s| s).count());
        Ok(mesh)
    }
}

// Registers the stage at link time and exports `descriptor()`; one per module (each call
// defines a function named `descriptor`).
export_stage!(Sharp);

/// Which vertices end a sharp edge; `cos_limit` is the cosine of the angle limit.
fn sharp_vertices(mesh: &Mesh, cos_limit: f64, boundary: bool) -> Vec<bool> {
    // Each undirected edge: its first face and how many faces share it.
    let mut edges: HashMap<(u32, u32), (usize, u32)> = HashMap::with_capacity(mesh.n_faces() * 2);
    let mut sharp = vec![false; mesh.n_vertices()];
    let mut mark = |(a, b): (u32, u32)| {
        sharp[a as usize] = true;
        sharp[b as usize] = true;
    };
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            let entry = edges.entry((a.min(b), a.max(b))).or_insert((f, 0));
            entry.1 += 1;
            if entry.1 == 2 {
                // The order the faces come in does not matter: the test is symmetric.
                let (n, m) = (mesh.face_normal(entry.0), mesh.face_normal(f));
                // A degenerate face has no normal, hence no angle with its neighbour.
                if n != DVec3::ZERO && m != DVec3::ZERO && n.dot(m) < cos_limit {
                    mark((a, b));
                }
            }
        }
    }
    for (&edge, &(_, count)) in &edges {
        if count > 2 || (boundary && count == 1) {
            mark(edge);
        }
    }
    sharp
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The corner of a cube cut off: three faces meet at right angles at vertex 0 (their
    /// normals differ by 90°), the slanted face's normal differs from theirs by 125.3°.
    fn corner() -> Mesh {
        Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
        )
    }

    /// Two triangles of one flat square: one inner edge, four boundary edges.
    fn square() -> Mesh {
        Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn creases_sharper_than_the_limit_are_marked() {
        let at = |deg: f64| sharp_vertices(&corner(), deg.to_radians().cos(), false);
        assert_eq!(at(80.0), [true; 4]);
        assert_eq!(at(100.0), [false, true, true, true]);
        assert_eq!(at(130.0), [false; 4]);
    }

    #[test]
    fn boundary_edges_count_only_when_asked() {
        assert_eq!(sharp_vertices(&square(), 0.5, true), [true; 4]);
        assert_eq!(sharp_vertices(&square(), 0.5, false), [false; 4]);
    }

    #[test]
    fn a_range_error_names_its_parameter() {
        let p = SharpParams {
            angle_deg: 200.0,
            ..SharpParams::default()
        };
        let issues: Vec<String> = p.validate().iter().map(|i| i.to_string()).collect();
        assert_eq!(issues, ["angle_deg: must be in 0..=180, got 200"]);
    }

    /// The whole path a user takes: a pipeline file naming the stage, run by coarsen.
    #[test]
    fn the_example_pipeline_runs_and_writes_the_density() {
        let text = include_str!("../sharp-cvt.toml");
        let (out, report) = coarsen::Remesher::new()
            .pipeline_text(text, "sharp-cvt.toml")
            .target(coarsen::Target::Vertices(300))
            .run(&coarsen::demo())
            .unwrap();
        assert_eq!(report.stages[0].kind, "density.sharp");
        assert!(
            out.n_vertices() > 250 && out.n_vertices() < 350,
            "{}",
            out.n_vertices()
        );
        // Without the stage before it, cluster.cvt's density is refused before anything runs.
        let without = "[[stage]]\nkind = \"cluster.cvt\"\nenergy = \"valette2004\"\ndensity = \"sharpness\"\n";
        let e = coarsen::Remesher::new()
            .pipeline_text(without, "bad.toml")
            .target(coarsen::Target::Vertices(300))
            .check()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("reads vertex scalar `sharpness`, which no earlier stage writes"),
            "{e}"
        );
    }
}
