//! Writes the seed corpora of every fuzz target into `corpus/<target>/`, from code:
//! small meshes in every format and encoding, the shipped pipeline files, and grid meshes
//! in the `stages` target's byte layout.
//!
//! Run from `fuzz/`: `cargo run --example seeds`.

use coarsen_io::{Format, PlyEncoding, WriteOptions, write_to};
use coarsen_mesh::{AttrValues, DVec2, Mesh};
use std::path::Path;

fn put(target: &str, name: &str, bytes: &[u8]) {
    let dir = Path::new("corpus").join(target);
    std::fs::create_dir_all(&dir).expect("create the corpus folder");
    std::fs::write(dir.join(name), bytes).expect("write a seed");
}

fn written(mesh: &Mesh, format: Format, encoding: PlyEncoding) -> Vec<u8> {
    let mut bytes = Vec::new();
    let opts = WriteOptions {
        ply_encoding: encoding,
        attributes: true,
    };
    write_to(mesh, format, &mut bytes, &opts).expect("the seed mesh is valid");
    bytes
}

/// Reader seeds: written meshes plus hand-written variants of each format.
fn readers() {
    let small = coarsen_shapes::icosphere(1.0, 0).expect("icosphere");
    let mut with_uv = coarsen_shapes::plane_grid(2, 2, 1.0).expect("grid");
    let uv: Vec<DVec2> = with_uv.positions.iter().map(|p| p.truncate()).collect();
    with_uv.vertex_attrs.insert("uv", AttrValues::Vec2(uv));
    // Marked edges, which OBJ writes as `l` lines and PLY as an `edge` element: each
    // face's first side (the other formats leave them out).
    with_uv.marked_edges = with_uv.faces.iter().map(|&[a, b, _]| [a, b]).collect();
    for (i, m) in [small, with_uv].iter().enumerate() {
        put(
            "read_obj",
            &format!("written{i}.obj"),
            &written(m, Format::Obj, PlyEncoding::Ascii),
        );
        put(
            "read_off",
            &format!("written{i}.off"),
            &written(m, Format::Off, PlyEncoding::Ascii),
        );
        put(
            "read_stl",
            &format!("written{i}.stl"),
            &written(m, Format::Stl, PlyEncoding::Ascii),
        );
        put(
            "read_gltf",
            &format!("written{i}.gltf"),
            &written(m, Format::Gltf, PlyEncoding::Ascii),
        );
        put(
            "read_glb",
            &format!("written{i}.glb"),
            &written(m, Format::Glb, PlyEncoding::Ascii),
        );
        for (e, enc) in [
            ("ascii", PlyEncoding::Ascii),
            ("le", PlyEncoding::BinaryLittleEndian),
            ("be", PlyEncoding::BinaryBigEndian),
        ] {
            put(
                "read_ply",
                &format!("written{i}_{e}.ply"),
                &written(m, Format::Ply, enc),
            );
        }
    }
    let texts: &[(&str, &str, &str)] = &[
        (
            "read_obj",
            "polygons.obj",
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 2 0\nf 1 2 3 4\nf -2 -1 3\n",
        ),
        (
            "read_obj",
            "corners.obj",
            "# c\no x\ng y\nv 0 0 0\nv 1 0 0 1\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n\
             usemtl m\ns off\nf 1/1/1 2/2/1 3/3/1\nf 1//1 3//1 2//1\nf 1/1 2/2 3/3\nl 1 2\n",
        ),
        (
            "read_obj",
            "lines.obj",
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1 2 3 4\nl 1 2/1 3 -1\nl -4 -2\nl 4 5\nv 2 2 0\n",
        ),
        (
            "read_off",
            "coff.off",
            "COFF\n# c\n4 2 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n0 1 0 9 9 9 255\n4 0 1 2 3\n3 0 2 1 7\n",
        ),
        (
            "read_off",
            "split.off",
            "OFF 3 1 0\n0 0 0 1 0 0\n0 1 0\n3 0 1 2\n",
        ),
        (
            "read_stl",
            "ascii.stl",
            "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n\
             facet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n",
        ),
        (
            "read_ply",
            "strips.ply",
            "ply\nformat ascii 1.0\ncomment c\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             property uchar red\nelement tristrips 1\nproperty list int int vertex_indices\nelement camera 1\nproperty float f\n\
             end_header\n0 0 0 1\n1 0 0 2\n0 1 0 3\n1 1 0 4\n5 0 1 2 -1 3\n0.5\n",
        ),
        (
            "read_ply",
            "faces.ply",
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\n\
             property float nx\nproperty float ny\nproperty float nz\nproperty float quality\n\
             element face 2\nproperty list uchar uint vertex_indices\nproperty int label\nend_header\n\
             0 0 0 0 0 1 0.5\n1 0 0 0 0 1 0.5\n1 1 0 0 0 1 0.5\n0 1 0 0 0 1 0.5\n4 0 1 2 3 7\n3 0 2 1 8\n",
        ),
        (
            "read_ply",
            "edges.ply",
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             element face 1\nproperty list uchar int vertex_indices\n\
             element edge 3\nproperty uchar red\nproperty short vertex2\nproperty uint vertex1\nend_header\n\
             0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n255 1 0\n0 2 1\n9 0 2\n",
        ),
    ];
    for (target, name, text) in texts {
        put(target, name, text.as_bytes());
    }
}

