//! Timing of `simplify.qem` beside meshoptimizer's simplifier on the same inputs.
//!
//! `cargo bench -p coarsen-benches --bench qem` measures each case several times, the two
//! simplifiers in turns, and shows the median CPU time per call of the whole process, all
//! threads counted (wall time where Linux's `schedstat` is unavailable), so that other
//! processes on a busy machine do not inflate the figures:
//!
//! * the Stanford bunny (when `../shared/data` has it) with 70 % and 95 % of faces removed;
//! * a 1.3M-face icosphere down to 60 000 faces;
//! * issue #6's speed bar: the bunny subdivided 1-to-4 three times (4.4M faces) down to
//!   60 000 faces by `simplify.qem` and `simplify.svec` (with the settings of the shipped
//!   `svec` pipeline, `pipelines/svec.toml`) against meshoptimizer
//!   (`cargo bench -p coarsen-benches --bench qem -- scale` runs only this case), with
//!   the ratios by wall time beside those by CPU time (the engine's set-up runs on
//!   rayon's threads: wall time is what a user waits, CPU time what the machine spends).
//!   In each of [`SCALE_ROUNDS`] rounds meshoptimizer runs, then QEM, SVEC and
//!   meshoptimizer again; a round's ratios are taken against the mean of its two
//!   meshoptimizer times, and the figure is the median ratio over the rounds (a single
//!   run's ratio moved by a tenth from one run to the next as the machine's speed drifted).
//!
//! * the price of carrying UVs and normals (`cargo bench -p coarsen-benches --bench qem --
//!   texture` runs only this case): `simplify.qem` on the 4.4M-face bunny with procedural
//!   UVs (longitude and height, a seam where the longitude wraps) and normals, beside the
//!   same without, in rounds as the scale case (the textured run as shipped, its vertices
//!   settled on the input, and with `placement = "optimal"`; each the second of two runs
//!   in a row, see `texture_speed`). The quality of textured outputs beside
//!   meshoptimizer's `simplifyWithAttributes` is measured by `coarsen-bench texture`
//!   (docs/results.md, *Textured*).
//!
//! coarsen's time covers what a run does with the input (in the scale case, given a copy
//! made before the clock starts): the renumbering along a Morton
//! curve that the runner gives inputs of 2¹⁸ faces or more (`coarsen_pipeline::run`),
//! then the whole stage (adjacency, quadrics, collapses, compaction with attribute
//! carrying); meshoptimizer's covers `meshopt::simplify` on an `f32` copy of the
//! positions (the copy itself not timed), with no error limit. meshoptimizer collapses onto
//! existing vertices without the f64 optimal placement, so the ratio is a speed reference,
//! not a like-for-like comparison.
//!
//! Both run with glibc's default allocator settings, not the `coarsen` binary's
//! (`coarsen-malloc`): calls repeated in one process would otherwise reuse the previous
//! call's memory, which a single run does not get (meshoptimizer gains more from that:
//! with the binary's settings the QEM ratio measured 1.98 instead of 1.8).

use coarsen_mesh::Mesh;
use coarsen_pipeline::RunOptions;
use coarsen_stage::{Context, Stage, StageReport, Target};
use coarsen_stage_qem::{QemParams, SimplifyQem};
use coarsen_stage_svec::{SimplifySvec, SvecParams};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// CPU time of every thread of this process (Linux: the sum over `/proc/self/task`), so
/// that work the stages hand to rayon's threads counts too; `None` elsewhere.
fn process_cpu_time() -> Option<Duration> {
    let mut ns = 0u64;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let text = std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
        ns += text.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(Duration::from_nanos(ns))
}

