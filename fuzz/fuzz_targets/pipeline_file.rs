//! Fuzz target: the pipeline-file parser must return a pipeline or diagnostics, never panic.
//!
//! Input: the TOML text of a pipeline file, then optionally a NUL byte followed by
//! `--set STAGE.PARAM=VALUE` overrides separated by NUL bytes (each parsed with
//! `parse_set`; the ones it refuses are skipped, as the CLI would refuse them first).
#![no_main]

use coarsen_pipeline::{Overrides, Pipeline, parse_set};
use coarsen_stage::Registry;
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static REGISTRY: LazyLock<Registry> = LazyLock::new(coarsen_builtin::registry);

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let mut parts = text.split('\0');
    let file = parts.next().unwrap_or_default();
    let sets = parts.filter_map(|s| parse_set(s).ok()).collect();
    let overrides = Overrides { target: None, sets };
    match Pipeline::parse(file, "fuzz.toml", &REGISTRY, &overrides) {
        // A checked pipeline names only registered stages.
        Ok(p) => assert!(p.stages.iter().all(|s| REGISTRY.get(s.kind).is_some())),
        // Every refusal says what is wrong.
        Err(diags) => assert!(!diags.0.is_empty() && diags.0.iter().all(|d| !d.message.is_empty())),
    }
});