/// Pipeline-file seeds: every shipped pipeline, one with overrides, one with errors.
fn pipelines() {
    for (name, text) in coarsen_builtin::PIPELINES {
        put("pipeline_file", &format!("{name}.toml"), text.as_bytes());
    }
    let with_sets = format!(
        "{}\0simplify.qem.min_quality=0.3\0metrics.fidelity=false",
        coarsen_builtin::pipeline("demo").expect("shipped")
    );
    put("pipeline_file", "demo_sets.toml", with_sets.as_bytes());
    put(
        "pipeline_file",
        "errors.toml",
        b"[pipeline]\nname = 3\ntarget = { ratio = 1.5 }\ninputs = [\"vertex.f\"]\n\n\
          [[stage]]\nkind = \"simplify.qme\"\n\n[[stage]]\nkind = \"refine.red-green\"\nalpha = \"x\"\nbogus = 1\n",
    );
}

/// `stages` seeds: a regular 8 × 8 grid patch and a closed octahedron, for every pipeline
/// and each kind of target (layout in `fuzz_targets/stages.rs`).
fn stages() {
    let mut grid = Vec::new();
    for y in 0..7u8 {
        for x in 0..7u8 {
            let v = y * 8 + x;
            grid.extend_from_slice(&[v, v + 1, v + 9, v, v + 9, v + 8]);
        }
    }
    // Octahedron on vertices 0..6 of the grid, lifted by the height bytes.
    let octahedron: &[u8] = &[
        0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4, 1, 0, 5, 2, 1, 5, 3, 2, 5, 0, 3, 5,
    ];
    let heights_oct: &[u8] = &[0, 0, 0, 0, 0, 0, 0, 0, 64, 0, 192, 0];
    for p in 0..coarsen_builtin::PIPELINES.len() as u8 {
        for (t, value) in [(0u8, 0u16), (1, 20), (2, 40), (3, 32765)] {
            let mut grid_seed = vec![p, t];
            grid_seed.extend_from_slice(&value.to_le_bytes());
            grid_seed.extend_from_slice(&[0, 0, 0, 61]);
            grid_seed.extend((0..64u32).flat_map(|i| [((i * 37) % 11) as u8, 0]));
            grid_seed.extend_from_slice(&grid);
            put("stages", &format!("grid_p{p}_t{t}"), &grid_seed);

            let mut oct = vec![p, t];
            oct.extend_from_slice(&value.to_le_bytes());
            oct.extend_from_slice(&[1, 0, 1, 0, 0, 0, 0, 0, 0, 3]);
            oct.extend_from_slice(heights_oct);
            oct.extend_from_slice(octahedron);
            put("stages", &format!("octahedron_p{p}_t{t}"), &oct);
        }
    }
}

fn main() {
    readers();
    pipelines();
    stages();
    println!("seed corpora written to corpus/");
}