/// Median time per call of `a` and of `b` over `runs` measurements taken in turns, so
/// that both see the same machine load; each measurement repeats its function for at
/// least `min` (the CPU clock ticks in milliseconds). Returns the last results.
fn time_both<A, B>(
    runs: usize,
    min: Duration,
    mut a: impl FnMut() -> A,
    mut b: impl FnMut() -> B,
) -> ((Duration, A), (Duration, B)) {
    fn clock() -> (Instant, Option<Duration>) {
        (Instant::now(), process_cpu_time())
    }
    fn since((wall, cpu): (Instant, Option<Duration>)) -> Duration {
        match (cpu, process_cpu_time()) {
            (Some(a), Some(b)) => b - a,
            _ => wall.elapsed(),
        }
    }
    /// Calls `f` `reps` times; the time per call and the last result.
    fn measure<T>(f: &mut impl FnMut() -> T, reps: u32) -> (Duration, T) {
        let start = clock();
        let mut out = std::hint::black_box(f());
        for _ in 1..reps {
            out = std::hint::black_box(f());
        }
        (since(start) / reps, out)
    }
    let reps = |once: Duration| {
        (min.as_secs_f64() / once.as_secs_f64().max(1e-6))
            .ceil()
            .clamp(1.0, 1000.0) as u32
    };
    let (ta, mut last_a) = measure(&mut a, 1);
    let (tb, mut last_b) = measure(&mut b, 1);
    let (ra, rb) = (reps(ta), reps(tb));
    let (mut times_a, mut times_b) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        let (t, out) = measure(&mut a, ra);
        times_a.push(t);
        last_a = out;
        let (t, out) = measure(&mut b, rb);
        times_b.push(t);
        last_b = out;
    }
    times_a.sort();
    times_b.sort();
    ((times_a[runs / 2], last_a), (times_b[runs / 2], last_b))
}

fn coarsen(mesh: &Mesh, target: Target) -> Mesh {
    run_stage(SimplifyQem::new(QemParams::default()), mesh.clone(), target)
}

/// Runs `stage` on `input` to `target`, prepared as a run prepares its input (renumbered
/// when large) and copied as the run keeps its original.
fn run_stage<S: Stage>(stage: S, input: Mesh, target: Target) -> Mesh {
    let input = RunOptions::default().prepare(input);
    let mut report = StageReport::default();
    let mut cx = Context::new(&input, &mut report);
    cx.target = Some(target);
    stage.run(input.clone(), &mut cx).expect("the stage runs")
}

/// Rounds of the scale case (see the module docs).
const SCALE_ROUNDS: usize = 3;

/// The median of `xs` (its upper middle for an even count).
fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

/// `f`'s result with the CPU time of the whole process while it ran (the initial ranking
/// runs on rayon's threads) and the wall time, in seconds: `(cpu, wall, result)`.
fn timed(f: impl FnOnce() -> usize) -> (f64, f64, usize) {
    let start = (Instant::now(), process_cpu_time());
    let out = f();
    let wall = start.0.elapsed();
    let cpu = match (start.1, process_cpu_time()) {
        (Some(a), Some(b)) => b - a,
        _ => wall,
    };
    (cpu.as_secs_f64(), wall.as_secs_f64(), out)
}

/// [`timed`] of `stage` on `big` to `target` (its output face count), on a copy made
/// before the clock starts, as meshoptimizer's input is (a run reads its input from a file).
fn timed_stage<S: Stage>(stage: S, big: &Mesh, target: Target) -> (f64, f64, usize) {
    let input = big.clone();
    timed(move || run_stage(stage, input, target).n_faces())
}

