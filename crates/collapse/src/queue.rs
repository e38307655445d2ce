//! The collapse queue: candidates in `(cost, sequence)` order (a sorted run and a heap),
//! lazy invalidation and a parking area for refused candidates.
//!
//! * **Order.** The cheapest candidate comes first; among equal costs the one queued first
//!   (lowest sequence number), so zero-cost candidates on flat regions are taken in queue
//!   order (paper 2, §3.5) and the run does not depend on the heap's internal layout.
//! * **Layout.** The initial ranking (every candidate of the input) is one sorted run,
//!   popped from its end; entries queued later go on an 8-ary heap in one `Vec`. Every
//!   heap pop walks down to a leaf, one dependent load per level, and below the first
//!   levels each load misses the cache, so fewer levels pay for more comparisons: eight
//!   children per node make a third of a binary heap's levels, and a node's children lie
//!   side by side in four cache lines (QEM on the bunny subdivided three times: the stage
//!   8.33 → 7.87 s and the CPU time 9.75 → 9.26 s against four children, medians of five
//!   alternating runs, the same output; sixteen were no faster). A pop takes the cheaper
//!   of the run's next entry and the heap's top. Most initial entries go stale before they
//!   come up, and skipping them costs one step along the run instead of a walk down a heap
//!   of all candidates (QEM on the bunny subdivided three times: 13.44 → 12.68 s, the same
//!   output).
//! * **Lazy invalidation.** Every vertex has a version stamp that grows by one whenever its
//!   data changes or it is merged away. An entry stores the (wrapping `u32`) sum of its
//!   vertices' stamps when it was queued; since stamps only grow, the entry is current
//!   exactly when that sum is unchanged (until 2³² changes pile up on the same vertices,
//!   which a mesh with 32-bit indices cannot reach). Stale entries are skipped when popped,
//!   and swept out in one pass when they make up a third of the heap. An addressable heap
//!   (one slot per candidate, entries replaced or removed in place) was measured instead,
//!   with the same pop order and outputs, and was slower on the bunny subdivided three
//!   times (issue #6): the entries a collapse re-costs are the cheap ones around it, near
//!   the top of the heap, so replacing one walks as far down as popping it stale would,
//!   and every move also writes the slot's position.
//! * **Parking.** A candidate refused by a validity check stays refused until something
//!   around it changes. It is parked on each of its vertices; when a collapse touches one
//!   of them, the engine decides its [`Fate`]: dropped when stale, back on the heap (behind
//!   everything queued so far), or left parked when the collapse cannot have changed the
//!   verdict (the parked entry's *witness*, see [`Queue::park`]).

use crate::Index;
use rayon::prelude::*;
use std::cmp::Ordering;

/// One queued candidate: up to three vertices (unused slots hold [`crate::NONE`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Entry {
    pub cost: f64,
    pub seq: u64,
    pub vertices: [Index; 3],
    pub stamp: u32,
}

impl Entry {
    /// The vertices in use.
    #[inline]
    pub fn vertices(&self) -> &[Index] {
        let n = if self.vertices[2] == crate::NONE {
            2
        } else {
            3
        };
        &self.vertices[..n]
    }

    /// The pop order: lower cost first, then lower sequence number.
    #[inline]
    fn order(&self, other: &Entry) -> Ordering {
        self.cost
            .total_cmp(&other.cost)
            .then(self.seq.cmp(&other.seq))
    }

    /// True when `self` pops before `other`.
    #[inline]
    fn before(&self, other: &Entry) -> bool {
        self.order(other) == Ordering::Less
    }
}

/// An 8-ary min-heap of entries under [`Entry::before`].
#[derive(Debug, Default)]
struct Heap {
    items: Vec<Entry>,
}

impl Heap {
    const ARITY: usize = 8;

    fn len(&self) -> usize {
        self.items.len()
    }

    fn push(&mut self, e: Entry) {
        let i = self.items.len();
        self.items.push(e);
        self.sift_up(i, e);
    }

