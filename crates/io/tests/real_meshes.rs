//! The real meshes of `../shared/data` load with the counts that `shared/README.md` gives,
//! and survive a binary PLY round trip bit for bit. Skipped, with a message, when the
//! folder is absent.

use coarsen_io::{Format, Loaded, ReadOptions, WriteOptions, read_bytes, read_path, write_to};
use std::path::{Path, PathBuf};

fn data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        println!(
            "skipped: {} is absent (the shared test meshes live beside the project)",
            dir.display()
        );
        None
    }
}

fn load(name: &str) -> Option<Loaded> {
    let path = data_dir()?.join(name);
    let loaded = read_path(&path, &ReadOptions::default())
        .unwrap_or_else(|e| panic!("{name} does not load: {e}"));
    println!("{name}: notes {:?}", loaded.notes);
    Some(loaded)
}

#[test]
fn shared_meshes_load_with_their_documented_counts() {
    let expected = [
        ("stanford-bunny.obj", 35_947, 69_451),
        ("rocker-arm.obj", 10_044, 20_088),
        ("fandisk.obj", 6_475, 12_946),
        ("spot.obj", 2_930, 5_856),
        ("cow.obj", 2_903, 5_804),
        ("teapot.obj", 3_644, 6_320),
        ("beetle.obj", 1_148, 2_053),
        ("suzanne.obj", 507, 968),
    ];
    for (name, v, f) in expected {
        let Some(loaded) = load(name) else { return };
        assert_eq!(loaded.format, Format::Obj);
        assert_eq!(
            (loaded.mesh.n_vertices(), loaded.mesh.n_faces()),
            (v, f),
            "{name}"
        );
        assert!(loaded.mesh.validate_indices().is_ok(), "{name}");
    }
}

/// Spot's wedges (one per `vt` line: no two vertices share one) and its vertices on seams.
const SPOT_WEDGES: usize = 3_225;
const SPOT_SEAM_VERTICES: usize = 277;

#[test]
fn spot_keeps_its_uvs_across_its_seams_as_wedges() {
    let Some(spot) = load("spot.obj") else { return };
    assert!(spot.mesh.vertex_attrs.vec2("uv").is_none());
    assert!(spot.notes.is_empty(), "{:?}", spot.notes);
    // 3,225 `vt` lines for 2,930 vertices: the seams' vertices take two or more.
    let w = &spot.mesh.wedges;
    assert_eq!(
        (w.len(), w.split_vertices()),
        (SPOT_WEDGES, SPOT_SEAM_VERTICES)
    );
}

#[test]
fn beetle_keeps_its_normals_or_says_why_not() {
    let Some(beetle) = load("beetle.obj") else {
        return;
    };
    match beetle.mesh.vertex_attrs.vec3("normal") {
        Some(n) => assert_eq!(n.len(), 1_148),
        // Hard edges: normals per corner.
        None if beetle.mesh.wedges.attrs().vec3("normal").is_some() => {}
        None => assert!(
            beetle
                .notes
                .iter()
                .any(|n| n.starts_with("normal not kept: ")),
            "{:?}",
            beetle.notes
        ),
    }
}

#[test]
fn suzanne_keeps_its_per_vertex_normals() {
    // Every corner of suzanne names the normal with its vertex's own number (`f 1//1 …`).
    let Some(suzanne) = load("suzanne.obj") else {
        return;
    };
    assert_eq!(
        suzanne.mesh.vertex_attrs.vec3("normal").map(<[_]>::len),
        Some(507)
    );
}

#[test]
fn shared_meshes_survive_a_binary_ply_round_trip_bit_for_bit() {
    let Some(dir) = data_dir() else { return };
    let mut names: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("data folder")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    names.sort();
    assert!(!names.is_empty());
    for path in names {
        let a = read_path(&path, &ReadOptions::default()).expect("load");
        let mut ply = Vec::new();
        write_to(&a.mesh, Format::Ply, &mut ply, &WriteOptions::default()).expect("write");
        let b = read_bytes(&ply, Format::Ply, "round-trip.ply", &ReadOptions::default())
            .expect("read back");
        // PLY holds no per-corner values (`left_out` says so): all the rest comes back.
        let mut expect = a.mesh;
        expect.wedges = Default::default();
        assert_eq!(b.mesh, expect, "{}", path.display());
        assert!(b.notes.is_empty(), "{}: {:?}", path.display(), b.notes);
    }
}
