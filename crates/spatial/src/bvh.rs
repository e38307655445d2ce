//! A bounding-volume hierarchy over triangles, answering nearest-point queries.
//!
//! Layout: one flat array of nodes (the root first, the two children of an inner node
//! side by side) and the triangles' corners copied in leaf order, so that a query walks
//! contiguous memory and the index owns everything it needs (no borrow of the mesh).
//!
//! Build: top-down binned surface-area heuristic (16 bins on each axis of the centroid
//! box), leaves of at most [`MAX_LEAF`] triangles; a node whose centroids all coincide, or
//! that lies deeper than [`MAX_SAH_DEPTH`], is split at the median of its range instead,
//! which bounds the depth. The build is single-threaded and depends only on the input
//! arrays, so the same mesh always gives the same tree.
//!
//! Query: depth-first, nearer child first, skipping any box farther than the best
//! distance so far (the box distance is a lower bound of every triangle inside).

use crate::closest::closest_point_on_triangle;
use coarsen_geom::Aabb;
use glam::DVec3;

/// Most triangles in one leaf.
pub const MAX_LEAF: usize = 4;

/// Below this depth nodes are split by the surface-area heuristic; deeper ones at the
/// median, so the tree is at most `MAX_SAH_DEPTH + 32` levels deep.
pub const MAX_SAH_DEPTH: usize = 64;

/// Traversal stack size: enough for the deepest possible tree (see [`MAX_SAH_DEPTH`]).
const STACK: usize = MAX_SAH_DEPTH + 40;

const BINS: usize = 16;

/// One node of the flat tree: a box, and either a range of triangles (leaf) or the index
/// of its first child (inner node; the second child follows it).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    min: DVec3,
    max: DVec3,
    /// Leaf: first triangle; inner node: first child.
    first: u32,
    /// Leaf: triangle count (≥ 1); inner node: 0.
    count: u32,
}

impl Node {
    #[inline]
    fn distance_squared(&self, p: DVec3) -> f64 {
        let d = (self.min - p).max(p - self.max).max(DVec3::ZERO);
        d.length_squared()
    }
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
    nodes: Vec<Node>,
    /// Corners of each indexed triangle, in leaf order.
    tris: Vec<[DVec3; 3]>,
    /// Original face index of each entry of `tris`.
    face_ids: Vec<u32>,
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
        self.boxes.min = self.boxes.min.min(it.min);
        self.boxes.max = self.boxes.max.max(it.max);
        self.centroids.grow((it.min + it.max) * 0.5);
    }

    fn of(items: &[Item]) -> Bounds {
        let mut b = Bounds::EMPTY;
        items.iter().for_each(|it| b.add(it));
        b
    }
}

impl Bvh {
    /// Builds the tree over `faces` (vertex indices into `positions`).
    ///
    /// Faces that cannot be measured — an index out of range, or a corner with a
    /// non-finite coordinate — are left out (see [`Bvh::len`]); zero-area faces are kept
    /// and measured as their edges. Faces beyond index `u32::MAX` are left out too.
    pub fn build(positions: &[DVec3], faces: &[[u32; 3]]) -> Bvh {
        let mut items: Vec<Item> = faces
            .iter()
            .enumerate()
            .take(u32::MAX as usize)
            .filter_map(|(f, idx)| {
                let c = corners(positions, idx)?;
                let min = c[0].min(c[1]).min(c[2]);
                let max = c[0].max(c[1]).max(c[2]);
                Some(Item {
                    min,
                    max,
                    face: f as u32,
                })
            })
            .collect();
        if items.is_empty() {
            return Bvh::default();
        }
        let mut nodes = Vec::with_capacity(2 * items.len().div_ceil(2));
        nodes.push(Node {
            min: DVec3::ZERO,
            max: DVec3::ZERO,
            first: 0,
            count: 0,
        });
        // The ranges still to place: (node, start, end, depth, their bounds).
        let mut work = vec![(0usize, 0usize, items.len(), 0usize, Bounds::of(&items))];
        while let Some((node, start, end, depth, bounds)) = work.pop() {
            let range = &mut items[start..end];
            nodes[node].min = bounds.boxes.min;
            nodes[node].max = bounds.boxes.max;
            let Some((mid, [lb, rb])) = split(range, &bounds, depth) else {
                nodes[node].first = start as u32;
                nodes[node].count = range.len() as u32;
                continue;
            };
            let left = nodes.len();
            nodes[node].first = left as u32;
            nodes[node].count = 0;
            let blank = nodes[node];
            nodes.push(blank);
            nodes.push(blank);
            work.push((left + 1, start + mid, end, depth + 1, rb));
            work.push((left, start, start + mid, depth + 1, lb));
        }
        let tris = items
            .iter()
            .map(|it| corners(positions, &faces[it.face as usize]).unwrap_or([DVec3::ZERO; 3]))
            .collect();
        let face_ids = items.iter().map(|it| it.face).collect();
        Bvh {
            nodes,
            tris,
            face_ids,
        }
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
        self.nodes.len()
    }

    /// Bounding box of every indexed triangle ([`Aabb::EMPTY`] when there is none).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| Aabb {
            min: n.min,
            max: n.max,
        })
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
        let root = self.nodes.first()?;
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
            let node = &self.nodes[ni as usize];
            if node.count > 0 {
                let first = node.first as usize;
                for (i, [a, b, c]) in self.tris[first..first + node.count as usize]
                    .iter()
                    .enumerate()
                {
                    let (q, w) = closest_point_on_triangle(p, *a, *b, *c);
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
            let l = node.first;
            let (dl, dr) = (
                self.nodes[l as usize].distance_squared(p),
                self.nodes[l as usize + 1].distance_squared(p),
            );
            // Push the farther child first so the nearer one is visited next.
            let (near, dn, far, df) = if dr < dl {
                (l + 1, dr, l, dl)
            } else {
                (l, dl, l + 1, dr)
            };
            if df <= best_d2 {
                stack[top] = (far, df);
                top += 1;
            }
            if dn <= best_d2 {
                stack[top] = (near, dn);
                top += 1;
            }
        }
        best.map(|(i, point, bary)| Nearest {
            face: self.face_ids[i],
            point,
            distance_squared: best_d2,
            bary,
        })
    }
}

