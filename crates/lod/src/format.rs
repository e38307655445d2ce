//! The record file: a versioned little-endian binary with a magic header, sized sections
//! and a trailing checksum.
//!
//! | bytes | content |
//! | --- | --- |
//! | 0–7 | magic `COARSLOD` |
//! | 8–11 | format version (`u32`, 1) |
//! | 12–15 | reserved, 0 |
//! | 16–19, 20–23 | input vertices, input faces (`u32`) |
//! | 24–31 | fingerprint of the coarse mesh (`u64`) |
//! | 32–71 | counts (`u64`): isolated vertices, steps, positions, deleted faces, renamed faces |
//! | 72– | the five sections, in that order (record sizes 28, 20, 24, 16, 8 bytes) |
//! | last 8 | FNV-1a hash of every byte before it (`u64`) |
//!
//! Records: isolated vertex = index `u32`, position 3 × `f64`; step = kept, removed₀,
//! removed₁ (`u32`, `0xFFFFFFFF` when unused), deleted count, renamed count (`u32`);
//! position = 3 × `f64`; deleted face = face, 3 corners (`u32`); renamed face = face,
//! vertex (`u32`).
//!
//! Reading checks the size announced by the header against the file's before allocating
//! anything, then the checksum, then every record ([`crate::check`]).

use crate::{LodError, check};
use coarsen_collapse::{ChangedFace, DeletedFace, Fnv, Progressive, Step};
use coarsen_geom::DVec3;
use std::io::Write;
use std::path::Path;

/// The first 8 bytes of every record file.
pub const MAGIC: [u8; 8] = *b"COARSLOD";
/// The format version this build writes and reads.
pub const VERSION: u32 = 1;
/// Bytes before the first section.
pub const HEADER: usize = 72;
/// Bytes of the trailing checksum.
const TRAILER: usize = 8;

/// Record sizes of the five sections, in file order.
const SIZES: [u64; 5] = [28, 20, 24, 16, 8];
/// Section names, in file order, for error messages.
pub(crate) const SECTIONS: [&str; 5] = [
    "isolated vertex",
    "step",
    "position",
    "deleted face",
    "renamed face",
];

/// Where each section starts, for a record with these section counts.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Layout {
    counts: [u64; 5],
}

impl Layout {
    pub(crate) fn of(p: &Progressive) -> Self {
        Layout {
            counts: [
                p.isolated.len() as u64,
                p.steps.len() as u64,
                p.positions.len() as u64,
                p.deleted.len() as u64,
                p.changed.len() as u64,
            ],
        }
    }

    /// The file size, or `None` when it does not fit in 64 bits.
    fn total(&self) -> Option<u64> {
        let mut n = (HEADER + TRAILER) as u64;
        for (c, s) in self.counts.iter().zip(SIZES) {
            n = n.checked_add(c.checked_mul(s)?)?;
        }
        Some(n)
    }

    /// Byte offset of record `index` of section `section` (saturating: only for messages
    /// about records that exist).
    pub(crate) fn offset(&self, section: usize, index: u64) -> u64 {
        let before: u64 = (0..section)
            .map(|s| self.counts[s].saturating_mul(SIZES[s]))
            .fold(HEADER as u64, u64::saturating_add);
        before.saturating_add(index.saturating_mul(SIZES[section]))
    }
}

/// A writer that hashes what goes through it.
struct Hashing<'a, W: Write> {
    inner: &'a mut W,
    hash: Fnv,
}

impl<W: Write> Hashing<'_, W> {
    fn put(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.hash.write(bytes);
        self.inner.write_all(bytes)
    }
    fn u32(&mut self, x: u32) -> std::io::Result<()> {
        self.put(&x.to_le_bytes())
    }
    fn u64(&mut self, x: u64) -> std::io::Result<()> {
        self.put(&x.to_le_bytes())
    }
    fn vec3(&mut self, p: DVec3) -> std::io::Result<()> {
        for x in p.to_array() {
            self.put(&x.to_le_bytes())?;
        }
        Ok(())
    }
}

/// Writes `record` in the file format to `w`.
pub fn write_to(w: &mut impl Write, record: &Progressive) -> std::io::Result<()> {
    let mut h = Hashing {
        inner: w,
        hash: Fnv::default(),
    };
    h.put(&MAGIC)?;
    h.u32(VERSION)?;
    h.u32(0)?;
    h.u32(record.input_vertices)?;
    h.u32(record.input_faces)?;
    h.u64(record.coarse)?;
    for c in Layout::of(record).counts {
        h.u64(c)?;
    }
    for &(v, p) in &record.isolated {
        h.u32(v)?;
        h.vec3(p)?;
    }
    for s in &record.steps {
        for x in [s.kept, s.removed[0], s.removed[1], s.deleted, s.changed] {
            h.u32(x)?;
        }
    }
    for &p in &record.positions {
        h.vec3(p)?;
    }
    for d in &record.deleted {
        for x in [d.face, d.corners[0], d.corners[1], d.corners[2]] {
            h.u32(x)?;
        }
    }
    for c in &record.changed {
        h.u32(c.face)?;
        h.u32(c.vertex)?;
    }
    let sum = h.hash.finish();
    h.inner.write_all(&sum.to_le_bytes())
}

