//! Named, typed attribute columns per vertex or per face.

use crate::IndexError;
use coarsen_geom::{DVec2, DVec3};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Which elements an attribute column belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Domain {
    /// One value per vertex.
    Vertex,
    /// One value per face.
    Face,
}

impl fmt::Display for Domain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Domain::Vertex => "vertex",
            Domain::Face => "face",
        })
    }
}

/// The value type of an attribute column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AttrKind {
    /// `f64` scalars (curvature, density, error).
    Scalar,
    /// 2-D vectors (texture coordinates).
    Vec2,
    /// 3-D vectors (normals, displacements).
    Vec3,
    /// `u32` labels (cluster, part, material); never interpolated.
    Label,
    /// 8-bit RGB colours.
    Color,
}

impl fmt::Display for AttrKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            AttrKind::Scalar => "scalar",
            AttrKind::Vec2 => "vec2",
            AttrKind::Vec3 => "vec3",
            AttrKind::Label => "label",
            AttrKind::Color => "color",
        })
    }
}

/// One attribute column: a value per element.
#[derive(Clone, Debug, PartialEq)]
pub enum AttrValues {
    /// `f64` scalars.
    Scalar(Vec<f64>),
    /// 2-D vectors.
    Vec2(Vec<DVec2>),
    /// 3-D vectors.
    Vec3(Vec<DVec3>),
    /// `u32` labels.
    Label(Vec<u32>),
    /// 8-bit RGB colours.
    Color(Vec<[u8; 3]>),
}

impl AttrValues {
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            AttrValues::Scalar(v) => v.len(),
            AttrValues::Vec2(v) => v.len(),
            AttrValues::Vec3(v) => v.len(),
            AttrValues::Label(v) => v.len(),
            AttrValues::Color(v) => v.len(),
        }
    }

    /// True when the column is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The value type.
    pub fn kind(&self) -> AttrKind {
        match self {
            AttrValues::Scalar(_) => AttrKind::Scalar,
            AttrValues::Vec2(_) => AttrKind::Vec2,
            AttrValues::Vec3(_) => AttrKind::Vec3,
            AttrValues::Label(_) => AttrKind::Label,
            AttrValues::Color(_) => AttrKind::Color,
        }
    }

    /// A new column holding `self[i]` for each `i` of `indices`, in order.
    pub fn gather(&self, indices: &[u32]) -> AttrValues {
        fn pick<T: Copy>(v: &[T], idx: &[u32]) -> Vec<T> {
            idx.iter().map(|&i| v[i as usize]).collect()
        }
        match self {
            AttrValues::Scalar(v) => AttrValues::Scalar(pick(v, indices)),
            AttrValues::Vec2(v) => AttrValues::Vec2(pick(v, indices)),
            AttrValues::Vec3(v) => AttrValues::Vec3(pick(v, indices)),
            AttrValues::Label(v) => AttrValues::Label(pick(v, indices)),
            AttrValues::Color(v) => AttrValues::Color(pick(v, indices)),
        }
    }

    /// A new column of weighted mixes, one per `(indices, weights)` of `mixes`: the sum of
    /// `weights[k] · self[indices[k]]` (labels: the value of the heaviest; colours rounded
    /// to the nearest 8-bit value).
    pub fn blend(&self, mixes: &[([u32; 3], [f64; 3])]) -> AttrValues {
        fn mix<T, S: std::iter::Sum<T>>(
            v: &[T],
            mixes: &[([u32; 3], [f64; 3])],
            term: impl Fn(f64, &T) -> T,
        ) -> Vec<S> {
            mixes
                .iter()
                .map(|(i, w)| (0..3).map(|k| term(w[k], &v[i[k] as usize])).sum())
                .collect()
        }
        let heaviest = |w: &[f64; 3]| (0..3).fold(0, |b, k| if w[k] > w[b] { k } else { b });
        match self {
            AttrValues::Scalar(v) => AttrValues::Scalar(mix(v, mixes, |w, x| w * x)),
            AttrValues::Vec2(v) => AttrValues::Vec2(mix(v, mixes, |w, x| w * *x)),
            AttrValues::Vec3(v) => AttrValues::Vec3(mix(v, mixes, |w, x| w * *x)),
            AttrValues::Label(v) => AttrValues::Label(
                mixes
                    .iter()
                    .map(|(i, w)| v[i[heaviest(w)] as usize])
                    .collect(),
            ),
            AttrValues::Color(v) => AttrValues::Color(
                mixes
                    .iter()
                    .map(|(i, w)| {
                        std::array::from_fn(|c| {
                            let x: f64 =
                                (0..3).map(|k| w[k] * f64::from(v[i[k] as usize][c])).sum();
                            x.round().clamp(0.0, 255.0) as u8
                        })
                    })
                    .collect(),
            ),
        }
    }

    /// The first index whose value is NaN or infinite, if any.
    pub fn first_non_finite(&self) -> Option<usize> {
        match self {
            AttrValues::Scalar(v) => v.iter().position(|x| !x.is_finite()),
            AttrValues::Vec2(v) => v.iter().position(|x| !x.is_finite()),
            AttrValues::Vec3(v) => v.iter().position(|x| !x.is_finite()),
            AttrValues::Label(_) | AttrValues::Color(_) => None,
        }
    }
}

/// An ordered set of named attribute columns for one domain.
///
/// Names are unique; iteration follows insertion order, so output is deterministic.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Attributes {
    columns: Vec<(String, AttrValues)>,
}

