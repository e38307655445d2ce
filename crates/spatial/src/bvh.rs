//! A bounding-volume hierarchy over triangles, answering nearest-point queries.
//!
//! Layout: one flat array of nodes (the root first, the two children of an inner node
//! side by side, each pair in one 64-byte cache line: 32-byte nodes with single-precision
//! boxes rounded outwards) and the triangles in leaf order as three indices into the
//! index's own copy of the positions, in double precision, so that the index owns
//! everything it needs (no borrow of the mesh); a leaf's corners are all loaded before
//! any is measured, so that their loads overlap.
//!
//! Build: top-down binned surface-area heuristic (16 bins on each axis of the centroid
//! box; a range of more than 2 × `SAMPLE` (1024) triangles bins an even sample of them), leaves of at most [`MAX_LEAF`] triangles; a range of at most [`MEDIAN_MAX`]
//! triangles, one whose centroids all coincide, or one deeper than [`MAX_SAH_DEPTH`] is
//! split at the median of its widest axis instead, which bounds the depth. Ranges of at
//! least 2¹⁴ triangles are split and their halves built in parallel (`rayon::join`), each
//! into an array of its own; the pieces are then stitched into the order a one-piece,
//! depth-first build gives (a node's two children side by side, the left child's subtree
//! before the right one's). The tree thus depends only on the input arrays: the same on
//! any number of threads.
//!
//! Meshes of at least [`MORTON_MIN`] faces are built the Morton way instead (the
//! `morton` module: faces sorted by the Morton code of their box centres, ranges split
//! where the highest differing bit turns, boxes gathered from the leaves up, leaves of up
//! to [`MORTON_LEAF`] triangles), into the same layout: half the time on big scans, whose
//! even triangles the heuristic gains little on.
//!
//! Query: depth-first, nearer child first, skipping any box farther than the best
//! distance so far (the box distance is a lower bound of every triangle inside).
//!
//! Batched queries: points that lie close together (the samples of one face of another
//! mesh) share one walk of the tree. [`Bvh::gather_near`] collects, into a reusable
//! [`NearSet`], every triangle that can be nearest to some point of a ball;
//! [`Bvh::closest_point_near`] then answers each point of the ball from those triangles
//! alone, nearest to the ball's centre first, stopping as soon as no further one can be
//! nearer. The distances are those of [`Bvh::closest_point`].

use crate::closest::closest_point_on_triangle;
use coarsen_geom::Aabb;
use glam::DVec3;
use rayon::prelude::*;

/// Most triangles in one leaf of the surface-area heuristic's build.
pub const MAX_LEAF: usize = 4;

/// Most triangles in one leaf of the Morton build: twice the heuristic's, so the big
/// meshes it serves get half the nodes (at 4.4M faces 94 → 47 MB) for queries that
/// measured no slower.
pub const MORTON_LEAF: usize = 8;

/// Most triangles in any leaf.
const LEAF_CAP: usize = if MORTON_LEAF > MAX_LEAF {
    MORTON_LEAF
} else {
    MAX_LEAF
};

/// Below this depth nodes are split by the surface-area heuristic; deeper ones at the
/// median, so the tree is at most `MAX_SAH_DEPTH + 32` levels deep.
pub const MAX_SAH_DEPTH: usize = 64;

/// Ranges of at most this many triangles are split at the median along the widest axis:
/// near the leaves the heuristic's 3 × 16 bins cost more to evaluate than they save
/// (measured: a 4M-face build 15 % faster, queries no slower).
pub const MEDIAN_MAX: usize = 16;

/// Traversal stack size: enough for the deepest possible tree (see [`MAX_SAH_DEPTH`]).
const STACK: usize = MAX_SAH_DEPTH + 40;

const BINS: usize = 16;

/// Ranges of at least twice as many items bin an even sample of about this many to place
/// their plane.
const SAMPLE: usize = 1 << 10;

/// Ranges of at least this many triangles are split into halves built in parallel.
pub(crate) const PARALLEL_MIN: usize = 1 << 14;

/// Meshes of at least this many faces are indexed by the Morton build (see the module
/// docs): on a 4.4M-face scan it takes less than half the time of the heuristic's, its
/// queries 2–4 % slower; on small CAD meshes its queries are up to a fifth slower.
pub const MORTON_MIN: usize = 1 << 20;

/// One node of the flat tree: a box, and either a range of triangles (leaf) or the index
/// of its first child (inner node; the second child follows it).
///
/// The box is kept in single precision, rounded outwards, so a node takes 32 bytes (two
/// to a cache line): it still contains its triangles, and its distance to a point is
/// still a lower bound of theirs, which is all a query asks of it; the triangles
/// themselves stay in double precision.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub(crate) struct Node {
    pub(crate) min: [f32; 3],
    pub(crate) max: [f32; 3],
    /// Leaf: first triangle; inner node: first child.
    pub(crate) first: u32,
    /// Leaf: triangle count (≥ 1); inner node: 0.
    pub(crate) count: u32,
}

impl Node {
    /// A placeholder, overwritten when its subtree is placed.
    pub(crate) const BLANK: Node = Node {
        min: [0.0; 3],
        max: [0.0; 3],
        first: 0,
        count: 0,
    };

    /// Sets the box to the smallest single-precision box holding `b`.
    #[inline]
    fn set_box(&mut self, b: &Aabb) {
        self.min = b.min.to_array().map(f32_at_most);
        self.max = b.max.to_array().map(f32_at_least);
    }

    #[inline]
    fn lo(&self) -> DVec3 {
        DVec3::new(self.min[0].into(), self.min[1].into(), self.min[2].into())
    }

    #[inline]
    fn hi(&self) -> DVec3 {
        DVec3::new(self.max[0].into(), self.max[1].into(), self.max[2].into())
    }

    #[inline]
    fn distance_squared(&self, p: DVec3) -> f64 {
        let d = max3(max3(self.lo() - p, p - self.hi()), DVec3::ZERO);
        d.length_squared()
    }
}

/// Two nodes in one cache line: the children of one inner node (or the root and a blank).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct Pair([Node; 2]);

/// Node `i` of a layout in pairs, for writing.
#[inline]
fn slot(pairs: &mut [Pair], i: usize) -> &mut Node {
    &mut pairs[i / 2].0[i % 2]
}

/// The largest `f32` not above `x` (an infinite one beyond the `f32` range below).
#[inline]
pub(crate) fn f32_at_most(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x { y.next_down() } else { y }
}

/// The smallest `f32` not below `x` (an infinite one beyond the `f32` range above).
#[inline]
pub(crate) fn f32_at_least(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x { y.next_up() } else { y }
}

/// The nearest point of the indexed surface to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// The face it lies on (index into the `faces` given to [`Bvh::build`]).
    pub face: u32,
    /// The nearest point.
    pub point: DVec3,
    /// Squared distance from the query point.
    pub distance_squared: f64,
    /// Barycentric coordinates of `point` in the face's corners, in the face's order.
    pub bary: [f64; 3],
}

impl Nearest {
    /// Distance from the query point.
    #[inline]
    pub fn distance(&self) -> f64 {
        self.distance_squared.sqrt()
    }
}

