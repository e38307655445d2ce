use super::*;
use coarsen_geom::SplitMix64;
use coarsen_shapes::{disk_with_holes, icosphere, plane_grid, torus};
use coarsen_stage::{DVec3, Target};

fn run(
    mesh: &Mesh,
    target: Option<Target>,
    p: CvtParams,
) -> (Result<Mesh, StageError>, StageReport) {
    let mut report = StageReport::default();
    let mut cx = Context::new(mesh, &mut report);
    cx.target = target;
    let out = ClusterCvt::new(p).run(mesh.clone(), &mut cx);
    (out, report)
}

/// Exactly `n` clusters, none empty, each connected across edges.
fn check_invariant(mesh: &Mesh, labels: &[u32], n: usize) {
    assert_eq!(labels.len(), mesh.n_faces());
    let topo = Topology::build(mesh);
    let e = Valette2004;
    let mut c = Clusterer::new(mesh, &topo, &e, None).unwrap();
    c.set_labels(labels.to_vec(), n).unwrap();
    assert_eq!(c.n_clusters(), n);
    for (i, s) in c.cluster_sums().iter().enumerate() {
        assert!(s.count >= 1.0, "cluster {i} is empty");
    }
    let connected = c.connected_clusters();
    let bad: Vec<_> = (0..n).filter(|&i| !connected[i]).collect();
    assert!(bad.is_empty(), "clusters in pieces: {bad:?}");
}

fn shapes() -> Vec<(&'static str, Mesh)> {
    vec![
        ("icosphere", icosphere(1.0, 4).unwrap()),
        ("torus", torus(2.0, 0.7, 48, 24).unwrap()),
        ("grid", plane_grid(30, 30, 1.0).unwrap()),
        ("disk with holes", disk_with_holes(3, 4, 2.0).unwrap()),
    ]
}

#[test]
fn every_clustering_has_exactly_n_connected_non_empty_clusters() {
    let mut rng = SplitMix64::new(99);
    for (name, mesh) in shapes() {
        for energy in [EnergyKind::Shu2009, EnergyKind::Valette2004] {
            for _ in 0..4 {
                let n = 1 + rng.below(mesh.n_faces() / 3);
                let p = CvtParams {
                    clusters: n as u64,
                    energy,
                    seed: rng.next_u64(),
                    ..CvtParams::default()
                };
                let (out, report) = run(&mesh, None, p);
                let out = out.unwrap_or_else(|e| panic!("{name} n={n}: {e}"));
                let labels = out.face_attrs.label(CLUSTER).unwrap();
                check_invariant(&mesh, labels, n);
                assert_eq!(report.get("clusters"), Some(&n.into()));
            }
        }
    }
}

#[test]
fn minimisation_lowers_the_energy_and_reports_each_pass() {
    let mesh = icosphere(1.0, 4).unwrap();
    let p = CvtParams {
        clusters: 100,
        energy: EnergyKind::Valette2004,
        ..CvtParams::default()
    };
    let (_, report) = run(&mesh, None, p);
    let init = report.get("initial_energy").unwrap().as_f64().unwrap();
    let per_pass: Vec<f64> =
        serde_json::from_value(report.get("energy_per_pass").unwrap().clone()).unwrap();
    let moves: Vec<u64> =
        serde_json::from_value(report.get("moves_per_pass").unwrap().clone()).unwrap();
    assert_eq!(per_pass.len(), moves.len());
    assert_eq!(report.get("passes"), Some(&per_pass.len().into()));
    assert!(
        *per_pass.last().unwrap() < 0.8 * init,
        "{init} → {per_pass:?}"
    );
    for w in per_pass.windows(2) {
        assert!(w[1] <= w[0] * (1.0 + 1e-9), "energy rose: {per_pass:?}");
    }
    assert_eq!(*moves.last().unwrap(), 0, "converged before max_passes");
}

#[test]
fn same_seed_same_labels_other_seed_other_labels() {
    let mesh = torus(2.0, 0.7, 40, 20).unwrap();
    let p = |seed| CvtParams {
        clusters: 60,
        seed,
        ..CvtParams::default()
    };
    let a = run(&mesh, None, p(5)).0.unwrap();
    let b = run(&mesh, None, p(5)).0.unwrap();
    let c = run(&mesh, None, p(6)).0.unwrap();
    assert_eq!(a, b);
    assert_ne!(a.face_attrs.label(CLUSTER), c.face_attrs.label(CLUSTER));
}

