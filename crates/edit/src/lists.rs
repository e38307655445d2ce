//! Vertex → faces lists that change as vertices merge: one arena of `u32`, a block per
//! vertex.
//!
//! Built by counting sort (counts, prefix sum, fill), so every block starts exactly full.
//! A list that outgrows its block moves to the end of the arena; when the abandoned
//! blocks outweigh the used ones the arena is compacted in one pass. Nothing is allocated
//! per vertex.

/// A vertex or face index.
type Index = u32;

/// The arena is compacted once it is longer than twice the blocks in use plus this.
const COMPACT_SLACK: usize = 1024;
/// Room reserved beyond twice the blocks in use: the compaction's slack and a moved block.
const SLACK: usize = COMPACT_SLACK + 1024;

/// Each vertex's faces, as lists in one arena.
#[derive(Clone, Debug, Default)]
pub struct FaceLists {
    start: Vec<u32>,
    len: Vec<u32>,
    cap: Vec<u32>,
    data: Vec<Index>,
    /// Sum of `cap` over all blocks in use.
    used: usize,
}

impl FaceLists {
    /// Lists of the faces around each of `n_vertices` vertices; faces with `use_face[f]`
    /// false are left out.
    pub fn build(n_vertices: usize, faces: &[[Index; 3]], use_face: &[bool]) -> Self {
        let mut len = vec![0u32; n_vertices];
        for (f, &ok) in faces.iter().zip(use_face) {
            if ok {
                for &v in f {
                    len[v as usize] += 1;
                }
            }
        }
        let mut start = Vec::with_capacity(n_vertices);
        let mut total = 0u32;
        for &l in &len {
            start.push(total);
            total += l;
        }
        let mut data = vec![0; total as usize];
        // Room for the blocks that move while collapsing, up to the size that compacts it
        // (growing would copy the arena).
        data.reserve(total as usize + SLACK);
        let mut cursor = start.clone();
        for (f, (face, &ok)) in faces.iter().zip(use_face).enumerate() {
            if ok {
                for &v in face {
                    let c = &mut cursor[v as usize];
                    data[*c as usize] = f as Index;
                    *c += 1;
                }
            }
        }
        FaceLists {
            start,
            cap: len.clone(),
            len,
            data,
            used: total as usize,
        }
    }

    /// The faces around `v`.
    #[inline]
    pub fn get(&self, v: Index) -> &[Index] {
        let s = self.start[v as usize] as usize;
        &self.data[s..s + self.len[v as usize] as usize]
    }

