//! The figures element by element: how far each vertex and face of one mesh lies from the
//! other surface, each face's smallest angle and quality, the output's flipped faces.
//!
//! They come from the samples of [`measure_with_fields`](crate::measure_with_fields),
//! the very samples its Hausdorff distance is taken over, so the largest
//! [`MeshFields::face_distance`] of the output is the output → input maximum of the
//! report, and the input's that of input → output.
//!
//! [`MeshFields::attach`] adds them to a mesh as attribute columns under the names below,
//! which a PLY file carries as scalar properties: MeshLab reads the vertex `quality` as
//! its per-vertex quality (as its own Hausdorff filter stores the distance there) and the
//! face `quality` as its per-face quality (as its triangle-quality filter does); ParaView
//! shows every column by name.

use crate::error::{MetricsError, Role};
use crate::fidelity::DistanceField;
use crate::prepare::{Prepared, map_chunks};
use coarsen_geom::triangle;
use coarsen_mesh::{AttrValues, Mesh};

/// Vertex column: the vertex's distance to the other surface, in model units.
pub const VERTEX_DISTANCE: &str = "quality";
/// Face column: the face's largest sampled distance to the other surface, in model units.
pub const FACE_DISTANCE: &str = "distance";
/// Face column: the face's smallest interior angle, in degrees.
pub const FACE_MIN_ANGLE: &str = "min_angle";
/// Face column: the face's Frey–Borouchaki quality Q in `[0, 1]` (1 equilateral).
pub const FACE_QUALITY: &str = "quality";
/// Face label column of the output: 1 where the face is turned over against the input
/// (see [`Validity::n_flipped`](crate::Validity::n_flipped)), else 0.
pub const FACE_FLIPPED: &str = "flipped";

/// Faces per parallel chunk of the shape fields.
const CHUNK: usize = 4096;

/// The fields of one mesh measured against the other.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshFields {
    /// Each vertex's distance to the other surface, in model units (0 for a vertex no
    /// face uses).
    pub vertex_distance: Vec<f64>,
    /// Each face's largest distance to the other surface over its samples (those of the
    /// report's sampling that the face owns, and its corners), in model units.
    pub face_distance: Vec<f64>,
    /// Each face's smallest interior angle, in degrees (0 when degenerate).
    pub face_min_angle_deg: Vec<f64>,
    /// Each face's Frey–Borouchaki quality (0 when degenerate).
    pub face_quality: Vec<f64>,
    /// The faces turned over against the input; `None` for the input itself.
    pub face_flipped: Option<Vec<bool>>,
    /// The input's bounding-box diagonal, for distances as percents.
    pub bbox_diagonal: f64,
}

/// The fields of both meshes of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct Fields {
    /// The output against the input (with its flipped faces).
    pub output: MeshFields,
    /// The input against the output.
    pub input: MeshFields,
}

impl MeshFields {
    /// Adds the fields to `mesh` (the mesh they were measured on) as attribute columns
    /// named by this module's constants, replacing columns of the same name.
    pub fn attach(&self, mesh: &mut Mesh) {
        let scalar = |v: &Vec<f64>| AttrValues::Scalar(v.clone());
        mesh.vertex_attrs
            .insert(VERTEX_DISTANCE, scalar(&self.vertex_distance));
        mesh.face_attrs
            .insert(FACE_DISTANCE, scalar(&self.face_distance));
        mesh.face_attrs
            .insert(FACE_MIN_ANGLE, scalar(&self.face_min_angle_deg));
        mesh.face_attrs
            .insert(FACE_QUALITY, scalar(&self.face_quality));
        if let Some(flipped) = &self.face_flipped {
            let labels = flipped.iter().map(|&f| u32::from(f)).collect();
            mesh.face_attrs
                .insert(FACE_FLIPPED, AttrValues::Label(labels));
        }
    }

    /// The largest face distance, as a percent of the input's diagonal.
    pub fn max_distance_pct(&self) -> f64 {
        let largest = self.face_distance.iter().copied().fold(0.0, f64::max);
        100.0 * largest / self.bbox_diagonal
    }
}

/// Each face's smallest angle (degrees) and Frey–Borouchaki quality.
///
/// Errors when a face index is out of range or a used vertex is not finite or too large
/// (the mesh is called the output in the error).
pub fn shape_fields(mesh: &Mesh) -> Result<(Vec<f64>, Vec<f64>), MetricsError> {
    Prepared::new(mesh, Role::Output).map(|p| shape_of(&p))
}

/// [`shape_fields`] of a checked mesh.
fn shape_of(p: &Prepared) -> (Vec<f64>, Vec<f64>) {
    let mesh = p.mesh;
    let parts = map_chunks(mesh.n_faces(), CHUNK, |range| {
        range
            .map(|f| {
                let [a, b, c] = mesh.corners(f);
                let angle = triangle::min_angle(a, b, c).to_degrees();
                (angle, triangle::quality(a, b, c))
            })
            .collect::<Vec<_>>()
    });
    parts.into_iter().flatten().unzip()
}