#[test]
fn cluster_count_comes_from_the_target_when_zero() {
    let mesh = icosphere(1.0, 3).unwrap();
    let stage = ClusterCvt::new(CvtParams::default());
    assert!(stage.contract().needs.target);
    let (out, _) = run(&mesh, Some(Target::Vertices(77)), CvtParams::default());
    let labels = out.unwrap().face_attrs.label(CLUSTER).unwrap().to_vec();
    check_invariant(&mesh, &labels, 77);
    let (out, _) = run(&mesh, None, CvtParams::default());
    assert!(out.unwrap_err().to_string().contains("needs a target"));
}

#[test]
fn every_component_gets_a_cluster() {
    // Two spheres side by side: 2 components.
    let a = icosphere(1.0, 2).unwrap();
    let mut m = a.clone();
    let off = a.n_vertices() as u32;
    m.positions
        .extend(a.positions.iter().map(|p| *p + DVec3::new(5.0, 0.0, 0.0)));
    m.faces.extend(a.faces.iter().map(|f| f.map(|v| v + off)));
    let p = CvtParams {
        clusters: 2,
        ..CvtParams::default()
    };
    let labels = run(&m, None, p)
        .0
        .unwrap()
        .face_attrs
        .label(CLUSTER)
        .unwrap()
        .to_vec();
    let half = a.n_faces();
    assert!(labels[..half].iter().all(|&l| l == labels[0]));
    assert!(labels[half..].iter().all(|&l| l == labels[half]));
    assert_ne!(labels[0], labels[half]);
    let p = CvtParams {
        clusters: 1,
        ..CvtParams::default()
    };
    let e = run(&m, None, p).0.unwrap_err().to_string();
    assert!(e.contains("2 connected components"), "{e}");
}

#[test]
fn bad_counts_and_parameters_are_named() {
    let mesh = icosphere(1.0, 1).unwrap();
    let p = CvtParams {
        clusters: 1000,
        ..CvtParams::default()
    };
    let e = run(&mesh, None, p).0.unwrap_err().to_string();
    assert!(
        e.contains("parameter `clusters`") && e.contains("only 80 faces"),
        "{e}"
    );
    let bad = CvtParams {
        r: -1.0,
        density: "rho".into(),
        ..CvtParams::default()
    };
    let fields: Vec<_> = bad.validate().iter().map(|i| i.field).collect();
    assert_eq!(fields, ["r", "density"]);
    assert!(CvtParams::default().validate().is_empty());
}

#[test]
fn density_is_read_only_when_named_and_must_be_positive() {
    let mut mesh = icosphere(1.0, 3).unwrap();
    let p = CvtParams {
        clusters: 40,
        energy: EnergyKind::Valette2004,
        density: "rho".into(),
        ..CvtParams::default()
    };
    let reads = ClusterCvt::new(p.clone()).contract().reads;
    assert_eq!(reads, vec![AttrRef::vertex("rho", AttrKind::Scalar)]);
    assert!(
        ClusterCvt::new(CvtParams::default())
            .contract()
            .reads
            .is_empty()
    );
    let e = run(&mesh, None, p.clone()).0.unwrap_err().to_string();
    assert!(e.contains("no vertex scalar `rho`"), "{e}");
    // Denser at +z: more, smaller clusters there.
    let rho: Vec<f64> = mesh
        .positions
        .iter()
        .map(|q| 1.0 + 20.0 * (q.z + 1.0))
        .collect();
    mesh.vertex_attrs.insert("rho", AttrValues::Scalar(rho));
    let out = run(&mesh, None, p.clone()).0.unwrap();
    let labels = out.face_attrs.label(CLUSTER).unwrap();
    check_invariant(&mesh, labels, 40);
    let mut top = std::collections::BTreeSet::new();
    let mut bottom = std::collections::BTreeSet::new();
    for (f, &l) in labels.iter().enumerate() {
        if mesh.face_centroid(f).z > 0.5 {
            top.insert(l);
        } else if mesh.face_centroid(f).z < -0.5 {
            bottom.insert(l);
        }
    }
    assert!(
        2 * top.len() > 3 * bottom.len(),
        "{} vs {}",
        top.len(),
        bottom.len()
    );
    let mut bad = mesh.clone();
    bad.vertex_attrs
        .insert("rho", AttrValues::Scalar(vec![0.0; bad.n_vertices()]));
    let e = run(&bad, None, p).0.unwrap_err().to_string();
    assert!(e.contains("density at vertex 0"), "{e}");
}