/// A bounding-volume hierarchy over the triangles of a mesh (see the module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bvh {
    /// The nodes two by two: the root and a blank, then each inner node's two children.
    pub(crate) pairs: Vec<Pair>,
    /// The indexed triangles, in leaf order.
    pub(crate) tris: Tris,
    /// Original face index of each entry of `tris`.
    pub(crate) face_ids: Vec<u32>,
    /// The exact box of every indexed triangle (the root's is rounded outwards).
    pub(crate) root_box: Option<Aabb>,
}

/// Relative rounding allowance of [`Bvh::gather_near`] and [`Bvh::closest_point_near`]:
/// far above the few units in the last place that the distances carry, far below any
/// distance that matters.
pub const NEAR_SLACK: f64 = 1e-9;

/// The triangles that can be nearest to some point of a ball, nearest to its centre
/// first: filled by [`Bvh::gather_near`], read by [`Bvh::closest_point_near`]. Keep one
/// per thread and reuse it, so that batches of queries allocate nothing.
#[derive(Clone, Debug, Default)]
pub struct NearSet {
    center: DVec3,
    radius: f64,
    /// Allowance for rounding in the distances compared.
    slack: f64,
    /// The gathered triangles, by distance from the centre, then position in the tree.
    candidates: Vec<Candidate>,
    /// False when the set is not to be used (never gathered, or too many triangles).
    ready: bool,
}

/// One triangle of a [`NearSet`].
#[derive(Clone, Copy, Debug)]
struct Candidate {
    /// Distance from the ball's centre (squared while gathering).
    distance: f64,
    /// Position in the tree's triangle order.
    tri: u32,
    /// The triangle's box, a cheap lower bound of its distance to each query.
    min: DVec3,
    max: DVec3,
}

impl NearSet {
    /// An empty set: every query through it walks the tree.
    pub fn new() -> NearSet {
        NearSet::default()
    }

    /// Empties the set, keeping its memory: queries through it walk the tree.
    pub fn clear(&mut self) {
        self.candidates.clear();
        self.ready = false;
    }

    /// True when queries of `p` through the set look at the gathered triangles alone: the
    /// set is gathered and `p` lies in its ball.
    #[inline]
    pub fn covers(&self, p: DVec3) -> bool {
        self.ready && (p - self.center).length() <= self.radius
    }

    /// Number of triangles gathered (0 when the last gathering gave up).
    pub fn len(&self) -> usize {
        self.candidates.len()
    }

    /// True when no triangle is gathered.
    pub fn is_empty(&self) -> bool {
        self.candidates.is_empty()
    }
}

/// A triangle waiting to be placed: its box and face index.
#[derive(Clone, Copy)]
struct Item {
    min: DVec3,
    max: DVec3,
    face: u32,
}

impl Item {
    /// The point that places the triangle: its box's centre.
    #[inline]
    fn centroid(&self, axis: usize) -> f64 {
        0.5 * (self.min[axis] + self.max[axis])
    }
}

/// Box of some items and box of their centroids.
#[derive(Clone, Copy)]
struct Bounds {
    boxes: Aabb,
    centroids: Aabb,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        boxes: Aabb::EMPTY,
        centroids: Aabb::EMPTY,
    };

    #[inline]
    fn add(&mut self, it: &Item) {
        self.boxes.min = min3(self.boxes.min, it.min);
        self.boxes.max = max3(self.boxes.max, it.max);
        let c = (it.min + it.max) * 0.5;
        self.centroids.min = min3(self.centroids.min, c);
        self.centroids.max = max3(self.centroids.max, c);
    }

    fn of(items: &[Item]) -> Bounds {
        let mut b = Bounds::EMPTY;
        items.iter().for_each(|it| b.add(it));
        b
    }

    fn merged(mut self, o: Bounds) -> Bounds {
        self.boxes.union(&o.boxes);
        self.centroids.union(&o.centroids);
        self
    }
}

/// The faces that can be measured (see [`Bvh::build`]), in face order, with their boxes.
fn items_of(positions: &[DVec3], faces: &[[u32; 3]]) -> Vec<Item> {
    // An indexed collect writes in place; a face left out is marked with `u32::MAX`
    // (never a face index here: there are at most `u32::MAX` faces) and dropped after.
    let mut items: Vec<Item> = faces
        .par_iter()
        .enumerate()
        .map(|(f, idx)| match corners(positions, idx) {
            Some(c) => Item {
                min: min3(min3(c[0], c[1]), c[2]),
                max: max3(max3(c[0], c[1]), c[2]),
                face: f as u32,
            },
            None => Item {
                min: DVec3::ZERO,
                max: DVec3::ZERO,
                face: u32::MAX,
            },
        })
        .collect();
    items.retain(|it| it.face != u32::MAX);
    items
}

/// A subtree under construction.
pub(crate) enum Subtree {
    /// Built in one piece: its root first, then its descendants, inner nodes' child
    /// indices relative to this array (leaves' triangle ranges are already final).
    Flat(Vec<Node>),
    /// Split in two halves built in parallel: the root (box set, children not yet placed)
    /// and both halves.
    Split(Node, Box<(Subtree, Subtree)>),
}

impl Subtree {
    /// Number of nodes.
    fn len(&self) -> usize {
        match self {
            Subtree::Flat(nodes) => nodes.len(),
            Subtree::Split(_, halves) => 1 + halves.0.len() + halves.1.len(),
        }
    }

    /// The whole tree, laid out two nodes to a cache line: the root and a blank (so that
    /// every pair of children fills one), then the rest (see [`Subtree::flatten_into`]).
    /// Written straight into its pairs, once: fresh pages are dear, and a second copy of
    /// the 2.9M nodes of a 4.4M-face mesh cost 0.25 s.
    pub(crate) fn into_pairs(self) -> Vec<Pair> {
        let mut pairs = Vec::with_capacity((self.len() + 1).div_ceil(2));
        pairs.push(Pair([Node::BLANK; 2]));
        self.flatten_into(&mut pairs, 0);
        pairs
    }

    /// Its root node.
    pub(crate) fn root(&self) -> &Node {
        match self {
            Subtree::Flat(nodes) => &nodes[0],
            Subtree::Split(root, _) => root,
        }
    }

    /// Writes the subtree into the pairs `out` with its root at node `at` (a placeholder
    /// already there) and its descendants appended, exactly where [`grow`] would have put
    /// them had it built the whole tree in one piece. Nodes are appended two at a time (a
    /// node's children), so `out` always ends on a whole pair.
    fn flatten_into(self, out: &mut Vec<Pair>, at: usize) {
        match self {
            Subtree::Flat(nodes) => {
                // nodes[i], i ≥ 1, lands at node 2·out.len() + i − 1.
                let shift = (2 * out.len() - 1) as u32;
                let place = |mut n: Node| {
                    if n.count == 0 {
                        n.first += shift;
                    }
                    n
                };
                *slot(out, at) = place(nodes[0]);
                out.extend(
                    nodes[1..]
                        .chunks_exact(2)
                        .map(|c| Pair([place(c[0]), place(c[1])])),
                );
            }
            Subtree::Split(mut root, halves) => {
                let left = 2 * out.len();
                root.first = left as u32;
                root.count = 0;
                *slot(out, at) = root;
                out.push(Pair([Node::BLANK; 2]));
                let (l, r) = *halves;
                l.flatten_into(out, left);
                r.flatten_into(out, left + 1);
            }
        }
    }
}

