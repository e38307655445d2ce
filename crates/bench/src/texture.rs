//! Issue #54's textured rows: spot with its UV seams, by meshoptimizer's
//! `simplifyWithAttributes`, the collapse pipelines and the CVT pipelines, every output
//! measured by `coarsen_metrics::texture` beside its shape and Hausdorff distance.

use anyhow::{Context as _, Result};
use coarsen_mesh::{AttrValues, Attributes, Mesh, Wedges, hygiene};
use coarsen_metrics::{MetricsOptions, measure};
use coarsen_stage::{Registry, Target};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// The mesh of the rows.
pub const MESH: &str = "spot.obj";

/// meshoptimizer's weight on each UV component: its positions are scaled to unit extent,
/// spot's UVs span about one unit, so an error of a texture's width weighs as one of the
/// model's size.
const UV_WEIGHT: f32 = 1.0;

/// The rows: who simplifies, and to what.
const ROWS: &[(Method, Target)] = &[
    (Method::Meshopt, Target::Ratio(0.7)),
    (Method::Pipeline("qem", &[]), Target::Ratio(0.7)),
    (Method::Pipeline("qem", OPTIMAL), Target::Ratio(0.7)),
    (Method::Pipeline("qem", AT_VERTICES), Target::Ratio(0.7)),
    (Method::Pipeline("qem", UV_TERMS), Target::Ratio(0.7)),
    (Method::Pipeline("svec", &[]), Target::Ratio(0.7)),
    (Method::Pipeline("svec", PAPER), Target::Ratio(0.7)),
    (Method::Meshopt, Target::Ratio(0.95)),
    (Method::Pipeline("qem", &[]), Target::Ratio(0.95)),
    (Method::Pipeline("qem", OPTIMAL), Target::Ratio(0.95)),
    (Method::Pipeline("qem", AT_VERTICES), Target::Ratio(0.95)),
    (Method::Pipeline("qem", UV_TERMS), Target::Ratio(0.95)),
    (Method::Pipeline("svec", &[]), Target::Ratio(0.95)),
    (Method::Pipeline("svec", PAPER), Target::Ratio(0.95)),
    // The CVT rows' face count: 1000 vertices on a closed genus-0 surface.
    (Method::Meshopt, Target::Faces(1996)),
    (
        Method::Pipeline("adaptive-cvt", &[]),
        Target::Vertices(1000),
    ),
    (Method::Pipeline("uniform-cvt", &[]), Target::Vertices(1000)),
    (Method::Pipeline("goal", &[]), Target::Vertices(1000)),
];

/// `qem` keeping input vertices where they are, as meshoptimizer does.
const AT_VERTICES: &[&str] = &["simplify.qem.placement=\"vertices\""];
/// `qem` with its vertices where the quadric is least, off the input surface (the
/// default settles them on it when the mesh has UVs).
const OPTIMAL: &[&str] = &["simplify.qem.placement=\"optimal\""];
/// `qem` with the UV fields' terms in its cost (Hoppe 1999).
const UV_TERMS: &[&str] = &["simplify.qem.uv_weight=0.01"];
/// `svec` with paper 2's placement alone (the default settles the vertices on the input
/// surface when the mesh has UVs).
const PAPER: &[&str] = &["simplify.svec.placement=\"paper\""];