#[test]
fn example_table_builds_through_the_registry() {
    let d = descriptor();
    let mut table: toml::Table =
        toml::from_str(&d.example_toml().replace("[[stage]]\n", "")).unwrap();
    assert_eq!(table.remove("kind"), Some("cluster.cvt".into()));
    let stage = (d.build)(&table).ok().unwrap();
    assert_eq!(stage.params()["energy"].as_str(), Some("shu2009"));
}

#[test]
fn bunny_clusters_are_valid_at_5000() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/stanford-bunny.obj");
    if !path.exists() {
        println!("skipped: {} is absent", path.display());
        return;
    }
    let mesh = coarsen_io::read_path(&path, &Default::default())
        .unwrap()
        .mesh;
    let (mesh, _) = coarsen_mesh::clean(mesh, &Default::default()).unwrap();
    let p = CvtParams {
        clusters: 5000,
        energy: EnergyKind::Valette2004,
        ..CvtParams::default()
    };
    let t = std::time::Instant::now();
    let (out, report) = run(&mesh, None, p);
    let out = out.unwrap();
    println!(
        "bunny → 5000 clusters in {:?}: passes {:?}, moves {:?}",
        t.elapsed(),
        report.get("passes"),
        report.get("moves")
    );
    check_invariant(&mesh, out.face_attrs.label(CLUSTER).unwrap(), 5000);
}

#[test]
fn parts_swept_in_parallel_give_the_same_clusters_with_any_thread_count() {
    // Big enough for the parallel sweep (≥ 20K faces, ≥ 512 clusters).
    let mesh = icosphere(1.0, 6).unwrap();
    let topo = Topology::build(&mesh);
    for energy in [EnergyKind::Shu2009, EnergyKind::Valette2004] {
        let p = CvtParams {
            energy,
            r: 2.0,
            ..CvtParams::default()
        };
        let on = |threads: usize| {
            coarsen_testdata::on_threads(threads, || {
                cluster(&mesh, &topo, 1500, &p, None, |_, _, _| {}).unwrap()
            })
        };
        let one = on(1);
        let three = on(3);
        assert_eq!(one.labels, three.labels, "{energy:?}");
        assert_eq!(one.log, three.log, "{energy:?}");
        check_invariant(&mesh, &one.labels, 1500);
        let log = &one.log;
        assert!(log.moves.len() > 2, "{energy:?}: {:?}", log.moves);
        assert!(
            *log.energy.last().unwrap() < log.initial_energy,
            "{energy:?}: {log:?}"
        );
        // Every pass lowers the energy, the border phase included.
        for w in log.energy.windows(2) {
            assert!(w[1] <= w[0], "{energy:?}: {:?}", log.energy);
        }
    }
}

/// Components computed directly on the mesh's own face numbering (edges of exactly two
/// faces join them), for comparing with the clusterer's renumbered layout.
fn direct_components(mesh: &Mesh, topo: &Topology) -> Vec<u32> {
    let nbr = face_neighbors(topo, mesh.n_faces());
    let mut comp = vec![u32::MAX; mesh.n_faces()];
    let mut n = 0;
    for s in 0..mesh.n_faces() {
        if comp[s] != u32::MAX {
            continue;
        }
        comp[s] = n;
        let mut stack = vec![s as u32];
        while let Some(f) = stack.pop() {
            for g in nbr[f as usize] {
                if g != u32::MAX && comp[g as usize] == u32::MAX {
                    comp[g as usize] = n;
                    stack.push(g);
                }
            }
        }
        n += 1;
    }
    comp
}

