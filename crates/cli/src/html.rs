//! Pictures of a run: snapshots after each stage, and the self-contained HTML report.

use crate::maps;
use base64::Engine as _;
use coarsen_mesh::{DVec3, Mesh};
use coarsen_metrics::MetricsReport;
use coarsen_metrics::Quality;
use coarsen_pipeline::{RunReport, StageRecord};
use coarsen_render::{RenderOptions, View};
use rayon::prelude::*;
use std::cell::RefCell;
use std::fmt::Write as _;
use std::path::PathBuf;

/// A titled PNG picture.
pub struct Picture {
    /// What it shows.
    pub title: String,
    /// PNG bytes.
    pub png: Vec<u8>,
}

/// The clusters of a run's first clustering stage, carried to the faces of the input the
/// viewer shows: each face takes the cluster of the working-mesh face nearest its centroid.
pub struct InputClusters {
    /// The clustering stage, as the report names it (`stage 4 \`cluster.cvt\``).
    pub stage: String,
    /// Per face of the shown input, its cluster.
    pub labels: Vec<u32>,
}

/// Collects pictures while a pipeline runs: after every stage, one picture per attribute the
/// stage added (curvature maps, clusters), plus one of the mesh when `every_stage` is set;
/// and, when given a mesh to carry them to, the first clustering's clusters.
pub struct Recorder {
    seen: RefCell<Vec<String>>,
    /// The face centroids of the input the viewer shows and its box's diagonal, when the
    /// clusters are wanted.
    centroids: Option<(Vec<DVec3>, f64)>,
    /// The first clustering's clusters on the shown input, once a stage made them.
    pub clusters: RefCell<Option<InputClusters>>,
    /// Pictures so far, in order.
    pub pictures: RefCell<Vec<Picture>>,
    /// Errors met while rendering (reported, never fatal).
    pub errors: RefCell<Vec<String>>,
    every_stage: bool,
    size: u32,
    view: View,
}

impl Recorder {
    /// A recorder whose pictures are `size` pixels square, seen from `view`; with `shown`,
    /// it carries the first clustering's clusters to that mesh's faces.
    pub fn new(
        every_stage: bool,
        size: u32,
        view: View,
        input: &Mesh,
        shown: Option<&Mesh>,
    ) -> Recorder {
        let centroids = shown.map(|m| {
            let c = (0..m.n_faces())
                .map(|f| {
                    let [a, b, c] = m.corners(f);
                    (a + b + c) / 3.0
                })
                .collect();
            (c, m.bbox().diagonal())
        });
        let seen = input
            .vertex_attrs
            .names()
            .chain(input.face_attrs.names())
            .map(String::from)
            .collect();
        Recorder {
            seen: RefCell::new(seen),
            centroids,
            clusters: RefCell::new(None),
            pictures: RefCell::new(Vec::new()),
            errors: RefCell::new(Vec::new()),
            every_stage,
            size,
            view,
        }
    }

    /// Renders `mesh` (coloured by `attribute`) and keeps the picture.
    pub fn picture(&self, title: String, mesh: &Mesh, attribute: Option<String>, wireframe: bool) {
        let opts = RenderOptions {
            width: self.size,
            height: self.size,
            view: self.view,
            smooth: attribute.is_some(),
            wireframe,
            attribute,
            ..Default::default()
        };
        self.keep(title, coarsen_render::render(&[mesh], &opts));
    }

    /// Renders `meshes` side by side (the input first) with their wire and sharp features,
    /// and keeps the picture.
    pub fn features(&self, title: String, meshes: &[&Mesh]) {
        let opts = RenderOptions {
            width: self.size,
            height: self.size,
            view: self.view,
            wireframe: true,
            features: true,
            ..Default::default()
        };
        self.keep(title, coarsen_render::render(meshes, &opts));
    }

    /// Renders `meshes` side by side (the input first) with their texture (a UV
    /// checkerboard when they have none) from four sides, and keeps the picture.
    pub fn texture(&self, title: String, meshes: &[&Mesh]) {
        let size = self.size * 3 / 5;
        let opts = RenderOptions {
            width: size,
            height: size,
            view: self.view,
            views: 4,
            texture: coarsen_render::Texturing::Image,
            ..Default::default()
        };
        self.keep(title, coarsen_render::render(meshes, &opts));
    }