/// Builds the subtree over `items` (which start at `start` in leaf order) whose bounds
/// are `bounds`, its root at `depth`: halves of at least [`PARALLEL_MIN`] items are built
/// in parallel, smaller ranges in one piece by [`grow`].
fn subtree(items: &mut [Item], start: usize, bounds: &Bounds, depth: usize) -> Subtree {
    if items.len() < PARALLEL_MIN {
        let mut nodes = vec![Node::BLANK];
        grow(&mut nodes, items, start, bounds, depth);
        return Subtree::Flat(nodes);
    }
    let mut root = Node::BLANK;
    root.set_box(&bounds.boxes);
    let Some((mid, [lb, rb])) = split(items, bounds, depth) else {
        root.first = start as u32;
        root.count = items.len() as u32;
        return Subtree::Flat(vec![root]);
    };
    let (l, r) = items.split_at_mut(mid);
    let halves = rayon::join(
        || subtree(l, start, &lb, depth + 1),
        || subtree(r, start + mid, &rb, depth + 1),
    );
    Subtree::Split(root, Box::new(halves))
}

/// Builds the subtree over `items` into `nodes`, whose only element is its root's
/// placeholder: depth first, left before right, the two children of a node appended side
/// by side when it is split. `start` is the position of `items[0]` in leaf order and
/// `depth` the root's depth.
fn grow(nodes: &mut Vec<Node>, items: &mut [Item], start: usize, bounds: &Bounds, depth: usize) {
    // The ranges still to place: (node, range start, range end, depth, their bounds).
    let mut work = vec![(0usize, 0usize, items.len(), depth, *bounds)];
    while let Some((node, lo, hi, depth, bounds)) = work.pop() {
        let range = &mut items[lo..hi];
        nodes[node].set_box(&bounds.boxes);
        let Some((mid, [lb, rb])) = split(range, &bounds, depth) else {
            nodes[node].first = (start + lo) as u32;
            nodes[node].count = range.len() as u32;
            continue;
        };
        let left = nodes.len();
        nodes[node].first = left as u32;
        nodes[node].count = 0;
        nodes.extend([Node::BLANK; 2]);
        work.push((left + 1, lo + mid, hi, depth + 1, rb));
        work.push((left, lo, lo + mid, depth + 1, lb));
    }
}

impl Bvh {
    /// Pushes the two children of an inner node (the first at `l`) that lie within `bound2`
    /// of `p`, the farther first so that the nearer is visited next; returns the new top.
    #[inline]
    fn push_children(
        &self,
        l: u32,
        p: DVec3,
        bound2: f64,
        stack: &mut [(u32, f64)],
        mut top: usize,
    ) -> usize {
        let (dl, dr) = (
            self.pairs[l as usize / 2].0[0].distance_squared(p),
            self.pairs[l as usize / 2].0[1].distance_squared(p),
        );
        let (near, dn, far, df) = if dr < dl {
            (l + 1, dr, l, dl)
        } else {
            (l, dl, l + 1, dr)
        };
        if df <= bound2 {
            stack[top] = (far, df);
            top += 1;
        }
        if dn <= bound2 {
            stack[top] = (near, dn);
            top += 1;
        }
        top
    }

    /// Builds the tree over `faces` (vertex indices into `positions`).
    ///
    /// Faces that cannot be measured — an index out of range, or a corner with a
    /// non-finite coordinate — are left out (see [`Bvh::len`]); zero-area faces are kept
    /// and measured as their edges. Faces beyond index `u32::MAX` are left out too.
    ///
    /// Runs on the current rayon pool; the tree is the same on any number of threads
    /// (see the module docs).
    pub fn build(positions: &[DVec3], faces: &[[u32; 3]]) -> Bvh {
        Bvh::build_with(positions, faces, MORTON_MIN)
    }

    /// [`Bvh::build`], choosing the Morton build from `morton_min` faces on.
    fn build_with(positions: &[DVec3], faces: &[[u32; 3]], morton_min: usize) -> Bvh {
        let faces = &faces[..faces.len().min(u32::MAX as usize)];
        if faces.len() >= morton_min {
            return crate::morton::build(positions, faces);
        }
        let mut items = items_of(positions, faces);
        if items.is_empty() {
            return Bvh::default();
        }
        // Minima and maxima are exact, so the chunks may be merged in any order.
        let bounds = items
            .par_chunks(PARALLEL_MIN)
            .map(Bounds::of)
            .reduce(|| Bounds::EMPTY, Bounds::merged);
        let pairs = subtree(&mut items, 0, &bounds, 0).into_pairs();
        Bvh::finish(positions, faces, items, pairs, bounds.boxes)
    }

    /// The tree laid out in `pairs` over `items` in leaf order: gathers their corners.
    fn finish(
        positions: &[DVec3],
        faces: &[[u32; 3]],
        items: Vec<Item>,
        pairs: Vec<Pair>,
        root_box: Aabb,
    ) -> Bvh {
        // The items go before the corners are gathered: the two are the largest arrays.
        let face_ids: Vec<u32> = items.par_iter().map(|it| it.face).collect();
        drop(items);
        let tris = Tris::gather(positions, faces, &face_ids);
        Bvh {
            pairs,
            tris,
            face_ids,
            root_box: Some(root_box),
        }
    }

    /// The root node, if any.
    #[inline]
    fn root(&self) -> Option<&Node> {
        self.pairs.first().map(|p| &p.0[0])
    }

    /// Node `i` (an index the tree holds).
    #[inline]
    fn node(&self, i: u32) -> &Node {
        &self.pairs[i as usize / 2].0[i as usize % 2]
    }

    /// Number of triangles indexed (faces left out by [`Bvh::build`] are not counted).
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// True when no triangle is indexed: every query answers `None`.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Number of nodes of the tree (diagnostics).
    pub fn node_count(&self) -> usize {
        // Without the blank beside the root.
        (2 * self.pairs.len()).saturating_sub(1)
    }

    /// Bounding box of every indexed triangle ([`Aabb::EMPTY`] when there is none).
    pub fn bounds(&self) -> Aabb {
        self.root_box.unwrap_or(Aabb::EMPTY)
    }

    /// The nearest point of the indexed surface to `p`; `None` when the tree is empty or
    /// `p` is not finite.
    ///
    /// When several faces are equally near (a shared vertex or edge) one of them is
    /// returned, always the same one for the same tree and point.
    #[inline]
    pub fn closest_point(&self, p: DVec3) -> Option<Nearest> {
        self.closest_point_within(p, f64::INFINITY)
    }

    /// The nearest point of the indexed surface to `p` if its squared distance is at most
    /// `max_distance_squared`, else `None`. A small bound makes the query faster.
    pub fn closest_point_within(&self, p: DVec3, max_distance_squared: f64) -> Option<Nearest> {
        self.nearest_accepted(p, max_distance_squared, |_| true)
    }