#[test]
fn the_layout_is_invisible_in_the_public_numbering() {
    // Two shapes with shuffled faces, so that the layout differs from the mesh order.
    let a = icosphere(1.0, 3).unwrap();
    let b = torus(2.0, 0.7, 24, 12).unwrap();
    let mut m = a.clone();
    let off = a.n_vertices() as u32;
    m.positions
        .extend(b.positions.iter().map(|p| *p + DVec3::new(6.0, 0.0, 0.0)));
    m.faces.extend(b.faces.iter().map(|f| f.map(|v| v + off)));
    let mut rng = SplitMix64::new(11);
    for i in (1..m.faces.len()).rev() {
        let j = rng.below(i + 1);
        m.faces.swap(i, j);
    }
    let topo = Topology::build(&m);
    let e = Valette2004;
    let mut c = Clusterer::with_layout(&m, &topo, &e, None, true, false).unwrap();
    // Components come back in the mesh's numbering: the same partition as found directly.
    let (comp, nc) = c.components();
    assert_eq!(nc, 2);
    let direct = direct_components(&m, &topo);
    for f in 0..m.n_faces() {
        assert_eq!(comp[f] == comp[0], direct[f] == direct[0], "face {f}");
    }
    // Labels given in the mesh's numbering are kept as given, sums follow them.
    let labels: Vec<u32> = comp.clone();
    c.set_labels(labels.clone(), 2).unwrap();
    assert_eq!(c.labels(), &labels[..]);
    let count0 = labels.iter().filter(|&&l| l == 0).count() as f64;
    assert_eq!(c.cluster_sums()[0].count, count0);
    assert!(c.connected_clusters().iter().all(|&k| k));
    // Moves take and keep faces in the mesh's numbering.
    let f = labels.iter().position(|&l| l == 1).unwrap() as u32;
    assert!(!c.may_move(f, labels[f as usize]));
    c.apply_move(f, 1 - labels[f as usize]);
    assert_eq!(c.labels()[f as usize], 1 - labels[f as usize]);
    assert_eq!(
        c.cluster_sums()[labels[f as usize] as usize].count,
        if labels[f as usize] == 0 {
            count0 - 1.0
        } else {
            m.n_faces() as f64 - count0 - 1.0
        }
    );
    // Minimising from scratch gives valid clusters back in the mesh's numbering, with the
    // layout along the curve and without.
    for curve in [true, false] {
        let mut c = Clusterer::with_layout(&m, &topo, &e, None, curve, false).unwrap();
        c.seed(40, 5).unwrap();
        let log = c.minimize(50, None, |_, _, _| {});
        assert!(log.energy.last().unwrap() < &log.initial_energy);
        check_invariant(&m, c.labels(), 40);
    }
}

#[test]
fn face_data_worked_out_when_asked_clusters_as_the_table_does() {
    // Both energies, a seeded start and a few passes as the post-process runs them: the
    // same clusters, moves and energies to the bit.
    let m = torus(2.0, 0.7, 48, 24).unwrap();
    let topo = Topology::build(&m);
    let shu = Shu2009 { r: 2.0 };
    let energies: [&dyn Energy; 2] = [&Valette2004, &shu];
    for e in energies {
        let run = |derive: bool| {
            let mut c = Clusterer::with_layout(&m, &topo, e, None, false, derive).unwrap();
            assert_eq!(c.derives_face_data(), derive);
            c.seed(50, 4).unwrap();
            let sums = c.cluster_sums().to_vec();
            let log = c.minimize(12, None, |_, _, _| {});
            let moved = (0..m.n_faces() as u32)
                .find(|&t| (0..50).any(|to| c.may_move(t, to)))
                .map(|t| {
                    let to = (0..50).find(|&to| c.may_move(t, to)).unwrap();
                    c.apply_move(t, to);
                    c.total_energy()
                });
            (c.into_labels(), sums, log, moved)
        };
        let kept = run(false);
        assert!(kept.2.moves.iter().sum::<u64>() > 0 && kept.3.is_some());
        assert_eq!(run(true), kept);
    }
}

