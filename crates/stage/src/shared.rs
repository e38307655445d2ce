//! What the stages of one run share instead of rebuilding: indexes of the run's input
//! (which never changes during a run) and the adjacency of the mesh passed between stages
//! (reused while its faces stay the same).

use coarsen_mesh::{Mesh, Topology, TopologyError};
use rayon::prelude::*;
use std::any::{Any, TypeId};
use std::sync::{Arc, Mutex, PoisonError, Weak};

/// A value derived from the run's input.
type Entry = Arc<dyn Any + Send + Sync>;

/// The adjacency last built, and what tells the faces it was built from.
struct Adjacency {
    /// The faces the adjacency skips (repeated or out-of-range index), with their corners:
    /// it keeps none of its own for them (usually empty).
    skipped: Vec<(u32, [u32; 3])>,
    topology: Arc<Topology>,
}

impl Adjacency {
    /// The adjacency `topology` of `mesh`.
    fn new(mesh: &Mesh, topology: Arc<Topology>) -> Adjacency {
        let skipped = (0..mesh.n_faces() as u32)
            .filter(|&f| topology.is_skipped_face(f))
            .map(|f| (f, mesh.faces[f as usize]))
            .collect();
        Adjacency { skipped, topology }
    }

    /// Whether `mesh` has the vertex count and the faces the adjacency was built from,
    /// read off its own edges instead of a copy of the faces: a face whose three edges
    /// join its corners in turn is the face they were made from (its corners differ).
    fn is_of(&self, mesh: &Mesh) -> bool {
        let t = &self.topology;
        t.n_vertices() == mesh.n_vertices()
            && t.n_faces() == mesh.n_faces()
            && self
                .skipped
                .iter()
                .all(|&(f, corners)| mesh.faces[f as usize] == corners)
            && mesh.faces.par_iter().enumerate().all(|(f, c)| {
                let edges = t.face_edges(f as u32);
                // Skipped faces are the ones listed above.
                edges[0] == coarsen_mesh::topology::NONE
                    || (0..3).all(|i| {
                        let (a, b) = (c[i], c[(i + 1) % 3]);
                        t.edge(edges[i]) == [a.min(b), a.max(b)]
                    })
            })
    }
}

/// The value of type `T` among the values derived from the run input, if there is one.
fn entry<T: Any + Send + Sync>(input: &[(TypeId, Entry)]) -> Option<Arc<T>> {
    let key = TypeId::of::<T>();
    input
        .iter()
        .find(|(k, _)| *k == key)
        .and_then(|(_, v)| Arc::clone(v).downcast::<T>().ok())
}

/// Values built once per run and handed to every stage that asks: see
/// [`crate::Context::input_index`] and [`crate::Context::topology`].
#[derive(Default)]
pub struct Shared {
    input: Mutex<Vec<(TypeId, Entry)>>,
    adjacency: Mutex<Option<Adjacency>>,
    /// The run input's adjacency while anything holds it: not kept for its own sake (at
    /// 4.4M faces it is 350 MiB, and the input indexes keep what they need of it).
    input_topology: Mutex<Weak<Topology>>,
}

impl Shared {
    /// An empty cache, for one run.
    pub fn new() -> Shared {
        Shared::default()
    }

    /// The value of type `T` derived from the run input: built by `build` on the first
    /// call, the same value afterwards. `build` must depend on the run input alone.
    pub fn input_index<T: Any + Send + Sync>(&self, build: impl FnOnce() -> T) -> Arc<T> {
        match self.try_input_index(|| Ok::<T, std::convert::Infallible>(build())) {
            Ok(v) => v,
            Err(never) => match never {},
        }
    }

    /// Like [`Shared::input_index`], for a `build` that may fail (nothing is kept then).
    pub fn try_input_index<T: Any + Send + Sync, E>(
        &self,
        build: impl FnOnce() -> Result<T, E>,
    ) -> Result<Arc<T>, E> {
        let mut input = self.input.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(v) = entry::<T>(&input) {
            return Ok(v);
        }
        let v = Arc::new(build()?);
        input.push((TypeId::of::<T>(), Arc::clone(&v) as Entry));
        Ok(v)
    }

