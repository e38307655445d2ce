//! Carrying attributes through connectivity changes.
//!
//! A stage that builds a new mesh from an old one records, for every new vertex, where it
//! came from ([`VertexOrigins`]: an old vertex, a point on an old edge, a weighted blend
//! such as a cluster of old vertices, or nothing), and for every new face its parent face
//! ([`FaceOrigins`]). [`Mesh::rebuilt`] then carries every attribute at once:
//!
//! | column kind | vertex from a blend | face with a parent |
//! | --- | --- | --- |
//! | scalar, vec2, vec3 | weighted mean | parent's value |
//! | colour | weighted mean, rounded | parent's value |
//! | label | value of the heaviest source | parent's value |
//!
//! A column that cannot be carried (some new element has no origin) is dropped and named
//! in the [`CarryReport`], so the run report can say so. No stage writes attribute
//! plumbing of its own.

use crate::{AttrValues, Attributes, Domain, Index, Mesh, Wedges};
use coarsen_geom::{DVec2, DVec3};

/// Where each new vertex came from: a list of weighted old vertices per new vertex.
///
/// Stored flat (CSR): `offsets[i]..offsets[i + 1]` indexes `sources` for new vertex `i`.
/// Weights of one vertex are positive; an empty list means "no origin".
#[derive(Clone, Debug, PartialEq)]
pub struct VertexOrigins {
    offsets: Vec<u32>,
    sources: Vec<(Index, f64)>,
}

impl Default for VertexOrigins {
    fn default() -> Self {
        Self {
            offsets: vec![0],
            sources: Vec::new(),
        }
    }
}

impl VertexOrigins {
    /// Empty, with room for `n` vertices of about two sources each.
    pub fn with_capacity(n: usize) -> Self {
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        Self {
            offsets,
            sources: Vec::with_capacity(2 * n),
        }
    }

    /// Empty, with room for `n` vertices and `sources` sources in all.
    pub fn with_capacities(n: usize, sources: usize) -> Self {
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        Self {
            offsets,
            sources: Vec::with_capacity(sources),
        }
    }

    /// Every vertex `i` of `0..n` is old vertex `i`.
    pub fn identity(n: usize) -> Self {
        let mut o = Self::with_capacity(n);
        (0..n as Index).for_each(|v| o.push_copy(v));
        o
    }

    /// Every new vertex is the old vertex at the same position in `old`.
    pub fn from_map(old: &[Index]) -> Self {
        let mut o = Self::with_capacity(old.len());
        old.iter().for_each(|&v| o.push_copy(v));
        o
    }

    /// Number of new vertices recorded.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// True when nothing is recorded.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The next new vertex is a copy of old vertex `v`.
    pub fn push_copy(&mut self, v: Index) {
        self.sources.push((v, 1.0));
        self.close();
    }

    /// The next new vertex lies on old edge `(a, b)` at `(1 − t)·a + t·b`.
    pub fn push_edge(&mut self, a: Index, b: Index, t: f64) {
        let t = t.clamp(0.0, 1.0);
        if t < 1.0 {
            self.sources.push((a, 1.0 - t));
        }
        if t > 0.0 {
            self.sources.push((b, t));
        }
        self.close();
    }

    /// The next new vertex blends old vertices with the given weights (normalised here;
    /// non-positive or non-finite weights are skipped, and an all-zero list means "no origin").
    pub fn push_blend(&mut self, sources: impl IntoIterator<Item = (Index, f64)>) {
        let start = self.sources.len();
        self.sources.extend(
            sources
                .into_iter()
                .filter(|&(_, w)| w > 0.0 && w.is_finite()),
        );
        let total: f64 = self.sources[start..].iter().map(|s| s.1).sum();
        if total > 0.0 && total.is_finite() {
            self.sources[start..].iter_mut().for_each(|s| s.1 /= total);
        } else {
            self.sources.truncate(start);
        }
        self.close();
    }

    /// The next new vertex has no origin: attributes cannot be carried to it.
    pub fn push_unknown(&mut self) {
        self.close();
    }

