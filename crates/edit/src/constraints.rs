//! The constraints every edit of an [`Editable`](crate::Editable) respects: vertices that
//! stay (a corner of a part), vertices bound to a curve (a sharp edge, a seam), and the
//! curves' edges between them.
//!
//! Where a vertex may go is the caller's geometry (a curve vertex slides along its curve);
//! what the edit crate enforces is topology: a fixed or curve vertex is never collapsed
//! away or into another, a curve edge is never flipped, and splitting a curve edge puts
//! the new vertex on that curve between the edge's ends.

use std::collections::HashMap;

/// What a vertex is to the constraints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Free to move and to be collapsed.
    Free,
    /// Stays where it is (a corner).
    Fixed,
    /// Bound to curve `0`: moves only along it.
    OnCurve(u32),
}

/// Fixed vertices, vertices bound to curves, and the curves' edges; empty (every vertex
/// free) by default.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Constraints {
    /// Each vertex's role; vertices past the end are free.
    role: Vec<Role>,
    /// The two curve neighbours of each curve vertex.
    ends: HashMap<u32, [u32; 2]>,
    /// The curve edges, as (smaller, larger) vertex, and their curve.
    edges: HashMap<(u32, u32), u32>,
}

impl Constraints {
    /// No constraint on `n_vertices` vertices.
    pub fn new(n_vertices: usize) -> Constraints {
        Constraints {
            role: vec![Role::Free; n_vertices],
            ..Constraints::default()
        }
    }

    /// True when no vertex is fixed or on a curve.
    pub fn is_empty(&self) -> bool {
        self.role.iter().all(|&r| r == Role::Free)
    }

    /// The role of vertex `v`.
    pub fn role(&self, v: u32) -> Role {
        self.role.get(v as usize).copied().unwrap_or(Role::Free)
    }

    /// Whether `v` is fixed or on a curve (no edit removes it).
    pub fn locked(&self, v: u32) -> bool {
        self.role(v) != Role::Free
    }

    /// Fixes vertex `v`.
    pub fn fix(&mut self, v: u32) {
        self.set_role(v, Role::Fixed);
    }

    /// Binds vertex `v` to curve `curve` between its curve neighbours `ends`.
    pub fn bind(&mut self, v: u32, curve: u32, ends: [u32; 2]) {
        self.set_role(v, Role::OnCurve(curve));
        self.ends.insert(v, ends);
    }

    /// Makes `a`–`b` an edge of curve `curve`.
    pub fn add_curve_edge(&mut self, a: u32, b: u32, curve: u32) {
        self.edges.insert((a.min(b), a.max(b)), curve);
    }

    /// The curve of edge `a`–`b`, when it is a curve edge.
    pub fn curve_of_edge(&self, a: u32, b: u32) -> Option<u32> {
        match self.edges.is_empty() {
            true => None,
            false => self.edges.get(&(a.min(b), a.max(b))).copied(),
        }
    }

    /// Whether `a`–`b` is a curve edge.
    pub fn is_curve_edge(&self, a: u32, b: u32) -> bool {
        self.curve_of_edge(a, b).is_some()
    }

    /// The two curve neighbours of curve vertex `v`.
    pub fn curve_ends(&self, v: u32) -> Option<[u32; 2]> {
        self.ends.get(&v).copied()
    }

    /// Records that edge `a`–`b` was split at vertex `v`: on a curve edge, `v` joins the
    /// curve between `a` and `b`; otherwise nothing changes.
    pub fn split_edge(&mut self, a: u32, b: u32, v: u32) {
        let Some(curve) = self.edges.remove(&(a.min(b), a.max(b))) else {
            return;
        };
        self.bind(v, curve, [a, b]);
        for (x, y) in [(a, b), (b, a)] {
            if let Some(e) = self.ends.get_mut(&x)
                && let Some(slot) = e.iter_mut().find(|w| **w == y)
            {
                *slot = v;
            }
            self.add_curve_edge(x, v, curve);
        }
    }

    fn set_role(&mut self, v: u32, role: Role) {
        let i = v as usize;
        if i >= self.role.len() {
            self.role.resize(i + 1, Role::Free);
        }
        self.role[i] = role;
    }
}
