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
    // The vertex `quality` column of a fields file is MeshLab's slot for the distance: it
    // would shadow the face column of the same name.
    for m in meshes.iter_mut() {
        m.vertex_attrs.remove(VERTEX_DISTANCE);
    }
    let (range, factor, label, high_is_bad) = match field {
        Field::Distance => {
            let (range, factor, label) = distance_scale(meshes)?;
            (range, factor, label, true)
        }
        Field::MinAngle | Field::Quality => {
            for m in meshes.iter_mut() {
                let (angles, q) = coarsen_metrics::shape_fields(m).map_err(|e| e.to_string())?;
                let values = if field == Field::MinAngle { angles } else { q };
                m.face_attrs
                    .insert(field.column(), AttrValues::Scalar(values));
            }
            if field == Field::MinAngle {
                let label = "smallest angle of each face, degrees".into();
                ((0.0, 60.0), 1.0, label, false)
            } else {
                let label = "quality Q of each face (1: equilateral)".into();
                ((0.0, 1.0), 1.0, label, false)
            }
        }
    };
    let label = match worst {
        Some(p) => format!("{label}; magenta: worst {p} % of faces"),
        None => label,
    };
    Ok(ColorScale {
        label,
        range: Some(range),
        factor,
        high_is_bad,
        highlight_worst: worst.unwrap_or(0.0) / 100.0,
    })
}

/// The distance map is red from this share of each mesh's faces up (the top of its
/// scale): a few faces far out would otherwise leave the rest of the map all blue.
const TOP_PERCENTILE: f64 = 0.99;

/// The range, tick factor and caption of the distance map: from 0 to the largest of the
/// meshes' 99th percentiles, the largest distance named in the caption.
fn distance_scale(meshes: &[Mesh]) -> Result<((f64, f64), f64, String), String> {
    let columns: Option<Vec<&[f64]>> = meshes
        .iter()
        .map(|m| m.face_attrs.scalar(FACE_DISTANCE))
        .collect();
    let Some(columns) = columns else {
        return Err(
            "--attribute distance needs two meshes (INPUT OUTPUT), or a file \
                    written by `coarsen metrics --fields`"
                .into(),
        );
    };
    let largest = columns
        .iter()
        .map(|c| percentile(c, 1.0))
        .fold(0.0, f64::max);
    let top = columns
        .iter()
        .map(|c| percentile(c, TOP_PERCENTILE))
        .fold(0.0, f64::max);
    let (factor, unit) = if meshes.len() == 2 {
        (
            100.0 / meshes[0].bbox().diagonal(),
            "% of the input's diagonal",
        )
    } else {
        (1.0, "model units")
    };
    let label = format!(
        "distance to the other mesh, {unit}; red from each mesh's 99th percentile of faces \
         up; largest {}",
        short(largest * factor)
    );
    Ok(((0.0, top.max(f64::MIN_POSITIVE)), factor, label))
}

/// The value a share `q` of the finite `values` lie at or below.
pub(crate) fn percentile(values: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    let at = (((v.len() - 1) as f64) * q).round() as usize;
    *v.select_nth_unstable_by(at, f64::total_cmp).1
}

/// A figure with three significant digits.
fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let decimals = (2 - x.abs().log10().floor() as i64).clamp(0, 12) as usize;
    format!("{x:.decimals$}")
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
        let err = prepare(Field::Distance, &mut meshes, None).unwrap_err();
        assert!(err.contains("two meshes"), "{err}");
        let d: Vec<f64> = (0..meshes[0].n_faces()).map(|f| f as f64).collect();
        meshes[0]
            .face_attrs
            .insert("distance", AttrValues::Scalar(d));
        let s = prepare(Field::Distance, &mut meshes, None).unwrap();
        // 80 faces valued 0..=79: the 99th percentile is 78; the largest is named.
        assert_eq!(s.range, Some((0.0, 78.0)));
        assert!(s.label.ends_with("largest 79.0"), "{}", s.label);
        assert_eq!(short(0.40625), "0.406");
        assert_eq!(short(1406.2), "1406");
        assert_eq!(short(0.001234), "0.00123");
    }
}
