//! glTF and GLB through the command: OBJ → GLB → OBJ keeps UVs and normals across seams
//! and hard edges bit for bit (at `f32`, as glTF stores them), and the written files pass the
//! Khronos glTF validator when it is installed (`npm install --prefix target/node
//! gltf-validator`, or `COARSEN_GLTF_VALIDATOR=/path/to/node_modules`).

use coarsen_mesh::{AttrValues, Attributes, DVec2, DVec3, Image, Materials, Mesh};
use coarsen_tests::{read_mesh, run_cli, shared_data, stderr, stdout};
use std::path::{Path, PathBuf};
use std::process::Command;

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

/// A cube whose six sides are UV charts of their own, with flat normals: every vertex is
/// on three seams and three hard edges.
fn charted_cube() -> Mesh {
    let p = |i: u32| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64);
    let positions = (0..8).map(p).collect();
    let sides: [[u32; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut faces = Vec::new();
    let (mut uv, mut normal) = (Vec::new(), Vec::new());
    let square = [[0.0, 0.0], [0.25, 0.0], [0.25, 0.25], [0.0, 0.25]];
    for (s, q) in sides.iter().enumerate() {
        let mesh_q: Vec<DVec3> = q.iter().map(|&i| p(i)).collect();
        let n = (mesh_q[1] - mesh_q[0])
            .cross(mesh_q[2] - mesh_q[0])
            .normalize();
        for tri in [[0, 1, 2], [0, 2, 3]] {
            faces.push(tri.map(|k| q[k]));
            for k in tri {
                uv.push(DVec2::new(
                    0.25 * s as f64 + square[k][0] * 0.5,
                    square[k][1] + 0.5,
                ));
                normal.push(n);
            }
        }
    }
    let mut cols = Attributes::default();
    cols.insert("uv", AttrValues::Vec2(uv));
    cols.insert("normal", AttrValues::Vec3(normal));
    Mesh::new(positions, faces).with_corner_attributes(cols)
}

/// Every corner's position, UV and normal as `f32` bits, as glTF stores them (`v` counted
/// from the image's top: `1 − v`).
fn corners_f32(m: &Mesh) -> Vec<[u32; 8]> {
    let uv = m.corner_column("uv");
    let normal = m.corner_column("normal");
    let (Some(AttrValues::Vec2(uv)), Some(AttrValues::Vec3(n))) = (uv, normal) else {
        panic!("the mesh has no uv or no normal");
    };
    let b = |x: f64| (x as f32).to_bits();
    m.faces
        .iter()
        .flatten()
        .zip(uv.iter().zip(&n))
        .map(|(&v, (t, n))| {
            let p = m.positions[v as usize];
            [
                b(p.x),
                b(p.y),
                b(p.z),
                b(t.x),
                b(1.0 - t.y),
                b(n.x),
                b(n.y),
                b(n.z),
            ]
        })
        .collect()
}

/// `coarsen convert FROM TO`, asserting success.
fn convert(from: &Path, to: &Path) {
    let out = run_cli(
        EXE,
        &["convert", &from.to_string_lossy(), &to.to_string_lossy()],
    );
    assert!(
        out.status.success(),
        "convert {}: {}",
        from.display(),
        stderr(&out)
    );
}

/// OBJ → GLB → OBJ → GLB → OBJ: the first OBJ written back has the input's corners at
/// `f32`, every seam kept; the second trip changes no byte.
fn round_trip(input: &Path, dir: &Path) -> PathBuf {
    let glb = dir.join("a.glb");
    let (obj1, glb2, obj2) = (dir.join("b.obj"), dir.join("c.glb"), dir.join("d.obj"));
    convert(input, &glb);
    convert(&glb, &obj1);
    let (a, b) = (read_mesh(input), read_mesh(&obj1));
    assert_eq!(b.n_faces(), a.n_faces());
    assert_eq!(corners_f32(&b), corners_f32(&a), "{}", input.display());
    assert_eq!(b.wedges.split_vertices(), a.wedges.split_vertices());
    convert(&obj1, &glb2);
    convert(&glb2, &obj2);
    let bytes = |p: &Path| std::fs::read(p).expect("written");
    assert!(
        bytes(&obj1) == bytes(&obj2),
        "the second trip changed {}",
        obj2.display()
    );
    assert!(bytes(&glb) == bytes(&glb2) || read_mesh(&glb2) == read_mesh(&glb));
    glb
}

/// The folder that holds `gltf-validator` and a working `node`, or why not.
fn validator() -> Result<PathBuf, String> {
    let dir = match std::env::var_os("COARSEN_GLTF_VALIDATOR") {
        Some(d) => PathBuf::from(d),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/node/node_modules"),
    };
    if !dir.join("gltf-validator").is_dir() {
        return Err(format!("no gltf-validator in {}", dir.display()));
    }
    match Command::new("node").arg("--version").output() {
        Ok(o) if o.status.success() => Ok(dir),
        _ => Err("no `node` command".into()),
    }
}

/// Runs the Khronos validator on `files`, asserting no errors; says so and returns when
/// the validator is not installed.
fn validate(files: &[PathBuf]) {
    let dir = match validator() {
        Ok(d) => d,
        Err(why) => {
            eprintln!(
                "glTF validation skipped: {why} (`npm install --prefix target/node gltf-validator`)"
            );
            return;
        }
    };
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/gltf-validate.js");
    let out = Command::new("node")
        .arg(script)
        .args(files)
        .env("NODE_PATH", dir)
        .output()
        .expect("node runs");
    eprint!("{}", stdout(&out));
    assert!(out.status.success(), "{}{}", stdout(&out), stderr(&out));
}

#[test]
fn a_charted_cube_round_trips_through_glb_and_validates() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cube.obj");
    let cube = charted_cube();
    assert_eq!(cube.wedges.split_vertices(), 8);
    coarsen_io::write_path(&cube, &input, &Default::default()).unwrap();
    let glb = round_trip(&input, dir.path());
    let gltf = dir.path().join("cube.gltf");
    convert(&input, &gltf);
    validate(&[glb, gltf.clone()]);
    // One mesh by name: this file's only mesh has none.
    let g = gltf.to_string_lossy();
    let out = run_cli(EXE, &["info", &g, "--gltf-mesh", "cow"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("no mesh called `cow` in the scene (meshes: #0 (unnamed))"),
        "{}",
        stderr(&out)
    );
    // A material library with a texture: the GLB embeds the image, the glTF refers to it.
    let textured = dir.path().join("textured.obj");
    let obj = std::fs::read_to_string(&input).unwrap();
    std::fs::write(&textured, format!("mtllib cube.mtl\nusemtl hide\n{obj}")).unwrap();
    let mtl = "newmtl other\nKd 1 0 0\nnewmtl hide\nKd 0.5 0.25 1\nmap_Kd -s 1 1 1 hide tex.png\n";
    std::fs::write(dir.path().join("cube.mtl"), mtl).unwrap();
    let opts = coarsen_render::RenderOptions {
        width: 32,
        height: 32,
        ..Default::default()
    };
    let png = coarsen_render::render(&[&cube], &opts)
        .unwrap()
        .to_png()
        .unwrap();
    std::fs::write(dir.path().join("hide tex.png"), &png).unwrap();
    let (tglb, tgltf) = (dir.path().join("t.glb"), dir.path().join("t.gltf"));
    convert(&textured, &tglb);
    convert(&textured, &tgltf);
    let back = read_mesh(&tglb);
    assert_eq!(back.materials.images[0].bytes.as_deref(), Some(&png[..]));
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&tgltf).unwrap()).unwrap();
    assert_eq!(doc["images"][0]["uri"], "hide%20tex.png");
    assert_eq!(doc["materials"][0]["name"], "hide");
    assert_eq!(
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"],
        serde_json::json!([0.5, 0.25, 1.0, 1.0])
    );
    validate(&[tglb, tgltf]);
    // PLY holds no per-corner values: said, not dropped silently.
    let ply = dir.path().join("cube.ply");
    let out = run_cli(
        EXE,
        &["convert", &input.to_string_lossy(), &ply.to_string_lossy()],
    );
    assert!(out.status.success());
    assert!(
        stderr(&out).contains("warning: per-corner `uv` and `normal` (8 vertices on seams"),
        "{}",
        stderr(&out)
    );
}