#[test]
fn a_mesh_already_along_the_curve_is_laid_out_as_it_is_and_clusters_the_same() {
    // Shuffled faces and vertices, and the same mesh renumbered along the curve (as the
    // runner renumbers large inputs).
    let mut m = torus(2.0, 0.7, 48, 24).unwrap();
    let mut rng = SplitMix64::new(3);
    for i in (1..m.faces.len()).rev() {
        let j = rng.below(i + 1);
        m.faces.swap(i, j);
    }
    let nv = m.n_vertices();
    let mut vmap: Vec<u32> = (0..nv as u32).collect();
    for i in (1..nv).rev() {
        let j = rng.below(i + 1);
        vmap.swap(i, j);
    }
    let mut positions = vec![DVec3::ZERO; nv];
    for (v, &to) in vmap.iter().enumerate() {
        positions[to as usize] = m.positions[v];
    }
    m.positions = positions;
    m.faces
        .iter_mut()
        .for_each(|f| *f = f.map(|v| vmap[v as usize]));
    let order = coarsen_mesh::order::CurveOrder::of(&m).unwrap();
    let ordered = coarsen_mesh::order::along_curve(m.clone());
    let e = Valette2004;
    let run = |mesh: &Mesh| {
        let topo = Topology::build(mesh);
        let mut c = Clusterer::with_layout(mesh, &topo, &e, None, true, false).unwrap();
        let borrowed = matches!(c.corners, std::borrow::Cow::Borrowed(_));
        c.seed(60, 9).unwrap();
        let log = c.minimize(200, None, |_, _, _| {});
        (c.into_labels(), log, borrowed)
    };
    let (shuffled, log_s, borrowed_s) = run(&m);
    let (along, log_a, borrowed_a) = run(&ordered);
    assert!(!borrowed_s && borrowed_a);
    // The same layout order, so the same sweep: the same clusters, moves and energies.
    for (i, &f) in order.faces.iter().enumerate() {
        assert_eq!(along[i], shuffled[f as usize], "face {f}");
    }
    assert_eq!(log_a, log_s);
    check_invariant(&ordered, &along, 60);
}

#[test]
fn bad_label_columns_are_errors_not_panics() {
    let mesh = icosphere(1.0, 2).unwrap();
    let topo = Topology::build(&mesh);
    let e = Valette2004;
    let mut c = Clusterer::new(&mesh, &topo, &e, None).unwrap();
    // Nothing labelled yet: nothing to minimise.
    assert_eq!(c.minimize(10, None, |_, _, _| {}), PassLog::default());
    let short = vec![0u32; mesh.n_faces() - 1];
    assert_eq!(
        c.set_labels(short, 1),
        Err(ClusterError::LabelCount {
            labels: mesh.n_faces() - 1,
            faces: mesh.n_faces()
        })
    );
    let big = vec![3u32; mesh.n_faces()];
    assert!(matches!(
        c.set_labels(big, 2),
        Err(ClusterError::BadLabel { label: 3, .. })
    ));
    // `cluster_from` falls back to fresh seeds on a column of the wrong length.
    let p = CvtParams {
        clusters: 10,
        energy: EnergyKind::Valette2004,
        ..CvtParams::default()
    };
    let r = cluster_from(
        &mesh,
        &topo,
        Start::Labels(vec![0; 5]),
        10,
        &p,
        None,
        |_, _, _| {},
    )
    .unwrap();
    check_invariant(&mesh, &r.labels, 10);
}

#[test]
fn the_curve_layout_gives_the_same_clusters_with_any_thread_count() {
    // Parallel parts (≥ 20K faces, ≥ 512 clusters) over the renumbered layout.
    let mesh = icosphere(1.0, 6).unwrap();
    let topo = Topology::build(&mesh);
    let e = Valette2004;
    let on = |threads: usize| {
        coarsen_testdata::on_threads(threads, || {
            let mut c = Clusterer::with_layout(&mesh, &topo, &e, None, true, false).unwrap();
            c.seed(1500, 1).unwrap();
            let log = c.minimize(200, None, |_, _, _| {});
            (c.into_labels(), log)
        })
    };
    let (one, log1) = on(1);
    let (three, log3) = on(3);
    assert_eq!(one, three);
    assert_eq!(log1, log3);
    assert!(log1.moves.len() > 2, "{:?}", log1.moves);
    check_invariant(&mesh, &one, 1500);
}

