//! `docs/stages.md` is generated from the registry: this test fails when it is stale.
//! Refresh it with `COARSEN_BLESS=1 cargo test -p coarsen-cli --test docs`.

use std::process::Command;

#[test]
fn docs_stages_md_matches_the_registry() {
    let out = Command::new(env!("CARGO_BIN_EXE_coarsen"))
        .args(["stages", "--markdown"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let body = String::from_utf8(out.stdout).unwrap();
    let text = format!(
        "# Stages\n\nEvery built-in stage kind with its parameters and defaults. Generated from the registry by \
         `coarsen stages --markdown`; do not edit by hand (refresh: \
         `COARSEN_BLESS=1 cargo test -p coarsen-cli --test docs`).\n\n{body}"
    );
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/stages.md");
    if std::env::var_os("COARSEN_BLESS").is_some() {
        std::fs::write(&path, &text).unwrap();
    }
    let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        on_disk == text,
        "docs/stages.md is stale: run COARSEN_BLESS=1 cargo test -p coarsen-cli --test docs"
    );
}