    /// The weighted sources of new vertex `i`.
    pub fn sources(&self, i: usize) -> &[(Index, f64)] {
        &self.sources[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    fn close(&mut self) {
        self.offsets.push(self.sources.len() as u32);
    }

    fn all_known(&self) -> bool {
        self.offsets.windows(2).all(|w| w[1] > w[0])
    }

    fn single_sources(&self) -> Option<Vec<Index>> {
        (self.sources.len() == self.len()).then(|| self.sources.iter().map(|s| s.0).collect())
    }
}

/// Where each new face came from: its parent face, or none.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaceOrigins {
    parents: Vec<Index>,
}

impl FaceOrigins {
    const NONE: Index = Index::MAX;

    /// Empty, with room for `n` faces.
    pub fn with_capacity(n: usize) -> Self {
        Self {
            parents: Vec::with_capacity(n),
        }
    }

    /// Every new face `i` is old face `parents[i]`'s child.
    pub fn from_parents(parents: Vec<Index>) -> Self {
        Self { parents }
    }

    /// Number of new faces recorded.
    pub fn len(&self) -> usize {
        self.parents.len()
    }

    /// True when nothing is recorded.
    pub fn is_empty(&self) -> bool {
        self.parents.is_empty()
    }

    /// The next new face is a child of old face `f`.
    pub fn push_parent(&mut self, f: Index) {
        debug_assert!(f != Self::NONE);
        self.parents.push(f);
    }

    /// The next new face has no parent.
    pub fn push_unknown(&mut self) {
        self.parents.push(Self::NONE);
    }

    /// The parent of new face `i`.
    pub fn parent(&self, i: usize) -> Option<Index> {
        let p = self.parents[i];
        (p != Self::NONE).then_some(p)
    }
}

/// What carrying did not manage: the columns dropped for lack of an origin.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CarryReport {
    /// `(domain, name)` of every dropped column.
    pub dropped: Vec<(Domain, String)>,
    /// Names of the per-corner (wedge) columns dropped: some new corner could not be
    /// traced to a corner of its parent face.
    pub dropped_wedges: Vec<String>,
}

impl CarryReport {
    /// One line per dropped column, for the run report.
    pub fn warnings(&self) -> Vec<String> {
        self.dropped
            .iter()
            .map(|(d, n)| {
                format!("{d} attribute `{n}` dropped: new elements have no origin to carry it from")
            })
            .chain(self.dropped_wedges.iter().map(|n| {
                format!("per-corner attribute `{n}` dropped: new corners have no corner of a parent face to carry it from")
            }))
            .collect()
    }
}

/// Carries vertex columns to new vertices; returns the carried set and dropped names.
pub fn carry_vertex_attributes(
    old: &Attributes,
    origins: &VertexOrigins,
) -> (Attributes, Vec<String>) {
    let mut out = Attributes::default();
    let mut dropped = Vec::new();
    if old.is_empty() {
        return (out, dropped);
    }
    if !origins.all_known() {
        dropped.extend(old.names().map(str::to_string));
        return (out, dropped);
    }
    if let Some(map) = origins.single_sources() {
        return (old.gather(&map), dropped);
    }
    for (name, values) in old.iter() {
        out.insert(name, blend_column(values, origins));
    }
    (out, dropped)
}

/// Carries face columns to new faces; returns the carried set and dropped names.
pub fn carry_face_attributes(old: &Attributes, origins: &FaceOrigins) -> (Attributes, Vec<String>) {
    if old.is_empty() {
        return (Attributes::default(), Vec::new());
    }
    if origins.parents.contains(&FaceOrigins::NONE) {
        return (
            Attributes::default(),
            old.names().map(str::to_string).collect(),
        );
    }
    (old.gather(&origins.parents), Vec::new())
}

fn blend_column(values: &AttrValues, o: &VertexOrigins) -> AttrValues {
    let n = o.len();
    match values {
        AttrValues::Scalar(v) => AttrValues::Scalar(
            (0..n)
                .map(|i| o.sources(i).iter().map(|&(s, w)| w * v[s as usize]).sum())
                .collect(),
        ),
        AttrValues::Vec2(v) => AttrValues::Vec2(
            (0..n)
                .map(|i| {
                    o.sources(i)
                        .iter()
                        .fold(DVec2::ZERO, |acc, &(s, w)| acc + w * v[s as usize])
                })
                .collect(),
        ),
        AttrValues::Vec3(v) => AttrValues::Vec3(
            (0..n)
                .map(|i| {
                    o.sources(i)
                        .iter()
                        .fold(DVec3::ZERO, |acc, &(s, w)| acc + w * v[s as usize])
                })
                .collect(),
        ),
        AttrValues::Label(v) => AttrValues::Label(
            (0..n)
                .map(|i| {
                    let src = o.sources(i);
                    // Heaviest source; the first one wins a tie.
                    let best = src
                        .iter()
                        .fold(src[0], |b, &s| if s.1 > b.1 { s } else { b });
                    v[best.0 as usize]
                })
                .collect(),
        ),
        AttrValues::Color(v) => AttrValues::Color(
            (0..n)
                .map(|i| {
                    let mut acc = [0.0f64; 3];
                    for &(s, w) in o.sources(i) {
                        for (a, c) in acc.iter_mut().zip(v[s as usize]) {
                            *a += w * c as f64;
                        }
                    }
                    acc.map(|a| a.round().clamp(0.0, 255.0) as u8)
                })
                .collect(),
        ),
    }
}