#[test]
fn a_cluster_in_two_pieces_is_reported_disconnected() {
    // A 30×30 grid: cluster 0 is two bands at both ends, cluster 1 the middle.
    let mesh = plane_grid(30, 30, 1.0).unwrap();
    let topo = Topology::build(&mesh);
    let e = Valette2004;
    let mut c = Clusterer::new(&mesh, &topo, &e, None).unwrap();
    let x = |f: usize| mesh.face_centroid(f).x;
    let (a, b) = (mesh.bbox().min.x, mesh.bbox().max.x);
    let third = |t: f64| a + t * (b - a);
    let labels: Vec<u32> = (0..mesh.n_faces())
        .map(|f| u32::from(x(f) > third(1.0 / 3.0) && x(f) < third(2.0 / 3.0)))
        .collect();
    c.set_labels(labels.clone(), 2).unwrap();
    assert_eq!(c.connected_clusters(), vec![false, true]);
    // Joined along one row of faces at the bottom, cluster 0 is one piece again.
    let y = |f: usize| mesh.face_centroid(f).y;
    let bottom = mesh.bbox().min.y + (mesh.bbox().max.y - mesh.bbox().min.y) / 30.0;
    let joined: Vec<u32> = (0..mesh.n_faces())
        .map(|f| u32::from(labels[f] == 1 && y(f) > bottom))
        .collect();
    c.set_labels(joined, 2).unwrap();
    assert_eq!(c.connected_clusters(), vec![true, true]);
}

#[test]
fn sleeping_faces_change_nothing() {
    // Big enough for the parallel sweep; run to the end (no tolerance) so that late
    // passes change few clusters and faces fall asleep, in the parts and on their borders.
    let mesh = icosphere(1.0, 6).unwrap();
    let topo = Topology::build(&mesh);
    let energy = Shu2009 { r: 2.0 };
    let run = |share: f64, threads: usize| {
        coarsen_testdata::on_threads(threads, || {
            let mut c = Clusterer::new(&mesh, &topo, &energy, None).unwrap();
            c.seed(1500, 7).unwrap();
            c.set_sleep_share(share);
            let log = c.minimize(300, None, |_, _, _| {});
            (c.into_labels(), log)
        })
    };
    let (awake, awake_log) = run(0.0, 1);
    assert_eq!(awake_log.slept, 0);
    assert!(awake_log.moves.len() > 20, "{:?}", awake_log.moves);
    check_invariant(&mesh, &awake, 1500);
    // By default, and from the first pass on (most sleepers woken again at once).
    for share in [engine::SLEEP_SHARE, 2.0] {
        for threads in [1, 3] {
            let (labels, log) = run(share, threads);
            assert!(log.slept > 1000, "share {share}: {} slept", log.slept);
            assert_eq!(labels, awake, "share {share}, {threads} threads");
            assert_eq!(
                log.moves, awake_log.moves,
                "share {share}, {threads} threads"
            );
            assert_eq!(
                log.energy, awake_log.energy,
                "share {share}, {threads} threads"
            );
            assert_eq!(log.refused, awake_log.refused);
        }
    }
}

#[test]
fn a_clustering_carried_through_a_uniform_split_is_taken_as_it_is() {
    let mesh = icosphere(1.0, 3).unwrap();
    let topo = Topology::build(&mesh);
    let p = CvtParams::default();
    let coarse = cluster(&mesh, &topo, 60, &p, None, |_, _, _| {}).unwrap();
    let fine = topo.uniform_split(&mesh);
    let fine_topo = Topology::build(&fine);
    // Faces 4f .. 4f + 3 are face f's children.
    let carried: Vec<u32> = (0..fine.n_faces()).map(|f| coarse.labels[f / 4]).collect();
    check_invariant(&fine, &carried, 60);
    let run = |start| cluster_from(&fine, &fine_topo, start, 60, &p, None, |_, _, _| {}).unwrap();
    let trusted = run(Start::Carried(carried.clone()));
    let checked = run(Start::Labels(carried));
    check_invariant(&fine, &trusted.labels, 60);
    assert_eq!(trusted.labels, checked.labels);
    assert_eq!(trusted.log, checked.log);
    // A warm start: far less to move than from fresh seeds.
    let fresh = run(Start::Seeds);
    assert!(
        trusted.log.moves.iter().sum::<u64>() < fresh.log.moves.iter().sum::<u64>(),
        "{:?} vs {:?}",
        trusted.log.moves,
        fresh.log.moves
    );
}

