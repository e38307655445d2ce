//! The sharp features of the CAD-like parts (`coarsen_shapes::cad`) as `coarsen-features`
//! finds them at its default angles (an edge is sharp above 40°, a vertex of two feature
//! edges a corner above a 45° turn), against what each part has by construction.
//!
//! Every part is 2.5-D: its flat faces meet its walls at 90°, so each outline is sharp at
//! each height where a flat face meets it; arcs meet lines tangentially, so an outline turns
//! by at most one segment (0.7° at 512 a turn) except at a sharp corner of a rectangle.

use coarsen_features::{FeatureCounts, FeatureOptions, Features};
use coarsen_mesh::{DVec3, Mesh, Topology};
use coarsen_shapes::cad;

fn detect(m: &Mesh, opts: &FeatureOptions) -> Features {
    Features::detect(m, &Topology::build(m), opts)
}

/// The vertex counts of the closed curves and of the open ones, each ascending.
fn curve_lengths(f: &Features) -> (Vec<usize>, Vec<usize>) {
    let (mut closed, mut open) = (Vec::new(), Vec::new());
    for c in 0..f.n_curves() {
        let list = if f.curve_closed[c] {
            &mut closed
        } else {
            &mut open
        };
        list.push(f.curve(c).len());
    }
    closed.sort_unstable();
    open.sort_unstable();
    (closed, open)
}

/// The corners' positions, sorted.
fn corner_points(m: &Mesh, f: &Features) -> Vec<DVec3> {
    let mut p: Vec<DVec3> = f.corners.iter().map(|&v| m.positions[v as usize]).collect();
    p.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
    p
}

fn points(xyz: &[[f64; 3]]) -> Vec<DVec3> {
    xyz.iter().map(|&p| DVec3::from_array(p)).collect()
}

#[test]
fn the_plate_has_its_holes_and_slot_as_closed_curves_and_four_corners() {
    let m = cad::plate(cad::SEGMENTS).unwrap();
    let f = detect(&m, &FeatureOptions::default());
    // The outline has 260 samples a level (two sharp corners, two quarter arcs of 129),
    // each hole 512, the slot 514 (two half turns of 257; its straight sides add none):
    // every one of their edges is sharp at both levels, plus the two vertical edges at
    // x = 0, the only sharp edges across the thickness.
    assert_eq!(
        f.counts(),
        FeatureCounts {
            sharp_edges: 2 * (260 + 2 * 512 + 514) + 2,
            boundary_edges: 0,
            junction_edges: 0,
            marked_edges: 0,
            curves: 12,
            closed_curves: 6,
            corners: 4,
        }
    );
    // Corners only where the vertical edges at x = 0 meet the top and the bottom; the
    // rounded edges at x = 100 and the slot's tangent joins are none.
    assert_eq!(
        corner_points(&m, &f),
        points(&[
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 10.0],
            [0.0, 60.0, 0.0],
            [0.0, 60.0, 10.0]
        ])
    );
    let (closed, open) = curve_lengths(&f);
    // Each rim of the holes and of the slot, whole, at each level.
    assert_eq!(closed, [512, 512, 512, 512, 514, 514]);
    // The two vertical edges and the side x = 0 at each level (one edge each), and the
    // rest of each level's outline from corner to corner.
    assert_eq!(open, [2, 2, 2, 2, 260, 260]);
}

#[test]
fn the_block_has_twelve_edges_eight_corners_and_six_round_rims() {
    let m = cad::block(cad::SEGMENTS).unwrap();
    let f = detect(&m, &FeatureOptions::default());
    // The box's 12 edges; the pocket's outline (516 samples: four quarter arcs of 129) at
    // its rim and its floor; the boss's circle at its foot and its top; the hole's at the
    // bottom and at the boss's top (512 each).
    assert_eq!(
        f.counts(),
        FeatureCounts {
            sharp_edges: 12 + 2 * 516 + 2 * 512 + 2 * 512,
            boundary_edges: 0,
            junction_edges: 0,
            marked_edges: 0,
            curves: 18,
            closed_curves: 6,
            corners: 8,
        }
    );
    let mut box_corners = Vec::new();
    for x in [0.0, 80.0] {
        for y in [0.0, 80.0] {
            for z in [0.0, 30.0] {
                box_corners.push([x, y, z]);
            }
        }
    }
    assert_eq!(corner_points(&m, &f), points(&box_corners));
    let (closed, open) = curve_lengths(&f);
    assert_eq!(closed, [512, 512, 512, 512, 516, 516]);
    assert_eq!(open, [2; 12]);
}

#[test]
fn the_shaft_has_nine_closed_circles_and_no_corner() {
    let m = cad::shaft(cad::SEGMENTS).unwrap();
    let f = detect(&m, &FeatureOptions::default());
    // The two caps' rims, both rims of each of the two plain steps, the chamfer's two
    // rims (45° each) and the inner rim of the step beside it: nine circles of 512.
    assert_eq!(
        f.counts(),
        FeatureCounts {
            sharp_edges: 9 * 512,
            boundary_edges: 0,
            junction_edges: 0,
            marked_edges: 0,
            curves: 9,
            closed_curves: 9,
            corners: 0,
        }
    );
    assert_eq!(curve_lengths(&f), (vec![512; 9], vec![]));
    // Above the chamfer's 45° its two rims are no longer sharp; the 90° rims stay.
    let blunt = FeatureOptions {
        angle_deg: 50.0,
        ..FeatureOptions::default()
    };
    let f = detect(&m, &blunt);
    assert_eq!((f.counts().closed_curves, f.counts().curves), (7, 7));
    let rims: Vec<[f64; 2]> = (0..f.n_curves())
        .map(|c| {
            let p = m.positions[f.curve(c)[0] as usize];
            [p.truncate().length().round(), p.z]
        })
        .collect();
    assert!(
        !rims.contains(&[15.0, 48.0]) && !rims.contains(&[13.0, 50.0]),
        "{rims:?}"
    );
}

/// The shipped `cad` pipeline on the block at 1500 vertices (issue #52): every corner of
/// its sharp edges kept as a vertex, the edges near, well-shaped triangles and no face
/// turned over, where `uniform-cvt` as shipped loses every corner and turns faces over.
#[test]
fn the_cad_pipeline_keeps_the_blocks_corners_and_shapes_its_triangles() {
    let block = cad::block(cad::SEGMENTS).unwrap();
    let run = |pipeline: &str| {
        let (out, _) = coarsen::Remesher::new()
            .pipeline(pipeline)
            .target(coarsen::Target::Vertices(1500))
            .run(&block)
            .unwrap_or_else(|e| panic!("{pipeline}: {e}"));
        let r = coarsen_metrics::measure(Some(&block), &out, &Default::default()).unwrap();
        let f = r.features.clone().unwrap();
        (out.n_vertices(), r, f)
    };
    let (n, r, f) = run("cad");
    assert_eq!(n, 1500);
    assert_eq!((f.corners_kept, f.n_corners), (8, 8), "{f:?}");
    assert!(f.max_pct < 0.6, "{f:?}");
    assert!(r.quality.alpha_min_deg > 25.0, "{:?}", r.quality);
    assert!(r.fidelity.as_ref().unwrap().hausdorff_pct < 0.6);
    assert_eq!(r.validity.n_flipped, Some(0));
    let (_, r, f) = run("uniform-cvt");
    assert_eq!(f.corners_kept, 0, "{f:?}");
    assert!(r.validity.n_flipped.unwrap() > 0);
}