impl Attributes {
    /// Number of columns.
    pub fn len(&self) -> usize {
        self.columns.len()
    }

    /// True when there is no column.
    pub fn is_empty(&self) -> bool {
        self.columns.is_empty()
    }

    /// The column called `name`.
    pub fn get(&self, name: &str) -> Option<&AttrValues> {
        self.columns.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }

    /// The column called `name`, mutably.
    pub fn get_mut(&mut self, name: &str) -> Option<&mut AttrValues> {
        self.columns
            .iter_mut()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v)
    }

    /// The scalar column called `name`, if it exists and is scalar.
    pub fn scalar(&self, name: &str) -> Option<&[f64]> {
        match self.get(name)? {
            AttrValues::Scalar(v) => Some(v),
            _ => None,
        }
    }

    /// The label column called `name`, if it exists and holds labels.
    pub fn label(&self, name: &str) -> Option<&[u32]> {
        match self.get(name)? {
            AttrValues::Label(v) => Some(v),
            _ => None,
        }
    }

    /// The 3-D vector column called `name`, if it exists and holds 3-D vectors.
    pub fn vec3(&self, name: &str) -> Option<&[DVec3]> {
        match self.get(name)? {
            AttrValues::Vec3(v) => Some(v),
            _ => None,
        }
    }

    /// The 2-D vector column called `name`, if it exists and holds 2-D vectors.
    pub fn vec2(&self, name: &str) -> Option<&[DVec2]> {
        match self.get(name)? {
            AttrValues::Vec2(v) => Some(v),
            _ => None,
        }
    }

    /// Adds a column, replacing any column of the same name in place.
    pub fn insert(&mut self, name: impl Into<String>, values: AttrValues) {
        let name = name.into();
        match self.columns.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => *v = values,
            None => self.columns.push((name, values)),
        }
    }

    /// Removes and returns the column called `name`.
    pub fn remove(&mut self, name: &str) -> Option<AttrValues> {
        let i = self.columns.iter().position(|(n, _)| n == name)?;
        Some(self.columns.remove(i).1)
    }

    /// Column names in order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.columns.iter().map(|(n, _)| n.as_str())
    }

    /// `(name, column)` pairs in order.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &AttrValues)> {
        self.columns.iter().map(|(n, v)| (n.as_str(), v))
    }

    /// Removes every column.
    pub fn clear(&mut self) {
        self.columns.clear();
    }

    /// Applies `f` to every column, keeping names and order.
    pub fn map(&self, mut f: impl FnMut(&AttrValues) -> AttrValues) -> Attributes {
        Attributes {
            columns: self
                .columns
                .iter()
                .map(|(n, v)| (n.clone(), f(v)))
                .collect(),
        }
    }

    /// Keeps, for every column, the values at `indices` (in that order).
    pub fn gather(&self, indices: &[u32]) -> Attributes {
        self.map(|v| v.gather(indices))
    }

    pub(crate) fn check_len(&self, domain: Domain, expected: usize) -> Result<(), IndexError> {
        for (name, v) in self.iter() {
            if v.len() != expected {
                return Err(IndexError::AttributeLength {
                    domain,
                    name: name.to_string(),
                    len: v.len(),
                    expected,
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blend_mixes_by_weight_and_labels_take_the_heaviest() {
        let mixes = [([0, 1, 2], [0.5, 0.25, 0.25]), ([2, 2, 2], [1.0, 0.0, 0.0])];
        let scalar = AttrValues::Scalar(vec![0.0, 4.0, 8.0]);
        assert_eq!(scalar.blend(&mixes), AttrValues::Scalar(vec![3.0, 8.0]));
        let labels = AttrValues::Label(vec![7, 8, 9]);
        assert_eq!(labels.blend(&mixes), AttrValues::Label(vec![7, 9]));
        let colors = AttrValues::Color(vec![[0, 0, 0], [255, 255, 255], [10, 20, 30]]);
        assert_eq!(
            colors.blend(&mixes),
            AttrValues::Color(vec![[66, 69, 71], [10, 20, 30]])
        );
    }

    #[test]
    fn insert_replaces_by_name_and_keeps_order() {
        let mut a = Attributes::default();
        a.insert("k", AttrValues::Scalar(vec![1.0, 2.0]));
        a.insert("cluster", AttrValues::Label(vec![0, 1]));
        a.insert("k", AttrValues::Scalar(vec![3.0, 4.0]));
        assert_eq!(a.names().collect::<Vec<_>>(), ["k", "cluster"]);
        assert_eq!(a.scalar("k"), Some(&[3.0, 4.0][..]));
        assert_eq!(a.scalar("cluster"), None);
        assert_eq!(a.remove("k").map(|v| v.kind()), Some(AttrKind::Scalar));
        assert_eq!(a.len(), 1);
    }

    #[test]
    fn gather_selects_values_in_order() {
        let v = AttrValues::Label(vec![10, 11, 12]);
        assert_eq!(v.gather(&[2, 0, 2]), AttrValues::Label(vec![12, 10, 12]));
    }

    #[test]
    fn non_finite_values_are_found() {
        let v = AttrValues::Vec3(vec![DVec3::ZERO, DVec3::new(0.0, f64::NAN, 0.0)]);
        assert_eq!(v.first_non_finite(), Some(1));
        assert_eq!(AttrValues::Scalar(vec![1.0]).first_non_finite(), None);
    }
}