/// Who simplifies a row.
#[derive(Clone, Copy)]
enum Method {
    /// meshoptimizer's `simplifyWithAttributes`, the UVs weighted [`UV_WEIGHT`].
    Meshopt,
    /// A shipped pipeline, with `--set`-style overrides.
    Pipeline(&'static str, &'static [&'static str]),
}

/// `path` read and cleaned as a run cleans its input, its UVs and normals kept.
pub fn load(path: &Path) -> Result<Mesh> {
    let loaded = coarsen_io::read_path(path, &coarsen_io::ReadOptions::default())?;
    let (mesh, _) = hygiene::clean(loaded.mesh, &hygiene::HygieneOptions::default())
        .with_context(|| path.display().to_string())?;
    Ok(mesh)
}

/// meshoptimizer's `simplifyWithAttributes` on `mesh`'s wedges (its vertices: one per
/// wedge, seams found where equal positions hold other UVs) down to `faces` faces; the
/// output keeps the input's vertex positions and the UVs of the wedges it keeps.
pub fn meshopt_textured(mesh: &Mesh, faces: usize) -> Result<Mesh> {
    let w = &mesh.wedges;
    let uv = w
        .attrs()
        .vec2("uv")
        .context("meshoptimizer's rows need per-corner UVs")?;
    let bytes: Vec<u8> = w
        .vertices()
        .iter()
        .flat_map(|&v| mesh.positions[v as usize].as_vec3().to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    let attrs: Vec<f32> = uv.iter().flat_map(|t| [t.x as f32, t.y as f32]).collect();
    let adapter = meshopt::VertexDataAdapter::new(&bytes, 12, 0)?;
    let locks = vec![false; w.len()];
    let out = meshopt::simplify_with_attributes_and_locks(
        w.corners(),
        &adapter,
        &attrs,
        &[UV_WEIGHT, UV_WEIGHT],
        8,
        &locks,
        faces * 3,
        1.0,
        meshopt::SimplifyOptions::None,
        None,
    );
    let faces: Vec<[u32; 3]> = out
        .chunks_exact(3)
        .map(|c| [0, 1, 2].map(|k| w.vertices()[c[k] as usize]))
        .collect();
    let mut cols = Attributes::default();
    cols.insert(
        "uv",
        AttrValues::Vec2(out.iter().map(|&c| uv[c as usize]).collect()),
    );
    let mut m = Mesh::new(mesh.positions.clone(), faces);
    m.wedges = Wedges::from_corners(&m.faces, cols);
    // meshoptimizer returns indices into the input's vertices: drop those it no longer uses.
    let (m, _) = hygiene::clean(m, &hygiene::HygieneOptions::default())?;
    Ok(m)
}

/// The section: one row per entry of [`ROWS`] on `input` (spot with its UVs).
pub fn section(registry: &Registry, input: &Mesh) -> Result<String> {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## Textured — {} with its UV seams\n",
        MESH.trim_end_matches(".obj")
    );
    let _ = writeln!(
        s,
        "Issue #54: spot as read ({} faces, {} vertices on UV seams), its UVs carried by every \
         run. meshoptimizer: `simplifyWithAttributes` (the meshopt crate), the UVs weighted \
         {UV_WEIGHT} against positions it scales to unit extent, seams where it finds equal \
         positions with other UVs; it keeps input vertices where they are. The collapse \
         pipelines hold seam vertices in place and merge along seams only; on a mesh with \
         UVs they settle each vertex they moved on the nearest point of the input it stands \
         for, where its UVs are taken, so that they are exact there (their `placement` \
         `auto`; `optimal` for `qem` and `paper` for `svec` leave the vertices where the cost \
         put them); `simplify.qem.uv_weight` adds Hoppe's (1999) terms of the UV fields to \
         the cost; `qem` with \
         `simplify.qem.placement=\"vertices\"` keeps every vertex it keeps where it was, as \
         meshoptimizer does; the CVT \
         pipelines lay the UVs back on with their `texture` stage, which mends faces laid \
         turned over in UV space. *seam v*: output vertices \
         on a seam. *flipped*: faces whose UV triangle winds against the input face under \
         its UV centroid; *degenerate*: faces of zero UV area. *distortion*: for each \
         output vertex and UV, the 3-D distance from the vertex to where its UV lies on the \
         input (at the vertices), and the same at four points inside each face (inside; \
         mean weighted by area), % of the diagonal; meshoptimizer's vertices are input \
         vertices, so its distortion at the vertices is zero by construction. Seconds: the \
         simplification alone, input loaded, one run. `cargo run --release -p coarsen-bench \
         -- texture` rewrites this section alone.\n",
        input.n_faces(),
        input.wedges.split_vertices(),
    );
    let _ = writeln!(
        s,
        "| target | method | V | F | α_min | α_avg | P<30° % | Q_min | Q_avg | Hausdorff % | seam v | flipped | degenerate | distortion at vertices max % | mean % | inside max % | mean % | s |"
    );
    let _ = writeln!(
        s,
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
    );
    for &(method, target) in ROWS {
        let label = match method {
            Method::Meshopt => "meshoptimizer".to_string(),
            Method::Pipeline(p, sets) => {
                let sets: Vec<String> = sets.iter().map(|x| format!(" `{x}`")).collect();
                format!("`{p}`{}", sets.concat())
            }
        };
        let shown = crate::target_text(&target);
        eprintln!("texture · {label} · {shown}");
        let t = Instant::now();
        let out = match method {
            Method::Meshopt => meshopt_textured(input, target.faces_for(input) as usize),
            Method::Pipeline(p, sets) => {
                crate::run_shipped(registry, p, sets, input, target).map(|(m, _)| m)
            }
        };
        let seconds = t.elapsed().as_secs_f64();
        let out = match out {
            Ok(m) => m,
            Err(e) => {
                let why = format!("{e:#}").replace('|', "/").replace('\n', " ");
                let _ = writeln!(
                    s,
                    "| {shown} | {label} | failed: {why} |{}",
                    " |".repeat(15)
                );
                continue;
            }
        };
        let m = measure(Some(input), &out, &MetricsOptions::default())?;
        let h = m
            .fidelity
            .map_or("—".to_string(), |f| format!("{:.3}", f.hausdorff_pct));
        let tex = match &m.texture {
            Some(t) => format!(
                "{} | {} | {} | {:.3} | {:.4} | {:.3} | {:.4}",
                t.seam_vertices,
                t.uv_flipped,
                t.uv_degenerate,
                t.distortion_max_pct,
                t.distortion_mean_pct,
                t.surface_distortion_max_pct,
                t.surface_distortion_mean_pct
            ),
            None => "no UVs | | | | | |".to_string(),
        };
        let _ = writeln!(
            s,
            "| {shown} | {label} | {} | {} | {} | {h} | {tex} | {seconds:.3} |",
            out.n_vertices(),
            out.n_faces(),
            crate::quality_cells(&m.quality),
        );
    }
    s.push('\n');
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meshoptimizer_keeps_a_seam_and_drops_the_vertices_it_no_longer_uses() {
        let grid = coarsen_shapes::with_spherical_uvs(coarsen_shapes::icosphere(1.0, 3).unwrap());
        assert!(grid.wedges.split_vertices() > 0);
        let out = meshopt_textured(&grid, 200).unwrap();
        assert!(
            out.n_faces() <= 200 && out.n_faces() > 100,
            "{}",
            out.n_faces()
        );
        assert!(out.wedges.split_vertices() > 0, "the meridian seam kept");
        assert!(out.n_vertices() < grid.n_vertices());
        // Every output UV is one of the input's, at the same position.
        let uv_in = grid.wedges.attrs().vec2("uv").unwrap();
        let uv_out = out.wedges.attrs().vec2("uv").unwrap();
        for (w, t) in uv_out.iter().enumerate() {
            let p = out.positions[out.wedges.vertices()[w] as usize];
            let found = grid
                .wedges
                .vertices()
                .iter()
                .zip(uv_in)
                .any(|(&v, s)| grid.positions[v as usize] == p && (*s - *t).length() < 1e-12);
            assert!(found, "{p} {t}");
        }
    }
}
