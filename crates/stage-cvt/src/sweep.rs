//! The passes of the minimisation, with the clusters split into parts swept in parallel.
//!
//! The clusters are renumbered so that each part (clusters close along the Morton curve)
//! is one range of labels. In the first phase of a pass every part sweeps, on its own
//! thread, the active faces whose cluster and neighbouring clusters all lie in the part;
//! such a move changes the sums of its own part alone, and a label only ever changes to
//! another label of the same part, so what a part reads of another part's labels (always
//! "not one of mine") cannot depend on timing. Faces on the border between two parts
//! are set aside and swept in the second phase, alone, in face order. Faces and vertices
//! here are the clusterer's layout (renumbered along a Morton curve). The number of parts
//! depends on the problem size, never on the thread count: the result is the same bytes
//! with one thread or many. With one part the passes are the plain sequential ACVD sweep.
//!
//! Once few clusters change per pass, a face whose clusters (its own and its neighbours')
//! changed neither in the previous pass nor so far in this one falls asleep instead of
//! being visited, to no effect, pass after pass; it wakes when one of those clusters
//! changes, in time for the visit the plain sweep would have made count. The moves are
//! the same, in the same order.

use crate::energy::{Energy, FacePoints, Sums};
use crate::engine::{FAN_WALK, Fans, fan_runs};
use coarsen_geom::DVec3;
use coarsen_mesh::topology::NONE;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};

/// What every part reads (faces and vertices in the clusterer's layout): the adjacency, the face sums, and the shared state that
/// parts change only in their own label range (labels, active-face bitsets).
pub(crate) struct View<'v, E: Energy + ?Sized, F: FacePoints + ?Sized> {
    /// Per face: its corners.
    pub corners: &'v [[u32; 3]],
    pub nbr: &'v [[u32; 3]],
    /// The faces round each corner, for the move test.
    pub fans: Fans<'v>,
    pub face_sums: &'v F,
    /// Per layout vertex: its position, when moves are checked against folds.
    pub pos: Option<&'v [DVec3]>,
    pub energy: &'v E,
    pub labels: &'v [AtomicU32],
    /// Faces to sweep in this pass.
    pub cur: &'v [AtomicU64],
    /// Faces to sweep in the next pass.
    pub next: &'v [AtomicU64],
    /// Faces asleep (see [`Part::sleepers`]).
    pub asleep: &'v [AtomicU64],
    /// Whether faces may fall asleep in this pass: only once few clusters change per
    /// pass, when most of them would sleep for many passes (else waking them costs more
    /// than visiting them).
    pub may_sleep: bool,
    /// Whether any face may be asleep (faces could fall asleep in this pass or before).
    pub sleeping: bool,
}

/// The running state of a range of clusters: `sums[c - range.start]` is cluster `c`'s.
pub(crate) struct Part<'p> {
    pub range: Range<u32>,
    pub sums: &'p mut [Sums],
    pub terms: &'p mut [f64],
    /// Per cluster: the sum of its faces' area vectors (with [`View::pos`]).
    pub normals: &'p mut [DVec3],
    /// Per cluster: the last pass that changed it.
    pub last_mod: &'p mut [u32],
    /// Per cluster: faces asleep next to it. A face whose cluster and neighbouring clusters
    /// all changed neither in the previous pass nor so far in this one would only be
    /// visited to no effect until one of them changes: it leaves the active set and waits
    /// on each of their lists (entries of faces woken since are stale, and skipped).
    pub sleepers: &'p mut [Vec<u32>],
}

/// What one part's sweep did.
#[derive(Default)]
pub(crate) struct Swept {
    pub moves: u64,
    pub refused: u64,
    /// Faces that fell asleep.
    pub slept: u64,
    /// Faces on a border with another part, in face order, for the second phase.
    pub deferred: Vec<u32>,
}

#[inline]
fn set(bits: &[AtomicU64], f: u32) {
    bits[f as usize / 64].fetch_or(1 << (f % 64), Relaxed);
}

/// Clears `f` in `bits`; true when it was set.
#[inline]
fn take(bits: &[AtomicU64], f: u32) -> bool {
    let (word, bit) = (&bits[f as usize / 64], 1 << (f % 64));
    word.load(Relaxed) & bit != 0 && word.fetch_and(!bit, Relaxed) & bit != 0
}

