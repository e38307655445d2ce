//! The measured maps of `coarsen render --attribute distance|min_angle|quality` and of
//! the HTML report: the columns of `coarsen_metrics::fields` drawn good (blue) to bad (red)
//! on one scale for every mesh, with a colour bar.

use coarsen_mesh::{AttrValues, Mesh};
use coarsen_metrics::fields::{FACE_DISTANCE, FACE_MIN_ANGLE, FACE_QUALITY, VERTEX_DISTANCE};
use coarsen_render::ColorScale;

/// A measured field a picture can show.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// Each face's largest distance to the other surface.
    Distance,
    /// Each face's smallest angle.
    MinAngle,
    /// Each face's Frey–Borouchaki quality Q.
    Quality,
}

impl Field {
    /// The field an `--attribute` name asks for.
    pub fn named(name: &str) -> Option<Field> {
        match name {
            "distance" => Some(Field::Distance),
            "min_angle" => Some(Field::MinAngle),
            "quality" => Some(Field::Quality),
            _ => None,
        }
    }

    /// The face column the picture draws.
    pub fn column(self) -> &'static str {
        match self {
            Field::Distance => FACE_DISTANCE,
            Field::MinAngle => FACE_MIN_ANGLE,
            Field::Quality => FACE_QUALITY,
        }
    }
}

/// Readies `meshes` for a picture of `field` and returns its colour scale: the smallest
/// angle and Q are measured on each mesh (a file's own columns of those names are
/// replaced); the distance must be there already (`coarsen_metrics::fields`, or a
/// `--fields` file), and is drawn in percents of the input's diagonal when the meshes are
/// a measured pair (the first one the input), else in model units. `worst` highlights that
/// percent of each mesh's worst faces.
pub fn prepare(
    field: Field,
    meshes: &mut [Mesh],
    worst: Option<f64>,
) -> Result<ColorScale, String> {
    let name = field.column();
    // The vertex `quality` column of a fields file is MeshLab's slot for the distance: it
    // would shadow the face column of the same name.
    for m in meshes.iter_mut() {
        m.vertex_attrs.remove(VERTEX_DISTANCE);
    }
    let (range, factor, label, high_is_bad) = match field {
        Field::Distance => {
            if meshes.iter().any(|m| m.face_attrs.scalar(name).is_none()) {
                return Err(
                    "--attribute distance needs two meshes (INPUT OUTPUT), or a file \
                     written by `coarsen metrics --fields`"
                        .into(),
                );
            }
            let largest = meshes
                .iter()
                .flat_map(|m| m.face_attrs.scalar(name).unwrap_or(&[]).iter())
                .copied()
                .filter(|x| x.is_finite())
                .fold(0.0, f64::max);
            let (factor, label) = if meshes.len() == 2 {
                let diagonal = meshes[0].bbox().diagonal();
                (
                    100.0 / diagonal,
                    "distance to the other mesh, % of the input's diagonal".to_string(),
                )
            } else {
                (1.0, "distance to the other mesh, model units".to_string())
            };
            ((0.0, largest.max(f64::MIN_POSITIVE)), factor, label, true)
        }
        Field::MinAngle | Field::Quality => {
            for m in meshes.iter_mut() {
                let (angles, q) = coarsen_metrics::shape_fields(m).map_err(|e| e.to_string())?;
                let values = if field == Field::MinAngle { angles } else { q };
                m.face_attrs.insert(name, AttrValues::Scalar(values));
            }
            if field == Field::MinAngle {
                (
                    (0.0, 60.0),
                    1.0,
                    "smallest angle of each face, degrees".into(),
                    false,
                )
            } else {
                (
                    (0.0, 1.0),
                    1.0,
                    "quality Q of each face (1: equilateral)".into(),
                    false,
                )
            }
        }
    };
    let highlight_worst = worst.unwrap_or(0.0) / 100.0;
    let label = match worst {
        Some(p) => format!("{label}; magenta: worst {p} % of faces"),
        None => label,
    };
    Ok(ColorScale {
        label,
        range: Some(range),
        factor,
        high_is_bad,
        highlight_worst,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_names_and_their_scales() {
        assert_eq!(Field::named("min_angle"), Some(Field::MinAngle));
        assert_eq!(Field::named("curvature"), None);
        let sphere = coarsen_shapes::icosphere(1.0, 1).unwrap();
        let mut meshes = vec![sphere.clone()];
        let s = prepare(Field::MinAngle, &mut meshes, Some(1.0)).unwrap();
        assert_eq!(
            (s.range, s.high_is_bad, s.highlight_worst),
            (Some((0.0, 60.0)), false, 0.01)
        );
        assert_eq!(meshes[0].face_attrs.scalar("min_angle").unwrap().len(), 80);
        assert!(
            prepare(Field::Distance, &mut meshes, None)
                .unwrap_err()
                .contains("two meshes")
        );
    }
}