    /// The nearest point to `p` of the indexed faces that `accept` takes (given a face's
    /// index into the `faces` given to [`Bvh::build`]); `None` when it takes none, the
    /// tree is empty or `p` is not finite. Faces are asked as the walk meets them, so a
    /// query costs what [`Bvh::closest_point`] does when the nearest taken face is near.
    pub fn closest_point_where(&self, p: DVec3, accept: impl Fn(u32) -> bool) -> Option<Nearest> {
        self.nearest_accepted(p, f64::INFINITY, |i| accept(self.face_ids[i]))
    }

    /// The walk of [`Bvh::closest_point_within`] over the triangles `accept` takes (given
    /// their position in leaf order).
    #[inline(always)]
    fn nearest_accepted(
        &self,
        p: DVec3,
        max_distance_squared: f64,
        accept: impl Fn(usize) -> bool,
    ) -> Option<Nearest> {
        let root = self.root()?;
        if !p.is_finite() || max_distance_squared.is_nan() {
            return None;
        }
        let mut best_d2 = max_distance_squared;
        let mut best: Option<(usize, DVec3, [f64; 3])> = None;
        let root_d2 = root.distance_squared(p);
        if root_d2 > best_d2 {
            return None;
        }
        let mut stack = [(0u32, 0.0f64); STACK];
        stack[0] = (0, root_d2);
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (ni, box_d2) = stack[top];
            if box_d2 > best_d2 {
                continue;
            }
            let node = self.node(ni);
            if node.count > 0 {
                let first = node.first as usize;
                let (leaf, count) = (self.tris.leaf(first, node.count), node.count as usize);
                for (i, &[a, b, c]) in leaf[..count].iter().enumerate() {
                    if !accept(first + i) {
                        continue;
                    }
                    let (q, w) = closest_point_on_triangle(p, a, b, c);
                    let d2 = (p - q).length_squared();
                    if d2 < best_d2 || (best.is_none() && d2 <= best_d2) {
                        best_d2 = d2;
                        best = Some((first + i, q, w));
                    }
                }
                if best_d2 == 0.0 && best.is_some() {
                    break;
                }
                continue;
            }
            top = self.push_children(node.first, p, best_d2, &mut stack, top);
        }
        best.map(|(i, point, bary)| Nearest {
            face: self.face_ids[i],
            point,
            distance_squared: best_d2,
            bary,
        })
    }

    /// Gathers into `set` every triangle that can be nearest to some point within `radius`
    /// of `center`, so that [`Bvh::closest_point_near`] answers the queries of such points
    /// from those triangles alone, without walking the tree. Returns false, leaving `set`
    /// unused, when more than `limit` triangles are needed (or the tree is empty, or the
    /// ball not finite); the queries then walk the tree as [`Bvh::closest_point`] does.
    ///
    /// Why the set suffices: with `c` the centre, `T_c` its nearest triangle and `d_c`
    /// their distance, a triangle `T` nearest to a point `p` with `|p − c| ≤ r` has
    /// `d(c, T) ≤ d(p, T) + r ≤ d(p, T_c) + r ≤ d_c + 2r`. The set holds every triangle
    /// within that distance of `c`, widened by a rounding allowance of [`NEAR_SLACK`]
    /// times `d_c + 2r` plus the centre's largest coordinate magnitude.
    pub fn gather_near(&self, center: DVec3, radius: f64, limit: usize, set: &mut NearSet) -> bool {
        set.clear();
        let Some(root) = self.root() else {
            return false;
        };
        if !(center.is_finite() && radius.is_finite() && radius >= 0.0) {
            return false;
        }
        let magnitude = center.abs().max_element();
        let reach = |d: f64| (d + 2.0 * radius) * (1.0 + NEAR_SLACK) + NEAR_SLACK * magnitude;
        let mut best_d2 = f64::INFINITY;
        let mut bound2 = f64::INFINITY;
        let mut stack = [(0u32, 0.0f64); STACK];
        stack[0] = (0, root.distance_squared(center));
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (ni, box_d2) = stack[top];
            if box_d2 > bound2 {
                continue;
            }
            let node = self.node(ni);
            if node.count > 0 {
                let first = node.first as usize;
                let (leaf, count) = (self.tris.leaf(first, node.count), node.count as usize);
                for (i, &[a, b, c]) in leaf[..count].iter().enumerate() {
                    let (q, _) = closest_point_on_triangle(center, a, b, c);
                    let d2 = (center - q).length_squared();
                    if d2 < best_d2 {
                        best_d2 = d2;
                        let r = reach(d2.sqrt());
                        bound2 = r * r;
                    }
                    if d2 <= bound2 {
                        set.candidates.push(Candidate {
                            distance: d2,
                            tri: (first + i) as u32,
                            min: DVec3::ZERO,
                            max: DVec3::ZERO,
                        });
                    }
                }
                // Keep the list short while the bound shrinks; give up when even the
                // current bound holds too many.
                if set.candidates.len() > 2 * limit {
                    set.candidates.retain(|c| c.distance <= bound2);
                    if set.candidates.len() > limit {
                        set.candidates.clear();
                        return false;
                    }
                }
                continue;
            }
            top = self.push_children(node.first, center, bound2, &mut stack, top);
        }
        set.candidates.retain(|c| c.distance <= bound2);
        if set.candidates.is_empty() || set.candidates.len() > limit {
            set.candidates.clear();
            return false;
        }
        for c in &mut set.candidates {
            c.distance = c.distance.sqrt();
            let [a, b, t] = self.tris.get(c.tri as usize);
            c.min = min3(min3(a, b), t);
            c.max = max3(max3(a, b), t);
        }
        set.candidates
            .sort_unstable_by(|a, b| a.distance.total_cmp(&b.distance).then(a.tri.cmp(&b.tri)));
        set.center = center;
        set.radius = radius;
        set.slack = NEAR_SLACK * (reach(best_d2.sqrt()) + magnitude);
        set.ready = true;
        true
    }

    /// The nearest point of the indexed surface to `p`, from the triangles gathered in
    /// `set` when `p` lies in its ball (see [`Bvh::gather_near`]), else by walking the
    /// tree. The distance is the one [`Bvh::closest_point`] gives; among equally near
    /// faces the one nearer the ball's centre (then the first in the tree) is named.
    pub fn closest_point_near(&self, set: &NearSet, p: DVec3) -> Option<Nearest> {
        let dp = (p - set.center).length();
        // As `set.covers(p)`, written so that NaN falls back too.
        if !(set.ready && dp <= set.radius) {
            return self.closest_point(p);
        }
        let mut best: Option<(usize, DVec3, [f64; 3])> = None;
        let (mut best_d2, mut best_d) = (f64::INFINITY, f64::INFINITY);
        // Squared distance beyond which a triangle's box rules it out.
        let mut cut2 = f64::INFINITY;
        for cand in &set.candidates {
            // d(p, T) ≥ d(c, T) − |p − c|: no later candidate can be nearer.
            if cand.distance - dp > best_d + set.slack {
                break;
            }
            // The box's distance is a lower bound of the triangle's.
            let gap = max3(max3(cand.min - p, p - cand.max), DVec3::ZERO);
            if gap.length_squared() > cut2 {
                continue;
            }
            let i = cand.tri as usize;
            let [a, b, c] = self.tris.get(i);
            let (q, w) = closest_point_on_triangle(p, a, b, c);
            let d2 = (p - q).length_squared();
            if d2 < best_d2 {
                (best_d2, best_d) = (d2, d2.sqrt());
                cut2 = (best_d + set.slack) * (best_d + set.slack);
                best = Some((i, q, w));
            }
        }
        match best {
            Some((i, point, bary)) => Some(Nearest {
                face: self.face_ids[i],
                point,
                distance_squared: best_d2,
                bary,
            }),
            None => self.closest_point(p),
        }
    }
}

