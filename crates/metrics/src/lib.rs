//! The figures `coarsen` reports about a mesh, exactly as `shared/spec/metrics.md` defines
//! them.
//!
//! * [`quality()`] — shape of the triangles: smallest angles, Frey–Borouchaki quality,
//!   a histogram of smallest angles ([`Quality`]).
//! * [`fidelity()`] — how far the output surface lies from the input: sampled two-sided
//!   Hausdorff, mean and RMS distance as percents of the input's bounding-box diagonal,
//!   and the volume change of closed meshes ([`Fidelity`]; the sampling rule is in the
//!   [`fidelity`](mod@fidelity) module docs).
//! * [`validity()`] — counts, manifoldness, components, boundary loops, genus, degenerate
//!   and turned-over faces ([`Validity`]).
//! * [`feature_edges()`] — distance from the input's sharp feature edges to the output
//!   ([`FeatureEdges`]).
//! * [`measure`] — all three at once, sharing the spatial index and topology, as a
//!   [`MetricsReport`] that serialises to JSON and prints as a Markdown table.
//! * [`measure_with_fields`] — the same, with the figures element by element ([`Fields`]:
//!   distances per vertex and face, smallest angle, quality and flips per face), for maps
//!   and for other tools (MeshLab, ParaView) to show.
//!
//! Every figure is plain data, never NaN, and bit-for-bit the same on any number of
//! threads: the parallel work is cut into fixed chunks whose partial results are combined
//! in order. Bad input (an index out of range, a used vertex that is not finite or lies
//! beyond ±[`MAX_COORDINATE`], an empty or point-like surface where distances are asked
//! for) is a [`MetricsError`] naming the mesh and the element.
//!
//! ```
//! use coarsen_metrics::{MetricsOptions, measure};
//! use coarsen_mesh::{DVec3, Mesh};
//! let tetra = Mesh::new(
//!     vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
//!     vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]],
//! );
//! let report = measure(Some(&tetra), &tetra, &MetricsOptions::default()).unwrap();
//! assert_eq!(report.fidelity.as_ref().unwrap().hausdorff_pct, 0.0);
//! assert_eq!(report.validity.genus, Some(0));
//! assert!((report.quality.alpha_min_deg - 45.0).abs() < 1e-9);
//! println!("{}", report.to_markdown());
//! ```

pub mod error;
pub mod features;
pub mod fidelity;
pub mod fields;
mod grid;
mod prepare;
pub mod quality;
#[cfg(test)]
mod test_meshes;
pub mod texture;
pub mod validity;

pub use error::{MAX_COORDINATE, MetricsError, Role};
pub use features::{FeatureEdges, FeatureOptions, feature_edges, sharp_edges};
pub use fidelity::{Fidelity, FidelityOptions, MIN_FACE_SAMPLES, SAMPLES_PER_FACE, fidelity};
pub use fields::{Fields, MeshFields, shape_fields};
pub use grid::{GridFacing, LazyGridFacing};
pub use quality::{Quality, quality};
pub use texture::{Texture, UvJudge, UvWinding, texture};
pub use validity::{Facing, SurfaceIndex, SurfaceParts, Validity, validity};

use coarsen_mesh::Mesh;
use prepare::Prepared;
use serde::{Deserialize, Serialize};
use std::fmt::Write;

/// Options of [`measure`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MetricsOptions {
    /// How fidelity is sampled.
    pub fidelity: FidelityOptions,
}

/// Every figure about an output mesh, and about it against its input when there is one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MetricsReport {
    /// Shape of the output's triangles.
    pub quality: Quality,
    /// Distance between the output and the input; `None` without an input.
    pub fidelity: Option<Fidelity>,
    /// Counts, topology, degenerate and flipped faces of the output.
    pub validity: Validity,
    /// Distance from the input's sharp edges (default angle) to the output; `None` without
    /// an input.
    #[serde(default)]
    pub features: Option<FeatureEdges>,
    /// Seams, UV flips and texture distortion against the input; `None` unless both
    /// carry a `uv` column.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture: Option<Texture>,
}