    /// Places `e` at hole `i` or above, moving dearer parents down.
    #[inline]
    fn sift_up(&mut self, mut i: usize, e: Entry) {
        while i > 0 {
            let parent = (i - 1) / Self::ARITY;
            if !e.before(&self.items[parent]) {
                break;
            }
            self.items[i] = self.items[parent];
            i = parent;
        }
        self.items[i] = e;
    }

    /// The cheapest child of node `i`, if it has children.
    #[inline]
    fn least_child(&self, i: usize) -> Option<usize> {
        let first = i * Self::ARITY + 1;
        let n = self.items.len();
        (first < n).then(|| {
            let mut best = first;
            for c in first + 1..(first + Self::ARITY).min(n) {
                if self.items[c].before(&self.items[best]) {
                    best = c;
                }
            }
            best
        })
    }

    fn pop(&mut self) -> Option<Entry> {
        let last = self.items.pop()?;
        if self.items.is_empty() {
            return Some(last);
        }
        let top = self.items[0];
        // The last entry is among the dearest: walk the hole down to a leaf along the
        // cheapest children, then let `last` rise from there (seven comparisons per level
        // instead of eight, and it rarely rises far).
        let mut i = 0;
        while let Some(best) = self.least_child(i) {
            self.items[i] = self.items[best];
            i = best;
        }
        self.sift_up(i, last);
        Some(top)
    }

    /// Places `e` at hole `i` or below, moving smaller children up.
    fn sift_down(&mut self, mut i: usize, e: Entry) {
        while let Some(best) = self.least_child(i) {
            if !self.items[best].before(&e) {
                break;
            }
            self.items[i] = self.items[best];
            i = best;
        }
        self.items[i] = e;
    }

    /// Keeps the entries `keep` accepts (after it may have changed them) and restores the
    /// heap order bottom-up.
    fn retain(&mut self, keep: impl FnMut(&mut Entry) -> bool) {
        self.items.retain_mut(keep);
        let n = self.items.len();
        if n > 1 {
            for i in (0..=(n - 2) / Self::ARITY).rev() {
                let e = self.items[i];
                self.sift_down(i, e);
            }
        }
    }
}

const NIL: u32 = u32::MAX;

/// What [`Queue::release`] does with a parked entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Fate {
    /// Stale: gone for good.
    Drop,
    /// Back on the heap.
    Requeue,
    /// Still refused: stays parked on the vertex.
    Keep,
}

/// One parked entry.
#[derive(Clone, Copy, Debug)]
struct Parked {
    entry: Entry,
    /// The vertex the refusal hangs on ([`crate::NONE`]: none known).
    witness: Index,
    /// Whether it has gone back on the heap or been dropped.
    released: bool,
}

#[derive(Debug, Default)]
pub(crate) struct Queue {
    heap: Heap,
    /// The initial ranking, sorted dearest first (it pops from the end).
    run: Vec<Entry>,
    next_seq: u64,
    /// Parked entries.
    parked: Vec<Parked>,
    n_released: usize,
    /// Per vertex: first node of its parked list in `nodes`.
    park_head: Vec<u32>,
    /// `(parked entry, next node)`.
    nodes: Vec<(u32, u32)>,
}

