//! Progressive levels of detail (paper 2 §3.6): the collapse record's file format, and the
//! rebuild of any intermediate level by undoing collapses (vertex splits).
//!
//! The collapse engine (`coarsen-collapse`) records, when asked, what undoing each collapse
//! needs: the kept and removed vertices' positions before it, the faces it deleted (with
//! their corners) and the faces it renamed (see [`Progressive`]). This crate
//!
//! * writes and reads that record as a versioned binary file ([`write()`], [`read()`]; format
//!   in the [`format`](mod@format) module), refusing with a typed error anything that is not exactly
//!   such a file — wrong magic or version, truncation, a size that disagrees with the
//!   header, a checksum mismatch, or records that contradict each other ([`check`]);
//! * rebuilds **level K** from the coarse mesh ([`rebuild`]): level 0 is the coarse mesh,
//!   level K has the last K collapses undone, and level [`levels`] is the mesh the engine
//!   started from — positions bit for bit, the same faces with the same corners, in the
//!   same order (vertices used by no face included).
//!
//! Vertices and faces of a level are the input's that exist at that level, in input order,
//! so level 0 is exactly the compacted coarse mesh the engine wrote. Every level is a state
//! the engine went through, so it is as valid as the engine keeps its meshes (manifold
//! where the input was, no flipped or degenerate face made). Only positions and faces are
//! rebuilt; attributes are not.
//!
//! ```
//! use coarsen_collapse::{Goal, LiveMesh, Options, QemOptions, QuadricModel};
//! let sphere = coarsen_shapes::icosphere(1.0, 2)?;
//! let mut live = LiveMesh::new(&sphere)?;
//! live.record_progressive();
//! let mut model = QuadricModel::new(&live, &QemOptions::default());
//! live.collapse(&mut model, &Options::new(Goal::Vertices(50)), &mut |_| {});
//! let (coarse, _) = live.to_mesh(&sphere)?;
//! let record = live.take_progressive(&coarse).unwrap();
//! let bytes = coarsen_lod::encode(&record);
//! let record = coarsen_lod::decode(&bytes)?;
//! let all = coarsen_lod::levels(&record);
//! assert_eq!(coarsen_lod::rebuild(&coarse, &record, all)?, sphere);
//! let level = coarsen_lod::level_with_vertices(&record, 100)?;
//! assert_eq!(coarsen_lod::rebuild(&coarse, &record, level)?.n_vertices(), 100);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod format;

pub use coarsen_collapse::Progressive;
pub use format::{decode, encode, read, write, write_to};

use coarsen_collapse::{Index, NONE, fingerprint};
use coarsen_geom::{DVec3, is_finite};
use coarsen_mesh::Mesh;
use format::{Layout, SECTIONS};