#[test]
fn components_count_only_edges_of_two_faces() {
    // One piece: the adjacency's single component is taken as it is.
    let sphere = icosphere(1.0, 2).unwrap();
    let topo = Topology::build(&sphere);
    let e = Valette2004;
    let c = Clusterer::new(&sphere, &topo, &e, None).unwrap();
    assert_eq!(c.components(), (vec![0; sphere.n_faces()], 1));
    // Two tetrahedra on one shared edge (four faces on it): one component for the
    // adjacency, two for the clustering, which never moves a face across that edge.
    let p = [
        DVec3::ZERO,
        DVec3::X,
        DVec3::Y,
        DVec3::Z,
        DVec3::new(1.0, 1.0, -1.0),
        DVec3::new(-1.0, 0.5, -1.0),
    ];
    let faces = vec![
        [0, 2, 1],
        [0, 1, 3],
        [1, 2, 3],
        [2, 0, 3],
        [0, 1, 4],
        [1, 5, 4],
        [5, 0, 4],
        [0, 5, 1],
    ];
    let m = Mesh::new(p.to_vec(), faces);
    let topo = Topology::build(&m);
    assert_eq!(topo.n_components(), 1);
    let c = Clusterer::new(&m, &topo, &e, None).unwrap();
    assert_eq!(c.components(), (vec![0, 0, 0, 0, 1, 1, 1, 1], 2));
}

/// Faces whose normal points more than 90° away from their cluster's summed area vector.
fn faces_against_their_cluster(mesh: &Mesh, labels: &[u32], n: usize) -> usize {
    let area = |f: &[u32; 3]| {
        let [a, b, c] = f.map(|v| mesh.positions[v as usize]);
        (b - a).cross(c - a)
    };
    let mut sums = vec![DVec3::ZERO; n];
    for (f, &l) in mesh.faces.iter().zip(labels) {
        sums[l as usize] += area(f);
    }
    mesh.faces
        .iter()
        .zip(labels)
        .filter(|(f, l)| area(f).dot(sums[**l as usize]) < 0.0)
        .count()
}

#[test]
fn the_fold_guard_keeps_clusters_off_the_far_side_of_a_thin_sheet() {
    // A sphere flattened to a sheet 0.04 thick, 2 across: clusters are wider than the
    // sheet is thick, so without the guard they grow round its rim onto the far side.
    let mut sheet = icosphere(1.0, 4).unwrap();
    for p in &mut sheet.positions {
        p.z *= 0.02;
    }
    let count = |fold_guard| {
        let p = CvtParams {
            clusters: 60,
            energy: EnergyKind::Valette2004,
            fold_guard,
            ..CvtParams::default()
        };
        let out = run(&sheet, None, p).0.unwrap();
        let labels = out.face_attrs.label(CLUSTER).unwrap();
        check_invariant(&sheet, labels, 60);
        faces_against_their_cluster(&sheet, labels, 60)
    };
    let (without, with) = (count(false), count(true));
    eprintln!("faces against their cluster: {without} without the guard, {with} with it");
    assert!(without > 0);
    assert!(
        with * 4 < without,
        "{with} with the guard, {without} without"
    );
}

#[test]
fn a_warm_start_on_a_big_mesh_sums_each_cluster_in_face_order() {
    // Above the size from which the sums are taken per cluster in parallel: the same
    // sums, to the bit, as one pass over the faces in order.
    use crate::energy::Derived;
    let m = torus(2.0, 0.7, 160, 80).unwrap();
    assert!(m.n_faces() >= 20_000);
    let topo = Topology::build(&m);
    let e = Valette2004;
    let mut seeded = Clusterer::new(&m, &topo, &e, None).unwrap();
    seeded.seed(300, 7).unwrap();
    let labels = seeded.into_labels();
    let (center, scale) = coarsen_mesh::order::unit_box(&m);
    let faces = Derived {
        corners: &m.faces,
        positions: &m.positions,
        center,
        scale,
    };
    let mut want = vec![Sums::default(); 300];
    for (f, &l) in labels.iter().enumerate() {
        want[l as usize] = want[l as usize].plus(faces.point(f, &e).sums());
    }
    let mut c = Clusterer::for_few_passes(&m, &topo, &e, None).unwrap();
    c.set_labels(labels, 300).unwrap();
    assert_eq!(c.cluster_sums(), &want[..]);
}

