//! The HTML report's interactive 3-D view: the input and the output embedded compactly
//! (positions as 16-bit fractions of their box, faces as varint deltas, one byte of
//! distance per face, all base64) and a small WebGL viewer written for the report
//! (`viewer.js`: orbit, zoom, side by side or overlaid, wire on/off, colour by distance,
//! smallest angle, curvature, regions — each output vertex a hue, each input vertex that
//! of the output vertex nearest it — or the first clustering's clusters, carried to the
//! input's faces and from there to the output's vertices). No library is vendored: the
//! viewer needs a few hundred lines, where three.js would add some 600 kB to every report.

use crate::html::InputClusters;
use base64::Engine as _;
use coarsen_mesh::Mesh;
use coarsen_metrics::MeshFields;
use std::fmt::Write as _;

/// The viewer's script.
const SCRIPT: &str = include_str!("viewer.js");

/// A mesh with more faces than this is embedded decimated (QEM) to this many.
pub const MAX_EMBED_FACES: usize = 250_000;

/// A mesh ready to embed, with the faces' distances to the other mesh.
pub struct Embedded<'a> {
    /// What the viewer calls it.
    pub name: &'a str,
    /// The mesh.
    pub mesh: &'a Mesh,
    /// Each face's distance to the other mesh (model units).
    pub face_distance: &'a [f64],
}

impl<'a> Embedded<'a> {
    /// `mesh` with its measured fields.
    pub fn new(name: &'a str, mesh: &'a Mesh, fields: &'a MeshFields) -> Self {
        Embedded {
            name,
            mesh,
            face_distance: &fields.face_distance,
        }
    }
}

/// The bytes of one mesh: positions as u16 triples over `[lo, hi]`, then the corners as
/// zigzag varint deltas from the corner before, then one byte per face of distance over
/// `[0, top]` (clamped).
fn encode(m: &Embedded<'_>, top: f64) -> (Vec<u8>, [f64; 3], [f64; 3]) {
    let bbox = m.mesh.bbox();
    let (lo, hi) = (bbox.min.to_array(), bbox.max.to_array());
    let mut out = Vec::with_capacity(6 * m.mesh.n_vertices() + 5 * m.mesh.n_faces());
    for p in &m.mesh.positions {
        for k in 0..3 {
            let span = hi[k] - lo[k];
            let t = if span > 0.0 {
                (p[k] - lo[k]) / span
            } else {
                0.0
            };
            let q = (t.clamp(0.0, 1.0) * 65535.0).round() as u16;
            out.extend_from_slice(&q.to_le_bytes());
        }
    }
    let mut prev = 0i64;
    for &v in m.mesh.faces.iter().flatten() {
        let delta = i64::from(v) - prev;
        prev = i64::from(v);
        push_varint(&mut out, ((delta << 1) ^ (delta >> 63)) as u64);
    }
    for &d in m.face_distance {
        let t = if top > 0.0 { d / top } else { 0.0 };
        out.push((t.clamp(0.0, 1.0) * 255.0).round() as u8);
    }
    (out, lo, hi)
}