/// Why a record cannot be read, written or used.
#[derive(Debug, thiserror::Error)]
pub enum LodError {
    /// The operating system refused to read the file.
    #[error("{file}: {source}")]
    Read {
        /// The file.
        file: String,
        /// What the system said.
        source: std::io::Error,
    },
    /// Writing the file failed (nothing was left behind).
    #[error(transparent)]
    Write(#[from] coarsen_io::IoError),
    /// The file does not start with the magic bytes.
    #[error(
        "byte 0: not a coarsen progressive record (it starts with {found:?}, expected \"COARSLOD\")"
    )]
    BadMagic {
        /// The first bytes found, as text.
        found: String,
    },
    /// A format version this build does not read.
    #[error(
        "byte 8: record format version {found} is not supported (this build reads version {})",
        format::VERSION
    )]
    Version {
        /// The version found.
        found: u32,
    },
    /// The file ends before what its header announces.
    #[error("the file is truncated: it has {len} bytes, its header needs {need}")]
    Truncated {
        /// Bytes in the file.
        len: u64,
        /// Bytes needed.
        need: u64,
    },
    /// The file is longer than its header announces, or the announced size overflows.
    #[error("the header's counts {counts:?} make {} bytes, but the file has {found}", expected.map_or("more than 2^64".to_string(), |e| e.to_string()))]
    Size {
        /// The size the header announces (`None`: overflows).
        expected: Option<u64>,
        /// The file's size.
        found: u64,
        /// The section counts of the header.
        counts: [u64; 5],
    },
    /// The checksum does not match the content (the file is damaged).
    #[error(
        "byte {offset}: checksum {stored:#018x} does not match the content ({computed:#018x}): the file is damaged"
    )]
    Checksum {
        /// Where the stored checksum is.
        offset: u64,
        /// The stored checksum.
        stored: u64,
        /// The checksum of the content.
        computed: u64,
    },
    /// A header field is wrong.
    #[error("byte {offset}: {detail}")]
    Header {
        /// Where the field is.
        offset: u64,
        /// What is wrong.
        detail: String,
    },
    /// A record contradicts the header or the records before it.
    #[error("{section} {index} (byte {offset}): {detail}")]
    Record {
        /// The section: `step`, `position`, …
        section: &'static str,
        /// The record's number within its section, from 0.
        index: u64,
        /// Where it is (or would be) in the file.
        offset: u64,
        /// What is wrong.
        detail: String,
    },
    /// The coarse mesh given is not the one the record was taken from.
    #[error(
        "the coarse mesh ({vertices} vertices, {faces} faces) is not the one the record was taken from \
         ({expected_vertices} vertices, {expected_faces} faces{}); give the mesh `coarsen run` wrote with \
         the record, in a lossless format (PLY, OBJ or OFF — STL rounds positions to 32 bits)",
        if *same_counts { ", and different positions or faces" } else { "" }
    )]
    CoarseMismatch {
        /// Vertices of the mesh given.
        vertices: usize,
        /// Faces of the mesh given.
        faces: usize,
        /// Vertices the record expects.
        expected_vertices: usize,
        /// Faces the record expects.
        expected_faces: usize,
        /// The counts agree (positions or faces differ).
        same_counts: bool,
    },
    /// Undoing a step met a state the step does not fit (a damaged record).
    #[error("step {step}: {detail}")]
    Undo {
        /// The step, from 0.
        step: usize,
        /// What does not fit.
        detail: String,
    },
    /// The level asked for does not exist.
    #[error(
        "level {level} does not exist: the record has levels 0 (the coarse mesh) to {max} (the input)"
    )]
    NoLevel {
        /// The level asked for.
        level: usize,
        /// The last level.
        max: usize,
    },
    /// No level has the vertex count asked for.
    #[error("no level has {vertices} vertices; {}", nearest_text(*below, *above))]
    NoVertexCount {
        /// The count asked for.
        vertices: usize,
        /// The nearest level below, as (level, vertices).
        below: Option<(usize, usize)>,
        /// The nearest level above, as (level, vertices).
        above: Option<(usize, usize)>,
    },
}

fn nearest_text(below: Option<(usize, usize)>, above: Option<(usize, usize)>) -> String {
    let one = |(l, v): (usize, usize)| format!("level {l} has {v}");
    match (below, above) {
        (Some(b), Some(a)) => format!("the nearest are {} and {}", one(b), one(a)),
        (Some(b), None) => format!("the largest is the input: {}", one(b)),
        (None, Some(a)) => format!("the smallest is the coarse mesh: {}", one(a)),
        (None, None) => "the record is empty".into(),
    }
}

/// The number of the last level (the input): one level per collapse recorded.
pub fn levels(record: &Progressive) -> usize {
    record.steps.len()
}

/// Vertices of level `level` (`level` ≤ [`levels`]).
pub fn level_vertices(record: &Progressive, level: usize) -> usize {
    let n = record.steps.len();
    let undone: usize = record.steps[n - level.min(n)..]
        .iter()
        .map(|s| s.n_removed())
        .sum();
    let isolated = if level >= n { record.isolated.len() } else { 0 };
    record.coarse_vertices() + undone + isolated
}

/// The level with exactly `vertices` vertices, or an error naming the nearest ones.
pub fn level_with_vertices(record: &Progressive, vertices: usize) -> Result<usize, LodError> {
    let n = record.steps.len();
    let (mut below, mut above) = (None, None);
    for level in 0..=n {
        let v = level_vertices(record, level);
        if v == vertices {
            return Ok(level);
        }
        if v < vertices {
            below = Some((level, v));
        } else if above.is_none() {
            above = Some((level, v));
        }
    }
    Err(LodError::NoVertexCount {
        vertices,
        below,
        above,
    })
}

