//! The feature-edge rows (issues #5 and #6): how far the output of each simplifier lies
//! from the fandisk's sharp feature edges (`coarsen_metrics::feature_edges`), at paper 2's
//! 70 %, how much `quadric` placement recovers for the CVT pipelines, and what `relax`'s
//! `features` (the input's corners and sharp curves kept) gives them, at what cost in
//! angles.

use anyhow::Result;
use coarsen_mesh::Mesh;
use coarsen_metrics::{FeatureEdges, FeatureOptions, feature_edges, fidelity, quality, validity};
use coarsen_stage::{Registry, Target};
use std::fmt::Write as _;

/// The mesh of the rows.
pub const MESH: &str = "fandisk.obj";

/// The share of faces the simplifiers remove.
const RATIO: f64 = 0.7;

/// The rows: shipped pipeline and `--set` overrides.
const ROWS: &[(&str, &[&str])] = &[
    ("qem", &[]),
    ("svec", &[]),
    ("qem", &["simplify.qem.features=true"]),
    ("svec", &["simplify.svec.features=true"]),
    ("uniform-cvt", &[]),
    ("adaptive-cvt", &[]),
    (
        "adaptive-cvt",
        &[
            "dual.placement=\"quadric\"",
            "postprocess.placement=\"quadric\"",
        ],
    ),
    ("goal", &[]),
    ("uniform-cvt", &["relax.features=true"]),
    ("adaptive-cvt", &["relax.features=true"]),
    ("goal", &["shape.features=true", "fit.features=true"]),
    ("cad", &[]),
];

/// The section: `qem` and `svec` at 70 % removed, then the CVT pipelines (paper 1's also
/// with `quadric` placement, issue #5) at the vertex count `qem` reached, each with the
/// distance from the input's feature edges to it.
pub fn section(registry: &Registry, input: &Mesh) -> Result<String> {
    let opts = FeatureOptions::default();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## Feature edges — fandisk, {:.0} % of faces removed\n",
        RATIO * 100.0
    );
    let mut rows = String::new();
    let mut vertices = None;
    let mut edges = None;
    for &(pipeline, sets) in ROWS {
        let label = match sets {
            [] => format!("`{pipeline}`"),
            _ => format!("`{pipeline}` {}", sets.join(" ").replace('"', "")),
        };
        let target = match (pipeline, vertices) {
            ("qem" | "svec", _) => Target::Ratio(RATIO),
            (_, Some(v)) => Target::Vertices(v),
            (_, None) => continue,
        };
        eprintln!("features · {label}");
        let out = match crate::run_shipped(registry, pipeline, sets, input, target) {
            Ok((out, _)) => out,
            Err(e) => {
                let _ = writeln!(
                    rows,
                    "| {label} | failed: {} | | | | | | |",
                    e.to_string().replace('|', "/")
                );
                continue;
            }
        };
        if pipeline == "qem" && vertices.is_none() {
            vertices = Some(out.n_vertices() as u64);
        }
        let (f, cells) = cells(input, &out, &opts)?;
        edges = Some((f.n_edges, f.length_pct, f.n_samples));
        let _ = writeln!(rows, "| {label} | {cells} |");
    }
    let (n, length, samples) = edges.unwrap_or_default();
    let _ = writeln!(
        s,
        "The input's feature edges are those whose two faces' normals differ by more than {}° \
         ({n} edges, {length:.0} % of the diagonal long in all); points along them, at most {} × \
         the diagonal apart ({samples} in all), are measured to the nearest point of the output \
         (`coarsen_metrics::feature_edges`); *corners* counts the input's corners of those edges \
         (`coarsen-features`) that have an output vertex on them. The CVT pipelines run to \
         `qem`'s vertex count. Distances in % of the bounding-box diagonal; *Hausdorff* is the \
         whole surface's, as in the tables above. `features=true` (off by default) captures the \
         input's corners and sharp curves in `relax` (see its docs), and in `simplify.qem` and \
         `simplify.svec` keeps the corners and the vertices of sharp curves where they are \
         (merged along their curve only); the `cad` pipeline is `uniform-cvt` with it and \
         `subdivide.max_edge=1`.\n",
        opts.angle_deg, opts.spacing
    );
    s.push_str(
        "| pipeline | V | F | feature max % | feature mean % | corners | Hausdorff % | α_min ° | Q_avg |\n",
    );
    s.push_str("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    s.push_str(&rows);
    s.push('\n');
    Ok(s)
}