    /// The faces in `a`'s list that also have corner `b` (the faces of edge `a`–`b`), in
    /// the list's order; `faces` are the corners of every face.
    #[inline]
    pub fn with_corner<'s>(
        &'s self,
        a: Index,
        b: Index,
        faces: &'s [[Index; 3]],
    ) -> impl Iterator<Item = Index> + 's {
        self.get(a)
            .iter()
            .copied()
            .filter(move |&f| faces[f as usize].contains(&b))
    }

    /// Removes face `f` from `v`'s list, keeping the order of the others.
    pub fn remove(&mut self, v: Index, f: Index) {
        let s = self.start[v as usize] as usize;
        let l = self.len[v as usize] as usize;
        if let Some(i) = self.data[s..s + l].iter().position(|&x| x == f) {
            self.data.copy_within(s + i + 1..s + l, s + i);
            self.len[v as usize] -= 1;
        }
    }

    /// Inserts face `f` into `v`'s list, which is ascending, where it keeps it ascending
    /// (nothing when it is there already).
    pub fn insert_sorted(&mut self, v: Index, f: Index) {
        let vi = v as usize;
        let (s, l) = (self.start[vi] as usize, self.len[vi] as usize);
        let Err(i) = self.data[s..s + l].binary_search(&f) else {
            return;
        };
        if l < self.cap[vi] as usize {
            self.data.copy_within(s + i..s + l, s + i + 1);
            self.data[s + i] = f;
            self.len[vi] += 1;
        } else {
            let mut items = Vec::with_capacity(l + 1);
            items.extend_from_slice(&self.data[s..s + i]);
            items.push(f);
            items.extend_from_slice(&self.data[s + i..s + l]);
            self.set(v, &items);
        }
    }

    /// Replaces `v`'s list by `items`.
    pub fn set(&mut self, v: Index, items: &[Index]) {
        let vi = v as usize;
        let n = items.len() as u32;
        if n > self.cap[vi] {
            self.used -= self.cap[vi] as usize;
            self.cap[vi] = n + n / 2 + 2;
            self.used += self.cap[vi] as usize;
            self.start[vi] = self.data.len() as u32;
            self.data
                .resize(self.data.len() + self.cap[vi] as usize, Index::MAX);
        }
        let s = self.start[vi] as usize;
        self.data[s..s + items.len()].copy_from_slice(items);
        self.len[vi] = n;
        if self.data.len() > 2 * self.used + COMPACT_SLACK {
            self.compact();
        }
    }

    /// A new vertex with an empty list; returns its index.
    pub fn push_vertex(&mut self) -> Index {
        self.start.push(self.data.len() as u32);
        self.len.push(0);
        self.cap.push(0);
        (self.start.len() - 1) as Index
    }

    /// The vertices there are lists for.
    pub fn n_vertices(&self) -> usize {
        self.start.len()
    }

    /// Empties `v`'s list and releases its block.
    pub fn clear(&mut self, v: Index) {
        let vi = v as usize;
        self.used -= self.cap[vi] as usize;
        self.cap[vi] = 0;
        self.len[vi] = 0;
    }

    /// The lists of vertices `old_of` (the new vertex `i` is the old `old_of[i]`), each in
    /// its order with its faces renamed by `new_face` (old → new), in a fresh arena.
    pub fn renumbered(&self, old_of: &[Index], new_face: &[Index]) -> Self {
        let mut start = Vec::with_capacity(old_of.len());
        let mut len = Vec::with_capacity(old_of.len());
        let total: usize = old_of.iter().map(|&v| self.len[v as usize] as usize).sum();
        let mut data = Vec::with_capacity(2 * total + SLACK);
        for &v in old_of {
            start.push(data.len() as u32);
            len.push(self.len[v as usize]);
            data.extend(self.get(v).iter().map(|&f| new_face[f as usize]));
        }
        FaceLists {
            start,
            cap: len.clone(),
            len,
            data,
            used: total,
        }
    }

    /// Moves every list to a fresh arena, blocks in vertex order, without slack.
    fn compact(&mut self) {
        let mut data = Vec::with_capacity(2 * self.used + SLACK);
        for v in 0..self.start.len() {
            let s = self.start[v] as usize;
            let l = self.len[v] as usize;
            self.start[v] = data.len() as u32;
            data.extend_from_slice(&self.data[s..s + l]);
            self.cap[v] = l as u32;
        }
        self.used = data.len();
        self.data = data;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_follow_face_order_and_skip_unused_faces() {
        let faces = [[0, 1, 2], [0, 2, 3], [1, 1, 2]];
        let l = FaceLists::build(4, &faces, &[true, true, false]);
        assert_eq!(l.get(0), &[0, 1]);
        assert_eq!(l.get(1), &[0]);
        assert_eq!(l.get(2), &[0, 1]);
        assert_eq!(l.get(3), &[1]);
    }

    #[test]
    fn renumbered_lists_keep_their_order_under_new_names() {
        let faces = [[0, 1, 2], [0, 2, 3], [2, 3, 4]];
        let mut l = FaceLists::build(5, &faces, &[true, true, true]);
        l.set(2, &[2, 0, 1]);
        // Vertex 1 and face 0 go; the others close up.
        let r = l.renumbered(&[0, 2, 3, 4], &[Index::MAX, 0, 1]);
        assert_eq!(r.get(0), &[Index::MAX, 0]);
        assert_eq!(r.get(1), &[1, Index::MAX, 0]);
        assert_eq!(r.get(2), &[0, 1]);
        assert_eq!(r.get(3), &[1]);
    }

    #[test]
    fn growing_a_list_moves_it_and_compaction_keeps_every_list() {
        let faces = [[0, 1, 2], [0, 2, 3]];
        let mut l = FaceLists::build(4, &faces, &[true, true]);
        l.set(1, &[7, 8, 9]);
        assert_eq!(l.get(1), &[7, 8, 9]);
        assert_eq!(l.get(0), &[0, 1]);
        l.remove(1, 8);
        assert_eq!(l.get(1), &[7, 9]);
        l.clear(3);
        assert!(l.get(3).is_empty());
        // Many moves force compactions; every list survives them.
        for i in 0..2000u32 {
            l.set(2, &(0..(i % 50)).collect::<Vec<_>>());
        }
        assert_eq!(l.get(2).len(), 1999 % 50);
        assert_eq!(l.get(1), &[7, 9]);
        assert_eq!(l.get(0), &[0, 1]);
        assert!(l.data.len() <= 2 * l.used + 1024 + 100);
    }
}
