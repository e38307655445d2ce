//! The rasterizer against a golden image of a procedural mesh (supersampled 3×, the wire
//! and outline of the default), compared with a tolerance.
//! Refresh after an intended change: `COARSEN_BLESS=1 cargo test -p coarsen-render --test golden`.

use coarsen_render::{RenderOptions, View, render};

fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
        .read_info()
        .unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn shaded_wireframe_torus_matches_the_golden_image() {
    let torus = coarsen_shapes::torus(2.0, 0.7, 24, 12).unwrap();
    let opts = RenderOptions {
        width: 96,
        height: 96,
        view: View::Iso,
        smooth: true,
        wireframe: true,
        ..Default::default()
    };
    let png = render(&[&torus], &opts).unwrap().to_png().unwrap();
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/torus-iso-96.png");
    if std::env::var_os("COARSEN_BLESS").is_some() {
        std::fs::write(&path, &png).unwrap();
    }
    let golden =
        std::fs::read(&path).expect("golden image present (bless it with COARSEN_BLESS=1)");
    let (w, h, want) = decode(&golden);
    let (w2, h2, got) = decode(&png);
    assert_eq!((w, h), (w2, h2));
    let diffs: Vec<u32> = want
        .iter()
        .zip(&got)
        .map(|(a, b)| a.abs_diff(*b) as u32)
        .collect();
    let mean = diffs.iter().sum::<u32>() as f64 / diffs.len() as f64;
    let off = diffs
        .chunks(3)
        .filter(|c| c.iter().any(|&d| d > 24))
        .count();
    assert!(
        mean < 1.0 && off < 96 * 96 / 100,
        "mean difference {mean:.2}, {off} pixels off"
    );
}