/// Lane-wise minimum. Unlike `f64::min` it does not look for NaN, which no box here holds
/// (corners and query points are finite), so it compiles to one instruction a lane.
#[inline(always)]
pub(crate) fn min3(a: DVec3, b: DVec3) -> DVec3 {
    let lo = |x: f64, y: f64| if x < y { x } else { y };
    DVec3::new(lo(a.x, b.x), lo(a.y, b.y), lo(a.z, b.z))
}

/// Lane-wise maximum, as [`min3`].
#[inline(always)]
pub(crate) fn max3(a: DVec3, b: DVec3) -> DVec3 {
    let hi = |x: f64, y: f64| if x > y { x } else { y };
    DVec3::new(hi(a.x, b.x), hi(a.y, b.y), hi(a.z, b.z))
}

/// The indexed triangles in leaf order, each as three indices into a copy of the mesh's
/// positions: a third of the memory of their corners copied out (at 4.4M faces 106 MB
/// against 320 MB). Big meshes come renumbered along a space-filling curve (the runner
/// does it), so a leaf's corners lie close together in the copy.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Tris {
    corners: Vec<[u32; 3]>,
    points: Vec<DVec3>,
}

impl Tris {
    /// The triangles `faces[face_ids[i]]`, all of whose corners are finite positions.
    pub(crate) fn gather(positions: &[DVec3], faces: &[[u32; 3]], face_ids: &[u32]) -> Tris {
        let corners: Vec<[u32; 3]> = face_ids.par_iter().map(|&f| faces[f as usize]).collect();
        if 6 * corners.len() >= positions.len() {
            return Tris {
                corners,
                points: positions.to_vec(),
            };
        }
        // Few triangles over many positions (a mesh's boundary edges as segments): only
        // the positions they use, in the order they first use them.
        let mut slot = std::collections::HashMap::new();
        let mut points = Vec::new();
        let corners = corners
            .into_iter()
            .map(|c| {
                c.map(|v| {
                    *slot.entry(v).or_insert_with(|| {
                        points.push(positions[v as usize]);
                        (points.len() - 1) as u32
                    })
                })
            })
            .collect();
        Tris { corners, points }
    }

    /// The corners of triangle `i`.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> [DVec3; 3] {
        self.corners[i].map(|v| self.points[v as usize])
    }

    /// The corners of the `count` (at most [`LEAF_CAP`]) triangles of a leaf from
    /// triangle `first` on, all loaded before any is measured, so that the loads overlap;
    /// the entries past `count` are zero.
    #[inline]
    pub(crate) fn leaf(&self, first: usize, count: u32) -> [[DVec3; 3]; LEAF_CAP] {
        let mut leaf = [[DVec3::ZERO; 3]; LEAF_CAP];
        for (i, t) in leaf[..count as usize].iter_mut().enumerate() {
            *t = self.get(first + i);
        }
        leaf
    }

    /// The number of triangles.
    pub(crate) fn len(&self) -> usize {
        self.corners.len()
    }

    /// Whether there is none.
    pub(crate) fn is_empty(&self) -> bool {
        self.corners.is_empty()
    }
}

/// The three corners of a face, if every index is in range and every coordinate finite.
#[inline]
pub(crate) fn corners(positions: &[DVec3], idx: &[u32; 3]) -> Option<[DVec3; 3]> {
    let mut c = [DVec3::ZERO; 3];
    for (k, &v) in idx.iter().enumerate() {
        let p = *positions.get(v as usize)?;
        if !p.is_finite() {
            return None;
        }
        c[k] = p;
    }
    Some(c)
}

/// Half the surface area of a box (the constant factor does not matter to the heuristic).
#[inline]
fn half_area(min: DVec3, max: DVec3) -> f64 {
    let e = max3(max - min, DVec3::ZERO);
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Decides how to split `items` (reordering them): the size of the left part and the
/// bounds of both parts, or `None` to make a leaf.
fn split(items: &mut [Item], bounds: &Bounds, depth: usize) -> Option<(usize, [Bounds; 2])> {
    let n = items.len();
    if n <= MAX_LEAF {
        return None;
    }
    let cbounds = &bounds.centroids;
    let extent = cbounds.max - cbounds.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    if extent[axis] <= 0.0 || depth >= MAX_SAH_DEPTH || n <= MEDIAN_MAX {
        // Coincident centroids, too deep or few triangles: split at the median along the
        // widest axis (or, when the centroids coincide, the range in its current order in
        // two).
        let mid = n / 2;
        if extent[axis] > 0.0 {
            items.select_nth_unstable_by(mid, |a, b| {
                a.centroid(axis)
                    .total_cmp(&b.centroid(axis))
                    .then(a.face.cmp(&b.face))
            });
        }
        return Some((mid, [Bounds::of(&items[..mid]), Bounds::of(&items[mid..])]));
    }

    // Binned SAH over all three axes, binned in one pass over the items; the cost of a
    // split is 1 (a node visit) plus the area-weighted triangle counts of both sides
    // relative to the parent.
    // A flat parent (zero area) makes every cost equal; any positive area will do then.
    let parent_area = half_area(bounds.boxes.min, bounds.boxes.max).max(f64::MIN_POSITIVE);
    let scale = DVec3::splat(BINS as f64) / extent;
    let mut bins = [[Bin::EMPTY; BINS]; 3];
    // Big ranges choose their plane from an even sample of their items (the partition
    // below still places every item, and gathers the exact bounds of both sides).
    let stride = (n / SAMPLE).max(1);
    let sampled = n.div_ceil(stride);
    // Each sampled item stands for `stride` of them in the cost.
    let weight = stride as f64;
    for it in items.iter().step_by(stride) {
        for (ax, axis_bins) in bins.iter_mut().enumerate() {
            if extent[ax] > 0.0 {
                axis_bins[bin_of(it.centroid(ax), cbounds.min[ax], scale[ax])].add(it);
            }
        }
    }
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, bins left of the plane)
    for (ax, b) in bins.iter().enumerate() {
        if extent[ax] <= 0.0 {
            continue;
        }
        // Right-hand sweep: area times count of bins k.. for every k.
        let mut right_cost = [0.0f64; BINS];
        let mut right = Bin::EMPTY;
        for k in (1..BINS).rev() {
            right.merge(&b[k]);
            right_cost[k] = half_area(right.min, right.max) * right.count as f64;
        }
        let mut left = Bin::EMPTY;
        for k in 1..BINS {
            left.merge(&b[k - 1]);
            if left.count == 0 || left.count == sampled {
                continue;
            }
            let cost = 1.0
                + weight * (half_area(left.min, left.max) * left.count as f64 + right_cost[k])
                    / parent_area;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, ax, k));
            }
        }
    }
    let Some((_, ax, k)) = best else {
        // Every item in one bin can only happen to a sample that missed the extreme
        // centroids (all items put the two extremes in the first and last bins): split at
        // the median instead.
        return match stride > 1 {
            true => split(items, bounds, MAX_SAH_DEPTH),
            false => None,
        };
    };
    let (lo, sc) = (cbounds.min[ax], scale[ax]);
    let (mid, sides) = partition(items, |it| bin_of(it.centroid(ax), lo, sc) < k);
    if mid == 0 || mid == n {
        // A sampled plane that has every item on one side: split at the median instead.
        return split(items, bounds, MAX_SAH_DEPTH);
    }
    Some((mid, sides))
}