    /// The value of type `T` derived from the run input when it is built already.
    pub fn input_index_at_hand<T: Any + Send + Sync>(&self) -> Option<Arc<T>> {
        entry::<T>(&self.input.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// The adjacency of the run input `input`: the one built before while something still
    /// holds it, or the adjacency kept for the next stage when that was built from the
    /// input's faces, else a new one.
    pub fn input_topology(&self, input: &Mesh) -> Result<Arc<Topology>, TopologyError> {
        let mut slot = self
            .input_topology
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if let Some(t) = slot.upgrade() {
            return Ok(t);
        }
        let kept = self
            .adjacency
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_ref()
            .filter(|a| a.is_of(input))
            .map(|a| Arc::clone(&a.topology));
        let t = match kept {
            Some(t) => t,
            None => Arc::new(Topology::try_build(input)?),
        };
        *slot = Arc::downgrade(&t);
        Ok(t)
    }

    /// Drops the adjacency kept for the next stage (before a stage that keeps its own, so
    /// that the two do not add up to its peak memory).
    pub fn forget_topology(&self) {
        *self
            .adjacency
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = None;
    }

    /// The adjacency kept from a stage before when `mesh` has the same vertex count and
    /// faces as the mesh it was built from; nothing is built.
    pub fn topology_at_hand(&self, mesh: &Mesh) -> Option<Arc<Topology>> {
        self.adjacency
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_ref()
            .filter(|a| a.is_of(mesh))
            .map(|a| Arc::clone(&a.topology))
    }

    /// The adjacency of `mesh`: the one built last when `mesh` has the same vertex count
    /// and faces as the mesh it was built from, else a new one (which replaces it).
    pub fn topology(&self, mesh: &Mesh) -> Result<Arc<Topology>, TopologyError> {
        let mut slot = self
            .adjacency
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if let Some(a) = slot.as_ref()
            && a.is_of(mesh)
        {
            return Ok(Arc::clone(&a.topology));
        }
        // Drop the old one first: at millions of faces both would not fit comfortably.
        *slot = None;
        let topology = Arc::new(Topology::try_build(mesh)?);
        *slot = Some(Adjacency::new(mesh, Arc::clone(&topology)));
        Ok(topology)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_mesh::DVec3;

    fn two_triangles() -> Mesh {
        Mesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::ONE],
            faces: vec![[0, 1, 2], [2, 1, 3]],
            ..Default::default()
        }
    }

    #[test]
    fn an_input_index_is_built_once_per_type() {
        let shared = Shared::new();
        let mut builds = 0;
        let a = shared.input_index(|| {
            builds += 1;
            7u64
        });
        let b = shared.input_index(|| {
            builds += 1;
            8u64
        });
        let c = shared.input_index(|| "other type");
        assert_eq!((*a, *b, *c, builds), (7, 7, "other type", 1));
    }

    #[test]
    fn the_kept_adjacency_serves_only_the_faces_it_was_built_from() {
        let shared = Shared::new();
        let mut mesh = two_triangles();
        mesh.faces.push([3, 3, 1]);
        let kept = shared.topology(&mesh).unwrap();
        assert!(Arc::ptr_eq(&shared.topology(&mesh.clone()).unwrap(), &kept));
        // The same triangle from another corner, the other way round, a skipped face
        // changed, one vertex more: each another mesh.
        let variants: [fn(&mut Mesh); 4] = [
            |m| m.faces[1] = [1, 3, 2],
            |m| m.faces[0] = [0, 2, 1],
            |m| m.faces[2] = [2, 2, 1],
            |m| m.positions.push(DVec3::Z),
        ];
        for change in variants {
            let mut other = mesh.clone();
            change(&mut other);
            assert!(shared.topology_at_hand(&other).is_none());
        }
        assert!(Arc::ptr_eq(&shared.topology_at_hand(&mesh).unwrap(), &kept));
    }

    #[test]
    fn an_input_index_is_at_hand_only_once_built() {
        let shared = Shared::new();
        assert!(shared.input_index_at_hand::<u64>().is_none());
        let built = shared.input_index(|| 7u64);
        let at_hand = shared.input_index_at_hand::<u64>().unwrap();
        assert!(Arc::ptr_eq(&built, &at_hand));
        assert!(shared.input_index_at_hand::<u32>().is_none());
    }

    #[test]
    fn the_input_topology_is_taken_from_the_kept_adjacency_when_the_faces_match() {
        let shared = Shared::new();
        let input = two_triangles();
        let kept = shared.topology(&input).unwrap();
        let t = shared.input_topology(&input).unwrap();
        assert!(Arc::ptr_eq(&kept, &t));
        // Once taken, it stays the input's even after the kept adjacency moves on.
        let mut other = input.clone();
        other.faces.pop();
        shared.topology(&other).unwrap();
        assert!(Arc::ptr_eq(&shared.input_topology(&input).unwrap(), &t));

        let fresh = Shared::new();
        fresh.topology(&other).unwrap();
        let built = fresh.input_topology(&input).unwrap();
        assert_eq!(built.n_faces(), 2);
        assert!(Arc::ptr_eq(&fresh.input_topology(&input).unwrap(), &built));
    }

    #[test]
    fn the_input_topology_goes_when_nothing_holds_it_and_comes_back_on_request() {
        let shared = Shared::new();
        let input = two_triangles();
        let t = shared.input_topology(&input).unwrap();
        let weak = Arc::downgrade(&t);
        drop(t);
        assert!(
            weak.upgrade().is_none(),
            "the shared state does not keep it alive"
        );
        let again = shared.input_topology(&input).unwrap();
        assert_eq!(again.n_faces(), 2);
        // An index built from it is built once, and the adjacency is not asked for again.
        let mut builds = 0;
        for _ in 0..2 {
            let v = shared
                .try_input_index(|| {
                    builds += 1;
                    shared.input_topology(&input).map(|t| t.n_edges())
                })
                .unwrap();
            assert_eq!(*v, 5);
        }
        assert_eq!(builds, 1);
        let failed: Result<Arc<u8>, &str> = shared.try_input_index(|| Err("no"));
        assert_eq!(failed.unwrap_err(), "no");
        assert_eq!(
            *shared.input_index(|| 3u8),
            3,
            "a failed build keeps nothing"
        );
    }

    #[test]
    fn the_topology_is_reused_only_while_the_faces_stay_the_same() {
        let shared = Shared::new();
        let mut m = two_triangles();
        let t1 = shared.topology(&m).unwrap();
        m.positions[3] = DVec3::splat(2.0); // positions do not matter to adjacency
        let t2 = shared.topology(&m).unwrap();
        assert!(Arc::ptr_eq(&t1, &t2));
        m.faces.pop();
        let t3 = shared.topology(&m).unwrap();
        assert!(!Arc::ptr_eq(&t1, &t3));
        assert_eq!(t3.n_edges(), 3);
        m.positions.push(DVec3::NEG_ONE); // a new isolated vertex changes the adjacency
        let t4 = shared.topology(&m).unwrap();
        assert!(!Arc::ptr_eq(&t3, &t4));
    }

    #[test]
    fn the_topology_at_hand_is_only_ever_the_kept_one() {
        let shared = Shared::new();
        let mut m = two_triangles();
        assert!(shared.topology_at_hand(&m).is_none(), "nothing built yet");
        let t = shared.topology(&m).unwrap();
        assert!(Arc::ptr_eq(&shared.topology_at_hand(&m).unwrap(), &t));
        m.faces.pop();
        assert!(shared.topology_at_hand(&m).is_none(), "other faces");
        assert!(Arc::ptr_eq(
            &shared.topology_at_hand(&two_triangles()).unwrap(),
            &t
        ));
    }
}