impl Queue {
    pub(crate) fn new(n_vertices: usize, capacity: usize) -> Self {
        Queue {
            // The heap is swept once it passes 1.5 times the live candidates (at most
            // `capacity`): room for that from the start spares the copies of its growth.
            heap: Heap {
                items: Vec::with_capacity(capacity + capacity / 2 + 8192),
            },
            run: Vec::with_capacity(capacity),
            park_head: vec![NIL; n_vertices],
            ..Default::default()
        }
    }

    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.heap.len() + self.run.len()
    }

    /// Queues a candidate behind every candidate of the same cost queued before.
    pub(crate) fn push(&mut self, cost: f64, vertices: [Index; 3], stamp: u32) {
        let seq = self.next_seq;
        self.next_seq += 1;
        self.heap.push(Entry {
            cost,
            seq,
            vertices,
            stamp,
        });
    }

    /// Queues again an entry popped and set aside, in its old place in the order.
    pub(crate) fn put_back(&mut self, e: Entry) {
        self.heap.push(e);
    }

    /// Takes `n` sequence numbers for the initial ranking, `base..base + n`, and returns
    /// `base`: entries queued later come after all of them.
    pub(crate) fn take_seqs(&mut self, n: u64) -> u64 {
        let base = self.next_seq;
        self.next_seq += n;
        base
    }

    /// Adds `entries`, numbered from [`Queue::take_seqs`], to the initial ranking, which
    /// [`Queue::sort_initial`] must sort before the first pop.
    pub(crate) fn extend_initial(&mut self, entries: &[Entry]) {
        self.run.extend_from_slice(entries);
    }

    /// Puts the initial ranking ([`Queue::extend_initial`]) in pop order (before the first
    /// pop).
    pub(crate) fn sort_initial(&mut self) {
        // Dearest first: the run pops from its end. Keys are distinct (the sequence
        // numbers are), so the parallel sort is deterministic.
        self.run.par_sort_unstable_by(|a, b| b.order(a));
    }

    /// The next entry in `(cost, sequence)` order, from the run or the heap.
    pub(crate) fn pop(&mut self) -> Option<Entry> {
        match (self.run.last(), self.heap.items.first()) {
            (Some(r), Some(h)) if h.before(r) => self.heap.pop(),
            (Some(_), _) => {
                let e = self.run.pop();
                if self.run.is_empty() {
                    self.run = Vec::new();
                }
                e
            }
            (None, _) => self.heap.pop(),
        }
    }

    /// Every queued entry (parked ones aside), in no particular order.
    pub(crate) fn entries(&self) -> impl Iterator<Item = &Entry> {
        self.heap.items.iter().chain(&self.run)
    }

    /// Parks a refused entry until one of its vertices is touched, with the vertex its
    /// refusal hangs on, if any (`witness`, else [`crate::NONE`]: [`Queue::release`] hands
    /// it back).
    pub(crate) fn park(&mut self, e: Entry, witness: Index) {
        let id = self.parked.len() as u32;
        self.parked.push(Parked {
            entry: e,
            witness,
            released: false,
        });
        for &v in e.vertices() {
            let head = &mut self.park_head[v as usize];
            self.nodes.push((id, *head));
            *head = self.nodes.len() as u32 - 1;
        }
    }

    /// Renames the vertices of every entry by `new_vertex` (old → new, [`crate::NONE`] for
    /// a vertex that is gone) and drops the entries that name a vertex gone or that
    /// `current` rejects once renamed: stale entries, skipped anyway when they come up. The
    /// order entries pop in, and the order parked ones come back in, stay the same.
    pub(crate) fn renumber(&mut self, new_vertex: &[Index], current: impl Fn(&Entry) -> bool) {
        let rename = |e: &mut Entry| {
            for v in e.vertices.iter_mut().filter(|v| **v != crate::NONE) {
                *v = new_vertex[*v as usize];
                if *v == crate::NONE {
                    return false;
                }
            }
            current(e)
        };
        self.heap.retain(rename);
        self.run.retain_mut(rename);
        let room = Vec::with_capacity(self.parked.capacity());
        let parked = std::mem::replace(&mut self.parked, room);
        self.nodes.clear();
        self.n_released = 0;
        self.park_head = vec![NIL; new_vertex.iter().filter(|&&v| v != crate::NONE).count()];
        // Parked again in their order: each vertex's list keeps its order.
        for mut p in parked {
            if !p.released && rename(&mut p.entry) {
                if p.witness != crate::NONE {
                    p.witness = new_vertex[p.witness as usize];
                }
                self.park(p.entry, p.witness);
            }
        }
    }

    /// Decides the fate of each entry parked on `v` by `fate(entry, witness)`: re-queued,
    /// dropped, or kept on `v`'s list (in its order).
    pub(crate) fn release(&mut self, v: Index, mut fate: impl FnMut(&Entry, Index) -> Fate) {
        let mut node = std::mem::replace(&mut self.park_head[v as usize], NIL);
        // The last node kept so far.
        let mut last = NIL;
        while node != NIL {
            let (id, next) = self.nodes[node as usize];
            let p = &mut self.parked[id as usize];
            if !p.released {
                let e = p.entry;
                match fate(&e, p.witness) {
                    Fate::Keep => {
                        match last {
                            NIL => self.park_head[v as usize] = node,
                            _ => self.nodes[last as usize].1 = node,
                        }
                        last = node;
                    }
                    f => {
                        p.released = true;
                        self.n_released += 1;
                        if f == Fate::Requeue {
                            self.push(e.cost, e.vertices, e.stamp);
                        }
                    }
                }
            }
            node = next;
        }
        if last != NIL {
            self.nodes[last as usize].1 = NIL;
        }
        if self.n_released > 1024 && self.n_released > 2 * (self.parked.len() - self.n_released) {
            self.compact_parked();
        }
    }

    /// Drops the entries that `current` rejects once the heap holds half again as many
    /// entries as there are live candidates: a sweep costs a sequential pass per entry, far
    /// less than popping stale entries one by one. The run is swept along (its stale
    /// entries cost nothing to pop, but memory).
    pub(crate) fn sweep_if_stale(
        &mut self,
        n_live_estimate: usize,
        current: impl Fn(&Entry) -> bool,
    ) {
        if self.heap.len() > n_live_estimate + n_live_estimate / 2 + 4096 {
            self.retain(current);
        }
    }

    /// Keeps the entries `keep` accepts, in the heap and in the run.
    fn retain(&mut self, keep: impl Fn(&Entry) -> bool) {
        self.heap.retain(|e| keep(e));
        self.run.retain(keep);
        if self.run.len() < self.run.capacity() / 2 {
            self.run.shrink_to_fit();
        }
    }

    /// Rebuilds the parking area from the entries still parked.
    fn compact_parked(&mut self) {
        // The same room as before: growing back from nothing would copy the list at
        // every doubling.
        let room = Vec::with_capacity(self.parked.capacity());
        let old = std::mem::replace(&mut self.parked, room);
        self.nodes.clear();
        // Only vertices of parked entries can have a list: reset those, not all heads.
        for p in &old {
            for &v in p.entry.vertices() {
                self.park_head[v as usize] = NIL;
            }
        }
        self.n_released = 0;
        for p in old {
            if !p.released {
                self.park(p.entry, p.witness);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NONE;

    #[test]
    fn equal_costs_pop_in_queue_order() {
        let mut q = Queue::new(10, 8);
        for v in [5, 1, 7, 3] {
            q.push(0.0, [v, v + 1, NONE], 0);
        }
        q.push(-0.0, [9, 0, NONE], 0);
        q.push(0.5, [0, 1, NONE], 0);
        let order: Vec<_> = std::iter::from_fn(|| q.pop())
            .map(|e| e.vertices[0])
            .collect();
        // -0.0 sorts before 0.0 under total order; then FIFO among the zeros.
        assert_eq!(order, [9, 5, 1, 7, 3, 0]);
    }

    #[test]
    fn entries_pop_in_cost_then_sequence_order_through_the_run_pushes_and_sweeps() {
        // Oracle: a sorted list. Costs drawn from a few values so that ties are common.
        let mut q = Queue::new(4, 8);
        let mut oracle: Vec<(f64, u64, u32)> = Vec::new();
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        let mut popped = Vec::new();
        let mut expected = Vec::new();
        // The first 300 entries make the initial ranking (numbered from `take_seqs`, then
        // sorted); the rest are pushed in order.
        let base = q.take_seqs(300);
        let mut initial = Vec::new();
        for round in 0..2000u32 {
            let cost = (next() % 7) as f64 * 0.5;
            if round < 300 {
                initial.push(Entry {
                    cost,
                    seq: base + u64::from(round),
                    vertices: [round, 0, NONE],
                    stamp: 0,
                });
            } else {
                q.push(cost, [round, 0, NONE], 0);
            }
            if round == 299 {
                q.extend_initial(&initial);
                q.sort_initial();
            }
            oracle.push((cost, round as u64, round));
            if round >= 300 && next() % 3 == 0 {
                oracle.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                expected.push(oracle.remove(0).2);
                popped.push(q.pop().unwrap().vertices[0]);
            }
            if round % 500 == 499 {
                // Sweep out the odd ids, from the queue and from the oracle.
                q.retain(|e| e.vertices[0] % 2 == 0);
                oracle.retain(|e| e.2 % 2 == 0);
            }
        }
        oracle.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        expected.extend(oracle.iter().map(|e| e.2));
        popped.extend(std::iter::from_fn(|| q.pop()).map(|e| e.vertices[0]));
        assert_eq!(popped, expected);
    }

    #[test]
    fn parked_entries_return_once_when_a_vertex_is_touched() {
        let requeue = |_: &Entry, _: Index| Fate::Requeue;
        let mut q = Queue::new(10, 8);
        q.push(1.0, [2, 3, NONE], 0);
        let e = q.pop().unwrap();
        q.park(e, NONE);
        assert_eq!(q.len(), 0);
        q.release(4, requeue);
        assert_eq!(q.len(), 0);
        q.release(3, requeue);
        assert_eq!(q.len(), 1);
        // Already released through vertex 3: touching vertex 2 does not queue it twice.
        q.release(2, requeue);
        assert_eq!(q.len(), 1);
        let back = q.pop().unwrap();
        assert_eq!(back.vertices, [2, 3, NONE]);
        assert!(back.seq > e.seq, "a re-queued entry goes behind");
        // A stale parked entry is dropped rather than re-queued.
        q.park(back, NONE);
        q.release(2, |_, _| Fate::Drop);
        assert_eq!(q.len(), 0);
        q.release(3, requeue);
        assert_eq!(
            q.len(),
            0,
            "dropped through one vertex, gone from the others"
        );
    }

    #[test]
    fn kept_entries_stay_parked_in_order_with_their_witness() {
        let mut q = Queue::new(10, 8);
        for (k, v) in [4, 5, 6, 7].into_iter().enumerate() {
            q.push(k as f64, [1, v, NONE], 0);
            let e = q.pop().unwrap();
            q.park(e, v + 1);
        }
        // Vertex 1's list, newest first: 7, 6, 5, 4. Keep the entries whose witness is
        // odd (those of 6 and 4), re-queue the others.
        let mut seen = Vec::new();
        q.release(1, |e, w| {
            seen.push((e.vertices[1], w));
            if w % 2 == 1 {
                Fate::Keep
            } else {
                Fate::Requeue
            }
        });
        assert_eq!(seen, [(7, 8), (6, 7), (5, 6), (4, 5)]);
        assert_eq!(q.len(), 2);
        // The kept ones are still on vertex 1's list, in their order, and still parked
        // on their other vertex.
        let mut again = Vec::new();
        q.release(1, |e, w| {
            again.push((e.vertices[1], w));
            Fate::Keep
        });
        assert_eq!(again, [(6, 7), (4, 5)]);
        q.release(6, |_, _| Fate::Requeue);
        assert_eq!(q.len(), 3);
        let mut last = Vec::new();
        q.release(1, |e, _| {
            last.push(e.vertices[1]);
            Fate::Requeue
        });
        assert_eq!(last, [4]);
        assert_eq!(q.len(), 4);
        // Renumbering renames the witness with the entry.
        q.push(9.0, [2, 3, NONE], 0);
        while q.pop().is_some() {}
        q.push(9.0, [2, 3, NONE], 0);
        let e = q.pop().unwrap();
        q.park(e, 4);
        let rename: Vec<Index> = (0..10).map(|v| 9 - v).collect();
        q.renumber(&rename, |_| true);
        let mut renamed = Vec::new();
        q.release(7, |e, w| {
            renamed.push((e.vertices, w));
            Fate::Keep
        });
        assert_eq!(renamed, [([7, 6, NONE], 5)]);
    }
}