/// What a visit of one face found.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Visit {
    /// No neighbour in another cluster: the face drops out of the active set.
    Inside,
    /// A neighbouring cluster lies in another part: left to the border phase.
    Deferred,
    /// On a cluster border, not moved.
    Stayed,
    /// On a cluster border, with nothing around changed since its last visit.
    Unchanged,
    /// Moved to another cluster.
    Moved,
}

impl<E: Energy + ?Sized, F: FacePoints + ?Sized> View<'_, E, F> {
    #[inline]
    fn label(&self, f: u32) -> u32 {
        self.labels[f as usize].load(Relaxed)
    }

    /// Sweeps face `t` of `part` (whose label range holds `t`'s cluster): moves it to the
    /// best neighbouring cluster if allowed and, under the fold guard ([`View::pos`]), if
    /// that cluster's summed area vector lies within 90° of the face's (refused moves are
    /// counted in `refused`). With `defer`, a face with a neighbouring cluster outside the
    /// part is left alone.
    #[inline]
    fn visit(
        &self,
        t: u32,
        part: &mut Part<'_>,
        pass: u32,
        defer: bool,
        refused: &mut u64,
    ) -> Visit {
        let lo = part.range.start;
        let from = self.label(t);
        let mut cands = [NONE; 3];
        let mut k = 0;
        for g in self.nbr[t as usize] {
            if g != NONE {
                let c = self.label(g);
                if c != from && !cands[..k].contains(&c) {
                    cands[k] = c;
                    k += 1;
                }
            }
        }
        if k == 0 {
            return Visit::Inside;
        }
        if defer && cands[..k].iter().any(|c| !part.range.contains(c)) {
            return Visit::Deferred;
        }
        let fresh = |c: u32| part.last_mod[(c - lo) as usize] + 1 >= pass;
        if !(fresh(from) || cands[..k].iter().any(|&c| fresh(c))) {
            return Visit::Unchanged;
        }
        let ft = self.face_sums.point(t as usize).sums();
        let fi = (from - lo) as usize;
        let a = part.sums[fi];
        let after_from = self.energy.cluster(&a.minus(ft));
        let mut best: Option<(f64, u32, f64)> = None;
        for &to in &cands[..k] {
            let ti = (to - lo) as usize;
            let before = part.terms[fi] + part.terms[ti];
            let after_to = self.energy.cluster(&part.sums[ti].plus(ft));
            let d = (after_from + after_to) - before;
            if d < -1e-12 * before.abs() && best.is_none_or(|(bd, _, _)| d < bd) {
                best = Some((d, to, after_to));
            }
        }
        let Some((_, to, after_to)) = best else {
            return Visit::Stayed;
        };
        let area = self.pos.map(|pos| {
            let [a, b, c] = self.corners[t as usize].map(|v| pos[v as usize]);
            (b - a).cross(c - a)
        });
        if let Some(n) = area
            && n.dot(part.normals[(to - lo) as usize]) < 0.0
        {
            *refused += 1;
            return Visit::Stayed;
        }
        let mut buf = [0u32; FAN_WALK];
        let allowed = a.count >= 1.5
            && (0..3).all(|i| {
                let (fan, closed) = self.fans.around(t, i, &mut buf);
                fan_runs(fan, closed, [from, to, t], |g| self.label(g))
                    .iter()
                    .all(|&r| r <= 1)
            });
        if !allowed {
            *refused += 1;
            return Visit::Stayed;
        }
        let ti = (to - lo) as usize;
        part.sums[fi] = a.minus(ft);
        part.sums[ti] = part.sums[ti].plus(ft);
        part.terms[fi] = after_from;
        part.terms[ti] = after_to;
        if let Some(n) = area {
            part.normals[fi] -= n;
            part.normals[ti] += n;
        }
        part.last_mod[fi] = pass;
        part.last_mod[ti] = pass;
        self.labels[t as usize].store(to, Relaxed);
        for i in [fi, ti] {
            if self.sleeping && !part.sleepers[i].is_empty() {
                self.wake(&mut part.sleepers[i], &part.range, t, defer);
            }
        }
        Visit::Moved
    }

    /// Puts face `t` of `part` to sleep on the lists of its cluster and of the
    /// neighbouring clusters (all in the part).
    #[inline(never)]
    fn fall_asleep(&self, t: u32, part: &mut Part<'_>) {
        let lo = part.range.start;
        let from = self.label(t);
        part.sleepers[(from - lo) as usize].push(t);
        let mut seen = [from; 3];
        for (i, g) in self.nbr[t as usize].into_iter().enumerate() {
            if g != NONE {
                let c = self.label(g);
                if !seen[..i].contains(&c) && c != from {
                    part.sleepers[(c - lo) as usize].push(t);
                }
                seen[i] = c;
            }
        }
        set(self.asleep, t);
    }

    /// Wakes the faces asleep on a cluster that face `t` just changed: those after `t`
    /// for this pass when in a part's sweep (`in_part`), the others for the next. A part
    /// looks only at faces in its clusters (`range`): a stale entry may name a face that
    /// another part owns now, whose state is that part's alone.
    #[inline(never)]
    fn wake(&self, sleepers: &mut Vec<u32>, range: &Range<u32>, t: u32, in_part: bool) {
        for f in sleepers.drain(..) {
            if (!in_part || range.contains(&self.label(f))) && take(self.asleep, f) {
                set(
                    if in_part && f > t {
                        self.cur
                    } else {
                        self.next
                    },
                    f,
                );
            }
        }
    }

    /// Marks face `g` (next to a face that moved) for a visit in `bits`, awake.
    #[inline]
    fn activate(&self, bits: &[AtomicU64], g: u32) {
        set(bits, g);
        if self.sleeping {
            take(self.asleep, g);
        }
    }

    /// The first phase of a pass for one part: its active faces (`own` marks the faces
    /// whose cluster is in the part) in face order.
    pub fn sweep_part(&self, mut part: Part<'_>, own: &[u64], pass: u32) -> Swept {
        let mut out = Swept::default();
        for (w, &mine) in own.iter().enumerate() {
            if mine == 0 {
                continue;
            }
            // Faces of this word already swept, and those staying active.
            let (mut done, mut keep) = (0u64, 0u64);
            loop {
                // Re-read the word each time: a move may activate later faces of it.
                let bits = self.cur[w].load(Relaxed) & mine & !done;
                if bits == 0 {
                    break;
                }
                let b = bits.trailing_zeros();
                done |= u64::MAX >> (63 - b);
                let t = (w * 64) as u32 + b;
                match self.visit(t, &mut part, pass, true, &mut out.refused) {
                    Visit::Inside => continue,
                    Visit::Unchanged if self.may_sleep => {
                        self.fall_asleep(t, &mut part);
                        out.slept += 1;
                        continue;
                    }
                    Visit::Deferred => out.deferred.push(t),
                    Visit::Stayed | Visit::Unchanged => {}
                    Visit::Moved => {
                        out.moves += 1;
                        for g in self.nbr[t as usize] {
                            if g != NONE {
                                self.activate(if g > t { self.cur } else { self.next }, g);
                            }
                        }
                    }
                }
                keep |= 1 << b;
            }
            if keep != 0 {
                self.next[w].fetch_or(keep, Relaxed);
            }
        }
        out
    }

    /// The second phase of a pass: the border faces, in face order, with the whole state;
    /// a face moving to another part changes owner in `own`.
    pub fn sweep_border(
        &self,
        mut all: Part<'_>,
        starts: &[u32],
        own: &mut [Vec<u64>],
        faces: &[u32],
        pass: u32,
    ) -> Swept {
        let mut out = Swept::default();
        let part_of = |c: u32| starts.partition_point(|&s| s <= c) - 1;
        for &t in faces {
            let from = self.label(t);
            if self.visit(t, &mut all, pass, false, &mut out.refused) == Visit::Moved {
                out.moves += 1;
                let (p, q) = (part_of(from), part_of(self.label(t)));
                if p != q {
                    let (w, bit) = (t as usize / 64, 1u64 << (t % 64));
                    own[p][w] &= !bit;
                    own[q][w] |= bit;
                }
                for g in self.nbr[t as usize] {
                    if g != NONE {
                        self.activate(self.next, g);
                    }
                }
            }
        }
        out
    }
}