/// Measures `output`, against `input` when given (fidelity and flipped faces need it).
///
/// Errors as [`quality()`], [`fidelity()`] and [`validity()`] do; in particular an input
/// or output without faces cannot be compared.
pub fn measure(
    input: Option<&Mesh>,
    output: &Mesh,
    opts: &MetricsOptions,
) -> Result<MetricsReport, MetricsError> {
    measure_and_record(input, output, opts, false).map(|(report, _)| report)
}

/// [`measure`] of `output` against `input`, with the fields of both meshes: the same
/// samples give the figures and the per-element distances (see [`fields`](mod@fields)).
///
/// Errors as [`measure`] does.
pub fn measure_with_fields(
    input: &Mesh,
    output: &Mesh,
    opts: &MetricsOptions,
) -> Result<(MetricsReport, Fields), MetricsError> {
    let (report, fields) = measure_and_record(Some(input), output, opts, true)?;
    // With an input and `record`, the fields are always made.
    Ok((report, fields.expect("fields recorded")))
}

/// [`measure`], and with `record` (and an input) the fields of both meshes.
fn measure_and_record(
    input: Option<&Mesh>,
    output: &Mesh,
    opts: &MetricsOptions,
    record: bool,
) -> Result<(MetricsReport, Option<Fields>), MetricsError> {
    let (out, input) = rayon::join(
        || Prepared::new(output, Role::Output),
        || input.map(|m| Prepared::new(m, Role::Input)).transpose(),
    );
    let (out, input) = (out?, input?);
    let out_topology = validity::topology(&out, Role::Output)?;
    let quality = quality::quality_of(&out);
    let (fidelity, n_flipped, fields, features, texture) = match &input {
        None => (None, None, None, None, None),
        Some(inp) => {
            let floor = fidelity::rounding_floor(inp, &out)?;
            // The input's topology (for its closedness and the flip test's edge normals)
            // is built alongside the distances, once.
            let mut sampled =
                fidelity::sample_both(inp, &out, &opts.fidelity, floor, record, || {
                    validity::topology(inp, Role::Input)
                });
            let in_topology = sampled.alongside.as_ref().map_err(Clone::clone)?;
            let both_closed =
                validity::encloses_volume(&out_topology) && validity::encloses_volume(in_topology);
            let fid = fidelity::figures(inp, &out, &sampled, both_closed);
            // The sharp edges' distance, on the adjacency and checks made above.
            let feature_opts = FeatureOptions::default();
            let edges = features::edges_to(
                inp.mesh,
                in_topology,
                out.mesh,
                fid.bbox_diagonal,
                &feature_opts,
            );
            let (n_flipped, fields) = if record {
                let flipped = validity::flipped_faces(&out, inp, &sampled.input_bvh, in_topology);
                let n = flipped.iter().filter(|&&f| f).count();
                let distances = sampled
                    .forward_field
                    .take()
                    .zip(sampled.backward_field.take());
                let (forward, backward) = distances.expect("distances recorded");
                (
                    n,
                    Some(fields::of_distances(inp, &out, forward, backward, flipped)),
                )
            } else {
                let n = validity::count_flipped(&out, inp, &sampled.input_bvh, in_topology);
                (n, None)
            };
            let tex = texture::texture(inp.mesh, out.mesh, fid.bbox_diagonal);
            (Some(fid), Some(n_flipped), fields, Some(edges), tex)
        }
    };
    let validity = validity::validity_of(&out, &out_topology.summary(output), n_flipped);
    let report = MetricsReport {
        quality,
        fidelity,
        validity,
        features,
        texture,
    };
    Ok((report, fields))
}