/// The fields of both meshes from the recorded distances and the output's flips.
pub(crate) fn of_distances(
    input: &Prepared,
    output: &Prepared,
    forward: DistanceField,
    backward: DistanceField,
    flipped: Vec<bool>,
) -> Fields {
    let diagonal = input.bbox.diagonal();
    let make = |p: &Prepared, d: DistanceField, flipped: Option<Vec<bool>>| {
        let (face_min_angle_deg, face_quality) = shape_of(p);
        MeshFields {
            vertex_distance: d.vertex,
            face_distance: d.face,
            face_min_angle_deg,
            face_quality,
            face_flipped: flipped,
            bbox_diagonal: diagonal,
        }
    };
    Fields {
        output: make(output, backward, Some(flipped)),
        input: make(input, forward, None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::icosphere;
    use crate::{MetricsOptions, measure, measure_with_fields};

    fn scaled(m: &Mesh, s: f64) -> Mesh {
        Mesh::new(
            m.positions.iter().map(|p| *p * s).collect(),
            m.faces.clone(),
        )
    }

    /// A polyhedron P with its vertices on the unit sphere against (1 + d)·P: each vertex
    /// of (1 + d)·P is exactly d from P (P lies in the unit ball, and the vertex it grew
    /// from is d away); each vertex of P is between d·h and d from (1 + d)·P, h the
    /// smallest distance of a face plane from the centre. The figures are [`measure`]'s.
    #[test]
    fn scaled_sphere_fields_are_bounded_by_the_scale_and_match_the_report() {
        let m = icosphere(3);
        let d = 0.02;
        let big = scaled(&m, 1.0 + d);
        let opts = MetricsOptions::default();
        let (report, fields) = measure_with_fields(&m, &big, &opts).unwrap();
        assert_eq!(report, measure(Some(&m), &big, &opts).unwrap());
        let h_min = (0..m.n_faces())
            .map(|i| m.face_normal(i).dot(m.corners(i)[0]))
            .fold(f64::INFINITY, f64::min);
        for &x in &fields.output.vertex_distance {
            assert!((x - d).abs() < 1e-12, "{x}");
        }
        for &x in &fields.input.vertex_distance {
            assert!(x >= d * h_min - 1e-12 && x <= d + 1e-12, "{x}");
        }
        let f = report.fidelity.unwrap();
        let pct = |x: f64| 100.0 * x / f.bbox_diagonal;
        let out_max = fields
            .output
            .face_distance
            .iter()
            .copied()
            .fold(0.0, f64::max);
        let in_max = fields
            .input
            .face_distance
            .iter()
            .copied()
            .fold(0.0, f64::max);
        assert_eq!(pct(out_max), f.backward_max_pct);
        assert_eq!(pct(in_max), f.forward_max_pct);
        assert_eq!(fields.output.max_distance_pct(), f.backward_max_pct);
        // A face's distance is at least its corners'.
        for (face, &x) in big.faces.iter().zip(&fields.output.face_distance) {
            for &v in face {
                assert!(x >= fields.output.vertex_distance[v as usize]);
            }
        }
        assert_eq!(fields.output.face_flipped, Some(vec![false; big.n_faces()]));
        assert_eq!(fields.input.face_flipped, None);
    }

    #[test]
    fn shape_fields_agree_with_the_quality_figures() {
        let m = crate::test_meshes::icosphere(2);
        let (angles, q) = shape_fields(&m).unwrap();
        let figures = crate::quality(&m).unwrap();
        assert_eq!(angles.len(), m.n_faces());
        let min = angles.iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(min, figures.alpha_min_deg);
        let q_min = q.iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(q_min, figures.q_min);
        let mean = angles.iter().sum::<f64>() / angles.len() as f64;
        assert!((mean - figures.alpha_avg_deg).abs() < 1e-9);
    }

    #[test]
    fn turned_faces_are_marked_and_columns_attach_under_their_names() {
        let a = icosphere(2);
        let mut b = a.clone();
        for f in [3usize, 17] {
            b.faces[f].swap(1, 2);
        }
        let (report, fields) = measure_with_fields(&a, &b, &MetricsOptions::default()).unwrap();
        let flipped = fields.output.face_flipped.as_ref().unwrap();
        let marked: Vec<usize> = (0..flipped.len()).filter(|&f| flipped[f]).collect();
        assert_eq!(marked, vec![3, 17]);
        assert_eq!(report.validity.n_flipped, Some(2));
        let mut out = b.clone();
        fields.output.attach(&mut out);
        assert_eq!(
            out.vertex_attrs.scalar(VERTEX_DISTANCE).unwrap().len(),
            b.n_vertices()
        );
        for name in [FACE_DISTANCE, FACE_MIN_ANGLE, FACE_QUALITY] {
            assert_eq!(
                out.face_attrs.scalar(name).unwrap().len(),
                b.n_faces(),
                "{name}"
            );
        }
        match out.face_attrs.get(FACE_FLIPPED) {
            Some(AttrValues::Label(l)) => assert_eq!(l.iter().sum::<u32>(), 2),
            other => panic!("{other:?}"),
        }
        let mut inp = a.clone();
        fields.input.attach(&mut inp);
        assert!(inp.face_attrs.get(FACE_FLIPPED).is_none());
        // Same meshes: zero distance everywhere.
        assert!(fields.input.vertex_distance.iter().all(|&x| x == 0.0));
    }

    #[test]
    fn fields_are_the_same_on_one_thread() {
        let (a, b) = (icosphere(3), scaled(&icosphere(1), 1.01));
        let opts = MetricsOptions::default();
        let (_, f) = measure_with_fields(&a, &b, &opts).unwrap();
        let (_, g) =
            coarsen_testdata::on_threads(1, || measure_with_fields(&a, &b, &opts).unwrap());
        assert_eq!(f, g);
        assert!(f.output.vertex_distance.iter().all(|x| x.is_finite()));
    }
}