    /// Renders `meshes` side by side (the input first) coloured by a measured `field`,
    /// with its colour bar, and keeps the picture; `worst` highlights that percent of
    /// each mesh's worst faces; `sheet` draws four views (a 2×2 sheet).
    pub fn map(
        &self,
        title: String,
        mut meshes: Vec<Mesh>,
        field: maps::Field,
        worst: Option<f64>,
        sheet: bool,
    ) {
        let scale = match maps::prepare(field, &mut meshes, worst) {
            Ok(s) => s,
            Err(e) => return self.errors.borrow_mut().push(format!("{title}: {e}")),
        };
        // The four views of a sheet, each 3/5 the size, cost about 1.5 single views.
        let size = if sheet { self.size * 3 / 5 } else { self.size };
        let opts = RenderOptions {
            width: size,
            height: size,
            view: self.view,
            views: if sheet { 4 } else { 1 },
            attribute: Some(field.column().into()),
            scale: Some(scale),
            ..Default::default()
        };
        let refs: Vec<&Mesh> = meshes.iter().collect();
        self.keep(title, coarsen_render::render(&refs, &opts));
    }

    /// Keeps a rendered picture, or the reason it could not be made.
    fn keep(
        &self,
        title: String,
        image: Result<coarsen_render::Image, coarsen_render::RenderError>,
    ) {
        match image.and_then(|img| img.to_png()) {
            Ok(png) => self.pictures.borrow_mut().push(Picture { title, png }),
            Err(e) => self.errors.borrow_mut().push(format!("{title}: {e}")),
        }
    }

    /// The after-stage hook.
    pub fn observe(&self, record: &StageRecord, mesh: &Mesh) {
        let names: Vec<String> = mesh
            .vertex_attrs
            .names()
            .chain(mesh.face_attrs.names())
            .map(String::from)
            .collect();
        let new: Vec<String> = names
            .iter()
            .filter(|n| !self.seen.borrow().contains(n))
            .cloned()
            .collect();
        if self.clusters.borrow().is_none()
            && let (Some((centroids, diagonal)), Some(labels)) =
                (&self.centroids, mesh.face_attrs.label(CLUSTER))
        {
            *self.clusters.borrow_mut() = Some(InputClusters {
                stage: format!("stage {} `{}`", record.index, record.kind),
                labels: carry_labels(mesh, labels, centroids, *diagonal),
            });
        }
        for name in new {
            let title = format!("after stage {} `{}`: {name}", record.index, record.kind);
            self.picture(title, mesh, Some(name), false);
        }
        if self.every_stage {
            self.picture(
                format!("after stage {} `{}`", record.index, record.kind),
                mesh,
                None,
                true,
            );
        }
        *self.seen.borrow_mut() = names;
    }

    /// Writes every picture to `dir` as `NN-title.png`.
    pub fn write_all(&self, dir: &std::path::Path) -> anyhow::Result<Vec<PathBuf>> {
        std::fs::create_dir_all(dir)?;
        let mut written = Vec::new();
        for (i, p) in self.pictures.borrow().iter().enumerate() {
            let slug: String = p
                .title
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '.' {
                        c
                    } else {
                        '-'
                    }
                })
                .collect::<String>()
                .split('-')
                .filter(|s| !s.is_empty())
                .collect::<Vec<_>>()
                .join("-");
            let path = dir.join(format!("{:02}-{slug}.png", i + 1));
            crate::commands::write_atomically(&path, &p.png)?;
            written.push(path);
        }
        Ok(written)
    }
}

/// The name of the face labels a clustering stage writes.
const CLUSTER: &str = "cluster";