/// spot with flat normals (hard edges everywhere) beside its UVs, written as OBJ, and
/// the same textured (a material whose base colour is an embedded PNG, a picture of spot)
/// as GLB, in a folder of their own; `None` without `../shared/data`.
struct TexturedSpot {
    dir: tempfile::TempDir,
    /// spot with its UVs and flat normals.
    mesh: Mesh,
    /// The embedded picture.
    png: Vec<u8>,
    /// `spot.obj` in `dir`.
    obj: PathBuf,
    /// `spot-textured.glb` in `dir`.
    glb: PathBuf,
}

fn textured_spot() -> Option<TexturedSpot> {
    let Some(data) = shared_data() else {
        eprintln!("skipped: ../shared/data is absent (set COARSEN_DATA)");
        return None;
    };
    let spot = data.join("spot.obj");
    let dir = tempfile::tempdir().unwrap();
    // spot has UVs, not normals: give it flat normals (hard edges everywhere) first.
    let mut m = read_mesh(&spot);
    let uv = m.corner_column("uv").expect("spot is textured");
    assert!(m.wedges.split_vertices() > 0, "spot's UV seams");
    let normal = (0..m.n_faces())
        .flat_map(|f| [m.face_normal(f); 3])
        .collect();
    let mut cols = Attributes::default();
    cols.insert("uv", uv);
    cols.insert("normal", AttrValues::Vec3(normal));
    m = Mesh::new(m.positions, m.faces).with_corner_attributes(cols);
    let input = dir.path().join("spot.obj");
    coarsen_io::write_path(&m, &input, &Default::default()).unwrap();
    // Textured: a material whose base colour is an embedded PNG (a picture of spot).
    let opts = coarsen_render::RenderOptions {
        width: 64,
        height: 64,
        ..Default::default()
    };
    let png = coarsen_render::render(&[&m], &opts)
        .unwrap()
        .to_png()
        .unwrap();
    m.materials = Materials {
        json: serde_json::json!({
            "materials": [{"name": "spot", "pbrMetallicRoughness":
                {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}],
            "textures": [{"source": 0}],
            "images": [{"name": "spot"}],
        })
        .to_string(),
        images: vec![Image {
            bytes: Some(png.clone()),
            mime_type: Some("image/png".into()),
            ..Default::default()
        }],
    };
    let textured = dir.path().join("spot-textured.glb");
    coarsen_io::write_path(&m, &textured, &Default::default()).unwrap();
    Some(TexturedSpot {
        dir,
        mesh: m,
        png,
        obj: input,
        glb: textured,
    })
}

#[test]
fn spot_round_trips_through_glb_with_its_uvs_normals_and_texture() {
    let Some(spot) = textured_spot() else {
        return;
    };
    let glb = round_trip(&spot.obj, spot.dir.path());
    let back = read_mesh(&spot.glb);
    assert_eq!(
        back.materials.images[0].bytes.as_deref(),
        Some(&spot.png[..])
    );
    validate(&[glb, spot.glb.clone()]);
}

#[test]
fn qem_and_lod_keep_spots_uvs_seams_normals_and_texture() {
    let Some(spot) = textured_spot() else {
        return;
    };
    let (dir, m, png) = (&spot.dir, &spot.mesh, &spot.png);
    let t = spot.glb.to_string_lossy().into_owned();
    let mut written = Vec::new();
    for ratio in ["0.7", "0.95"] {
        let out_glb = dir.path().join(format!("spot-qem-{ratio}.glb"));
        let o = out_glb.to_string_lossy();
        let html = dir.path().join("report.html");
        let h = html.to_string_lossy();
        let run = run_cli(
            EXE,
            &["run", "qem", &t, "-o", &o, "--ratio", ratio, "--html", &h],
        );
        assert!(run.status.success(), "{}", stderr(&run));
        // The report shows the texture and its figures.
        let page = std::fs::read_to_string(&html).unwrap();
        assert!(page.contains("texture: input and output from four sides"));
        assert!(page.contains("texture distortion inside the faces"));
        // UVs and normals carried: nothing said about them, the texture written.
        let said = format!("{}{}", stdout(&run), stderr(&run));
        assert!(!said.contains("per-corner"), "{said}");
        assert!(
            !said.contains("textures of the materials not written"),
            "{said}"
        );
        let out = read_mesh(&out_glb);
        assert_eq!(out.materials.images[0].bytes.as_deref(), Some(&png[..]));
        assert!(out.corner_column("normal").is_some());
        // Seams kept, no face turned over in UV space, each UV within the geometric error
        // of its vertex's place, and on the whole naming it: the moved vertices settle on
        // the input where their UVs are taken, but where that would spoil a face (one at
        // 95 % here: 1.0 %). Mean at 70 % 4e-6 % (glTF's f32), unsettled 0.044 %.
        let report = coarsen_metrics::measure(Some(m), &out, &Default::default()).unwrap();
        let tex = report.texture.expect("both carry UVs");
        let hausdorff = report.fidelity.unwrap().hausdorff_pct;
        assert!(tex.seam_vertices > 40, "{ratio}: {tex:?}");
        assert_eq!(tex.uv_flipped + tex.uv_degenerate, 0, "{ratio}: {tex:?}");
        assert!(tex.distortion_max_pct <= hausdorff, "{ratio}: {tex:?}");
        assert!(tex.distortion_mean_pct < 0.01, "{ratio}: {tex:?}");
        written.push(out_glb);
    }
    // `lod`: the same, with normals recomputed for the coarse faces (unit, near their
    // faces' own on the whole: a smooth group may bend further than the crease edge by edge).
    let lod = dir.path().join("spot-lod.glb");
    let run = run_cli(
        EXE,
        &[
            "run",
            "lod",
            &t,
            "-o",
            lod.to_str().unwrap(),
            "--ratio",
            "0.9",
            "-q",
        ],
    );
    assert!(run.status.success(), "{}", stderr(&run));
    let out = read_mesh(&lod);
    let Some(AttrValues::Vec3(n)) = out.corner_column("normal") else {
        panic!("normals written");
    };
    assert!(n.iter().all(|n| (n.length() - 1.0).abs() < 1e-6));
    let agree: f64 = n
        .iter()
        .enumerate()
        .map(|(c, n)| n.dot(out.face_normal(c / 3)))
        .sum::<f64>()
        / n.len() as f64;
    assert!(agree > 0.9, "mean cosine to the face normal {agree}");
    written.push(lod);
    validate(&written);
}

#[test]
fn cvt_pipelines_lay_spots_uvs_back_on_and_render_draws_them() {
    let Some(spot) = textured_spot() else {
        return;
    };
    let (dir, m) = (&spot.dir, &spot.mesh);
    let t = spot.glb.to_string_lossy().into_owned();
    let mut written = Vec::new();
    // The CVT pipelines lay the input's UVs onto their output (the `texture` stage): seams
    // kept, no face turned over in UV space (the stage mends those it lays so), and files
    // that validate.
    for pipeline in ["adaptive-cvt", "uniform-cvt", "goal"] {
        let out_glb = dir.path().join(format!("spot-{pipeline}.glb"));
        let o = out_glb.to_string_lossy();
        let run = run_cli(
            EXE,
            &["run", pipeline, &t, "-o", &o, "--vertices", "1000", "-q"],
        );
        assert!(run.status.success(), "{}", stderr(&run));
        let said = format!("{}{}", stdout(&run), stderr(&run));
        assert!(!said.contains("per-corner"), "{said}");
        let out = read_mesh(&out_glb);
        let report = coarsen_metrics::measure(Some(m), &out, &Default::default()).unwrap();
        let tex = report.texture.expect("UVs laid on");
        assert!(tex.seam_vertices > 40, "{pipeline}: {tex:?}");
        assert_eq!(tex.uv_flipped + tex.uv_degenerate, 0, "{pipeline}: {tex:?}");
        assert!(tex.distortion_mean_pct < 0.3, "{pipeline}: {tex:?}");
        written.push(out_glb);
    }
    // `render --texture`: the embedded PNG, or a checkerboard; a mesh without UVs is refused.
    let picture = |args: &[&str]| {
        let png = dir.path().join("p.png");
        let mut all = vec!["render"];
        all.extend_from_slice(args);
        all.extend(["-o", png.to_str().unwrap(), "--size", "64x64"]);
        let out = run_cli(EXE, &all);
        (out, std::fs::read(&png).unwrap_or_default())
    };
    let last = written.last().unwrap().to_string_lossy().into_owned();
    let (plain, grey) = picture(&[&last]);
    let (textured, image) = picture(&[&last, "--texture"]);
    let (checker, squares) = picture(&[&last, "--texture", "checker"]);
    for out in [&plain, &textured, &checker] {
        assert!(out.status.success(), "{}", stderr(out));
    }
    assert!(grey != image && image != squares && grey != squares);
    let bare = dir.path().join("bare.ply");
    coarsen_io::write_path(
        &Mesh::new(m.positions.clone(), m.faces.clone()),
        &bare,
        &Default::default(),
    )
    .unwrap();
    let (refused, _) = picture(&[bare.to_str().unwrap(), "--texture", "checker"]);
    assert_eq!(refused.status.code(), Some(1));
    assert!(
        stderr(&refused).contains("no `uv` column"),
        "{}",
        stderr(&refused)
    );
    validate(&written);
}
