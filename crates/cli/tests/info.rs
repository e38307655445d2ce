//! `coarsen info` on a file that marks feature edges: the count, and the clean-up's notes.

use std::path::PathBuf;
use std::process::Command;

/// `coarsen info ARGS…`'s standard output, the command having succeeded.
fn info(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_coarsen"))
        .arg("info")
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Writes `text` to a file called `name` in the tests' scratch folder.
fn file(name: &str, text: &str) -> PathBuf {
    let path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn info_counts_the_marked_edges_only_when_there_are_some() {
    // 4---3
    // | / |   marked: the rim 1-2-3 (a polyline), the diagonal 1-3, and 2-4, which is
    // 1---2   no edge of a face (dropped by the clean-up, with a note)
    let square = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";
    let marked = file("marked.obj", &format!("{square}l 1 2 3\nl 1 3\nl 2 4\n"));
    let text = info(&[marked.to_str().unwrap()]);
    assert!(
        text.contains("note: drop marked edges that are no edge of a face: 1"),
        "{text}"
    );
    assert!(
        text.contains(
            "0 sharp edges (over 40°), 2 boundary, 0 of 3+ faces, 3 marked by the input;"
        ),
        "{text}"
    );
    let json = info(&["--json", marked.to_str().unwrap()]);
    let json: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(json["features"]["counts"]["marked_edges"], 3, "{json}");
    let plain = file("plain.obj", square);
    let text = info(&[plain.to_str().unwrap()]);
    assert!(!text.contains("marked"), "{text}");
}