/// The viewer's section of the report: the controls, the canvas, the embedded meshes (and
/// clusters, when given) and the script; `note` says why the input shown is not the input
/// itself, when it is not.
pub fn section(
    input: &Embedded<'_>,
    output: &Embedded<'_>,
    clusters: Option<&Clusters<'_>>,
    note: Option<&str>,
) -> String {
    let top = [input.face_distance, output.face_distance]
        .iter()
        .map(|d| crate::maps::percentile(d, 0.99))
        .fold(0.0, f64::max);
    let option = clusters.map_or(String::new(), |c| {
        format!(
            "<option value=\"clusters\">clusters of {} (output: those of the input nearest)</option>",
            c.stage.replace('`', "")
        )
    });
    let mut h = format!(
        "<h2>Interactive view</h2><div id=\"viewer-controls\">\
         <label><input type=\"radio\" name=\"mode\" value=\"side\" checked> side by side</label> \
         <label><input type=\"radio\" name=\"mode\" value=\"overlay\"> overlaid</label> \
         <label><input type=\"checkbox\" name=\"wire\" checked> wireframe</label> \
         <label>colour by <select name=\"colour\"><option value=\"plain\">nothing</option>\
         <option value=\"distance\">distance to the other mesh</option>\
         <option value=\"min_angle\">smallest angle</option>\
         <option value=\"curvature\">curvature (angle deficit)</option>\
         <option value=\"regions\">regions (input: nearest output vertex)</option>{clusters}</select></label></div>\
         <canvas id=\"viewer\" width=\"1000\" height=\"460\" style=\"border:1px solid #ddd;max-width:100%;cursor:grab\"></canvas>\
         <p id=\"viewer-status\">The view needs JavaScript and WebGL.</p>",
        clusters = option
    );
    if let Some(note) = note {
        let _ = write!(h, "<p class=\"warn\" id=\"viewer-note\">{note}</p>");
    }
    let _ = write!(
        h,
        "<p>Drag to turn, wheel to zoom; left the input, right the output. Distance colours \
         run from 0 (blue) to {:.4} model units (red, the larger of the meshes' 99th \
         percentiles of faces).</p>",
        top
    );
    for (id, m) in [("mesh-input", input), ("mesh-output", output)] {
        let (bytes, lo, hi) = encode(m, top);
        let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
        let list = |a: [f64; 3]| format!("{:e},{:e},{:e}", a[0], a[1], a[2]);
        let _ = write!(
            h,
            "<script type=\"application/octet-stream\" id=\"{id}\" data-name=\"{}\" \
             data-vertices=\"{}\" data-faces=\"{}\" data-min=\"{}\" data-max=\"{}\">{data}</script>",
            m.name,
            m.mesh.n_vertices(),
            m.mesh.n_faces(),
            list(lo),
            list(hi)
        );
    }
    if let Some(c) = clusters {
        for (id, labels) in [
            ("clusters-input", c.input_faces),
            ("clusters-output", &c.output_vertices[..]),
        ] {
            let data = base64::engine::general_purpose::STANDARD.encode(varints(labels));
            let _ = write!(
                h,
                "<script type=\"application/octet-stream\" id=\"{id}\" data-count=\"{}\">{data}</script>",
                labels.len()
            );
        }
    }
    let _ = write!(h, "<script>{SCRIPT}</script>");
    h
}

/// The input as the viewer shows it: `None` for the input itself, else the input
/// decimated (QEM) to [`MAX_EMBED_FACES`] faces; with the note saying so.
pub struct ShownInput {
    /// The decimated input, when the input has too many faces to embed.
    pub decimated: Option<Mesh>,
    /// Why the input shown is not the input itself, when it is not.
    pub notes: Vec<String>,
}

impl ShownInput {
    /// How the viewer will show `input`.
    pub fn of(input: &Mesh) -> ShownInput {
        let mut notes = Vec::new();
        let decimated = decimated(input, "input", &mut notes);
        ShownInput { decimated, notes }
    }
}

/// The viewer's section for a run's input (shown as `shown` says) and output and their
/// fields, with the first clustering's clusters on the shown input when the run made
/// some: an output over [`MAX_EMBED_FACES`] is shown decimated by the `qem` pipeline too
/// (and the pair measured again), with a note saying so.
pub fn for_report(
    input: &Mesh,
    shown: ShownInput,
    output: &Mesh,
    fields: &coarsen_metrics::Fields,
    clusters: Option<&InputClusters>,
) -> String {
    let ShownInput {
        decimated: small_input,
        mut notes,
    } = shown;
    let small_output = decimated(output, "output", &mut notes);
    let (a, b) = (
        small_input.as_ref().unwrap_or(input),
        small_output.as_ref().unwrap_or(output),
    );
    let remeasured = (small_input.is_some() || small_output.is_some())
        .then(|| coarsen_metrics::measure_with_fields(a, b, &Default::default()));
    let fields = match &remeasured {
        None => fields,
        Some(Ok((_, f))) => f,
        Some(Err(e)) => {
            return format!("<h2>Interactive view</h2><p class=\"warn\">not available: {e}</p>");
        }
    };
    let note = (!notes.is_empty()).then(|| notes.join(" "));
    let clusters = clusters
        .filter(|c| c.labels.len() == a.n_faces())
        .map(|c| Clusters::new(c, a, b));
    section(
        &Embedded::new("input", a, &fields.input),
        &Embedded::new("output", b, &fields.output),
        clusters.as_ref(),
        note.as_deref(),
    )
}

