//! The Morton build of [`Bvh`] for big meshes: the faces sorted by the Morton code of
//! their box centres (21 bits per axis, quantised in the box of the positions), each range
//! split where its highest differing bit turns (a range of equal codes in the middle),
//! leaves of at most [`MORTON_LEAF`] faces, boxes gathered from the leaves up.
//!
//! Sorting 64-bit keys and cutting sorted ranges costs far less than binning and
//! partitioning boxes level by level. The key ties are broken by face index, so the tree
//! depends only on the input arrays; ranges of at least [`PARALLEL_MIN`] faces build their
//! halves in parallel and are stitched into the layout a one-piece build gives, as the
//! heuristic build does.

use crate::bvh::{
    Bvh, MORTON_LEAF, Node, PARALLEL_MIN, Subtree, Tris, corners, f32_at_least, f32_at_most, max3,
    min3,
};
use coarsen_geom::Aabb;
use glam::DVec3;
use rayon::prelude::*;

/// Largest quantised coordinate (21 bits).
const CELLS: u64 = (1 << 21) - 1;

/// Spreads the low 21 bits of `x` to every third bit.
#[inline]
fn spread3(x: u64) -> u64 {
    let mut x = x & CELLS;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Where a sorted range of codes (at least two) splits: at the first code with the
/// highest differing bit set, or in the middle when all are equal.
fn split_at(codes: &[u64]) -> usize {
    let (a, b) = (codes[0], codes[codes.len() - 1]);
    if a == b {
        return codes.len() / 2;
    }
    let bit = 63 - (a ^ b).leading_zeros();
    codes.partition_point(|&c| c >> bit & 1 == 0)
}

/// The exact box of the triangles `range` of `tris`.
fn box_of(tris: &Tris, range: std::ops::Range<usize>) -> Aabb {
    let mut b = Aabb::EMPTY;
    for i in range {
        let t = tris.get(i);
        b.min = min3(min3(min3(b.min, t[0]), t[1]), t[2]);
        b.max = max3(max3(max3(b.max, t[0]), t[1]), t[2]);
    }
    b
}

/// The box of the triangles `range` of `tris`, rounded outwards to single precision.
fn leaf_box(tris: &Tris, range: std::ops::Range<usize>) -> ([f32; 3], [f32; 3]) {
    let b = box_of(tris, range);
    (
        b.min.to_array().map(f32_at_most),
        b.max.to_array().map(f32_at_least),
    )
}

/// Sets `node`'s box to the union of its children's (exact: rounding outwards commutes
/// with taking minima and maxima).
fn join_boxes(node: &mut Node, a: &Node, b: &Node) {
    node.min = [0, 1, 2].map(|k| a.min[k].min(b.min[k]));
    node.max = [0, 1, 2].map(|k| a.max[k].max(b.max[k]));
}

/// The subtree over `codes` and their triangles, which start at `start` in the leaf order
/// of `tris`, boxes set.
fn subtree(codes: &[u64], tris: &Tris, start: usize) -> Subtree {
    let n = codes.len();
    if n < PARALLEL_MIN {
        let mut nodes = vec![Node::BLANK];
        let mut work = vec![(0usize, 0usize, n)];
        while let Some((node, lo, hi)) = work.pop() {
            if hi - lo <= MORTON_LEAF {
                nodes[node].first = (start + lo) as u32;
                nodes[node].count = (hi - lo) as u32;
                (nodes[node].min, nodes[node].max) = leaf_box(tris, start + lo..start + hi);
                continue;
            }
            let mid = lo + split_at(&codes[lo..hi]);
            let left = nodes.len();
            nodes[node].first = left as u32;
            nodes[node].count = 0;
            nodes.extend([Node::BLANK; 2]);
            work.push((left + 1, mid, hi));
            work.push((left, lo, mid));
        }
        // Children follow their parents: inner boxes from the last node back.
        for i in (0..nodes.len()).rev() {
            let n = nodes[i];
            if n.count == 0 {
                let (a, b) = (nodes[n.first as usize], nodes[n.first as usize + 1]);
                join_boxes(&mut nodes[i], &a, &b);
            }
        }
        return Subtree::Flat(nodes);
    }
    let mid = split_at(codes);
    let (lc, rc) = codes.split_at(mid);
    let halves = rayon::join(
        || subtree(lc, tris, start),
        || subtree(rc, tris, start + mid),
    );
    let mut root = Node::BLANK;
    join_boxes(&mut root, halves.0.root(), halves.1.root());
    Subtree::Split(root, Box::new(halves))
}

/// The tree over `faces` (at most `u32::MAX` of them) by the Morton build.
pub(crate) fn build(positions: &[DVec3], faces: &[[u32; 3]]) -> Bvh {
    let empty = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    let (lo, hi) = positions
        .par_chunks(PARALLEL_MIN)
        .map(|c| {
            c.iter()
                .filter(|p| p.is_finite())
                .fold(empty, |(a, b), &p| (min3(a, p), max3(b, p)))
        })
        .reduce(|| empty, |(a, b), (c, d)| (min3(a, c), max3(b, d)));
    let scale = (hi - lo)
        .to_array()
        .map(|e| if e > 0.0 { CELLS as f64 / e } else { 0.0 });
    // (code, face); faces that cannot be measured are marked with `u32::MAX` (never a
    // face index here) and dropped.
    let mut keyed: Vec<(u64, u32)> = faces
        .par_iter()
        .enumerate()
        .map(|(f, idx)| match corners(positions, idx) {
            Some([a, b, c]) => {
                let centre = (min3(min3(a, b), c) + max3(max3(a, b), c)) * 0.5 - lo;
                // `as` saturates: below the box (never, but for rounding) gives 0.
                let q = |k: usize| ((centre[k] * scale[k]) as u64).min(CELLS);
                let code = spread3(q(0)) << 2 | spread3(q(1)) << 1 | spread3(q(2));
                (code, f as u32)
            }
            None => (u64::MAX, u32::MAX),
        })
        .collect();
    keyed.retain(|k| k.1 != u32::MAX);
    if keyed.is_empty() {
        return Bvh::default();
    }
    // Face indices are distinct: one sorted order.
    keyed.par_sort_unstable();
    let codes: Vec<u64> = keyed.par_iter().map(|k| k.0).collect();
    let face_ids: Vec<u32> = keyed.par_iter().map(|k| k.1).collect();
    drop(keyed);
    let tris = Tris::gather(positions, faces, &face_ids);
    let tree = subtree(&codes, &tris, 0);
    drop(codes);
    let pairs = tree.into_pairs();
    // Minima and maxima are exact, so the chunks may be merged in any order.
    let n = tris.len();
    let root_box = (0..n.div_ceil(PARALLEL_MIN))
        .into_par_iter()
        .map(|k| box_of(&tris, k * PARALLEL_MIN..((k + 1) * PARALLEL_MIN).min(n)))
        .reduce(
            || Aabb::EMPTY,
            |mut a, b| {
                a.union(&b);
                a
            },
        );
    Bvh {
        pairs,
        tris,
        face_ids,
        root_box: Some(root_box),
    }
}
