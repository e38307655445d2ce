//! Face guards: tests from outside the engine that a collapse's reshaped faces must pass.

use coarsen_geom::{DVec3, triangle};

/// One face a collapse would reshape, as a [`FaceGuard`] sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reshape {
    /// Its corners now.
    pub old: [DVec3; 3],
    /// Its corners after the collapse (one of them moved).
    pub new: [DVec3; 3],
    /// How flat the input surface merged into its corners is: |Σ area-weighted input
    /// normals| / Σ areas over the input faces around the input vertices merged into a
    /// corner (the moved corner counting every vertex of the collapse), the smallest of
    /// this for each corner alone and for the three corners together. 1 on a flat region;
    /// near 0 where the region wraps around a thin part of the input, so that the face may
    /// lie close to a sheet facing the other way.
    pub coherence: f64,
}

/// A test the engine cannot make alone (e.g. against the input surface, which it does not
/// index), run on every face a collapse would reshape after the engine's own checks passed.
pub trait FaceGuard {
    /// True when the face may be reshaped as `r` says.
    fn allows(&mut self, r: &Reshape) -> bool;
    /// How many faces it tested and refused, for reports (none, by default).
    fn counts(&self) -> GuardCounts {
        GuardCounts::default()
    }
}

/// No guard: every face passes.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoGuard;

impl FaceGuard for NoGuard {
    #[inline]
    fn allows(&mut self, _: &Reshape) -> bool {
        true
    }
}

/// How many faces a [`Gated`] guard tested, and how many it refused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GuardCounts {
    /// Faces that passed the cheap gate untested.
    pub skipped: u64,
    /// Faces given to the test.
    pub tested: u64,
    /// Faces the test refused (the face passed before the collapse and fails after).
    pub refused: u64,
}

impl GuardCounts {
    /// These counts and `other`'s added up.
    pub fn plus(&self, other: &GuardCounts) -> GuardCounts {
        GuardCounts {
            skipped: self.skipped + other.skipped,
            tested: self.tested + other.tested,
            refused: self.refused + other.refused,
        }
    }
}

/// The coherence below which [`Gated::standard`] tests a face.
pub const GATE_COHERENCE: f64 = 0.9;

/// The turn (degrees) above which [`Gated::standard`] tests a face.
pub const GATE_TURN_DEG: f64 = 45.0;

/// An expensive per-face test behind a cheap gate: `test(a, b, c)`, true when triangle
/// `abc` is acceptable, is made only when the face's [`Reshape::coherence`] is below a
/// bound or the face turns by more than a given angle. A face that already failed the
/// test before the collapse is not held to it (so a bad input does not block collapses).
///
/// Meant for the metrics' facing test ("does the face point away from the input surface
/// nearest its centroid?"). The engine's own checks keep a face from turning against the
/// input merged into its corners; what they cannot see is a face that ends nearer to
/// *another* sheet of the input, facing the other way — which needs a thin part of the
/// input about as thick as the faces are wide, and there the input merged into the face's
/// corners wraps around the part and its coherence drops. On the ten cases of paper 2's
/// table the standard gate ([`GATE_COHERENCE`], [`GATE_TURN_DEG`]) tests 0.2–2 faces per
/// collapse where the full test would take about 7, and leaves no flipped face.
pub struct Gated<T> {
    test: T,
    /// Cosine of the turn above which a face is tested.
    cos_turn: f64,
    /// Coherence below which a face is tested.
    coherence: f64,
    /// What the guard did.
    pub counts: GuardCounts,
}

impl<T: FnMut(DVec3, DVec3, DVec3) -> bool> Gated<T> {
    /// Guards with `test` behind the gate: faces whose coherence is below `coherence`, or
    /// that turn by more than `turn` radians, are tested. A `coherence` above 1 tests
    /// every face.
    pub fn new(test: T, turn: f64, coherence: f64) -> Self {
        Gated {
            test,
            cos_turn: turn.cos(),
            coherence,
            counts: GuardCounts::default(),
        }
    }

    /// `test` behind the standard gate ([`GATE_COHERENCE`], [`GATE_TURN_DEG`]).
    pub fn standard(test: T) -> Self {
        Gated::new(test, GATE_TURN_DEG.to_radians(), GATE_COHERENCE)
    }

    /// The gate: true when the reshape `r` needs the test.
    fn needs_test(&self, r: &Reshape) -> bool {
        if r.coherence < self.coherence {
            return true;
        }
        let (old, new) = (r.old, r.new);
        let n_old = triangle::cross(old[0], old[1], old[2]);
        let n_new = triangle::cross(new[0], new[1], new[2]);
        n_old.dot(n_new) < self.cos_turn * n_old.length() * n_new.length()
    }
}

impl<T: FnMut(DVec3, DVec3, DVec3) -> bool> FaceGuard for Gated<T> {
    fn counts(&self) -> GuardCounts {
        self.counts
    }

    fn allows(&mut self, r: &Reshape) -> bool {
        if !self.needs_test(r) {
            self.counts.skipped += 1;
            return true;
        }
        self.counts.tested += 1;
        let (old, new) = (r.old, r.new);
        if (self.test)(new[0], new[1], new[2]) || !(self.test)(old[0], old[1], old[2]) {
            return true;
        }
        self.counts.refused += 1;
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reshape(moved: DVec3, coherence: f64) -> Reshape {
        let old = [DVec3::ZERO, DVec3::X, DVec3::Y];
        Reshape {
            old,
            new: [moved, DVec3::X, DVec3::Y],
            coherence,
        }
    }

    #[test]
    fn only_faces_past_the_gate_are_tested() {
        let calls = std::cell::Cell::new(0);
        let mut g = Gated::standard(|_, _, _| {
            calls.set(calls.get() + 1);
            false
        });
        // Flat, coherent: untested, allowed even though the test would refuse it.
        assert!(g.allows(&reshape(DVec3::new(0.1, 0.1, 0.0), 1.0)));
        // Turned by about 55°: tested; the old face fails too, so it is let through.
        assert!(g.allows(&reshape(DVec3::new(0.0, 0.0, 1.0), 1.0)));
        // Coherence below the bound: tested.
        assert!(g.allows(&reshape(DVec3::new(0.1, 0.1, 0.0), 0.5)));
        assert_eq!(
            g.counts,
            GuardCounts {
                skipped: 1,
                tested: 2,
                refused: 0
            }
        );
        assert_eq!(
            calls.get(),
            4,
            "two tested faces, each tested before and after"
        );
    }

    #[test]
    fn a_face_that_starts_to_fail_is_refused() {
        // The test refuses faces whose first corner rose above z = 0.
        let mut g = Gated::new(|a: DVec3, _, _| a.z <= 0.0, 0.0, 2.0);
        assert!(!g.allows(&reshape(DVec3::new(0.0, 0.0, 0.3), 1.0)));
        assert!(g.allows(&reshape(DVec3::new(0.2, 0.0, 0.0), 1.0)));
        assert_eq!(g.counts.refused, 1);
        assert_eq!(g.counts.tested, 2);
        assert!(NoGuard.allows(&reshape(DVec3::new(0.0, 0.0, 9.0), 0.0)));
    }
}