/// Checks that a record is consistent in itself: indices in range, positions finite, the
/// arenas as long as the steps say, no vertex removed twice or used after its removal, no
/// face deleted twice or renamed after its deletion, each step's faces matching its
/// vertices. [`decode`] and [`rebuild`] call it; allocations are bounded by the record's
/// own size.
pub fn check(p: &Progressive) -> Result<(), LodError> {
    let c = Checker {
        p,
        layout: Layout::of(p),
    };
    c.isolated()?;
    let mut removed_at = c.steps()?;
    c.arenas()?;
    // Across steps: removals are once and final; deletions are once and final.
    c.removals(&mut removed_at)?;
    let deleted_at = c.step_faces(&removed_at)?;
    c.deletions(deleted_at)
}

/// The checks of [`check`] on one record.
struct Checker<'a> {
    p: &'a Progressive,
    layout: Layout,
}

impl Checker<'_> {
    /// The error for element `index` of section `section`, at its offset in the file.
    fn bad(&self, section: usize, index: usize, detail: String) -> LodError {
        LodError::Record {
            section: SECTIONS[section],
            index: index as u64,
            offset: self.layout.offset(section, index as u64),
            detail,
        }
    }

    /// Whether `v` is an input vertex.
    fn vertex(&self, v: Index) -> Result<(), String> {
        let nv = self.p.input_vertices;
        if v < nv {
            Ok(())
        } else {
            Err(format!("vertex {v} out of range (the input has {nv})"))
        }
    }

    /// Whether `f` is an input face.
    fn face(&self, f: Index) -> Result<(), String> {
        let nf = self.p.input_faces;
        if f < nf {
            Ok(())
        } else {
            Err(format!("face {f} out of range (the input has {nf})"))
        }
    }

    /// The vertices no face uses: in range, at finite positions, ascending.
    fn isolated(&self) -> Result<(), LodError> {
        let p = self.p;
        for (i, &(v, q)) in p.isolated.iter().enumerate() {
            self.vertex(v)
                .and_then(|_| finite(q))
                .map_err(|d| self.bad(0, i, d))?;
            if i > 0 && v <= p.isolated[i - 1].0 {
                return Err(self.bad(0, i, format!("vertex {v} is not after the previous one")));
            }
        }
        Ok(())
    }

    /// Each step alone (its vertices in range and distinct), and the arenas as long as the
    /// steps say. Returns each removed vertex with its step, in step order.
    fn steps(&self) -> Result<Vec<(Index, usize)>, LodError> {
        let p = self.p;
        let (mut n_pos, mut n_del, mut n_chg) = (0u64, 0u64, 0u64);
        let mut removed_at: Vec<(Index, usize)> = Vec::with_capacity(p.positions.len());
        for (i, s) in p.steps.iter().enumerate() {
            let ok = (|| {
                self.vertex(s.kept)?;
                if s.removed[0] == NONE {
                    return Err("no removed vertex".to_string());
                }
                for r in s.removed() {
                    self.vertex(r)?;
                }
                if s.removed.contains(&s.kept) || s.removed[0] == s.removed[1] {
                    return Err(format!(
                        "kept {} and removed {:?} are not distinct",
                        s.kept, s.removed
                    ));
                }
                Ok(())
            })();
            ok.map_err(|d| self.bad(1, i, d))?;
            removed_at.extend(s.removed().map(|r| (r, i)));
            n_pos += s.n_positions() as u64;
            n_del += s.deleted as u64;
            n_chg += s.changed as u64;
        }
        for (name, offset, sum, len) in [
            ("positions", 48, n_pos, p.positions.len()),
            ("deleted faces", 56, n_del, p.deleted.len()),
            ("renamed faces", 64, n_chg, p.changed.len()),
        ] {
            if sum != len as u64 {
                return Err(LodError::Header {
                    offset,
                    detail: format!("the steps account for {sum} {name}, the record holds {len}"),
                });
            }
        }
        Ok(removed_at)
    }

    /// The arenas' elements alone: positions finite, deleted faces in range with three
    /// distinct corners in range, renamed faces and their vertices in range.
    fn arenas(&self) -> Result<(), LodError> {
        let p = self.p;
        for (i, &q) in p.positions.iter().enumerate() {
            finite(q).map_err(|d| self.bad(2, i, d))?;
        }
        for (i, d) in p.deleted.iter().enumerate() {
            self.face(d.face)
                .and_then(|_| d.corners.iter().try_for_each(|&v| self.vertex(v)))
                .map_err(|e| self.bad(3, i, e))?;
            let [a, b, c] = d.corners;
            if a == b || b == c || a == c {
                return Err(self.bad(3, i, format!("corners {:?} repeat a vertex", d.corners)));
            }
        }
        for (i, c) in p.changed.iter().enumerate() {
            self.face(c.face)
                .and_then(|_| self.vertex(c.vertex))
                .map_err(|e| self.bad(4, i, e))?;
        }
        Ok(())
    }

    /// No vertex removed twice, nor one that no face uses. Sorts `removed_at` by vertex.
    fn removals(&self, removed_at: &mut [(Index, usize)]) -> Result<(), LodError> {
        removed_at.sort_unstable();
        for w in removed_at.windows(2) {
            if w[0].0 == w[1].0 {
                return Err(self.bad(
                    1,
                    w[1].1,
                    format!("vertex {} was already removed by step {}", w[0].0, w[0].1),
                ));
            }
        }
        for (i, &(v, _)) in self.p.isolated.iter().enumerate() {
            if let Ok(k) = removed_at.binary_search_by_key(&v, |e| e.0) {
                return Err(self.bad(
                    0,
                    i,
                    format!(
                        "vertex {v} is used by no face, yet step {} removes it",
                        removed_at[k].1
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Each step against the others (`removed_at`: sorted by vertex): its kept vertex not
    /// removed before and used by faces, its deleted faces holding two of its merged
    /// vertices, its renamed vertices among its removed ones. Returns each deleted face
    /// with its step, in step order.
    fn step_faces(&self, removed_at: &[(Index, usize)]) -> Result<Vec<(Index, usize)>, LodError> {
        let p = self.p;
        let removed_before = |v: Index, step: usize| {
            removed_at
                .binary_search_by_key(&v, |e| e.0)
                .ok()
                .map(|k| removed_at[k].1)
                .filter(|&s| s < step)
        };
        let mut deleted_at: Vec<(Index, usize)> = Vec::with_capacity(p.deleted.len());
        let (mut d0, mut c0) = (0usize, 0usize);
        for (i, s) in p.steps.iter().enumerate() {
            if let Some(j) = removed_before(s.kept, i) {
                return Err(self.bad(
                    1,
                    i,
                    format!("kept vertex {} was removed by step {j}", s.kept),
                ));
            }
            if p.isolated.binary_search_by_key(&s.kept, |e| e.0).is_ok() {
                return Err(self.bad(1, i, format!("kept vertex {} is used by no face", s.kept)));
            }
            let merged = |v: Index| v == s.kept || s.removed.contains(&v);
            let d1 = d0 + s.deleted as usize;
            for (k, d) in p.deleted[d0..d1].iter().enumerate() {
                if d.corners.iter().filter(|&&v| merged(v)).count() < 2 {
                    return Err(self.bad(
                        3,
                        d0 + k,
                        format!(
                            "face {} {:?} has fewer than two of step {i}'s merged vertices",
                            d.face, d.corners
                        ),
                    ));
                }
                deleted_at.push((d.face, i));
            }
            let c1 = c0 + s.changed as usize;
            for (k, c) in p.changed[c0..c1].iter().enumerate() {
                if !s.removed.contains(&c.vertex) {
                    return Err(self.bad(
                        4,
                        c0 + k,
                        format!(
                            "vertex {} is not one of step {i}'s removed vertices {:?}",
                            c.vertex, s.removed
                        ),
                    ));
                }
            }
            (d0, c0) = (d1, c1);
        }
        Ok(deleted_at)
    }

    /// No face deleted twice, nor renamed after its deletion.
    fn deletions(&self, mut deleted_at: Vec<(Index, usize)>) -> Result<(), LodError> {
        let p = self.p;
        deleted_at.sort_unstable();
        for w in deleted_at.windows(2) {
            if w[0].0 == w[1].0 {
                return Err(self.bad(
                    1,
                    w[1].1,
                    format!("face {} was already deleted by step {}", w[0].0, w[0].1),
                ));
            }
        }
        let mut c0 = 0usize;
        for (i, s) in p.steps.iter().enumerate() {
            for (k, c) in p.changed[c0..c0 + s.changed as usize].iter().enumerate() {
                if let Ok(j) = deleted_at.binary_search_by_key(&c.face, |e| e.0)
                    && deleted_at[j].1 < i
                {
                    return Err(self.bad(
                        4,
                        c0 + k,
                        format!("face {} was deleted by step {}", c.face, deleted_at[j].1),
                    ));
                }
            }
            c0 += s.changed as usize;
        }
        Ok(())
    }
}

/// Whether `q` is finite, said as a record problem.
fn finite(q: DVec3) -> Result<(), String> {
    if is_finite(q) {
        Ok(())
    } else {
        Err(format!(
            "position ({}, {}, {}) is not finite",
            q.x, q.y, q.z
        ))
    }
}

/// Level `level` of the record, rebuilt from `coarse` (level 0) by undoing the last
/// `level` collapses; level [`levels`] is the engine's input. `coarse` must be the mesh the
/// record was taken with (checked by [`fingerprint`]). Only positions and faces are rebuilt.
pub fn rebuild(coarse: &Mesh, record: &Progressive, level: usize) -> Result<Mesh, LodError> {
    check(record)?;
    let n = record.steps.len();
    if level > n {
        return Err(LodError::NoLevel { level, max: n });
    }
    check_coarse(coarse, record)?;
    let mut at = Input::of_coarse(coarse, record)?;
    at.undo(record, level)?;
    at.compact(record, level)
}

/// [`LodError::CoarseMismatch`] unless `coarse` is the mesh `p` was taken with: the counts
/// agree and the fingerprint is the record's.
fn check_coarse(coarse: &Mesh, p: &Progressive) -> Result<(), LodError> {
    let removed: usize = p.steps.iter().map(|s| s.n_removed()).sum();
    let counts_agree = coarse.n_vertices() as u64 + removed as u64 + p.isolated.len() as u64
        == p.input_vertices as u64
        && coarse.n_faces() as u64 + p.deleted.len() as u64 == p.input_faces as u64;
    if !counts_agree || fingerprint(coarse) != p.coarse {
        let (ev, ef) = (p.coarse_vertices(), p.coarse_faces());
        return Err(LodError::CoarseMismatch {
            vertices: coarse.n_vertices(),
            faces: coarse.n_faces(),
            expected_vertices: ev,
            expected_faces: ef,
            same_counts: (coarse.n_vertices(), coarse.n_faces()) == (ev, ef),
        });
    }
    Ok(())
}

/// A level being rebuilt, in the input's numbering.
struct Input {
    pos: Vec<DVec3>,
    vertex_alive: Vec<bool>,
    /// Each input face's corners (input vertices; `NONE` while it does not exist).
    faces: Vec<[Index; 3]>,
    face_alive: Vec<bool>,
}

impl Input {
    /// Level 0: the coarse mesh in the input's numbering (coarse vertex `i` is the `i`-th
    /// input vertex that survives every step, and likewise its faces). The counts agree
    /// with the coarse mesh ([`check_coarse`]), so these tables are as large as it and
    /// the record together.
    fn of_coarse(coarse: &Mesh, p: &Progressive) -> Result<Input, LodError> {
        let (nv, nf) = (p.input_vertices as usize, p.input_faces as usize);
        let mut pos = vec![DVec3::ZERO; nv];
        let mut vertex_alive = vec![true; nv];
        for &(v, _) in &p.isolated {
            vertex_alive[v as usize] = false;
        }
        for s in &p.steps {
            for r in s.removed() {
                vertex_alive[r as usize] = false;
            }
        }
        let mut face_alive = vec![true; nf];
        for d in &p.deleted {
            face_alive[d.face as usize] = false;
        }
        // The compaction map: coarse vertex i is the i-th surviving input vertex.
        let input_of: Vec<Index> = (0..nv as Index)
            .filter(|&v| vertex_alive[v as usize])
            .collect();
        for (&v, &q) in input_of.iter().zip(&coarse.positions) {
            pos[v as usize] = q;
        }
        let mut faces = vec![[NONE; 3]; nf];
        let mut coarse_faces = coarse.faces.iter().enumerate();
        for (f, slot) in faces.iter_mut().enumerate() {
            if !face_alive[f] {
                continue;
            }
            let Some((j, face)) = coarse_faces.next() else {
                break;
            };
            for (c, &v) in slot.iter_mut().zip(face) {
                *c = *input_of
                    .get(v as usize)
                    .ok_or_else(|| LodError::CoarseMismatch {
                        vertices: coarse.n_vertices(),
                        faces: j,
                        expected_vertices: p.coarse_vertices(),
                        expected_faces: p.coarse_faces(),
                        same_counts: true,
                    })?;
            }
        }
        Ok(Input {
            pos,
            vertex_alive,
            faces,
            face_alive,
        })
    }

    /// Undoes the last `level` steps of `p`, from the last back.
    fn undo(&mut self, p: &Progressive, level: usize) -> Result<(), LodError> {
        let (mut po, mut de, mut ch) = (p.positions.len(), p.deleted.len(), p.changed.len());
        for (i, s) in p.steps.iter().enumerate().rev().take(level) {
            let undo = |detail: String| LodError::Undo { step: i, detail };
            ch -= s.changed as usize;
            for c in &p.changed[ch..ch + s.changed as usize] {
                let f = c.face as usize;
                if !self.face_alive[f] {
                    return Err(undo(format!("renamed face {f} does not exist")));
                }
                let face = &mut self.faces[f];
                let corner = face.iter().position(|&v| v == s.kept).ok_or_else(|| {
                    undo(format!(
                        "renamed face {f} {face:?} does not hold kept vertex {}",
                        s.kept
                    ))
                })?;
                face[corner] = c.vertex;
            }
            de -= s.deleted as usize;
            for d in &p.deleted[de..de + s.deleted as usize] {
                self.faces[d.face as usize] = d.corners;
                self.face_alive[d.face as usize] = true;
            }
            po -= s.n_positions();
            self.pos[s.kept as usize] = p.positions[po];
            for (k, r) in s.removed().enumerate() {
                self.pos[r as usize] = p.positions[po + 1 + k];
                self.vertex_alive[r as usize] = true;
            }
        }
        if level == p.steps.len() {
            for &(v, q) in &p.isolated {
                self.pos[v as usize] = q;
                self.vertex_alive[v as usize] = true;
            }
        }
        Ok(())
    }

    /// The level's mesh: its vertices and faces in input order.
    fn compact(self, p: &Progressive, level: usize) -> Result<Mesh, LodError> {
        let nv = self.pos.len();
        let mut new_index = vec![NONE; nv];
        let mut positions = Vec::with_capacity(level_vertices(p, level));
        for (v, (&alive, &q)) in self.vertex_alive.iter().zip(&self.pos).enumerate() {
            if alive {
                new_index[v] = positions.len() as Index;
                positions.push(q);
            }
        }
        let mut out_faces = Vec::with_capacity(self.faces.len());
        for (f, face) in self.faces.iter().enumerate() {
            if !self.face_alive[f] {
                continue;
            }
            let mut mapped = [NONE; 3];
            for (m, &v) in mapped.iter_mut().zip(face) {
                *m = new_index.get(v as usize).copied().unwrap_or(NONE);
            }
            if mapped.contains(&NONE) {
                return Err(LodError::Undo {
                    step: p.steps.len() - level,
                    detail: format!(
                        "face {f} {face:?} uses a vertex that does not exist at this level"
                    ),
                });
            }
            out_faces.push(mapped);
        }
        Ok(Mesh::new(positions, out_faces))
    }
}

#[cfg(test)]
mod tests;
