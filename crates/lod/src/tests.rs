use super::*;
use crate::format::HEADER;
use coarsen_collapse::{CostModel, Goal, LiveMesh, Options, QemOptions, QuadricModel};
use coarsen_mesh::Topology;

/// A plane grid bent into a bump: an open disk with one boundary loop.
fn open_disk() -> Mesh {
    let mut m = coarsen_shapes::plane_grid(12, 10, 2.0).unwrap();
    for p in &mut m.positions {
        p.z = 0.3 * (1.3 * p.x).sin() * (1.7 * p.y).cos();
    }
    m
}

/// Collapses `mesh` to `goal` with `model` while recording; the coarse mesh and the record.
fn collapse_with<M: CostModel>(
    mesh: &Mesh,
    goal: Goal,
    model: impl FnOnce(&LiveMesh) -> M,
) -> (Mesh, Progressive) {
    let mut live = LiveMesh::new(mesh).unwrap();
    live.record_progressive();
    let mut m = model(&live);
    live.collapse(&mut m, &Options::new(goal), &mut |_| {});
    let (coarse, _) = live.to_mesh(mesh).unwrap();
    let record = live.take_progressive(&coarse).unwrap();
    (coarse, record)
}

fn qem(mesh: &Mesh, goal: Goal) -> (Mesh, Progressive) {
    collapse_with(mesh, goal, |l| QuadricModel::new(l, &QemOptions::default()))
}

/// A model whose candidates are triangles costed by area (3 → 1 collapses).
struct ByArea;

impl CostModel for ByArea {
    fn unit(&self) -> coarsen_collapse::Unit {
        coarsen_collapse::Unit::Triangle
    }
    fn reach(&self) -> coarsen_collapse::Reach {
        coarsen_collapse::Reach::Ring
    }
    fn plan(
        &self,
        mesh: &LiveMesh,
        merge: &coarsen_collapse::Merge<'_>,
    ) -> Option<coarsen_collapse::Plan> {
        let p = merge.vertices.iter().map(|&v| mesh.position(v));
        let centroid = p.clone().sum::<DVec3>() / merge.vertices.len() as f64;
        let position = merge.pinned.map_or(centroid, |v| mesh.position(v));
        let [a, b, c] = [0, 1, 2].map(|i| mesh.position(merge.vertices[i % merge.vertices.len()]));
        Some(coarsen_collapse::Plan {
            position,
            cost: (b - a).cross(c - a).length(),
        })
    }
    fn merged(&mut self, _: &LiveMesh, _: Index, _: &[Index]) {}
}

fn triangles(mesh: &Mesh, goal: Goal) -> (Mesh, Progressive) {
    collapse_with(mesh, goal, |_| ByArea)
}

fn shapes() -> Vec<(&'static str, Mesh)> {
    vec![
        ("icosphere", coarsen_shapes::icosphere(1.0, 3).unwrap()),
        ("torus", coarsen_shapes::torus(3.0, 1.0, 24, 12).unwrap()),
        ("open disk", open_disk()),
    ]
}

#[test]
fn undoing_every_collapse_gives_the_input_exactly() {
    for (name, mesh) in shapes() {
        let goal = Goal::Vertices(mesh.n_vertices() / 10);
        for (how, (coarse, record)) in [
            ("edges", qem(&mesh, goal)),
            ("triangles", triangles(&mesh, goal)),
        ] {
            assert!(record.steps.len() > 10, "{name} {how}");
            assert_eq!(
                (record.coarse_vertices(), record.coarse_faces()),
                (coarse.n_vertices(), coarse.n_faces()),
                "{name} {how}"
            );
            let all = rebuild(&coarse, &record, levels(&record)).unwrap();
            // Bit for bit: Mesh equality compares the f64s, and the faces keep their corners.
            assert_eq!(all.positions.len(), mesh.positions.len(), "{name} {how}");
            assert!(
                all.positions
                    .iter()
                    .zip(&mesh.positions)
                    .all(|(a, b)| a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits)),
                "{name} {how}"
            );
            assert_eq!(all.faces, mesh.faces, "{name} {how}");
            assert_eq!(
                rebuild(&coarse, &record, 0).unwrap(),
                coarse,
                "{name} {how}"
            );
        }
    }
}