#[test]
fn fans_walked_across_edges_are_the_fan_table_s() {
    // Each pole of a sphere of 60 meridians has 60 faces: more than a walk lists.
    let mut meshes = shapes();
    meshes.push(("uv sphere", coarsen_shapes::uv_sphere(1.0, 12, 60).unwrap()));
    let (mut walked, mut gave_up, mut open) = (0, 0, 0);
    for (name, mesh) in meshes {
        let topo = Topology::build(&mesh);
        assert!(
            topo.is_manifold() && topo.is_consistently_oriented(),
            "{name}"
        );
        let nbr = engine::face_neighbors(&topo, mesh.n_faces());
        let mut buf = [0u32; engine::FAN_WALK];
        for (t, corners) in mesh.faces.iter().enumerate() {
            for (i, &v) in corners.iter().enumerate() {
                let table = topo.vertex_faces(v);
                let Some((n, closed)) = engine::walk_fan(&nbr, t as u32, i, &mut buf) else {
                    assert!(
                        table.len() > engine::FAN_WALK,
                        "{name}: face {t} corner {i}"
                    );
                    gave_up += 1;
                    continue;
                };
                walked += 1;
                assert_eq!(closed, !topo.is_boundary_vertex(v), "{name}: vertex {v}");
                // The same faces in the same cyclic order (a closed fan) or along the
                // same path (an open one), either way round.
                let got = &buf[..n];
                let same = |way: &[u32]| match closed {
                    true => (0..n).any(|r| way.iter().cycle().skip(r).take(n).eq(got)),
                    false => way == got,
                };
                let back: Vec<u32> = table.iter().rev().copied().collect();
                assert!(
                    got.len() == table.len() && (same(table) || same(&back)),
                    "{name}: face {t} corner {i}: walked {got:?}, table {table:?}"
                );
                open += usize::from(!closed);
            }
        }
    }
    assert!(
        walked > 10_000 && gave_up == 2 * 60 && open > 100,
        "{walked} {gave_up} {open}"
    );
}

#[test]
fn regions_grown_in_blocks_cover_every_face_each_region_connected() {
    // A torus laid out along the curve, cut into blocks of 500 faces; seeds in some
    // blocks only, so the faces of the others are grown into from their neighbours.
    let mesh = coarsen_mesh::order::along_curve(torus(2.0, 0.7, 96, 48).unwrap());
    let topo = Topology::build(&mesh);
    let nf = mesh.n_faces();
    let nbr = engine::face_neighbors(&topo, nf);
    for (every, block) in [(97, 500), (331, 500), (97, 4096), (2003, 1000)] {
        let seeds: Vec<u32> = (0..nf as u32)
            .filter(|f| f % every == 7 && (f / 1500) % 3 != 1)
            .collect();
        let mut labels = vec![coarsen_mesh::topology::NONE; nf];
        for (l, &f) in seeds.iter().enumerate() {
            labels[f as usize] = l as u32;
        }
        engine::grow_in_blocks(&nbr, &mut labels, seeds.clone(), block);
        assert!(labels.iter().all(|&l| (l as usize) < seeds.len()));
        for (l, &f) in seeds.iter().enumerate() {
            assert_eq!(labels[f as usize], l as u32, "seed {f} lost its region");
        }
        check_invariant(&mesh, &labels, seeds.len());
        // The same labels again (and so with any thread count: blocks are fixed).
        let mut again = vec![coarsen_mesh::topology::NONE; nf];
        for (l, &f) in seeds.iter().enumerate() {
            again[f as usize] = l as u32;
        }
        engine::grow_in_blocks(&nbr, &mut again, seeds, block);
        assert_eq!(labels, again);
    }
}
