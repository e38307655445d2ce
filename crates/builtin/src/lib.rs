//! Coarsen's built-in stages and pipelines.
//!
//! Every built-in stage crate is named here, so a binary that depends on this crate links
//! them all and sees them in the registry. (A binary that depends on a stage crate but never
//! names it sees none of its link-time registrations — inventory issues #7 and #50.) Third-party
//! stages found at link time are added on top by [`registry`].
//!
//! Adding a built-in stage: create `crates/stage-NAME`, add it to `[workspace.dependencies]`,
//! to this crate's `Cargo.toml`, and one line to [`builtin_stages`].

use coarsen_stage::{Registry, StageDescriptor};

/// The descriptors of every built-in stage.
pub fn builtin_stages() -> Vec<StageDescriptor> {
    vec![
        coarsen_stage_curvature::descriptor(),
        coarsen_stage_cvt::descriptor(),
        coarsen_stage_dual::descriptor(),
        coarsen_stage_metrics::descriptor(),
        coarsen_stage_normals::descriptor(),
        coarsen_stage_postprocess::descriptor(),
        coarsen_stage_qem::descriptor(),
        coarsen_stage_refine::descriptor(),
        coarsen_stage_relax::descriptor(),
        coarsen_stage_subdivide::descriptor(),
        coarsen_stage_svec::descriptor(),
        coarsen_stage_texture::descriptor(),
    ]
}

/// Built-in stages plus every stage registered at link time by crates the binary links.
///
/// Never fails: a kind registered by two packages is kept as a conflict, which
/// [`Registry::conflicts`] lists (show them as warnings) and [`Registry::lookup`] refuses,
/// so only a pipeline that uses that kind fails.
pub fn registry() -> Registry {
    let mut r = Registry::from_descriptors(builtin_stages());
    r.add_linked();
    r
}

/// The pipelines shipped with coarsen: `(name, TOML text)`, from `pipelines/*.toml`.
///
/// They are read through `crates/builtin/pipelines`, a symbolic link to the top-level
/// `pipelines/` where they are edited, so that the package holds them: `cargo package`
/// follows the link and ships the files themselves.
pub const PIPELINES: &[(&str, &str)] = &[
    (
        "adaptive-cvt",
        include_str!("../pipelines/adaptive-cvt.toml"),
    ),
    (
        "adaptive-cvt-r05",
        include_str!("../pipelines/adaptive-cvt-r05.toml"),
    ),
    ("cad", include_str!("../pipelines/cad.toml")),
    ("curvature", include_str!("../pipelines/curvature.toml")),
    ("demo", include_str!("../pipelines/demo.toml")),
    ("goal", include_str!("../pipelines/goal.toml")),
    ("lod", include_str!("../pipelines/lod.toml")),
    ("metrics", include_str!("../pipelines/metrics.toml")),
    ("qem", include_str!("../pipelines/qem.toml")),
    ("refine", include_str!("../pipelines/refine.toml")),
    ("svec", include_str!("../pipelines/svec.toml")),
    (
        "svec-then-cvt",
        include_str!("../pipelines/svec-then-cvt.toml"),
    ),
    ("uniform-cvt", include_str!("../pipelines/uniform-cvt.toml")),
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
        let r = registry();
        assert!(r.conflicts().is_empty(), "{:?}", r.conflicts());
        for d in builtin_stages() {
            assert_eq!(r.get(d.kind).map(|x| x.crate_name), Some(d.crate_name));
        }
    }

    /// A second package registering a built-in kind spoils that kind only.
    #[test]
    fn a_kind_registered_twice_fails_only_where_it_is_used() {
        let mut r = registry();
        let mut rogue = coarsen_stage_qem::descriptor();
        rogue.crate_name = "rogue-qem";
        r.add(rogue);
        let conflicts = r.conflicts();
        assert_eq!(conflicts.len(), 1);
        assert_eq!(conflicts[0].kind, "simplify.qem");
        assert_eq!(conflicts[0].packages, ["coarsen-stage-qem", "rogue-qem"]);
        // Listed once per package, for `coarsen stages`.
        assert_eq!(r.iter().filter(|d| d.kind == "simplify.qem").count(), 2);
        let e = r.lookup("simplify.qem").unwrap_err().to_string();
        assert!(
            e.contains("by `coarsen-stage-qem` and by `rogue-qem`"),
            "{e}"
        );
        // Every other kind still works.
        for d in builtin_stages().iter().filter(|d| d.kind != "simplify.qem") {
            assert_eq!(r.lookup(d.kind).unwrap().crate_name, d.crate_name);
        }
    }
}