/// The file bytes of `record`.
pub fn encode(record: &Progressive) -> Vec<u8> {
    let mut out = Vec::with_capacity(Layout::of(record).total().unwrap_or(0) as usize);
    // Writing to a Vec cannot fail.
    let _ = write_to(&mut out, record);
    out
}

/// Writes `record` to `path` atomically (a temporary file renamed into place: a failure
/// leaves no half-written file).
pub fn write(path: &Path, record: &Progressive) -> Result<(), LodError> {
    let name = path.display().to_string();
    coarsen_io::write_atomically(path, |w| {
        write_to(w, record).map_err(|e| coarsen_io::IoError {
            file: name.clone(),
            at: coarsen_io::Location::File,
            kind: e.into(),
        })
    })?;
    Ok(())
}

/// Reads and checks the record file at `path`.
pub fn read(path: &Path) -> Result<Progressive, LodError> {
    let bytes = std::fs::read(path).map_err(|source| LodError::Read {
        file: path.display().to_string(),
        source,
    })?;
    decode(&bytes)
}

/// A cursor over bytes whose length was checked beforehand.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        // The caller checked the length: the slice is always there, but stay panic-free.
        if let Some(s) = self.bytes.get(self.at..self.at + N) {
            out.copy_from_slice(s);
        }
        self.at += N;
        out
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn vec3(&mut self) -> DVec3 {
        let x = f64::from_le_bytes(self.take());
        let y = f64::from_le_bytes(self.take());
        let z = f64::from_le_bytes(self.take());
        DVec3::new(x, y, z)
    }
}

/// Parses and checks record-file bytes.
pub fn decode(bytes: &[u8]) -> Result<Progressive, LodError> {
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        let n = bytes.len().min(MAGIC.len());
        return Err(LodError::BadMagic {
            found: String::from_utf8_lossy(&bytes[..n]).into_owned(),
        });
    }
    if bytes.len() < HEADER + TRAILER {
        return Err(LodError::Truncated {
            len: bytes.len() as u64,
            need: (HEADER + TRAILER) as u64,
        });
    }
    let mut r = Reader { bytes, at: 8 };
    let version = r.u32();
    if version != VERSION {
        return Err(LodError::Version { found: version });
    }
    let reserved = r.u32();
    if reserved != 0 {
        return Err(LodError::Header {
            offset: 12,
            detail: format!("reserved field is {reserved}, expected 0"),
        });
    }
    let input_vertices = r.u32();
    let input_faces = r.u32();
    let coarse = r.u64();
    let mut counts = [0u64; 5];
    for c in &mut counts {
        *c = r.u64();
    }
    let layout = Layout { counts };
    let expected = layout.total();
    if expected != Some(bytes.len() as u64) {
        return Err(match expected {
            Some(e) if e > bytes.len() as u64 => LodError::Truncated {
                len: bytes.len() as u64,
                need: e,
            },
            _ => LodError::Size {
                expected,
                found: bytes.len() as u64,
                counts,
            },
        });
    }
    let body = bytes.len() - TRAILER;
    let mut hash = Fnv::default();
    hash.write(&bytes[..body]);
    let stored = u64::from_le_bytes(bytes[body..].try_into().unwrap_or([0; 8]));
    if hash.finish() != stored {
        return Err(LodError::Checksum {
            offset: body as u64,
            stored,
            computed: hash.finish(),
        });
    }
    // Every count times its record size fits in the file: these allocations are bounded
    // by its length.
    let [ni, ns, np, nd, nc] = counts.map(|c| c as usize);
    let mut p = Progressive::new(input_vertices, input_faces);
    p.coarse = coarse;
    p.isolated.reserve_exact(ni);
    for _ in 0..ni {
        let v = r.u32();
        p.isolated.push((v, r.vec3()));
    }
    p.steps.reserve_exact(ns);
    for _ in 0..ns {
        p.steps.push(Step {
            kept: r.u32(),
            removed: [r.u32(), r.u32()],
            deleted: r.u32(),
            changed: r.u32(),
        });
    }
    p.positions.reserve_exact(np);
    for _ in 0..np {
        p.positions.push(r.vec3());
    }
    p.deleted.reserve_exact(nd);
    for _ in 0..nd {
        p.deleted.push(DeletedFace {
            face: r.u32(),
            corners: [r.u32(), r.u32(), r.u32()],
        });
    }
    p.changed.reserve_exact(nc);
    for _ in 0..nc {
        p.changed.push(ChangedFace {
            face: r.u32(),
            vertex: r.u32(),
        });
    }
    check(&p)?;
    Ok(p)
}