impl MetricsReport {
    /// A two-column Markdown table of every figure, rounded for reading.
    pub fn to_markdown(&self) -> String {
        let mut rows: Vec<(&str, String)> = Vec::new();
        let (q, v) = (&self.quality, &self.validity);
        rows.push(("vertices", v.n_vertices.to_string()));
        rows.push(("faces", v.n_faces.to_string()));
        rows.push(("α_min", format!("{:.2}°", q.alpha_min_deg)));
        rows.push(("α_avg", format!("{:.2}°", q.alpha_avg_deg)));
        rows.push(("triangles under 30°", format!("{:.2} %", q.p_lt30_pct)));
        rows.push(("Q_min", format!("{:.3}", q.q_min)));
        rows.push(("Q_avg", format!("{:.3}", q.q_avg)));
        let histogram: Vec<String> = q.min_angle_histogram.iter().map(u32::to_string).collect();
        rows.push(("smallest angles in 5° bins from 0°", histogram.join(" ")));
        if let Some(f) = &self.fidelity {
            rows.push(("Hausdorff", format!("{:.3} % of diagonal", f.hausdorff_pct)));
            rows.push(("input → output max", format!("{:.3} %", f.forward_max_pct)));
            rows.push(("output → input max", format!("{:.3} %", f.backward_max_pct)));
            rows.push(("mean distance", format!("{:.4} %", f.mean_dist_pct)));
            rows.push(("RMS distance", format!("{:.4} %", f.rms_dist_pct)));
            rows.push((
                "distance samples",
                format!(
                    "{} (input → output {}, output → input {})",
                    f.n_samples, f.forward_samples, f.backward_samples
                ),
            ));
            if let Some(e) = self.features.as_ref().filter(|e| e.n_edges > 0) {
                rows.push((
                    "sharp edges → output",
                    format!(
                        "max {:.3} %, mean {:.4} % ({} input edges over 40° or marked); corners kept {} of {}",
                        e.max_pct, e.mean_pct, e.n_edges, e.corners_kept, e.n_corners
                    ),
                ));
            }
            rows.push(("input bbox diagonal", format!("{:.6}", f.bbox_diagonal)));
            rows.push((
                "volume change",
                f.volume_change_pct
                    .map_or("n/a (not both closed)".into(), |x| format!("{x:.3} %")),
            ));
        }
        rows.push(("manifold", if v.manifold { "yes" } else { "no" }.into()));
        rows.push(("components", v.n_components.to_string()));
        rows.push(("boundary loops", v.n_boundary_loops.to_string()));
        rows.push((
            "genus",
            v.genus
                .map_or("n/a (not an orientable manifold)".into(), |g| g.to_string()),
        ));
        rows.push(("degenerate faces", v.n_degenerate.to_string()));
        rows.push((
            "flipped faces",
            v.n_flipped
                .map_or("n/a (no input)".into(), |n| n.to_string()),
        ));
        if let Some(t) = &self.texture {
            rows.push((
                "seam vertices",
                format!("{} (input {})", t.seam_vertices, t.seam_vertices_in),
            ));
            rows.push((
                "UV-flipped faces",
                format!("{} ({} of zero UV area)", t.uv_flipped, t.uv_degenerate),
            ));
            rows.push((
                "texture distortion",
                format!(
                    "max {:.3} %, mean {:.4} % ({} UVs outside the input's)",
                    t.distortion_max_pct, t.distortion_mean_pct, t.uv_outside
                ),
            ));
            rows.push((
                "texture distortion inside faces",
                format!(
                    "max {:.3} %, mean {:.4} %",
                    t.surface_distortion_max_pct, t.surface_distortion_mean_pct
                ),
            ));
        }
        let mut out = String::from("| figure | value |\n| --- | --- |\n");
        for (name, value) in rows {
            let _ = writeln!(out, "| {name} | {value} |");
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::icosphere;
    use coarsen_mesh::DVec3;

    /// The acceptance figures: an independent tool measured the raw Stanford bunny at
    /// α_min 0.48°, α_avg 36.8°, P<30 6.8 %, Q_avg 0.714; against itself it is 0 apart.
    #[test]
    fn stanford_bunny_against_itself_matches_the_independent_figures() {
        let Some(bunny) = coarsen_testdata::raw("stanford-bunny.obj") else {
            return;
        };
        assert_eq!((bunny.n_vertices(), bunny.n_faces()), (35_947, 69_451));
        let r = measure(Some(&bunny), &bunny, &MetricsOptions::default()).unwrap();
        let (q, f, v) = (&r.quality, r.fidelity.as_ref().unwrap(), &r.validity);
        assert_eq!(f.hausdorff_pct, 0.0);
        assert_eq!(f.mean_dist_pct, 0.0);
        assert!(
            (q.alpha_min_deg - 0.48).abs() < 0.005,
            "{}",
            q.alpha_min_deg
        );
        assert!((q.alpha_avg_deg - 36.8).abs() < 0.05, "{}", q.alpha_avg_deg);
        assert!((q.p_lt30_pct - 6.8).abs() < 0.05, "{}", q.p_lt30_pct);
        assert!((q.q_avg - 0.714).abs() < 0.0005, "{}", q.q_avg);
        assert_eq!(v.n_boundary_loops, 5);
        assert_eq!(v.n_components, 1);
        assert_eq!(v.n_flipped, Some(0));
        assert_eq!(f.volume_change_pct, None);
        assert!(f.forward_samples >= 100 * 69_451 && f.backward_samples >= 1_000_000);
    }

    #[test]
    fn measure_agrees_with_the_separate_figures() {
        let (a, b) = (icosphere(3), icosphere(2));
        let r = measure(Some(&a), &b, &MetricsOptions::default()).unwrap();
        assert_eq!(r.quality, quality(&b).unwrap());
        assert_eq!(
            r.fidelity,
            Some(fidelity(&a, &b, &FidelityOptions::default()).unwrap())
        );
        assert_eq!(r.validity, validity(Some(&a), &b).unwrap());
        let alone = measure(None, &b, &MetricsOptions::default()).unwrap();
        assert_eq!(alone.fidelity, None);
        assert_eq!(alone.validity.n_flipped, None);
    }

    #[test]
    fn report_is_the_same_on_one_thread_and_round_trips_through_json() {
        let (a, b) = (icosphere(4), icosphere(2));
        let opts = MetricsOptions::default();
        let r = measure(Some(&a), &b, &opts).unwrap();
        assert_eq!(
            coarsen_testdata::on_threads(1, || measure(Some(&a), &b, &opts).unwrap()),
            r
        );
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains("\"hausdorff_pct\"") && json.contains("\"alpha_min_deg\""));
        let back: MetricsReport = serde_json::from_str(&json).unwrap();
        assert_eq!(back, r);
    }

    #[test]
    fn markdown_table_lists_every_figure_rounded() {
        let (a, b) = (icosphere(3), icosphere(1));
        let md = measure(Some(&a), &b, &MetricsOptions::default())
            .unwrap()
            .to_markdown();
        assert!(md.starts_with("| figure | value |\n| --- | --- |\n"));
        assert!(md.contains("| faces | 80 |"));
        assert!(md.contains("| genus | 0 |"));
        assert!(md.contains("| flipped faces | 0 |"));
        assert!(md.lines().all(|l| l.starts_with('|') && l.ends_with('|')));
        assert_eq!(md.lines().count(), 2 + 22);
    }

    #[test]
    fn bad_input_is_named_and_messy_meshes_never_give_nan() {
        let a = icosphere(2);
        let mut bad = a.clone();
        bad.faces[4][2] = 10_000;
        let err = measure(Some(&bad), &a, &MetricsOptions::default()).unwrap_err();
        assert!(matches!(
            err,
            MetricsError::Indices {
                mesh: Role::Input,
                ..
            }
        ));
        // Non-manifold, with a loose vertex and a degenerate face.
        let mut messy = a.clone();
        messy.faces.push(messy.faces[0]);
        messy.faces.push([1, 1, 2]);
        messy.positions.push(DVec3::splat(f64::NAN));
        let r = measure(Some(&messy), &messy, &MetricsOptions::default()).unwrap();
        assert!(!r.validity.manifold);
        let json = serde_json::to_string(&r).unwrap();
        assert!(!json.contains("null") || json.contains("\"volume_change_pct\":null"));
        assert!(!json.contains("NaN"));
        assert_eq!(r.fidelity.unwrap().hausdorff_pct, 0.0);
    }
}
