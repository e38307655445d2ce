//! Meshes built in code (and the bunny read from `../shared/data`) for the metrics
//! benchmark and the `scale` tool.

use coarsen_mesh::{DVec3, Mesh};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Latitude–longitude sphere of radius 1: `2·segments·(rings − 1)` faces.
pub fn uv_sphere(rings: u32, segments: u32) -> Mesh {
    let mut positions = vec![DVec3::Z, -DVec3::Z];
    for r in 1..rings {
        let theta = std::f64::consts::PI * r as f64 / rings as f64;
        for s in 0..segments {
            let phi = std::f64::consts::TAU * s as f64 / segments as f64;
            positions.push(DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ));
        }
    }
    let ring = |r: u32, s: u32| 2 + (r - 1) * segments + s % segments;
    let mut faces = Vec::new();
    for s in 0..segments {
        faces.push([0, ring(1, s), ring(1, s + 1)]);
        faces.push([1, ring(rings - 1, s + 1), ring(rings - 1, s)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s),
                ring(r + 1, s + 1),
            );
            faces.push([a, c, d]);
            faces.push([a, d, b]);
        }
    }
    Mesh::new(positions, faces)
}

/// The sphere pair of the benchmark: about 70K faces (69 660) and about 10K (9 800).
pub fn spheres_70k_10k() -> (Mesh, Mesh) {
    (uv_sphere(130, 270), uv_sphere(50, 100))
}

/// The large input of the benchmark: about 4M faces (3 996 000).
pub fn sphere_4m() -> Mesh {
    uv_sphere(1000, 2000)
}

/// `../shared/data/stanford-bunny.obj` beside the workspace.
pub fn bunny_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/stanford-bunny.obj")
}

/// Only `v x y z` and `f a b c` lines: enough for the bunny. `None` when the file is
/// missing or not of that form.
pub fn read_obj(path: &Path) -> Option<Mesh> {
    let text = std::fs::read_to_string(path).ok()?;
    let (mut positions, mut faces) = (Vec::new(), Vec::new());
    for line in text.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.first() {
            Some(&"v") => {
                let mut c = [0.0; 3];
                for (k, x) in c.iter_mut().enumerate() {
                    *x = w.get(k + 1)?.parse().ok()?;
                }
                positions.push(DVec3::from_array(c));
            }
            Some(&"f") => {
                let mut i = [0u32; 3];
                for (k, x) in i.iter_mut().enumerate() {
                    let word = w.get(k + 1)?.split('/').next()?;
                    *x = word.parse::<u32>().ok()?.checked_sub(1)?;
                }
                faces.push(i);
            }
            _ => {}
        }
    }
    Some(Mesh::new(positions, faces))
}

/// A crude coarsening: vertices snapped to a grid of `cells` cells along the longest axis
/// and merged per cell (at their mean), faces that collapse dropped. The result stays
/// close to the input, as a real run's output does.
pub fn grid_clustered(mesh: &Mesh, cells: f64) -> Mesh {
    let b = mesh.bbox();
    let size = b.extent().max_element() / cells;
    let mut cell_of: HashMap<[i64; 3], u32> = HashMap::new();
    let mut sums: Vec<(DVec3, f64)> = Vec::new();
    let mut remap = vec![u32::MAX; mesh.n_vertices()];
    for f in &mesh.faces {
        for &v in f {
            if remap[v as usize] != u32::MAX {
                continue;
            }
            let p = mesh.positions[v as usize];
            let key = ((p - b.min) / size).floor().as_i64vec3().to_array();
            let id = *cell_of.entry(key).or_insert_with(|| {
                sums.push((DVec3::ZERO, 0.0));
                sums.len() as u32 - 1
            });
            sums[id as usize].0 += p;
            sums[id as usize].1 += 1.0;
            remap[v as usize] = id;
        }
    }
    let positions = sums.iter().map(|(s, n)| *s / *n).collect();
    let faces = mesh
        .faces
        .iter()
        .map(|f| f.map(|v| remap[v as usize]))
        .filter(|[a, b, c]| a != b && b != c && c != a)
        .collect();
    Mesh::new(positions, faces)
}