/// The three corners of a face, if every index is in range and every coordinate finite.
#[inline]
fn corners(positions: &[DVec3], idx: &[u32; 3]) -> Option<[DVec3; 3]> {
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
    let e = (max - min).max(DVec3::ZERO);
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
    if extent[axis] <= 0.0 || depth >= MAX_SAH_DEPTH {
        // Coincident centroids, or too deep: split at the median along the widest axis
        // (or, when the centroids coincide, the range in its current order in two).
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
    for it in items.iter() {
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
            if left.count == 0 || left.count == n {
                continue;
            }
            let cost = 1.0
                + (half_area(left.min, left.max) * left.count as f64 + right_cost[k]) / parent_area;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, ax, k));
            }
        }
    }
    let (_, ax, k) = best?;
    let (lo, sc) = (cbounds.min[ax], scale[ax]);
    Some(partition(items, |it| bin_of(it.centroid(ax), lo, sc) < k))
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
        self.min = self.min.min(it.min);
        self.max = self.max.max(it.max);
        self.count += 1;
    }

    #[inline]
    fn merge(&mut self, o: &Bin) {
        self.min = self.min.min(o.min);
        self.max = self.max.max(o.max);
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
    use crate::closest::tests::Rng;

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
    fn random_mesh(rng: &mut Rng, n: u32, loose: usize) -> (Vec<DVec3>, Vec<[u32; 3]>) {
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
            let c = rng.vec(-0.5, 1.5);
            for _ in 0..3 {
                pos.push(c + rng.vec(-0.1, 0.1));
            }
            faces.push([base, base + 1, base + 2]);
        }
        (pos, faces)
    }

    #[test]
    fn closest_point_equals_brute_force_on_random_meshes() {
        let mut rng = Rng(42);
        for round in 0..4 {
            let (pos, faces) = random_mesh(&mut rng, 6 + 5 * round, 20 * round as usize);
            let bvh = Bvh::build(&pos, &faces);
            assert_eq!(bvh.len(), faces.len());
            for _ in 0..300 {
                let p = rng.vec(-1.0, 2.0);
                let got = bvh.closest_point(p).unwrap();
                let want = brute_force(&pos, &faces, p);
                assert_eq!(got.distance_squared, want, "at {p}");
                // The answer is consistent with the face it names.
                let [a, b, c] = faces[got.face as usize].map(|i| pos[i as usize]);
                let w = got.bary;
                assert!((a * w[0] + b * w[1] + c * w[2] - got.point).length() < 1e-12);
                assert!(((p - got.point).length_squared() - got.distance_squared).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn closest_point_within_respects_the_bound() {
        let mut rng = Rng(5);
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
        let mut rng = Rng(9);
        let (pos, faces) = random_mesh(&mut rng, 20, 50);
        let a = Bvh::build(&pos, &faces);
        let b = Bvh::build(&pos, &faces);
        assert_eq!(a, b);
        let p = DVec3::new(0.3, 0.7, 0.4);
        assert_eq!(a.closest_point(p), b.closest_point(p));
    }

    #[test]
    fn leaves_hold_at_most_max_leaf_triangles_and_cover_every_face_once() {
        let mut rng = Rng(13);
        let (pos, faces) = random_mesh(&mut rng, 30, 100);
        let bvh = Bvh::build(&pos, &faces);
        let mut seen = vec![false; faces.len()];
        for n in bvh.nodes.iter().filter(|n| n.count > 0) {
            assert!(n.count as usize <= MAX_LEAF);
            for i in n.first..n.first + n.count {
                let f = bvh.face_ids[i as usize] as usize;
                assert!(!seen[f]);
                seen[f] = true;
                for c in bvh.tris[i as usize] {
                    assert!(c.cmpge(n.min).all() && c.cmple(n.max).all());
                }
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn many_identical_triangles_build_a_bounded_tree() {
        let pos = vec![DVec3::ZERO, DVec3::X, DVec3::Y];
        let faces = vec![[0, 1, 2]; 1000];
        let bvh = Bvh::build(&pos, &faces);
        assert_eq!(bvh.len(), 1000);
        let got = bvh.closest_point(DVec3::new(0.2, 0.2, 1.0)).unwrap();
        assert_eq!(got.distance_squared, 1.0);
    }

    #[test]
    fn bad_faces_are_left_out_and_empty_trees_answer_none() {
        let pos = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::splat(f64::NAN)];
        let faces = vec![[0, 1, 2], [0, 1, 9], [0, 1, 3]];
        let bvh = Bvh::build(&pos, &faces);
        assert_eq!(bvh.len(), 1);
        assert_eq!(bvh.closest_point(DVec3::Z).unwrap().face, 0);
        assert!(bvh.closest_point(DVec3::splat(f64::NAN)).is_none());
        let empty = Bvh::build(&pos, &[]);
        assert!(empty.is_empty());
        assert!(empty.closest_point(DVec3::ZERO).is_none());
        assert!(empty.bounds().is_empty());
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
        let bvh = Bvh::build(&pos, &faces);
        let got = bvh.closest_point(DVec3::new(5.5, 5.5, 5.6)).unwrap();
        assert_eq!(got.face, 1);
        assert!(got.distance_squared < 0.02);
    }
}
