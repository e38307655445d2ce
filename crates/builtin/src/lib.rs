//! Coarsen's built-in stages and pipelines.
//!
//! Every built-in stage crate is named here, so a binary that depends on this crate links
//! them all and sees them in the registry. (A binary that depends on a stage crate but never
//! names it sees none of its link-time registrations — inventory issues #7 and #50.) Third-party
//! stages found at link time are added on top by [`registry`].
//!
//! Adding a built-in stage: create `crates/stage-NAME`, add it to `[workspace.dependencies]`,
//! to this crate's `Cargo.toml`, and one line to [`builtin_stages`].

use coarsen_stage::{Registry, RegistryError, StageDescriptor};

/// The descriptors of every built-in stage.
pub fn builtin_stages() -> Vec<StageDescriptor> {
    vec![
        coarsen_stage_curvature::descriptor(),
        coarsen_stage_cvt::descriptor(),
        coarsen_stage_dual::descriptor(),
        coarsen_stage_metrics::descriptor(),
        coarsen_stage_postprocess::descriptor(),
        coarsen_stage_qem::descriptor(),
        coarsen_stage_refine::descriptor(),
        coarsen_stage_relax::descriptor(),
        coarsen_stage_subdivide::descriptor(),
        coarsen_stage_svec::descriptor(),
    ]
}

/// Built-in stages plus every stage registered at link time by crates the binary links.
///
/// Fails when two different packages register the same kind.
pub fn registry() -> Result<Registry, RegistryError> {
    let mut r = Registry::from_descriptors(builtin_stages())?;
    r.add_linked()?;
    Ok(r)
}

/// The pipelines shipped with coarsen: `(name, TOML text)`, from `pipelines/*.toml`.
pub const PIPELINES: &[(&str, &str)] = &[
    (
        "adaptive-cvt",
        include_str!("../../../pipelines/adaptive-cvt.toml"),
    ),
    (
        "adaptive-cvt-r05",
        include_str!("../../../pipelines/adaptive-cvt-r05.toml"),
    ),
    (
        "curvature",
        include_str!("../../../pipelines/curvature.toml"),
    ),
    ("demo", include_str!("../../../pipelines/demo.toml")),
    ("goal", include_str!("../../../pipelines/goal.toml")),
    ("metrics", include_str!("../../../pipelines/metrics.toml")),
    ("qem", include_str!("../../../pipelines/qem.toml")),
    ("refine", include_str!("../../../pipelines/refine.toml")),
    ("svec", include_str!("../../../pipelines/svec.toml")),
    (
        "svec-then-cvt",
        include_str!("../../../pipelines/svec-then-cvt.toml"),
    ),
    (
        "uniform-cvt",
        include_str!("../../../pipelines/uniform-cvt.toml"),
    ),
];

/// The text of the shipped pipeline called `name`.
pub fn pipeline(name: &str) -> Option<&'static str> {
    PIPELINES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_stage_is_in_the_registry_once() {
        let r = registry().unwrap();
        for d in builtin_stages() {
            assert_eq!(r.get(d.kind).map(|x| x.crate_name), Some(d.crate_name));
        }
    }
}