/// Issue #6's bar: `big` to 60 000 faces by meshoptimizer, QEM, SVEC and meshoptimizer
/// again, in rounds (see the module docs).
fn scale_case(big: &Mesh) {
    let target = Target::Faces(60_000);
    let goal = target.faces_for(big) as usize;
    let indices: Vec<u32> = big.faces.iter().flatten().copied().collect();
    let positions: Vec<[f32; 3]> = big
        .positions
        .iter()
        .map(|p| p.as_vec3().to_array())
        .collect();
    // Per round: QEM's and SVEC's ratios by CPU time, then by wall time.
    let mut ratios: [Vec<f64>; 4] = Default::default();
    let mut faces = (0, 0, 0);
    for round in 1..=SCALE_ROUNDS {
        let (before, before_wall, their_faces) =
            timed(|| meshopt_simplify(&indices, &positions, goal));
        let qem_stage = SimplifyQem::new(QemParams::default());
        let (qem, qem_wall, qem_faces) = timed_stage(qem_stage, big, target);
        let svec_stage = SimplifySvec::new(shipped_svec());
        let (svec, svec_wall, svec_faces) = timed_stage(svec_stage, big, target);
        let (after, after_wall, _) = timed(|| meshopt_simplify(&indices, &positions, goal));
        let (theirs, theirs_wall) = (0.5 * (before + after), 0.5 * (before_wall + after_wall));
        let round_ratios = [
            qem / theirs,
            svec / theirs,
            qem_wall / theirs_wall,
            svec_wall / theirs_wall,
        ];
        for (all, r) in ratios.iter_mut().zip(round_ratios) {
            all.push(r);
        }
        faces = (their_faces, qem_faces, svec_faces);
        println!(
            "round {round}: CPU time (wall): meshopt {before:.2} s ({before_wall:.2} s) and \
             {after:.2} s ({after_wall:.2} s), qem {qem:.2} s ({qem_wall:.2} s), svec {svec:.2} s \
             ({svec_wall:.2} s); ratios by CPU time qem {:.2}, svec {:.2}, by wall time qem \
             {:.2}, svec {:.2}",
            round_ratios[0], round_ratios[1], round_ratios[2], round_ratios[3]
        );
    }
    let [qem_cpu, svec_cpu, qem_wall, svec_wall] = ratios.map(median);
    println!(
        "subdivided bunny {} → 60K faces (meshopt {}, qem {}, svec {} faces): median ratio to \
         meshoptimizer over {SCALE_ROUNDS} rounds: by CPU time qem {qem_cpu:.2}, svec \
         {svec_cpu:.2}; by wall time qem {qem_wall:.2}, svec {svec_wall:.2}",
        big.n_faces(),
        faces.0,
        faces.1,
        faces.2,
    );
}

/// The parameters of `simplify.svec` in the shipped `svec` pipeline (the stage's defaults
/// where it sets none).
fn shipped_svec() -> SvecParams {
    let text = include_str!("../../builtin/pipelines/svec.toml");
    let pipeline: toml::Table = toml::from_str(text).expect("the shipped pipeline parses");
    let mut stage = pipeline["stage"].as_array().expect("stages")[0]
        .as_table()
        .expect("a stage table")
        .clone();
    assert_eq!(stage.remove("kind"), Some("simplify.svec".into()));
    stage.try_into().expect("the shipped parameters")
}

/// The bunny subdivided 1-to-4 three times (as the tables' scale section builds it).
fn subdivided(bunny: &Mesh) -> Mesh {
    let mut m = bunny.clone();
    for _ in 0..3 {
        let all = vec![true; m.n_faces()];
        m = coarsen_stage_refine::split_once(&m, &all)
            .expect("the bunny subdivides")
            .0;
    }
    m
}

/// meshoptimizer on the same triangles; returns the output face count.
fn meshopt_simplify(indices: &[u32], positions: &[[f32; 3]], faces: usize) -> usize {
    let bytes: Vec<u8> = positions
        .iter()
        .flat_map(|p| p.iter().flat_map(|c| c.to_le_bytes()))
        .collect();
    let adapter = meshopt::VertexDataAdapter::new(&bytes, 12, 0).expect("valid vertex buffer");
    meshopt::simplify(
        indices,
        &adapter,
        faces * 3,
        1.0,
        meshopt::SimplifyOptions::None,
        None,
    )
    .len()
        / 3
}