/// The running state of all clusters, indexed by label.
pub(crate) struct State<'s> {
    pub sums: &'s mut [Sums],
    pub terms: &'s mut [f64],
    pub normals: &'s mut [DVec3],
    pub last_mod: &'s mut [u32],
    pub sleepers: &'s mut [Vec<u32>],
}

/// Splits `state` at the part boundaries `starts` (ascending, first 0, last the cluster
/// count).
pub(crate) fn split_parts<'p>(starts: &[u32], state: State<'p>) -> Vec<Part<'p>> {
    let State {
        mut sums,
        mut terms,
        mut normals,
        mut last_mod,
        mut sleepers,
    } = state;
    let mut parts = Vec::with_capacity(starts.len().saturating_sub(1));
    for w in starts.windows(2) {
        let len = (w[1] - w[0]) as usize;
        let (s, rest_s) = std::mem::take(&mut sums).split_at_mut(len);
        let (t, rest_t) = std::mem::take(&mut terms).split_at_mut(len);
        let (nm, rest_n) = std::mem::take(&mut normals).split_at_mut(len);
        let (l, rest_l) = std::mem::take(&mut last_mod).split_at_mut(len);
        let (z, rest_z) = std::mem::take(&mut sleepers).split_at_mut(len);
        parts.push(Part {
            range: w[0]..w[1],
            sums: s,
            terms: t,
            normals: nm,
            last_mod: l,
            sleepers: z,
        });
        (sums, terms, normals, last_mod, sleepers) = (rest_s, rest_t, rest_n, rest_l, rest_z);
    }
    parts
}