/// One bin of the heuristic: how many triangles fall in it and their joint box.
#[derive(Clone, Copy)]
struct Bin {
    min: DVec3,
    max: DVec3,
    count: usize,
}

impl Bin {
    const EMPTY: Bin = Bin {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
        count: 0,
    };

    #[inline]
    fn add(&mut self, it: &Item) {
        self.min = min3(self.min, it.min);
        self.max = max3(self.max, it.max);
        self.count += 1;
    }

    #[inline]
    fn merge(&mut self, o: &Bin) {
        self.min = min3(self.min, o.min);
        self.max = max3(self.max, o.max);
        self.count += o.count;
    }
}

#[inline]
fn bin_of(x: f64, lo: f64, scale: f64) -> usize {
    // The i32 cast is the cheap one; the clamp keeps rounding at the top edge in range.
    (((x - lo) * scale) as i32).clamp(0, BINS as i32 - 1) as usize
}

/// Moves the items satisfying `left` to the front (deterministically; the order within
/// each side does not matter) and returns how many there are, with the bounds of both
/// sides gathered on the way.
fn partition(items: &mut [Item], left: impl Fn(&Item) -> bool) -> (usize, [Bounds; 2]) {
    let mut sides = [Bounds::EMPTY; 2];
    let mut i = 0;
    let mut j = items.len();
    while i < j {
        if left(&items[i]) {
            sides[0].add(&items[i]);
            i += 1;
        } else {
            sides[1].add(&items[i]);
            j -= 1;
            items.swap(i, j);
        }
    }
    (i, sides)
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_geom::SplitMix64;

    /// The obvious answer: every face, one by one.
    fn brute_force(positions: &[DVec3], faces: &[[u32; 3]], p: DVec3) -> f64 {
        faces
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| positions[i as usize]);
                (p - closest_point_on_triangle(p, a, b, c).0).length_squared()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// A bumpy height-field grid of `n × n` quads, plus some random loose triangles.
    fn random_mesh(rng: &mut SplitMix64, n: u32, loose: usize) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mut pos = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f64 / n as f64, j as f64 / n as f64);
                pos.push(DVec3::new(
                    x,
                    y,
                    0.1 * (7.0 * x).sin() * (5.0 * y).cos() + 0.01 * rng.unit(),
                ));
            }
        }
        let mut faces = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let v = j * (n + 1) + i;
                faces.push([v, v + 1, v + n + 2]);
                faces.push([v, v + n + 2, v + n + 1]);
            }
        }
        for _ in 0..loose {
            let base = pos.len() as u32;
            let c = rng.point(-0.5, 1.5);
            for _ in 0..3 {
                pos.push(c + rng.point(-0.1, 0.1));
            }
            faces.push([base, base + 1, base + 2]);
        }
        (pos, faces)
    }

    /// The tree by each build: the heuristic's and the Morton one.
    fn both_builds(positions: &[DVec3], faces: &[[u32; 3]]) -> [Bvh; 2] {
        [
            Bvh::build_with(positions, faces, usize::MAX),
            Bvh::build_with(positions, faces, 0),
        ]
    }

    #[test]
    fn closest_point_equals_brute_force_on_random_meshes() {
        let mut rng = SplitMix64::new(42);
        for round in 0..4 {
            let (pos, faces) = random_mesh(&mut rng, 6 + 5 * round, 20 * round as usize);
            for bvh in both_builds(&pos, &faces) {
                assert_eq!(bvh.len(), faces.len());
                for _ in 0..300 {
                    let p = rng.point(-1.0, 2.0);
                    let got = bvh.closest_point(p).unwrap();
                    let want = brute_force(&pos, &faces, p);
                    assert_eq!(got.distance_squared, want, "at {p}");
                    // The answer is consistent with the face it names.
                    let [a, b, c] = faces[got.face as usize].map(|i| pos[i as usize]);
                    let w = got.bary;
                    assert!((a * w[0] + b * w[1] + c * w[2] - got.point).length() < 1e-12);
                    assert!(
                        ((p - got.point).length_squared() - got.distance_squared).abs() < 1e-15
                    );
                }
            }
        }
    }

    #[test]
    fn closest_point_where_looks_at_the_accepted_faces_alone() {
        let mut rng = SplitMix64::new(17);
        let (pos, faces) = random_mesh(&mut rng, 9, 30);
        // Every third face, then none.
        let taken = |f: u32| f % 3 == 1;
        let kept: Vec<[u32; 3]> = (0..faces.len() as u32)
            .filter(|&f| taken(f))
            .map(|f| faces[f as usize])
            .collect();
        for bvh in both_builds(&pos, &faces) {
            for _ in 0..300 {
                let p = rng.point(-1.0, 2.0);
                let got = bvh.closest_point_where(p, taken).unwrap();
                assert!(taken(got.face));
                assert_eq!(got.distance_squared, brute_force(&pos, &kept, p), "at {p}");
                // Taking every face is the plain query.
                assert_eq!(bvh.closest_point_where(p, |_| true), bvh.closest_point(p));
            }
            assert!(bvh.closest_point_where(DVec3::ZERO, |_| false).is_none());
        }
    }

    #[test]
    fn few_faces_over_many_positions_keep_only_the_positions_they_use() {
        let mut rng = SplitMix64::new(9);
        let (pos, faces) = random_mesh(&mut rng, 12, 0);
        let few = [faces[40], faces[3], faces[40]];
        let bvh = Bvh::build(&pos, &few);
        assert!(bvh.tris.points.len() <= 6, "{}", bvh.tris.points.len());
        for (i, f) in few.iter().enumerate() {
            let corners = f.map(|v| pos[v as usize]);
            let k = bvh.face_ids.iter().position(|&g| g as usize == i).unwrap();
            assert_eq!(bvh.tris.get(k), corners);
            let centre = (corners[0] + corners[1] + corners[2]) / 3.0;
            let hit = bvh.closest_point(centre).unwrap();
            assert!(hit.distance_squared < 1e-24);
        }
        // The whole mesh keeps every position, in its order.
        assert_eq!(Bvh::build(&pos, &faces).tris.points, pos);
    }

    #[test]
    fn closest_point_within_respects_the_bound() {
        let mut rng = SplitMix64::new(5);
        let (pos, faces) = random_mesh(&mut rng, 8, 0);
        let bvh = Bvh::build(&pos, &faces);
        let p = DVec3::new(0.5, 0.5, 2.0);
        let d2 = bvh.closest_point(p).unwrap().distance_squared;
        assert!(bvh.closest_point_within(p, d2 * 0.99).is_none());
        assert_eq!(
            bvh.closest_point_within(p, d2).unwrap().distance_squared,
            d2
        );
        assert_eq!(
            bvh.closest_point_within(p, d2 * 4.0)
                .unwrap()
                .distance_squared,
            d2
        );
    }

    #[test]
    fn same_input_gives_the_same_tree_and_answers() {
        let mut rng = SplitMix64::new(9);
        let (pos, faces) = random_mesh(&mut rng, 20, 50);
        for (a, b) in both_builds(&pos, &faces)
            .into_iter()
            .zip(both_builds(&pos, &faces))
        {
            assert_eq!(a, b);
            let p = DVec3::new(0.3, 0.7, 0.4);
            assert_eq!(a.closest_point(p), b.closest_point(p));
        }
    }

    #[test]
    fn single_precision_boxes_round_outwards() {
        let mut rng = SplitMix64::new(5);
        let mut xs: Vec<f64> = (0..10_000)
            .map(|i| (rng.unit() - 0.5) * 10f64.powi(i % 80 - 40))
            .collect();
        xs.extend([
            0.0,
            -0.0,
            0.1,
            -0.1,
            1e300,
            -1e300,
            f64::from(f32::MAX),
            1.0 + 1e-12,
        ]);
        for x in xs {
            let (lo, hi) = (f32_at_most(x), f32_at_least(x));
            assert!(f64::from(lo) <= x && x <= f64::from(hi), "{x}: {lo} {hi}");
            // Tight: the next single-precision values out are on the wrong side.
            assert!(
                f64::from(lo.next_up()) > x || f64::from(lo) == x,
                "{x}: {lo}"
            );
            assert!(
                f64::from(hi.next_down()) < x || f64::from(hi) == x,
                "{x}: {hi}"
            );
        }
    }

    /// The tree built in one piece by [`grow`], as a single-threaded build without the
    /// parallel split would give it.
    fn one_piece(positions: &[DVec3], faces: &[[u32; 3]]) -> Bvh {
        let mut items = items_of(positions, faces);
        let bounds = Bounds::of(&items);
        let mut nodes = vec![Node::BLANK; 2];
        grow(&mut nodes, &mut items, 0, &bounds, 0);
        let pairs = nodes.chunks_exact(2).map(|p| Pair([p[0], p[1]])).collect();
        Bvh::finish(positions, faces, items, pairs, bounds.boxes)
    }

    #[test]
    fn parallel_builds_give_the_same_tree_on_any_thread_count() {
        let mut rng = SplitMix64::new(17);
        // Over 4·PARALLEL_MIN faces, so that two levels are built in parallel pieces.
        let (pos, faces) = random_mesh(&mut rng, 190, 300);
        assert!(faces.len() > 4 * PARALLEL_MIN);
        // The heuristic's build (its one-piece tree is the reference), then the Morton one.
        for morton_min in [usize::MAX, 0] {
            let single =
                coarsen_testdata::on_threads(1, || Bvh::build_with(&pos, &faces, morton_min));
            let triple =
                coarsen_testdata::on_threads(3, || Bvh::build_with(&pos, &faces, morton_min));
            assert_eq!(single, triple, "Morton from {morton_min} faces");
            let reference = one_piece(&pos, &faces);
            if morton_min > faces.len() {
                assert_eq!(single, reference);
            }
            // Both hold the exact box of every triangle.
            assert_eq!(single.bounds(), reference.bounds());
            for _ in 0..200 {
                let p = rng.point(-1.0, 2.0);
                assert_eq!(
                    triple.closest_point(p).unwrap().distance_squared,
                    brute_force(&pos, &faces, p)
                );
            }
        }
    }

    #[test]
    fn big_meshes_take_the_morton_build() {
        let mut rng = SplitMix64::new(29);
        let (pos, faces) = random_mesh(&mut rng, 20, 0);
        assert_eq!(
            Bvh::build_with(&pos, &faces, faces.len()),
            Bvh::build_with(&pos, &faces, 0)
        );
        assert_ne!(
            Bvh::build_with(&pos, &faces, faces.len() + 1),
            Bvh::build_with(&pos, &faces, 0)
        );
    }

    /// A point uniformly in the ball of radius `r` around `c` (rejection sampling).
    fn in_ball(rng: &mut SplitMix64, c: DVec3, r: f64) -> DVec3 {
        loop {
            let d = rng.point(-1.0, 1.0);
            if d.length_squared() <= 1.0 {
                return c + d * r;
            }
        }
    }

    #[test]
    fn near_set_answers_equal_the_tree_walk() {
        let mut rng = SplitMix64::new(21);
        let (pos, faces) = random_mesh(&mut rng, 24, 40);
        for bvh in both_builds(&pos, &faces) {
            let mut set = NearSet::new();
            let mut gathered = 0;
            for round in 0..400 {
                // Balls around faces (the samples of a face of another mesh) and near the
                // surface; the second kind often holds too many triangles for the limit.
                let (centre, radius) = if round % 2 == 0 {
                    let [a, b, c] =
                        faces[rng.next_u64() as usize % faces.len()].map(|i| pos[i as usize]);
                    let centre = (a + b + c) / 3.0 + rng.point(-0.005, 0.005);
                    (centre, (a - centre).length().max((b - centre).length()))
                } else {
                    let centre = DVec3::new(rng.unit(), rng.unit(), rng.range(-0.05, 0.1));
                    (centre, rng.range(0.0, 0.02))
                };
                if bvh.gather_near(centre, radius, 64, &mut set) {
                    gathered += 1;
                    assert!(!set.is_empty() && set.len() <= 64);
                } else {
                    assert!(set.is_empty());
                }
                let corner = centre + DVec3::X * radius;
                for p in (0..20)
                    .map(|_| in_ball(&mut rng, centre, radius))
                    .chain([centre, corner])
                {
                    let want = bvh.closest_point(p).unwrap();
                    let got = bvh.closest_point_near(&set, p).unwrap();
                    assert_eq!(got.distance_squared, want.distance_squared, "at {p}");
                    let [a, b, c] = faces[got.face as usize].map(|i| pos[i as usize]);
                    let w = got.bary;
                    assert!((a * w[0] + b * w[1] + c * w[2] - got.point).length() < 1e-12);
                }
                // A point outside the ball walks the tree instead.
                let far = centre + DVec3::Y * (2.0 * radius + 0.1);
                assert!(!set.covers(far));
                assert_eq!(bvh.closest_point_near(&set, far), bvh.closest_point(far));
            }
            assert!(gathered > 350, "{gathered} of 400 balls gathered");
        }
    }

    #[test]
    fn gathering_gives_up_beyond_its_limit_and_on_bad_balls() {
        let mut rng = SplitMix64::new(23);
        let (pos, faces) = random_mesh(&mut rng, 16, 0);
        let bvh = Bvh::build(&pos, &faces);
        let mut set = NearSet::new();
        let centre = DVec3::new(0.5, 0.5, 0.0);
        assert!(bvh.gather_near(centre, 0.3, 10_000, &mut set));
        let all = set.len();
        assert!(all > 8);
        assert!(!bvh.gather_near(centre, 0.3, all - 1, &mut set));
        assert!(set.is_empty() && !set.covers(centre));
        let p = centre + DVec3::new(0.1, -0.05, 0.2);
        assert_eq!(bvh.closest_point_near(&set, p), bvh.closest_point(p));
        assert!(!bvh.gather_near(DVec3::splat(f64::NAN), 0.1, 64, &mut set));
        assert!(!bvh.gather_near(centre, f64::INFINITY, 64, &mut set));
        assert!(!bvh.gather_near(centre, -1.0, 64, &mut set));
        assert!(!Bvh::default().gather_near(centre, 0.1, 64, &mut set));
        assert!(Bvh::default().closest_point_near(&set, p).is_none());
        set.clear();
        assert!(set.is_empty());
    }

    #[test]
    fn big_ranges_placed_from_a_sample_still_answer_exactly() {
        // 9,200 faces: the top levels bin every second to eighth item.
        let mut rng = SplitMix64::new(7);
        let (pos, faces) = random_mesh(&mut rng, 60, 2000);
        assert!(faces.len() > 8 * SAMPLE);
        let bvh = Bvh::build(&pos, &faces);
        assert_eq!(bvh.len(), faces.len());
        for _ in 0..200 {
            let p = rng.point(-1.0, 2.0);
            let got = bvh.closest_point(p).unwrap();
            assert_eq!(got.distance_squared, brute_force(&pos, &faces, p), "at {p}");
        }
    }

    #[test]
    fn leaves_hold_at_most_max_leaf_triangles_and_cover_every_face_once() {
        let mut rng = SplitMix64::new(13);
        for (n, loose) in [(30, 100), (60, 2000)] {
            let (pos, faces) = random_mesh(&mut rng, n, loose);
            leaves_cover_every_face_once(&pos, &faces);
        }
    }

    #[test]
    fn children_share_a_cache_line_and_lie_in_their_parent() {
        let mut rng = SplitMix64::new(23);
        let (pos, faces) = random_mesh(&mut rng, 60, 2000);
        for bvh in both_builds(&pos, &faces) {
            assert_eq!(std::mem::size_of::<Pair>(), 64);
            assert_eq!(bvh.pairs.as_ptr() as usize % 64, 0);
            let mut inner = 0;
            let mut stack = vec![0u32];
            while let Some(i) = stack.pop() {
                let n = *bvh.node(i);
                if n.count > 0 {
                    continue;
                }
                inner += 1;
                assert!(n.first.is_multiple_of(2) && n.first > i, "node {i}: {n:?}");
                for c in [n.first, n.first + 1] {
                    let k = bvh.node(c);
                    assert!(k.lo().cmpge(n.lo()).all() && k.hi().cmple(n.hi()).all());
                    stack.push(c);
                }
            }
            assert_eq!(bvh.node_count(), 2 * inner + 1);
        }
    }

    fn leaves_cover_every_face_once(pos: &[DVec3], faces: &[[u32; 3]]) {
        for (bvh, most) in both_builds(pos, faces).iter().zip([MAX_LEAF, MORTON_LEAF]) {
            let mut seen = vec![false; faces.len()];
            for n in bvh.pairs.iter().flat_map(|p| &p.0).filter(|n| n.count > 0) {
                assert!(n.count as usize <= most);
                for i in n.first..n.first + n.count {
                    let f = bvh.face_ids[i as usize] as usize;
                    assert!(!seen[f]);
                    seen[f] = true;
                    for c in bvh.tris.get(i as usize) {
                        assert!(c.cmpge(n.lo()).all() && c.cmple(n.hi()).all());
                    }
                }
            }
            assert!(seen.iter().all(|&s| s));
        }
    }

    #[test]
    fn many_identical_triangles_build_a_bounded_tree() {
        let pos = vec![DVec3::ZERO, DVec3::X, DVec3::Y];
        let faces = vec![[0, 1, 2]; 1000];
        for bvh in both_builds(&pos, &faces) {
            assert_eq!(bvh.len(), 1000);
            let got = bvh.closest_point(DVec3::new(0.2, 0.2, 1.0)).unwrap();
            assert_eq!(got.distance_squared, 1.0);
        }
    }

    #[test]
    fn a_sample_that_misses_the_outliers_still_splits_to_small_leaves() {
        // 4,000 copies of one triangle and 20 far ones, none at a multiple of 3: the root
        // bins every third item, so its sample holds one centroid only.
        let mut pos = vec![DVec3::ZERO, DVec3::X, DVec3::Y];
        let mut faces = Vec::new();
        for i in 0..4000u32 {
            if i % 3 == 1 && i < 60 {
                let base = pos.len() as u32;
                let c = DVec3::new(100.0 + f64::from(i), 0.0, 0.0);
                pos.extend([c, c + DVec3::X, c + DVec3::Y]);
                faces.push([base, base + 1, base + 2]);
            } else {
                faces.push([0, 1, 2]);
            }
        }
        leaves_cover_every_face_once(&pos, &faces);
        let bvh = Bvh::build(&pos, &faces);
        let far = DVec3::new(158.2, 0.2, 1.0);
        assert_eq!(bvh.closest_point(far).unwrap().distance_squared, 1.0);
    }

    #[test]
    fn bad_faces_are_left_out_and_empty_trees_answer_none() {
        let pos = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::splat(f64::NAN)];
        let faces = vec![[0, 1, 2], [0, 1, 9], [0, 1, 3]];
        for bvh in both_builds(&pos, &faces) {
            assert_eq!(bvh.len(), 1);
            assert_eq!(bvh.closest_point(DVec3::Z).unwrap().face, 0);
            assert!(bvh.closest_point(DVec3::splat(f64::NAN)).is_none());
        }
        for empty in both_builds(&pos, &[])
            .into_iter()
            .chain(both_builds(&pos, &faces[1..]))
        {
            assert!(empty.is_empty());
            assert!(empty.closest_point(DVec3::ZERO).is_none());
            assert!(empty.bounds().is_empty());
        }
    }

    #[test]
    fn degenerate_faces_are_found_by_their_edges() {
        // A zero-area face far from a regular one.
        let pos = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::Y,
            DVec3::splat(5.0),
            DVec3::splat(6.0),
        ];
        let faces = vec![[0, 1, 2], [3, 4, 3]];
        for bvh in both_builds(&pos, &faces) {
            let got = bvh.closest_point(DVec3::new(5.5, 5.5, 5.6)).unwrap();
            assert_eq!(got.face, 1);
            assert!(got.distance_squared < 0.02);
        }
    }
}