impl Mesh {
    /// A new mesh from new arrays, with every attribute of `self` carried through the
    /// recorded origins. The report names the columns that could not be carried.
    ///
    /// `vertex_origins` must have one entry per new position and `face_origins` one per new
    /// face; sources must index `self`'s vertices and faces.
    ///
    /// The marked edges are not carried (the new mesh has none): only a caller that knows
    /// which new vertex each old one became can renumber them, as load-time hygiene and
    /// the Morton renumbering do.
    pub fn rebuilt(
        &self,
        positions: Vec<DVec3>,
        faces: Vec<[Index; 3]>,
        vertex_origins: &VertexOrigins,
        face_origins: &FaceOrigins,
    ) -> (Mesh, CarryReport) {
        assert_eq!(
            vertex_origins.len(),
            positions.len(),
            "one vertex origin per new vertex"
        );
        assert_eq!(
            face_origins.len(),
            faces.len(),
            "one face origin per new face"
        );
        let (vertex_attrs, dv) = carry_vertex_attributes(&self.vertex_attrs, vertex_origins);
        let (face_attrs, df) = carry_face_attributes(&self.face_attrs, face_origins);
        let dropped = dv
            .into_iter()
            .map(|n| (Domain::Vertex, n))
            .chain(df.into_iter().map(|n| (Domain::Face, n)))
            .collect();
        let (wedges, dropped_wedges) =
            match self.traced_corners(&faces, vertex_origins, face_origins) {
                Some(old_corners) => (self.wedges.regrouped(&old_corners, &faces), Vec::new()),
                None => (
                    Wedges::default(),
                    self.wedges.attrs().names().map(str::to_string).collect(),
                ),
            };
        (
            Mesh {
                positions,
                faces,
                vertex_attrs,
                face_attrs,
                wedges,
                materials: self.materials.clone(),
                marked_edges: Vec::new(),
            },
            CarryReport {
                dropped,
                dropped_wedges,
            },
        )
    }

