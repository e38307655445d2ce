//! The HTML report of a run: self-contained, and it opens in a real headless browser with
//! a working 3-D view (WebGL on the software rasterizer). The browser part needs Chromium
//! (`apt-get install chromium`); without it the test says so and checks only the file.

use coarsen_tests::{run_cli, stderr};
use std::fs;
use std::path::Path;
use std::process::Command;

const EXE: &str = env!("CARGO_BIN_EXE_coarsen-under-test");

fn chromium() -> Option<&'static str> {
    ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| {
            Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
}

fn headless(browser: &str, profile: &Path) -> Command {
    let mut c = Command::new(browser);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

/// The report of paper 1's pipeline on the bunny at 5000 vertices, under 5 MB (the demo
/// pipeline on the demo mesh when the shared meshes are absent); the snapshots of every
/// stage on the demo mesh.
#[test]
fn html_report_is_self_contained_and_opens_in_a_headless_browser() {
    let dir = tempfile::tempdir().unwrap();
    let html = dir.path().join("report.html");
    let snaps = dir.path().join("snaps");
    let out = dir.path().join("out.ply");
    let bunny = coarsen_tests::shared_data().map(|d| d.join("stanford-bunny.obj"));
    let mut args = vec!["run".to_string()];
    match &bunny {
        Some(b) => args.extend([
            "adaptive-cvt".into(),
            b.display().to_string(),
            "--vertices".into(),
            "5000".into(),
        ]),
        None => args.push("demo".into()),
    }
    for a in [
        "-o",
        out.to_str().unwrap(),
        "--html",
        html.to_str().unwrap(),
        "-q",
    ] {
        args.push(a.to_string());
    }
    let o = run_cli(EXE, &args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = fs::read_to_string(&html).unwrap();
    // Everything inline: no stylesheet, script or image fetched from anywhere.
    for needle in [
        "src=\"http",
        "href=\"http",
        "<script src",
        "<link",
        "import(",
    ] {
        assert!(
            !text.contains(needle),
            "the report must not load `{needle}`"
        );
    }
    assert!(
        text.matches("data:image/png;base64,").count() >= 3,
        "input, per-stage and output pictures"
    );
    assert!(
        text.contains("id=\"metrics\"") && text.contains("<svg") && text.contains("id=\"stages\"")
    );
    let demo_html = dir.path().join("demo.html");
    let o = run_cli(
        EXE,
        &[
            "run",
            "demo",
            "-o",
            out.to_str().unwrap(),
            "--html",
            demo_html.to_str().unwrap(),
            "--snapshots",
            snaps.to_str().unwrap(),
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let pictures = fs::read_dir(&snaps).unwrap().count();
    let demo_text = fs::read_to_string(&demo_html).unwrap();
    assert!(pictures >= 3 && demo_text.matches("data:image/png;base64,").count() >= pictures);
    assert!(text.contains("id=\"mesh-input\"") && text.contains("id=\"viewer\""));
    assert!(text.contains("class=\"plot\""), "the stages' plots");
    if bunny.is_some() {
        assert!(
            text.len() < 5_000_000,
            "the bunny's report is {} bytes",
            text.len()
        );
        // The clustering's 5000 clusters carried to the input's faces: nearly every one
        // holds the centroid of some input face (the bunny has 69451 faces, 14 a cluster).
        let labels = embedded_varints(&text, "clusters-input");
        assert_eq!(labels.len(), 69451);
        let distinct: std::collections::BTreeSet<u32> = labels.iter().copied().collect();
        assert!(
            distinct.len() > 4900 && distinct.iter().all(|&l| l < 5000),
            "{} distinct clusters on the input's faces",
            distinct.len()
        );
        assert_eq!(embedded_varints(&text, "clusters-output").len(), 5000);
    } else {
        assert!(
            !demo_text.contains("id=\"clusters-input\""),
            "the demo pipeline makes no clusters"
        );
    }

    let Some(browser) = chromium() else {
        eprintln!("skipped the browser check: no chromium found (apt-get install chromium)");
        return;
    };
    let url = format!("file://{}", html.display());
    let dom = headless(browser, &dir.path().join("profile1"))
        .args(["--dump-dom", &url])
        .output()
        .unwrap();
    assert!(
        dom.status.success(),
        "{}",
        String::from_utf8_lossy(&dom.stderr)
    );
    let dom = String::from_utf8_lossy(&dom.stdout);
    assert!(
        dom.contains("id=\"metrics\"") && dom.contains("Hausdorff"),
        "the browser did not build the page"
    );
    let shot = dir.path().join("shot.png");
    let s = headless(browser, &dir.path().join("profile2"))
        .args([
            &format!("--screenshot={}", shot.display()),
            "--window-size=1200,1800",
            &url,
        ])
        .output()
        .unwrap();
    assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
    let png = fs::read(&shot).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    assert!(
        png.len() > 20_000,
        "a near-empty screenshot ({} bytes)",
        png.len()
    );
    // The clusters' colouring on the bunny (regions without them).
    let colour = if bunny.is_some() {
        "clusters"
    } else {
        "regions"
    };
    viewer_draws_and_turns(browser, dir.path(), &url, colour);
}

/// The varints of the report's element `id` (base64, as the viewer reads them).
fn embedded_varints(html: &str, id: &str) -> Vec<u32> {
    use base64::Engine as _;
    let start = html
        .find(&format!("id=\"{id}\""))
        .unwrap_or_else(|| panic!("no element `{id}` in the report"));
    let body = &html[start..];
    let body = &body[body.find('>').unwrap() + 1..];
    let data = base64::engine::general_purpose::STANDARD
        .decode(&body[..body.find('<').unwrap()])
        .unwrap();
    let (mut out, mut x, mut shift) = (Vec::new(), 0u32, 0);
    for b in data {
        x |= u32::from(b & 127) << shift;
        shift += 7;
        if b & 128 == 0 {
            out.push(x);
            (x, shift) = (0, 0);
        }
    }
    out
}

/// Chromium with WebGL on SwiftShader, its console on standard error.
fn with_webgl(browser: &str, profile: &Path) -> Command {
    let mut c = Command::new(browser);
    c.args([
        "--headless",
        "--no-sandbox",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--enable-logging=stderr",
        "--v=0",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--virtual-time-budget=20000",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

/// The pixels of a PNG screenshot, rows of RGB.
fn pixels(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let rgb: Vec<u8> = match info.color_type {
        png::ColorType::Rgba => buf.chunks(4).flat_map(|p| [p[0], p[1], p[2]]).collect(),
        _ => buf[..info.buffer_size()].to_vec(),
    };
    (info.width, info.height, rgb)
}

/// The viewer loads without console errors (coloured by `colour`, overlaid), WebGL draws, and
/// a scripted turn changes a picture that is not blank.
fn viewer_draws_and_turns(browser: &str, dir: &Path, url: &str, colour: &str) {
    let dom = with_webgl(browser, &dir.join("profile3"))
        .args(["--dump-dom", &format!("{url}#colour={colour}&mode=overlay")])
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&dom.stderr);
    let console: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("CONSOLE") || l.contains("Uncaught"))
        .collect();
    assert!(console.is_empty(), "console messages: {console:#?}");
    let dom = String::from_utf8_lossy(&dom.stdout);
    assert!(
        dom.contains("WebGL: drawn"),
        "the viewer did not draw: {}",
        dom.split("id=\"viewer-status\"")
            .nth(1)
            .unwrap_or("no status")
            .chars()
            .take(200)
            .collect::<String>()
    );
    let shot = |name: &str, address: &str| {
        let path = dir.join(name);
        let s = with_webgl(browser, &dir.join(format!("profile-{name}")))
            .args([
                &format!("--screenshot={}", path.display()),
                "--window-size=1100,900",
                address,
            ])
            .output()
            .unwrap();
        assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
        pixels(&path)
    };
    let (w, h, first) = shot("view.png", url);
    let (_, _, turned) = shot("turned.png", &format!("{url}#turn=70&colour=distance"));
    // The canvas: find its rows by the viewer's background colour (247, 247, 245) and
    // count the colours inside them.
    let row_has_canvas = |img: &[u8], y: u32| {
        (0..w)
            .filter(|&x| {
                let i = ((y * w + x) * 3) as usize;
                img[i..i + 3] == [247, 247, 245]
            })
            .count()
            > 100
    };
    let rows: Vec<u32> = (0..h).filter(|&y| row_has_canvas(&first, y)).collect();
    assert!(
        rows.len() > 100,
        "no canvas found in the screenshot ({} rows)",
        rows.len()
    );
    let colours = |img: &[u8]| {
        let mut set = std::collections::BTreeSet::new();
        for &y in &rows {
            for x in 0..w {
                let i = ((y * w + x) * 3) as usize;
                set.insert([img[i], img[i + 1], img[i + 2]]);
            }
        }
        set.len()
    };
    assert!(
        colours(&first) > 50 && colours(&turned) > 50,
        "a blank view"
    );
    let differing = rows
        .iter()
        .flat_map(|&y| (0..w).map(move |x| ((y * w + x) * 3) as usize))
        .filter(|&i| first[i..i + 3] != turned[i..i + 3])
        .count();
    assert!(differing > 2000, "the turn changed {differing} pixels only");
}