fn case(name: &str, mesh: &Mesh, target: Target, runs: usize, min: Duration) {
    let goal = target.faces_for(mesh) as usize;
    // Build the meshopt input once, outside the timing.
    let indices: Vec<u32> = mesh.faces.iter().flatten().copied().collect();
    let positions: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .map(|p| p.as_vec3().to_array())
        .collect();
    let ((ours, out), (theirs, their_faces)) = time_both(
        runs,
        min,
        || coarsen(mesh, target),
        || meshopt_simplify(&indices, &positions, goal),
    );
    println!(
        "{name:<28} {:>9} → {:>7} faces  coarsen {:>9.1} ms  meshopt {:>8.1} ms ({:>7} faces)  ratio {:>5.2}",
        mesh.n_faces(),
        out.n_faces(),
        ours.as_secs_f64() * 1e3,
        theirs.as_secs_f64() * 1e3,
        their_faces,
        ours.as_secs_f64() / theirs.as_secs_f64()
    );
}

/// `mesh` with procedural texture coordinates per corner: longitude and height around its
/// centroid's vertical axis, a seam where the longitude wraps (and wherever a face
/// straddles the axis), and its area-weighted vertex normals.
fn charted(mesh: &Mesh) -> Mesh {
    use coarsen_mesh::{AttrValues, Attributes, DVec2, DVec3};
    let centre = mesh.positions.iter().sum::<DVec3>() / mesh.n_vertices() as f64;
    let (lo, hi) = mesh
        .positions
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    let tau = std::f64::consts::TAU;
    let lon = |p: DVec3| ((p.z - centre.z).atan2(p.x - centre.x) / tau).rem_euclid(1.0);
    let mut uv = Vec::with_capacity(3 * mesh.n_faces());
    for face in &mesh.faces {
        let ps = face.map(|v| mesh.positions[v as usize]);
        let mut u = ps.map(lon);
        let (min, max) = (
            u.iter().copied().fold(1.0, f64::min),
            u.iter().copied().fold(0.0, f64::max),
        );
        if max - min > 0.5 {
            u.iter_mut().filter(|x| **x < 0.5).for_each(|x| *x += 1.0);
        }
        for k in 0..3 {
            uv.push(DVec2::new(u[k], (ps[k].y - lo) / (hi - lo)));
        }
    }
    let mut normal = vec![DVec3::ZERO; mesh.n_vertices()];
    for face in &mesh.faces {
        let [a, b, c] = face.map(|v| mesh.positions[v as usize]);
        let n = (b - a).cross(c - a);
        for &v in face {
            normal[v as usize] += n;
        }
    }
    let corner_normals = mesh
        .faces
        .iter()
        .flatten()
        .map(|&v| normal[v as usize].normalize_or_zero())
        .collect();
    let mut cols = Attributes::default();
    cols.insert("uv", AttrValues::Vec2(uv));
    cols.insert("normal", AttrValues::Vec3(corner_normals));
    let mut m = Mesh::new(mesh.positions.clone(), mesh.faces.clone());
    m.wedges = coarsen_mesh::Wedges::from_corners(&m.faces, cols);
    m
}

