//! Finding stages by kind: explicit registration plus link-time discovery.

use crate::{Context, Contract, FieldDoc, Params, Stage, StageError};
use coarsen_mesh::Mesh;
use serde::Deserialize;
use std::fmt;

/// A built stage, its type erased, as the runner holds it.
pub trait DynStage: Send + Sync {
    /// The stage's kind name.
    fn kind(&self) -> &'static str;
    /// The stage's declared data flow.
    fn contract(&self) -> Contract;
    /// The effective parameters (defaults filled in), for the run report.
    fn params(&self) -> toml::Table;
    /// Runs the stage.
    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError>;
    /// True when the stage hands back a progressive record ([`Stage::RECORDS_COLLAPSES`]).
    fn records_collapses(&self) -> bool {
        false
    }
}

struct Built<S: Stage> {
    stage: S,
    params: S::Params,
}

impl<S: Stage> DynStage for Built<S> {
    fn kind(&self) -> &'static str {
        S::KIND
    }
    fn contract(&self) -> Contract {
        self.stage.contract()
    }
    fn params(&self) -> toml::Table {
        toml::Table::try_from(&self.params).unwrap_or_default()
    }
    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        self.stage.run(mesh, cx)
    }
    fn records_collapses(&self) -> bool {
        S::RECORDS_COLLAPSES
    }
}

/// A problem with one key of a stage's parameter table (`key` is `None` for the table).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KeyIssue {
    /// The offending key, when one is to blame.
    pub key: Option<String>,
    /// What is wrong.
    pub message: String,
}

/// What building a stage from its parameter table gives: the stage, or every problem.
pub type BuildResult = Result<Box<dyn DynStage>, Vec<KeyIssue>>;

/// The registry record of one stage kind: constant data and function pointers.
#[derive(Clone, Copy)]
pub struct StageDescriptor {
    /// Kind name, e.g. `cluster.cvt`.
    pub kind: &'static str,
    /// One-line summary.
    pub summary: &'static str,
    /// The package that provides the stage.
    pub crate_name: &'static str,
    /// The documented parameter fields.
    pub fields: fn() -> &'static [FieldDoc],
    /// The default parameters as a TOML table.
    pub defaults: fn() -> toml::Table,
    /// The contract of the stage built with default parameters.
    pub default_contract: fn() -> Contract,
    /// Builds the stage from a parameter table, reporting every problem at once.
    pub build: fn(&toml::Table) -> BuildResult,
}

impl fmt::Debug for StageDescriptor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("StageDescriptor")
            .field("kind", &self.kind)
            .field("crate_name", &self.crate_name)
            .finish_non_exhaustive()
    }
}

impl StageDescriptor {
    /// The descriptor of stage type `S`, provided by package `crate_name`.
    pub fn of<S: Stage>(crate_name: &'static str) -> Self {
        StageDescriptor {
            kind: S::KIND,
            summary: S::SUMMARY,
            crate_name,
            fields: <S::Params as crate::params::ParamFields>::fields,
            defaults: || toml::Table::try_from(S::Params::default()).unwrap_or_default(),
            default_contract: || S::new(S::Params::default()).contract(),
            build: build::<S>,
        }
    }

    /// An example `[[stage]]` table with every parameter at its default.
    pub fn example_toml(&self) -> String {
        let mut t = toml::Table::new();
        t.insert("kind".into(), toml::Value::String(self.kind.into()));
        t.extend((self.defaults)());
        let body = toml::to_string(&t).unwrap_or_default();
        format!("[[stage]]\n{body}")
    }
}