/// The clusters as the viewer colours them: per face of the shown input its cluster, per
/// vertex of the output the cluster of the input face nearest it (so that the two sides
/// match in colour).
pub struct Clusters<'a> {
    /// The stage that made them.
    pub stage: &'a str,
    /// Per face of the shown input.
    pub input_faces: &'a [u32],
    /// Per vertex of the output.
    pub output_vertices: Vec<u32>,
}

impl<'a> Clusters<'a> {
    /// `clusters` on `input` (the shown input), carried to the vertices of `output`.
    pub fn new(clusters: &'a InputClusters, input: &Mesh, output: &Mesh) -> Self {
        let diagonal = input.bbox().diagonal();
        let output_vertices =
            crate::html::carry_labels(input, &clusters.labels, &output.positions, diagonal);
        Clusters {
            stage: &clusters.stage,
            input_faces: &clusters.labels,
            output_vertices,
        }
    }
}

/// `values` as varints, one after the other.
fn varints(values: &[u32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(2 * values.len());
    for &v in values {
        push_varint(&mut out, u64::from(v));
    }
    out
}

/// Appends `z` as a varint: seven bits a byte, low first, the top bit set on all but the
/// last.
fn push_varint(out: &mut Vec<u8>, mut z: u64) {
    loop {
        let byte = (z & 127) as u8;
        z >>= 7;
        if z == 0 {
            out.push(byte);
            break;
        }
        out.push(byte | 128);
    }
}

/// `mesh` decimated to [`MAX_EMBED_FACES`] faces when it has more, with a note.
fn decimated(mesh: &Mesh, what: &str, notes: &mut Vec<String>) -> Option<Mesh> {
    if mesh.n_faces() <= MAX_EMBED_FACES {
        return None;
    }
    let run = coarsen::Remesher::new()
        .pipeline("qem")
        .target(coarsen_stage::Target::Faces(MAX_EMBED_FACES as u64))
        .run(mesh);
    match run {
        Ok((small, _)) => {
            notes.push(format!(
                "The {what} has {} faces, too many to embed: the view shows it decimated \
                 (QEM) to {} faces; the pictures and figures are of the whole {what}.",
                mesh.n_faces(),
                small.n_faces()
            ));
            Some(small)
        }
        Err(e) => {
            notes.push(format!(
                "The {what} could not be decimated for the view ({e}): it is shown whole."
            ));
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Decodes [`encode`]'s bytes as the viewer does.
    fn decode(bytes: &[u8], nv: usize, nf: usize, lo: [f64; 3], hi: [f64; 3]) -> Mesh {
        let mut at = 0;
        let mut positions = Vec::new();
        for _ in 0..nv {
            let p: [f64; 3] = std::array::from_fn(|k| {
                let q = u16::from_le_bytes([bytes[at + 2 * k], bytes[at + 2 * k + 1]]);
                lo[k] + (hi[k] - lo[k]) * f64::from(q) / 65535.0
            });
            at += 6;
            positions.push(coarsen_mesh::DVec3::from_array(p));
        }
        let (mut prev, mut corners) = (0i64, Vec::new());
        for _ in 0..3 * nf {
            let (mut z, mut shift) = (0u64, 0);
            loop {
                let b = bytes[at];
                at += 1;
                z |= u64::from(b & 127) << shift;
                shift += 7;
                if b & 128 == 0 {
                    break;
                }
            }
            prev += ((z >> 1) as i64) ^ -((z & 1) as i64);
            corners.push(prev as u32);
        }
        assert_eq!(bytes.len(), at + nf, "one distance byte per face");
        let faces = corners.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        Mesh::new(positions, faces)
    }

    #[test]
    fn meshes_round_trip_through_the_encoding_within_a_quantum() {
        let mut m = coarsen_shapes::icosphere(2.0, 3).unwrap();
        m.faces.reverse(); // large jumps between faces: negative and long deltas
        let d: Vec<f64> = (0..m.n_faces()).map(|f| f as f64 / 100.0).collect();
        let e = Embedded {
            name: "sphere",
            mesh: &m,
            face_distance: &d,
        };
        let (bytes, lo, hi) = encode(&e, 1.0);
        let back = decode(&bytes, m.n_vertices(), m.n_faces(), lo, hi);
        assert_eq!(back.faces, m.faces);
        for (a, b) in back.positions.iter().zip(&m.positions) {
            assert!((*a - *b).abs().max_element() <= 4.0 / 65535.0 * 0.5 + 1e-12);
        }
        let distances = &bytes[bytes.len() - m.n_faces()..];
        assert_eq!((distances[0], distances[50], distances[100]), (0, 128, 255));
        // Compact: under 11 bytes a face for a mesh in cache-friendly order.
        let fresh = coarsen_shapes::icosphere(2.0, 3).unwrap();
        let e = Embedded { mesh: &fresh, ..e };
        assert!(encode(&e, 1.0).0.len() < 11 * fresh.n_faces());
    }

    #[test]
    fn the_section_is_offline_and_names_both_meshes() {
        let m = coarsen_shapes::icosphere(1.0, 1).unwrap();
        let d = vec![0.0; m.n_faces()];
        let e = Embedded {
            name: "input",
            mesh: &m,
            face_distance: &d,
        };
        let s = section(
            &e,
            &Embedded {
                name: "output",
                ..e
            },
            None,
            Some("decimated"),
        );
        assert!(s.contains("id=\"mesh-input\"") && s.contains("id=\"mesh-output\""));
        assert!(s.contains("data-faces=\"80\"") && s.contains("viewer-note"));
        assert!(!s.contains("http") && !s.contains("<script src"));
        assert!(
            !s.contains("value=\"clusters\"") && !s.contains("id=\"clusters-input\""),
            "no clusters offered without them"
        );
    }

    #[test]
    fn clusters_reach_the_output_vertices_through_the_nearest_input_face() {
        // Two clusters on a sphere: its upper and lower half.
        let m = coarsen_shapes::icosphere(1.0, 2).unwrap();
        let labels: Vec<u32> = (0..m.n_faces())
            .map(|f| {
                let [a, b, c] = m.corners(f);
                u32::from((a + b + c).z < 0.0)
            })
            .collect();
        let input = InputClusters {
            stage: "stage 2 `cluster.cvt`".into(),
            labels,
        };
        let out = coarsen_shapes::icosphere(1.0, 0).unwrap();
        let c = Clusters::new(&input, &m, &out);
        for (p, &l) in out.positions.iter().zip(&c.output_vertices) {
            if p.z.abs() > 0.1 {
                assert_eq!(l, u32::from(p.z < 0.0), "vertex at {p}");
            }
        }
        let d = vec![0.0; m.n_faces()];
        let e = Embedded {
            name: "input",
            mesh: &m,
            face_distance: &d,
        };
        let s = section(&e, &e, Some(&c), None);
        assert!(s.contains("clusters of stage 2 cluster.cvt"));
        assert!(s.contains(&format!(
            "id=\"clusters-input\" data-count=\"{}\"",
            m.n_faces()
        )));
        assert!(s.contains("id=\"clusters-output\" data-count=\"12\""));
    }

    #[test]
    fn varints_take_one_byte_below_128_and_more_above() {
        assert_eq!(varints(&[0, 127, 128, 300]), vec![0, 127, 128, 1, 172, 2]);
    }
}