#[test]
fn every_level_is_a_manifold_of_the_input_topology() {
    for (name, mesh) in shapes() {
        let want = Topology::build(&mesh).summary(&mesh);
        let (coarse, record) = triangles(&mesh, Goal::Vertices(mesh.n_vertices() / 8));
        let mut previous = 0;
        for level in 0..=levels(&record) {
            let m = rebuild(&coarse, &record, level).unwrap();
            let t = Topology::build(&m).summary(&m);
            assert!(
                t.manifold && t.consistently_oriented,
                "{name} level {level}"
            );
            assert_eq!(
                (t.euler, t.n_boundary_loops, t.n_isolated_vertices),
                (want.euler, want.n_boundary_loops, 0),
                "{name} level {level}"
            );
            assert_eq!(m.n_vertices(), level_vertices(&record, level));
            assert!(m.n_vertices() > previous || level == 0);
            previous = m.n_vertices();
            coarsen_mesh::sanity::sanity_check(&m)
                .unwrap_or_else(|e| panic!("{name} level {level}: {e}"));
        }
    }
}

#[test]
fn the_level_of_a_vertex_count_is_found_or_the_nearest_are_named() {
    let mesh = coarsen_shapes::icosphere(1.0, 2).unwrap();
    let (coarse, record) = qem(&mesh, Goal::Vertices(40));
    assert_eq!(level_with_vertices(&record, 40).unwrap(), 0);
    let l = level_with_vertices(&record, 100).unwrap();
    assert_eq!(l, 60);
    assert_eq!(rebuild(&coarse, &record, l).unwrap().n_vertices(), 100);
    assert_eq!(level_with_vertices(&record, 162).unwrap(), levels(&record));
    let e = level_with_vertices(&record, 500).unwrap_err();
    assert!(e.to_string().contains("level 122 has 162"), "{e}");
    assert!(matches!(
        rebuild(&coarse, &record, levels(&record) + 1),
        Err(LodError::NoLevel {
            level: 123,
            max: 122
        })
    ));
    // Triangle collapses remove two vertices at a time: odd gaps are named.
    let (_, record) = triangles(&mesh, Goal::Vertices(40));
    let odd = (41..162)
        .find(|&n| level_with_vertices(&record, n).is_err())
        .unwrap();
    let e = level_with_vertices(&record, odd).unwrap_err().to_string();
    assert!(e.contains("the nearest are level"), "{e}");
}

#[test]
fn vertices_no_face_uses_come_back_at_the_last_level() {
    let mut mesh = coarsen_shapes::icosphere(1.0, 2).unwrap();
    mesh.positions.insert(5, DVec3::splat(9.0));
    for f in &mut mesh.faces {
        for v in f {
            if *v >= 5 {
                *v += 1;
            }
        }
    }
    let (coarse, record) = qem(&mesh, Goal::Vertices(60));
    assert_eq!(record.isolated, vec![(5, DVec3::splat(9.0))]);
    assert_eq!(coarse.n_vertices(), 60);
    assert_eq!(rebuild(&coarse, &record, levels(&record)).unwrap(), mesh);
    let before_last = rebuild(&coarse, &record, levels(&record) - 1).unwrap();
    assert_eq!(before_last.n_vertices(), mesh.n_vertices() - 2);
}

#[test]
fn files_round_trip_and_are_written_atomically() {
    let mesh = coarsen_shapes::torus(3.0, 1.0, 16, 8).unwrap();
    let (coarse, record) = triangles(&mesh, Goal::Vertices(30));
    let bytes = encode(&record);
    assert_eq!(&bytes[..8], b"COARSLOD");
    assert_eq!(decode(&bytes).unwrap(), record);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.lod");
    write(&path, &record).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), bytes);
    let back = read(&path).unwrap();
    assert_eq!(rebuild(&coarse, &back, levels(&back)).unwrap(), mesh);
    // A folder that does not exist: an error, and nothing written.
    let e = write(&dir.path().join("no/such/r.lod"), &record).unwrap_err();
    assert!(e.to_string().contains("r.lod"), "{e}");
    let e = read(&dir.path().join("missing.lod")).unwrap_err();
    assert!(e.to_string().contains("missing.lod"), "{e}");
}

/// `bytes` with the checksum made right again, so that the structural checks are reached.
fn resealed(mut bytes: Vec<u8>) -> Vec<u8> {
    let body = bytes.len() - 8;
    let mut h = coarsen_collapse::Fnv::default();
    h.write(&bytes[..body]);
    bytes[body..].copy_from_slice(&h.finish().to_le_bytes());
    bytes
}