    /// For each corner of `faces`, the corner of its parent face whose vertex the new
    /// vertex copies; `None` when `self` has no wedges or some corner cannot be traced
    /// (a face without parent, a vertex that is not a copy of one of its parent's).
    fn traced_corners(
        &self,
        faces: &[[Index; 3]],
        vertex_origins: &VertexOrigins,
        face_origins: &FaceOrigins,
    ) -> Option<Vec<Index>> {
        if self.wedges.is_empty() {
            return None;
        }
        let copies = vertex_origins.single_sources()?;
        let mut old_corners = Vec::with_capacity(3 * faces.len());
        for (i, face) in faces.iter().enumerate() {
            let p = face_origins.parent(i)?;
            let parent = self.faces.get(p as usize)?;
            for &v in face {
                let source = copies[v as usize];
                let k = parent.iter().position(|&u| u == source)?;
                old_corners.push(3 * p + k as Index);
            }
        }
        Some(old_corners)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strip() -> Mesh {
        // 2---3
        // | \ |
        // 0---1
        let mut m = Mesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)],
            vec![[0, 1, 2], [1, 3, 2]],
        );
        m.vertex_attrs
            .insert("k", AttrValues::Scalar(vec![0.0, 1.0, 2.0, 3.0]));
        m.vertex_attrs
            .insert("part", AttrValues::Label(vec![7, 8, 9, 9]));
        m.face_attrs
            .insert("cluster", AttrValues::Label(vec![4, 5]));
        m
    }

    #[test]
    fn edge_midpoints_interpolate_scalars_and_pick_labels() {
        let m = strip();
        let mut vo = VertexOrigins::identity(4);
        vo.push_edge(1, 2, 0.5); // the diagonal's midpoint
        vo.push_edge(0, 1, 0.25);
        let mut positions = m.positions.clone();
        positions.push(DVec3::new(0.5, 0.5, 0.0));
        positions.push(DVec3::new(0.25, 0.0, 0.0));
        let fo = FaceOrigins::from_parents(vec![0, 0, 1, 1]);
        let faces = vec![[0, 4, 2], [0, 1, 4], [1, 3, 4], [4, 3, 2]];
        let (out, report) = m.rebuilt(positions, faces, &vo, &fo);
        assert!(report.dropped.is_empty());
        assert_eq!(
            out.vertex_attrs.scalar("k").unwrap(),
            &[0.0, 1.0, 2.0, 3.0, 1.5, 0.25]
        );
        // Midpoint of 1 (label 8) and 2 (label 9): a tie, so the first source wins.
        assert_eq!(out.vertex_attrs.label("part").unwrap(), &[7, 8, 9, 9, 8, 7]);
        assert_eq!(out.face_attrs.label("cluster").unwrap(), &[4, 4, 5, 5]);
        assert!(out.validate_indices().is_ok());
    }

    #[test]
    fn blends_normalise_weights_and_unknowns_drop_columns() {
        let m = strip();
        let mut vo = VertexOrigins::default();
        vo.push_blend([(0, 2.0), (3, 6.0)]);
        vo.push_unknown();
        let fo = FaceOrigins::from_parents(vec![0]);
        let (out, report) = m.rebuilt(vec![DVec3::ZERO; 2], vec![[0, 1, 1]], &vo, &fo);
        assert!(out.vertex_attrs.is_empty());
        assert_eq!(
            report.dropped,
            vec![
                (Domain::Vertex, "k".into()),
                (Domain::Vertex, "part".into())
            ]
        );
        assert_eq!(out.face_attrs.label("cluster").unwrap(), &[4]);
        assert_eq!(vo.sources(0), &[(0, 0.25), (3, 0.75)]);
        assert_eq!(report.warnings().len(), 2);
    }

    #[test]
    fn faces_without_parent_drop_face_columns() {
        let m = strip();
        let mut fo = FaceOrigins::default();
        fo.push_unknown();
        let (out, report) = m.rebuilt(
            m.positions.clone(),
            vec![[0, 1, 2]],
            &VertexOrigins::identity(4),
            &fo,
        );
        assert!(out.face_attrs.is_empty());
        assert_eq!(report.dropped, vec![(Domain::Face, "cluster".into())]);
    }

    proptest::proptest! {
        #![proptest_config(crate::fixtures::fixed_seed(0xCA44_0001))]

        #[test]
        fn blended_values_stay_within_the_range_of_their_sources(
            values in proptest::collection::vec(-1e6f64..1e6, 2..20),
            blends in proptest::collection::vec(
                proptest::collection::vec((0usize..20, 0.0f64..10.0), 1..6), 1..30),
        ) {
            let n = values.len();
            let mut mesh = Mesh::new(vec![DVec3::ZERO; n], vec![]);
            mesh.vertex_attrs.insert("s", AttrValues::Scalar(values.clone()));
            let mut vo = VertexOrigins::default();
            let mut sources = Vec::new();
            for b in &blends {
                let list: Vec<(Index, f64)> = b.iter().map(|&(v, w)| ((v % n) as Index, w)).collect();
                vo.push_blend(list.iter().copied());
                sources.push(list);
            }
            let (out, report) = mesh.rebuilt(vec![DVec3::ZERO; blends.len()], vec![], &vo, &FaceOrigins::default());
            match out.vertex_attrs.scalar("s") {
                Some(carried) => {
                    for (x, list) in carried.iter().zip(&sources) {
                        let used: Vec<f64> = list.iter().filter(|s| s.1 > 0.0).map(|s| values[s.0 as usize]).collect();
                        let (lo, hi) = used.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
                        let tol = 1e-9 * hi.abs().max(lo.abs()).max(1.0);
                        proptest::prop_assert!(*x >= lo - tol && *x <= hi + tol, "{x} outside [{lo}, {hi}]");
                    }
                }
                // A blend whose weights are all zero has no origin: the column is dropped, and said so.
                None => proptest::prop_assert!(report.dropped.iter().any(|(_, n)| n == "s")),
            }
        }
    }
}