/// The label of the face of `mesh` nearest each of `points`, which lie on a mesh whose box
/// has diagonal `diagonal`. `mesh` may be that surface in other units by a power of two
/// (the runner rescales meshes of extreme size), which is undone first.
pub(crate) fn carry_labels(
    mesh: &Mesh,
    labels: &[u32],
    points: &[DVec3],
    diagonal: f64,
) -> Vec<u32> {
    let ratio = mesh.bbox().diagonal() / diagonal;
    let scale = if ratio.is_finite() && ratio > 0.0 {
        2f64.powi(ratio.log2().round() as i32)
    } else {
        1.0
    };
    let bvh = coarsen_spatial::Bvh::build(&mesh.positions, &mesh.faces);
    points
        .par_iter()
        .map(|&p| {
            bvh.closest_point(p * scale)
                .map_or(0, |n| labels[n.face as usize])
        })
        .collect()
}

/// The report's maps of the output against the input: the distance of each to the other
/// (far in red: where the output left the surface, e.g. rounded feature edges), the
/// smallest angles (the worst 1 % of faces in magenta), the sharp features of both and,
/// when both carry texture coordinates, their texture.
pub fn maps_of(r: &Recorder, input: &Mesh, output: &Mesh, fields: &coarsen_metrics::Fields) {
    let (mut a, mut b) = (input.clone(), output.clone());
    fields.input.attach(&mut a);
    fields.output.attach(&mut b);
    let title = "distance: input (to the output) and output (to the input), from four sides \
                 (top left: the pictures' view; top right: the other side; bottom: from above \
                 and from below)"
        .to_string();
    r.map(title, vec![a, b], maps::Field::Distance, None, true);
    let title = "smallest angle: input and output, the worst 1 % in magenta".to_string();
    r.map(
        title,
        vec![input.clone(), output.clone()],
        maps::Field::MinAngle,
        Some(1.0),
        false,
    );
    let title = "sharp features: input and output (edges over 40° or marked red, boundary \
                 blue, of three or more faces purple, corners yellow)"
        .to_string();
    r.features(title, &[input, output]);
    let textured = |m: &Mesh| coarsen_metrics::texture::corner_uvs(m).is_some();
    if textured(input) && textured(output) {
        let title = "texture: input and output from four sides (a UV checkerboard when the \
                     material has no PNG texture: squares that meet across a seam show it held)"
            .to_string();
        r.texture(title, &[input, output]);
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn img(p: &Picture) -> String {
    let data = base64::engine::general_purpose::STANDARD.encode(&p.png);
    format!(
        "<figure><img alt=\"{t}\" src=\"data:image/png;base64,{data}\"><figcaption>{t}</figcaption></figure>",
        t = escape(&p.title)
    )
}

/// An SVG bar chart of the smallest-angle histograms (5° bins from 0°) as percents of
/// each mesh's faces: the output's in colour (red under 30°), the input's, when given,
/// overlaid as grey outlines.
fn histogram_svg(output: &[u32], input: Option<&[u32]>) -> String {
    let share = |bins: &[u32]| -> Vec<f64> {
        let n = bins.iter().map(|&b| f64::from(b)).sum::<f64>().max(1.0);
        bins.iter().map(|&b| 100.0 * f64::from(b) / n).collect()
    };
    let (out, inp) = (share(output), input.map(share));
    let max = out
        .iter()
        .chain(inp.iter().flatten())
        .copied()
        .fold(1.0, f64::max);
    let (w, h, bar) = (480.0, 160.0, 480.0 / output.len().max(1) as f64);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{}\" role=\"img\" aria-label=\"smallest angles\">",
        h + 34.0
    );
    for (i, &p) in out.iter().enumerate() {
        let bh = p / max * h;
        let x = i as f64 * bar;
        let fill = if i < 6 { "#c2553a" } else { "#3a78c2" };
        let _ = write!(
            s,
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{bh:.1}\" fill=\"{fill}\"><title>output {}–{}°: {} faces ({p:.1} %)</title></rect>",
            x + 1.0,
            h - bh,
            bar - 2.0,
            i * 5,
            i * 5 + 5,
            output[i]
        );
        let _ = write!(
            s,
            "<text x=\"{:.1}\" y=\"{}\" font-size=\"10\" text-anchor=\"middle\">{}°</text>",
            x + bar / 2.0,
            h + 14.0,
            i * 5 + 5
        );
    }
    if let (Some(inp), Some(counts)) = (&inp, input) {
        for (i, &p) in inp.iter().enumerate() {
            let bh = p / max * h;
            let _ = write!(
                s,
                "<rect class=\"input\" x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{bh:.1}\" fill=\"none\" stroke=\"#333\" stroke-dasharray=\"3 2\"><title>input {}–{}°: {} faces ({p:.1} %)</title></rect>",
                i as f64 * bar + 3.0,
                h - bh,
                bar - 6.0,
                i * 5,
                i * 5 + 5,
                counts.get(i).copied().unwrap_or(0)
            );
        }
        let _ = write!(
            s,
            "<text x=\"{w}\" y=\"{}\" font-size=\"11\" text-anchor=\"end\">bars: output · dashed: input · % of each mesh's faces</text>",
            h + 28.0
        );
    }
    s.push_str("</svg>");
    s
}

/// The self-contained HTML page of a run: pictures inline, no network needed.
pub fn page(
    report: &RunReport,
    metrics: Option<&MetricsReport>,
    input_quality: Option<&Quality>,
    viewer: Option<&str>,
    pictures: &[Picture],
    notes: &[String],
) -> String {
    let mut h = String::new();
    write_head(&mut h, report);
    write_summary(&mut h, report);
    if let Some(v) = viewer {
        h.push_str(v);
    }
    write_pictures(&mut h, pictures);
    if let Some(m) = metrics {
        write_metrics(&mut h, m, input_quality);
    }
    write_stage_plots(&mut h, report);
    write_stages(&mut h, report);
    write_warnings(&mut h, report, notes);
    h.push_str("</body></html>\n");
    h
}

/// Writes the page's head (title and style sheet) and opens its body.
fn write_head(h: &mut String, report: &RunReport) {
    let _ = write!(
        h,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>coarsen: {name}</title><style>\
         body{{font:14px/1.45 system-ui,sans-serif;margin:2em auto;max-width:1100px;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:3px 8px;text-align:right}}\
         th{{background:#f2f2f2}}td:first-child,th:first-child{{text-align:left}}\
         figure{{display:inline-block;margin:0 1em 1em 0}}figure img{{max-width:520px;border:1px solid #ddd}}\
         figcaption{{font-size:12px;color:#555}}.warn{{color:#a33}}</style></head><body>",
        name = escape(&report.pipeline)
    );
}

/// Writes the heading and the one-line summary: pipeline, input and output sizes, run time.
fn write_summary(h: &mut String, report: &RunReport) {
    let _ = write!(
        h,
        "<h1>coarsen run: pipeline <code>{}</code></h1><p>Input <code>{}</code>: {} vertices, {} faces → output: {} vertices, {} faces, in {:.3} s.</p>",
        escape(&report.pipeline),
        escape(&report.input),
        report.input_vertices,
        report.input_faces,
        report.output_vertices,
        report.output_faces,
        report.seconds
    );
}

/// Writes the pictures section.
fn write_pictures(h: &mut String, pictures: &[Picture]) {
    h.push_str("<h2>Pictures</h2><div id=\"pictures\">");
    for p in pictures {
        h.push_str(&img(p));
    }
    h.push_str("</div>");
}

/// Writes the table of the output's figures against the input and the smallest-angle
/// histogram.
fn write_metrics(h: &mut String, m: &MetricsReport, input_quality: Option<&Quality>) {
    let (q, v) = (&m.quality, &m.validity);
    h.push_str("<h2>Output against the input</h2><table id=\"metrics\"><tr><th>figure</th><th>value</th></tr>");
    let mut row = |k: &str, val: String| {
        let _ = write!(h, "<tr><td>{k}</td><td>{}</td></tr>", escape(&val));
    };
    row(
        "vertices / faces",
        format!("{} / {}", v.n_vertices, v.n_faces),
    );
    row("α_min", format!("{:.2}°", q.alpha_min_deg));
    row("α_avg", format!("{:.2}°", q.alpha_avg_deg));
    row("triangles under 30°", format!("{:.2} %", q.p_lt30_pct));
    row("Q_min / Q_avg", format!("{:.3} / {:.3}", q.q_min, q.q_avg));
    if let Some(f) = &m.fidelity {
        row(
            "Hausdorff",
            format!("{:.3} % of the diagonal", f.hausdorff_pct),
        );
        row(
            "mean / RMS distance",
            format!("{:.4} % / {:.4} %", f.mean_dist_pct, f.rms_dist_pct),
        );
        row(
            "distance samples (input → output / output → input)",
            format!("{} / {}", f.forward_samples, f.backward_samples),
        );
    }
    row("manifold", v.manifold.to_string());
    row(
        "components / boundary loops",
        format!("{} / {}", v.n_components, v.n_boundary_loops),
    );
    row(
        "genus",
        v.genus
            .map(|g| g.to_string())
            .unwrap_or_else(|| "undefined".into()),
    );
    row(
        "degenerate / flipped faces",
        format!(
            "{} / {}",
            v.n_degenerate,
            v.n_flipped
                .map(|n| n.to_string())
                .unwrap_or_else(|| "—".into())
        ),
    );
    if let Some(t) = &m.texture {
        row(
            "seam vertices (input → output)",
            format!("{} → {}", t.seam_vertices_in, t.seam_vertices),
        );
        row(
            "faces turned over / flat in UV space",
            format!("{} / {}", t.uv_flipped, t.uv_degenerate),
        );
        row(
            "texture distortion at the vertices (max / mean)",
            format!(
                "{:.3} % / {:.4} % of the diagonal",
                t.distortion_max_pct, t.distortion_mean_pct
            ),
        );
        row(
            "texture distortion inside the faces (max / mean)",
            format!(
                "{:.3} % / {:.4} % of the diagonal",
                t.surface_distortion_max_pct, t.surface_distortion_mean_pct
            ),
        );
    }
    h.push_str("</table><h3>Smallest angle of each triangle</h3>");
    let input_bins = input_quality.map(|q| q.min_angle_histogram.as_slice());
    h.push_str(&histogram_svg(&q.min_angle_histogram, input_bins));
}

/// Writes the per-stage plots, if the run has any.
fn write_stage_plots(h: &mut String, report: &RunReport) {
    let plots = crate::plots::stage_plots(report);
    if !plots.is_empty() {
        h.push_str("<h2>How the stages went</h2><div id=\"plots\">");
        for p in plots {
            h.push_str(&p);
        }
        h.push_str("</div>");
    }
}

/// Writes the table of stages: sizes before and after, and run time.
fn write_stages(h: &mut String, report: &RunReport) {
    h.push_str("<h2>Stages</h2><table id=\"stages\"><tr><th>#</th><th>stage</th><th>faces before</th><th>faces after</th><th>vertices after</th><th>seconds</th></tr>");
    for s in &report.stages {
        let _ = write!(
            h,
            "<tr><td>{}</td><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td><td>{:.3}</td></tr>",
            s.index,
            escape(&s.kind),
            s.faces_before,
            s.faces_after,
            s.vertices_after,
            s.seconds
        );
    }
    h.push_str("</table>");
}

/// Writes the stages' warnings and the run's notes, if there are any.
fn write_warnings(h: &mut String, report: &RunReport, notes: &[String]) {
    let warnings: Vec<String> = report
        .stages
        .iter()
        .flat_map(|s| {
            s.warnings
                .iter()
                .map(move |w| format!("stage {} `{}`: {w}", s.index, s.kind))
        })
        .chain(notes.iter().cloned())
        .collect();
    if !warnings.is_empty() {
        h.push_str("<h2>Notes and warnings</h2><ul>");
        for w in warnings {
            let _ = write!(h, "<li class=\"warn\">{}</li>", escape(&w));
        }
        h.push_str("</ul>");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_has_one_bar_per_bin_and_escapes_nothing_unsafe() {
        let svg = histogram_svg(&[0, 3, 9, 1], None);
        assert_eq!(svg.matches("<rect").count(), 4);
        let both = histogram_svg(&[0, 3, 9, 1], Some(&[5, 5, 0, 0]));
        assert_eq!(both.matches("<rect class=\"input\"").count(), 4);
        // Shares, not counts: the input's 50 % bins are the tallest bars.
        assert!(both.contains("input 0–5°: 5 faces (50.0 %)"));
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>"));
        assert_eq!(
            escape("<a href=\"x\">&"),
            "&lt;a href=&quot;x&quot;&gt;&amp;"
        );
    }
}