#[test]
fn truncated_damaged_and_foreign_files_are_typed_errors() {
    let mesh = coarsen_shapes::icosphere(1.0, 1).unwrap();
    let (coarse, record) = triangles(&mesh, Goal::Vertices(12));
    let bytes = encode(&record);
    for len in 0..bytes.len() {
        let e = decode(&bytes[..len]).unwrap_err();
        assert!(
            matches!(e, LodError::BadMagic { .. } | LodError::Truncated { .. }),
            "{len}: {e}"
        );
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(matches!(decode(&longer), Err(LodError::Size { .. })));
    // Every single flipped bit is caught.
    for i in 0..bytes.len() {
        let mut b = bytes.clone();
        b[i] ^= 0x10;
        assert!(decode(&b).is_err(), "byte {i}");
    }
    let e = decode(b"ply\nformat ascii 1.0\n").unwrap_err();
    assert!(
        e.to_string().contains("not a coarsen progressive record"),
        "{e}"
    );
    let mut v2 = bytes.clone();
    v2[8] = 2;
    assert!(matches!(decode(&v2), Err(LodError::Version { found: 2 })));
    // Huge counts do not allocate: the size check comes first.
    let mut huge = bytes.clone();
    huge[40..48].copy_from_slice(&u64::MAX.to_le_bytes());
    assert!(matches!(
        decode(&huge),
        Err(LodError::Size { expected: None, .. })
    ));
    huge[40..48].copy_from_slice(&(1u64 << 40).to_le_bytes());
    assert!(matches!(decode(&huge), Err(LodError::Truncated { .. })));

    // Records that contradict each other, with a valid checksum.
    let step0 = HEADER; // no isolated vertices
    let mut out_of_range = bytes.clone();
    out_of_range[step0..step0 + 4].copy_from_slice(&1000u32.to_le_bytes());
    let e = decode(&resealed(out_of_range)).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("step 0 (byte 72): vertex 1000 out of range"),
        "{e}"
    );
    let mut twice = record.clone();
    twice.steps[1].removed[0] = twice.steps[0].removed[0];
    let e = decode(&encode(&twice)).unwrap_err();
    assert!(
        e.to_string().contains("was already removed by step 0"),
        "{e}"
    );
    let mut nan = record.clone();
    nan.positions[3].y = f64::NAN;
    let e = decode(&encode(&nan)).unwrap_err();
    assert!(e.to_string().starts_with("position 3 "), "{e}");
    let mut short = record.clone();
    short.steps[0].changed += 1;
    let e = decode(&encode(&short)).unwrap_err();
    assert!(e.to_string().contains("renamed faces"), "{e}");
    let mut used_after = record.clone();
    used_after.steps[1].kept = used_after.steps[0].removed[0];
    assert!(decode(&encode(&used_after)).is_err());
    assert!(rebuild(&coarse, &used_after, 1).is_err());

    // The wrong coarse mesh.
    let mut moved = coarse.clone();
    moved.positions[0].x += 1e-9;
    let e = rebuild(&moved, &record, 1).unwrap_err();
    assert!(
        matches!(
            e,
            LodError::CoarseMismatch {
                same_counts: true,
                ..
            }
        ),
        "{e}"
    );
    let e = rebuild(&mesh, &record, 1).unwrap_err();
    assert!(
        e.to_string()
            .contains("is not the one the record was taken from"),
        "{e}"
    );
}

#[test]
fn damaged_records_with_valid_checksums_never_panic() {
    let mesh = open_disk();
    let (coarse, record) = triangles(&mesh, Goal::Vertices(40));
    let bytes = encode(&record);
    let mut state = 7u64;
    let mut next = move |n: usize| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as usize % n
    };
    let (mut refused, mut rebuilt) = (0, 0);
    for _ in 0..3000 {
        let mut b = bytes.clone();
        for _ in 0..1 + next(3) {
            let i = HEADER + next(bytes.len() - HEADER - 8);
            b[i] = match next(3) {
                0 => b[i] ^ (1 << next(8)),
                1 => 0xff,
                _ => next(256) as u8,
            };
        }
        match decode(&resealed(b)) {
            Err(_) => refused += 1,
            Ok(r) => {
                for level in [0, levels(&r) / 2, levels(&r)] {
                    if let Ok(m) = rebuild(&coarse, &r, level) {
                        assert!(m.validate_indices().is_ok());
                        rebuilt += 1;
                    }
                }
            }
        }
    }
    // Most damage is caught by the checks; position bits pass and still rebuild.
    assert!(
        refused > 1000 && rebuilt > 100,
        "{refused} refused, {rebuilt} rebuilt"
    );
}