/// QEM with UVs and normals beside QEM without, on `big` to 60 000 faces, in rounds (the
/// plain run before and after; the figures are the median ratios of the textured runs to
/// their mean, by CPU and by wall time): as shipped (its vertices settled on the input,
/// `placement = "auto"`) and with the vertices left where the quadric puts them
/// (`placement = "optimal"`).
fn texture_speed(big: &Mesh) {
    let target = Target::Faces(60_000);
    let textured = charted(big);
    // Per round: shipped and optimal, by CPU time then wall time.
    let mut ratios: [Vec<f64>; 4] = Default::default();
    // Each case runs twice in a row and the second run is timed: with glibc's dynamic
    // thresholds for handing big blocks back to the system, a run that follows a smaller
    // one pays for fresh pages that one following its own kind does not (measured: 0.8 s
    // of 8 s, whichever of the two textured cases came first).
    let twice = |placement: &str, mesh: &Mesh| {
        let qem = || {
            SimplifyQem::new(QemParams {
                placement: placement.into(),
                ..QemParams::default()
            })
        };
        timed_stage(qem(), mesh, target);
        timed_stage(qem(), mesh, target)
    };
    for round in 1..=SCALE_ROUNDS {
        let (before, before_wall, _) = twice("auto", big);
        let (with, with_wall, faces) = twice("auto", &textured);
        let (optimal, optimal_wall, _) = twice("optimal", &textured);
        let (after, after_wall, _) = twice("auto", big);
        let (plain, plain_wall) = (0.5 * (before + after), 0.5 * (before_wall + after_wall));
        let r = [
            with / plain,
            optimal / plain,
            with_wall / plain_wall,
            optimal_wall / plain_wall,
        ];
        println!(
            "round {round}: CPU time (wall): plain {before:.2} s ({before_wall:.2} s) and \
             {after:.2} s ({after_wall:.2} s), with UVs and normals {with:.2} s ({with_wall:.2} \
             s, {faces} faces), the same unsettled {optimal:.2} s ({optimal_wall:.2} s); \
             ratios {:.2} and {:.2} by CPU time, {:.2} and {:.2} by wall time",
            r[0], r[1], r[2], r[3]
        );
        for (all, r) in ratios.iter_mut().zip(r) {
            all.push(r);
        }
    }
    let [cpu, cpu_optimal, wall, wall_optimal] = ratios.map(median);
    println!(
        "subdivided bunny {} → 60K faces, {} seam vertices: QEM with UVs and normals against \
         QEM without, median over {SCALE_ROUNDS} rounds: {cpu:.2} by CPU time, {wall:.2} by \
         wall time; unsettled (placement = \"optimal\") {cpu_optimal:.2} and {wall_optimal:.2}",
        big.n_faces(),
        textured.wedges.split_vertices()
    );
}

fn main() {
    // `cargo bench` passes `--bench`; `cargo test --benches` does not: then run one quick case.
    let quick = !std::env::args().any(|a| a == "--bench");
    let only_scale = std::env::args().any(|a| a == "scale");
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if std::env::args().any(|a| a == "texture") {
        let bunny = data.join("stanford-bunny.obj");
        if bunny.exists() && !quick {
            let mesh = coarsen_io::read_path(&bunny, &Default::default())
                .expect("the bunny loads")
                .mesh;
            texture_speed(&subdivided(&mesh));
        }
        return;
    }
    let bunny = data.join("stanford-bunny.obj");
    if bunny.exists() {
        let mesh = coarsen_io::read_path(&bunny, &Default::default())
            .expect("the bunny loads")
            .mesh;
        if only_scale {
            scale_case(&subdivided(&mesh));
            return;
        }
        if quick {
            case(
                "bunny, 70 % removed",
                &mesh,
                Target::Ratio(0.7),
                1,
                Duration::ZERO,
            );
            return;
        }
        let min = Duration::from_millis(250);
        case("bunny, 70 % removed", &mesh, Target::Ratio(0.7), 5, min);
        case("bunny, 95 % removed", &mesh, Target::Ratio(0.95), 5, min);
    } else {
        println!("bunny skipped: {} is absent", bunny.display());
    }
    if !quick {
        let sphere = coarsen_shapes::icosphere(1.0, 8).expect("icosphere");
        let min = Duration::from_millis(250);
        case(
            "icosphere (8 splits) → 60K",
            &sphere,
            Target::Faces(60_000),
            3,
            min,
        );
        if bunny.exists() {
            let mesh = coarsen_io::read_path(&bunny, &Default::default())
                .expect("the bunny loads")
                .mesh;
            scale_case(&subdivided(&mesh));
        }
    }
}