/// The vertex count of the CAD parts' rows.
const CAD_VERTICES: u64 = 1500;

/// The CAD parts' rows: shipped pipeline and `--set` overrides.
const CAD_ROWS: &[(&str, &[&str])] = &[
    ("qem", &[]),
    ("qem", &["simplify.qem.features=true"]),
    ("uniform-cvt", &[]),
    ("uniform-cvt", &["relax.features=true"]),
    ("adaptive-cvt", &["relax.features=true"]),
    ("goal", &["shape.features=true", "fit.features=true"]),
    ("uniform-cvt", &["subdivide.max_edge=1"]),
    ("cad", &[]),
];

/// The CAD parts of `coarsen_shapes::cad` (issue #52's fixtures), each coarsened to
/// [`CAD_VERTICES`] by `qem` and the CVT pipelines with and without `features`: the
/// feature-edge distance, the corners kept, the whole surface's Hausdorff distance, the
/// angles and the flipped faces.
pub fn cad_section(registry: &Registry) -> Result<String> {
    let opts = FeatureOptions::default();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "### CAD parts made in code — {CAD_VERTICES} vertices\n\n\
         The parts of `coarsen_shapes::cad` (a plate with two holes and a slot, a block with a \
         pocket and a bored boss, a stepped shaft: flat faces triangulated from their outlines \
         alone, as a CAD program's STL export is, so all slivers; 512 segments per circle), \
         coarsened to {CAD_VERTICES} vertices; columns as above, and *flipped* the output faces \
         facing away from the input nearest them. As shipped, the CVT pipelines fail on such \
         input (clusters of slivers that span a whole face: Hausdorff distances of whole \
         percents, faces turned over); `subdivide.max_edge=1` (long edges split to a target \
         edge, flat slivers flipped to Delaunay) repairs `uniform-cvt`, and with `relax`'s \
         `features` too (the `cad` pipeline) it keeps every corner. `adaptive-cvt` and \
         `goal` are not repaired by it: their curvature density is extreme along the sharp \
         edges.\n"
    );
    s.push_str(
        "| part | pipeline | V | F | feature max % | feature mean % | corners | Hausdorff % | α_min ° | Q_avg | flipped |\n",
    );
    s.push_str("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    for (name, input) in coarsen_shapes::cad::parts()? {
        for &(pipeline, sets) in CAD_ROWS {
            let label = match sets {
                [] => format!("`{pipeline}`"),
                _ => format!("`{pipeline}` {}", sets.join(" ").replace('"', "")),
            };
            eprintln!("features · {name} · {label}");
            let target = Target::Vertices(CAD_VERTICES);
            let out = match crate::run_shipped(registry, pipeline, sets, &input, target) {
                Ok((out, _)) => out,
                Err(e) => {
                    let _ = writeln!(
                        s,
                        "| {name} | {label} | failed: {} | | | | | | | | |",
                        e.to_string().replace('|', "/")
                    );
                    continue;
                }
            };
            let (_, cells) = cells(&input, &out, &opts)?;
            let v = validity(Some(&input), &out)?;
            let flipped = v.n_flipped.unwrap_or(0);
            let _ = writeln!(s, "| {name} | {label} | {cells} | {flipped} |");
        }
    }
    s.push('\n');
    Ok(s)
}

/// The cells both tables share for `out` against `input`: V, F, the feature distance (max,
/// mean), corners kept, Hausdorff, α_min and Q_avg; with the feature figures.
fn cells(input: &Mesh, out: &Mesh, opts: &FeatureOptions) -> Result<(FeatureEdges, String)> {
    let f = feature_edges(input, out, opts)?;
    let h = fidelity(input, out, &Default::default())?;
    let q = quality(out)?;
    let cells = format!(
        "{} | {} | {:.4} | {:.4} | {} of {} | {:.4} | {:.2} | {:.3}",
        out.n_vertices(),
        out.n_faces(),
        f.max_pct,
        f.mean_pct,
        f.corners_kept,
        f.n_corners,
        h.hausdorff_pct,
        q.alpha_min_deg,
        q.q_avg
    );
    Ok((f, cells))
}