fn build<S: Stage>(table: &toml::Table) -> BuildResult {
    let fields = <S::Params as crate::params::ParamFields>::fields();
    let mut issues = Vec::new();
    // Unknown keys, each with the nearest known one.
    for key in table.keys() {
        if !fields.iter().any(|f| f.name == key) {
            let mut message = format!("`{}` has no parameter `{key}`", S::KIND);
            if let Some(s) = closest(key, fields.iter().map(|f| f.name)) {
                message.push_str(&format!(" (did you mean `{s}`?)"));
            } else if !fields.is_empty() {
                let names: Vec<_> = fields.iter().map(|f| f.name).collect();
                message.push_str(&format!("; its parameters are {}", names.join(", ")));
            } else {
                message.push_str("; it takes no parameters");
            }
            issues.push(KeyIssue {
                key: Some(key.clone()),
                message,
            });
        }
    }
    // Mistyped values, one key at a time so that each error names its key.
    for (key, value) in table
        .iter()
        .filter(|(k, _)| fields.iter().any(|f| f.name == *k))
    {
        let mut one = toml::Table::new();
        one.insert(key.clone(), value.clone());
        if let Err(e) = S::Params::deserialize(one) {
            let msg = e
                .message()
                .lines()
                .next()
                .unwrap_or("invalid value")
                .to_string();
            issues.push(KeyIssue {
                key: Some(key.clone()),
                message: msg,
            });
        }
    }
    if !issues.is_empty() {
        return Err(issues);
    }
    let params = S::Params::deserialize(table.clone()).map_err(|e| {
        vec![KeyIssue {
            key: None,
            message: e.message().trim().to_string(),
        }]
    })?;
    let problems = params.validate();
    if !problems.is_empty() {
        return Err(problems
            .into_iter()
            .map(|p| KeyIssue {
                key: Some(p.field.to_string()),
                message: p.message,
            })
            .collect());
    }
    Ok(Box::new(Built {
        stage: S::new(params.clone()),
        params,
    }))
}

/// The name among `candidates` nearest to `name`, if one is near enough to suggest.
pub fn closest<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (strsim::jaro_winkler(name, c), c))
        .filter(|(score, _)| *score > 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(a.1)))
        .map(|(_, c)| c)
}

/// A link-time registration record (submitted by [`export_stage!`](crate::export_stage)).
pub struct Registration(pub fn() -> StageDescriptor);

inventory::collect!(Registration);

/// Why a registry could not be built or could not find a stage.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RegistryError {
    /// Two different packages register the same kind.
    #[error("stage kind `{kind}` is registered twice: by `{first}` and by `{second}`")]
    Duplicate {
        /// The kind.
        kind: &'static str,
        /// The package registered first.
        first: &'static str,
        /// The other package.
        second: &'static str,
    },
    /// No stage of that kind is registered.
    #[error("unknown stage kind `{kind}`{}; known kinds: {}", suggestion.map(|s| format!(" (did you mean `{s}`?)")).unwrap_or_default(), known.join(", "))]
    Unknown {
        /// The kind asked for.
        kind: String,
        /// The nearest known kind.
        suggestion: Option<&'static str>,
        /// Every known kind, sorted.
        known: Vec<&'static str>,
    },
}

/// Every stage kind a run can use, sorted by kind.
#[derive(Clone, Debug, Default)]
pub struct Registry {
    stages: Vec<StageDescriptor>,
}

