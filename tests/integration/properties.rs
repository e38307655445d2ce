//! Property tests of the coarsening pipelines: random shapes (perturbed spheres, tori, double
//! tori, open patches with holes, several components), random targets — every output is a
//! valid manifold with the exact vertex target, the input's topology, no NaN, no degenerate
//! face, and the same bytes when run again or on one thread.
//!
//! The case count is bounded for CI (`PROPTEST_CASES` raises it for a long run).

use coarsen_geom::SplitMix64;
use coarsen_mesh::sanity::{SanityOptions, sanity_check_with};
use coarsen_mesh::{DVec3, Mesh, Topology};
use coarsen_pipeline::{Overrides, Pipeline, RunOptions};
use coarsen_stage::Target;
use proptest::prelude::*;

/// The shipped coarsening pipelines that take a vertex target.
const COARSENERS: &[&str] = &["qem", "svec", "uniform-cvt", "adaptive-cvt"];

/// Shape `kind` with every vertex moved by up to `noise` times the bounding-box diagonal.
fn shape_with(kind: u8, seed: u64, noise: f64) -> Mesh {
    let mut m = match kind % 5 {
        0 => coarsen_shapes::icosphere(1.0, 3).unwrap(),
        1 => coarsen_shapes::torus(2.0, 0.6, 36, 18).unwrap(),
        2 => coarsen_shapes::double_torus(1.0, 12).unwrap(),
        3 => coarsen_shapes::disk_with_holes(2, 24, 1.0).unwrap(),
        _ => {
            // Two components: a sphere and a torus beside it.
            let a = coarsen_shapes::icosphere(0.8, 3).unwrap();
            let b = coarsen_shapes::torus(1.0, 0.3, 24, 12).unwrap();
            let n = a.n_vertices() as u32;
            let mut positions = a.positions;
            positions.extend(b.positions.iter().map(|p| *p + DVec3::new(3.0, 0.0, 0.0)));
            let mut faces = a.faces;
            faces.extend(b.faces.iter().map(|f| f.map(|v| v + n)));
            Mesh::new(positions, faces)
        }
    };
    // Deterministic perturbation, so nothing is too regular.
    let mut rng = SplitMix64::new(seed);
    let mut next = || rng.unit() - 0.5;
    let scale = m.bbox().diagonal() * noise;
    for p in &mut m.positions {
        *p += DVec3::new(next(), next(), next()) * scale;
    }
    m
}

/// Shape `kind` perturbed by 1 % of its size: rough enough that faces of the input fold
/// over their neighbours (hundreds of edges with normals more than 90° apart).
fn shape(kind: u8, seed: u64) -> Mesh {
    shape_with(kind, seed, 0.01)
}

fn run(name: &str, mesh: &Mesh, vertices: u64) -> Option<(Mesh, String)> {
    let text = coarsen_builtin::pipeline(name)?;
    let registry = coarsen_builtin::registry();
    let overrides = Overrides {
        target: Some(Target::Vertices(vertices)),
        ..Default::default()
    };
    let p = Pipeline::parse(text, name, &registry, &overrides).unwrap();
    let (out, report) = p
        .run(
            mesh.clone(),
            RunOptions {
                sanity: true,
                ..Default::default()
            },
        )
        .unwrap();
    Some((out, report.to_json()))
}

fn bytes(m: &Mesh) -> Vec<u8> {
    let mut v = Vec::new();
    coarsen_io::write_to(m, coarsen_io::Format::Ply, &mut v, &Default::default()).unwrap();
    v
}

proptest! {
    #![proptest_config(config())]

    /// On gently perturbed shapes (0.1 % of the size; at 1 % the input itself folds, and
    /// "facing away from the input" means little), no output face faces away from the
    /// input. Also on the voxel double torus, where a coarse triangle cutting one of its
    /// right-angled corners used to face away from the input face nearest its centroid
    /// (`svec` before the collapse stages' facing guard, `uniform-cvt` before the
    /// post-process's dual turned such faces round; docs/robustness.md).
    #[test]
    fn coarsening_turns_no_face_away_from_the_input(kind in 0u8..5, seed in any::<u64>(), frac in 0.08f64..0.6) {
        let input = shape_with(kind, seed, 0.001);
        let target = ((input.n_vertices() as f64 * frac) as u64).max(40);
        for name in COARSENERS {
            let Some((out, report)) = run(name, &input, target) else {
                continue;
            };
            let v = coarsen_metrics::validity(Some(&input), &out).unwrap();
            prop_assert_eq!(v.n_flipped, Some(0), "{}: {}", name, report);
        }
    }

    #[test]
    fn coarsening_keeps_validity_topology_and_the_exact_target(kind in 0u8..5, seed in any::<u64>(), frac in 0.08f64..0.6) {
        check_case(kind, seed, frac)?;
    }
}