/// Per part, the faces whose cluster is in it, as bitsets over the faces.
pub(crate) fn owners(labels: &[AtomicU32], starts: &[u32]) -> Vec<Vec<u64>> {
    let words = labels.len().div_ceil(64);
    let n_parts = starts.len().saturating_sub(1);
    if n_parts == 0 {
        return Vec::new();
    }
    // Word by word in parallel (each word's bits for every part side by side), then
    // gathered part by part.
    let mut by_word = vec![0u64; words * n_parts];
    by_word
        .par_chunks_mut(n_parts)
        .zip(labels.par_chunks(64))
        .for_each(|(bits, word)| {
            for (b, l) in word.iter().enumerate() {
                let p = starts.partition_point(|&s| s <= l.load(Relaxed)) - 1;
                bits[p] |= 1 << b;
            }
        });
    (0..n_parts)
        .into_par_iter()
        .map(|p| (0..words).map(|w| by_word[w * n_parts + p]).collect())
        .collect()
}

/// One pass over all parts (in parallel) and then the border faces: `(moves, refused,
/// slept)`.
pub(crate) fn pass<E: Energy + ?Sized, F: FacePoints + ?Sized>(
    view: &View<'_, E, F>,
    starts: &[u32],
    own: &mut [Vec<u64>],
    state: State<'_>,
    pass: u32,
) -> (u64, u64, u64) {
    let State {
        sums,
        terms,
        normals,
        last_mod,
        sleepers,
    } = state;
    let parts = split_parts(
        starts,
        State {
            sums: &mut *sums,
            terms: &mut *terms,
            normals: &mut *normals,
            last_mod: &mut *last_mod,
            sleepers: &mut *sleepers,
        },
    );
    let swept: Vec<Swept> = if parts.len() == 1 {
        parts
            .into_iter()
            .zip(own.iter())
            .map(|(p, o)| view.sweep_part(p, o, pass))
            .collect()
    } else {
        parts
            .into_par_iter()
            .zip(own.par_iter())
            .map(|(p, o)| view.sweep_part(p, o, pass))
            .collect()
    };
    let (mut moves, mut refused, mut slept) = (0, 0, 0);
    let mut border = Vec::new();
    for s in swept {
        moves += s.moves;
        refused += s.refused;
        slept += s.slept;
        border.extend(s.deferred);
    }
    if !border.is_empty() {
        border.sort_unstable();
        let n = *starts.last().unwrap_or(&0);
        let all = Part {
            range: 0..n,
            sums,
            terms,
            normals,
            last_mod,
            sleepers,
        };
        let s = view.sweep_border(all, starts, own, &border, pass);
        moves += s.moves;
        refused += s.refused;
    }
    (moves, refused, slept)
}