impl Registry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }

    /// A registry of exactly these descriptors.
    pub fn from_descriptors(
        descriptors: impl IntoIterator<Item = StageDescriptor>,
    ) -> Result<Self, RegistryError> {
        let mut r = Self::new();
        for d in descriptors {
            r.add(d)?;
        }
        Ok(r)
    }

    /// Adds one stage. The same kind from the same package again is a no-op (a built-in
    /// named explicitly and also found at link time); from another package it is an error.
    pub fn add(&mut self, d: StageDescriptor) -> Result<(), RegistryError> {
        match self.stages.binary_search_by(|s| s.kind.cmp(d.kind)) {
            Ok(i) if self.stages[i].crate_name == d.crate_name => Ok(()),
            Ok(i) => Err(RegistryError::Duplicate {
                kind: d.kind,
                first: self.stages[i].crate_name,
                second: d.crate_name,
            }),
            Err(i) => {
                self.stages.insert(i, d);
                Ok(())
            }
        }
    }

    /// Adds every stage registered at link time by crates this binary links.
    pub fn add_linked(&mut self) -> Result<(), RegistryError> {
        let mut found: Vec<StageDescriptor> =
            inventory::iter::<Registration>().map(|r| (r.0)()).collect();
        // inventory's order is unspecified: sort so that errors are deterministic.
        found.sort_by(|a, b| (a.kind, a.crate_name).cmp(&(b.kind, b.crate_name)));
        found.into_iter().try_for_each(|d| self.add(d))
    }

    /// The stage of kind `kind`.
    pub fn get(&self, kind: &str) -> Option<&StageDescriptor> {
        self.stages
            .binary_search_by(|s| s.kind.cmp(kind))
            .ok()
            .map(|i| &self.stages[i])
    }

    /// The stage of kind `kind`, or an error listing the known kinds.
    pub fn lookup(&self, kind: &str) -> Result<&StageDescriptor, RegistryError> {
        self.get(kind).ok_or_else(|| RegistryError::Unknown {
            kind: kind.to_string(),
            suggestion: closest(kind, self.kinds()),
            known: self.kinds().collect(),
        })
    }

    /// Every kind, sorted.
    pub fn kinds(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.stages.iter().map(|s| s.kind)
    }

    /// Every descriptor, sorted by kind.
    pub fn iter(&self) -> impl Iterator<Item = &StageDescriptor> {
        self.stages.iter()
    }

    /// Number of kinds.
    pub fn len(&self) -> usize {
        self.stages.len()
    }

    /// True when no stage is registered.
    pub fn is_empty(&self) -> bool {
        self.stages.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ParamIssue, params};

    params! {
        /// Parameters of the test stage.
        pub struct NudgeParams {
            /// Distance moved along +x.
            pub dx: f64 = 1.0,
            /// Number of repetitions.
            pub times: u32 = 1,
        }
    }
    impl Params for NudgeParams {
        fn validate(&self) -> Vec<ParamIssue> {
            let mut v = Vec::new();
            crate::params::check_range(&mut v, "times", self.times, 1, 10);
            v
        }
    }
    struct Nudge(NudgeParams);
    impl Stage for Nudge {
        type Params = NudgeParams;
        const KIND: &'static str = "test.nudge";
        const SUMMARY: &'static str = "Moves every vertex along +x.";
        fn new(p: NudgeParams) -> Self {
            Nudge(p)
        }
        fn contract(&self) -> Contract {
            Contract::default()
        }
        fn run(&self, mut mesh: Mesh, _: &mut Context<'_>) -> Result<Mesh, StageError> {
            for _ in 0..self.0.times {
                mesh.positions.iter_mut().for_each(|p| p.x += self.0.dx);
            }
            Ok(mesh)
        }
    }
    crate::export_stage!(Nudge);

    fn table(s: &str) -> toml::Table {
        toml::from_str(s).unwrap()
    }

    #[test]
    fn build_reports_every_unknown_and_mistyped_key_at_once() {
        let d = descriptor();
        let issues = (d.build)(&table("dxx = 1\ntimes = \"two\"\nfoo = 3"))
            .err()
            .unwrap();
        let keys: Vec<_> = issues.iter().map(|i| i.key.clone().unwrap()).collect();
        assert_eq!(keys, ["dxx", "foo", "times"]);
        assert!(
            issues[0].message.contains("did you mean `dx`"),
            "{}",
            issues[0].message
        );
        assert!(
            issues[2].message.contains("invalid type"),
            "{}",
            issues[2].message
        );
    }

    #[test]
    fn build_validates_ranges_and_runs_with_defaults_filled_in() {
        let d = descriptor();
        let issues = (d.build)(&table("times = 0")).err().unwrap();
        assert_eq!(issues[0].key.as_deref(), Some("times"));
        let stage = (d.build)(&table("times = 2")).ok().unwrap();
        assert_eq!(stage.params()["dx"], toml::Value::Float(1.0));
        let original = Mesh::new(vec![coarsen_mesh::DVec3::ZERO], vec![]);
        let mut report = crate::StageReport::default();
        let out = stage
            .run(original.clone(), &mut Context::new(&original, &mut report))
            .unwrap();
        assert_eq!(out.positions[0].x, 2.0);
    }

    #[test]
    fn registry_dedups_same_crate_and_rejects_other_crates() {
        let mut r = Registry::from_descriptors([descriptor()]).unwrap();
        r.add_linked().unwrap(); // finds the same record through inventory: no error
        assert_eq!(r.len(), 1);
        let mut other = descriptor();
        other.crate_name = "someone-else";
        let e = r.add(other).unwrap_err();
        assert_eq!(
            e.to_string(),
            "stage kind `test.nudge` is registered twice: by `coarsen-stage` and by `someone-else`"
        );
    }

    #[test]
    fn unknown_kind_suggests_and_lists() {
        let r = Registry::from_descriptors([descriptor()]).unwrap();
        let e = r.lookup("test.nudg").unwrap_err().to_string();
        assert!(e.contains("did you mean `test.nudge`"), "{e}");
        assert!(e.ends_with("known kinds: test.nudge"), "{e}");
        assert!(
            descriptor()
                .example_toml()
                .contains("kind = \"test.nudge\"")
        );
    }
}