/// Coarsens one random shape with every shipped coarsener and checks the invariants.
fn check_case(kind: u8, seed: u64, frac: f64) -> Result<(), TestCaseError> {
    let input = shape(kind, seed);
    let topo_in = Topology::build(&input).summary(&input);
    let target = ((input.n_vertices() as f64 * frac) as u64).max(40);
    for name in COARSENERS {
        let Some((out, report)) = run(name, &input, target) else {
            continue;
        };
        prop_assert!(
            sanity_check_with(&out, &SanityOptions::strict()).is_ok(),
            "{name}: {:?}",
            sanity_check_with(&out, &SanityOptions::strict())
        );
        prop_assert!(out.positions.iter().all(|p| p.is_finite()), "{name}: NaN");
        let v = coarsen_metrics::validity(Some(&input), &out).unwrap();
        prop_assert_eq!(v.n_degenerate, 0, "{}: degenerate faces", name);
        prop_assert_eq!(out.n_vertices() as u64, target, "{}: {}", name, report);
        let t = Topology::build(&out).summary(&out);
        prop_assert!(t.manifold, "{name}");
        prop_assert_eq!(t.n_components, topo_in.n_components, "{}", name);
        prop_assert_eq!(t.n_boundary_loops, topo_in.n_boundary_loops, "{}", name);
        // Components may come out in another order: compare genera as multisets.
        prop_assert_eq!(sorted(&t.genus), sorted(&topo_in.genus), "{}", name);
    }
    Ok(())
}

fn sorted(genus: &[Option<i64>]) -> Vec<Option<i64>> {
    let mut g = genus.to_vec();
    g.sort();
    g
}

/// Twelve cases from a fixed seed, so CI sees the same cases on every run; set
/// `PROPTEST_RNG_SEED` (and `PROPTEST_CASES`) to explore others.
fn config() -> ProptestConfig {
    let mut c = ProptestConfig::default();
    if matches!(c.rng_seed, proptest::test_runner::RngSeed::Random) {
        c.rng_seed = proptest::test_runner::RngSeed::Fixed(0x00C0_A125_E000_0001);
    }
    if std::env::var_os("PROPTEST_CASES").is_none() {
        c.cases = 12;
    }
    c
}

/// Found by CI: a sphere and a torus come out with their components in the other order.
#[test]
fn two_components_at_nine_percent_keep_their_genera() {
    check_case(4, 15377377452388811766, 0.0902008168611812).unwrap();
}

#[test]
fn coarsening_is_deterministic_across_runs_and_thread_counts() {
    // The torus is small; the sphere has enough faces (81,920) for the parallel sweeps of
    // the CVT clustering, and its target enough vertices (2¹¹ or more) for `relax`'s.
    let cases = [
        (shape(1, 7), 300),
        (coarsen_shapes::icosphere(1.0, 6).unwrap(), 2500),
    ];
    for (input, target) in &cases {
        for name in COARSENERS {
            if input.n_faces() > 50_000 && !name.ends_with("cvt") {
                continue;
            }
            deterministic(name, input, *target);
        }
    }
}

/// Runs `name` twice on the pool and once on one thread: the same bytes every time.
fn deterministic(name: &str, input: &Mesh, target: u64) {
    {
        let Some((a, _)) = run(name, input, target) else {
            return;
        };
        let (b, _) = run(name, input, target).unwrap();
        let (c, _) = coarsen_testdata::on_threads(1, || run(name, input, target)).unwrap();
        assert_eq!(bytes(&a), bytes(&b), "{name}: two runs differ");
        assert_eq!(
            bytes(&a),
            bytes(&c),
            "{name}: one thread differs from the pool"
        );
    }
}
