//! The HTML report of a run: self-contained, and it opens in a real headless browser.
//! The browser part needs Chromium (`apt-get install chromium`); without it the test says
//! so and checks only the file.

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

/// The report of paper 1's pipeline on the bunny (the demo pipeline on the demo mesh when
/// the shared meshes are absent).
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
            "3000".into(),
        ]),
        None => args.push("demo".into()),
    }
    for a in [
        "-o",
        out.to_str().unwrap(),
        "--html",
        html.to_str().unwrap(),
        "--snapshots",
        snaps.to_str().unwrap(),
        "-q",
    ] {
        args.push(a.to_string());
    }
    let o = run_cli(EXE, &args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = fs::read_to_string(&html).unwrap();
    // Everything inline: no stylesheet, script or image fetched from anywhere.
    for needle in ["src=\"http", "href=\"http", "<script", "<link"] {
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
    assert!(fs::read_dir(&snaps).unwrap().count() >= 3);

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
}
