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
    /// What is wrong; names the key, e.g. "amount: must be in 0..=0.1, got 0.5".
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
                message: format!("{key}: {msg}"),
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
                message: p.to_string(),
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

/// Where a plug-in author learns how a third-party stage is linked into a binary.
pub const PLUGIN_DOC: &str = "docs/writing-a-stage.md";

/// A stage kind registered by more than one package.
///
/// The registry keeps every registration and reports the conflict instead of failing:
/// commands and pipelines that do not use the kind keep working, and only a pipeline that
/// uses it fails ([`Registry::lookup`] names every package).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Conflict {
    /// The kind.
    pub kind: &'static str,
    /// The packages that register it, sorted.
    pub packages: Vec<&'static str>,
}

impl Conflict {
    /// "stage kind `k` is registered twice: by `a` and by `b`".
    fn registered(&self) -> String {
        let times = match self.packages.len() {
            2 => "twice".to_string(),
            n => format!("{n} times"),
        };
        let by: Vec<String> = self.packages.iter().map(|p| format!("by `{p}`")).collect();
        let by = match by.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => by.join(""),
        };
        format!("stage kind `{}` is registered {times}: {by}", self.kind)
    }
}

impl fmt::Display for Conflict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}; a pipeline that uses it fails until only one of them is linked",
            self.registered()
        )
    }
}

/// Why the registry could not give a stage.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RegistryError {
    /// Two or more packages register the kind (see [`Conflict`]).
    #[error("{}; link only one of them into this binary", .0.registered())]
    Duplicate(Conflict),
    /// No stage of that kind is registered.
    #[error("{}", unknown_message(kind, *suggestion, known))]
    Unknown {
        /// The kind asked for.
        kind: String,
        /// The nearest known kind.
        suggestion: Option<&'static str>,
        /// Every known kind, sorted.
        known: Vec<&'static str>,
    },
}

/// A typo gets the nearest kind; a kind like no known one most often is a plug-in the
/// binary links but never names, so that case says how plug-ins are linked.
fn unknown_message(kind: &str, suggestion: Option<&str>, known: &[&str]) -> String {
    let known = known.join(", ");
    match suggestion {
        Some(s) => {
            format!("unknown stage kind `{kind}` (did you mean `{s}`?); known kinds: {known}")
        }
        None => format!(
            "unknown stage kind `{kind}`; known kinds: {known}. A third-party stage must be \
             linked into the binary and named there (`use my_stage as _;`): see {PLUGIN_DOC}"
        ),
    }
}

/// Every stage kind a run can use, sorted by kind, and the kinds registered twice.
#[derive(Clone, Debug, Default)]
pub struct Registry {
    /// One record per (kind, package), sorted by kind then package; a kind with more than
    /// one record is a [`Conflict`].
    stages: Vec<StageDescriptor>,
}

impl Registry {
    /// An empty registry.
    pub fn new() -> Self {
        Self::default()
    }

    /// A registry of exactly these descriptors (a kind given by two packages is a
    /// [`Conflict`], kept and reported by [`Registry::conflicts`]).
    pub fn from_descriptors(descriptors: impl IntoIterator<Item = StageDescriptor>) -> Self {
        let mut r = Self::new();
        for d in descriptors {
            r.add(d);
        }
        r
    }

    /// Adds one stage. The same kind from the same package again is a no-op (a built-in
    /// named explicitly and also found at link time); from another package it makes the
    /// kind a [`Conflict`]: listed, but refused by [`Registry::lookup`].
    pub fn add(&mut self, d: StageDescriptor) {
        let key = (d.kind, d.crate_name);
        if let Err(i) = self
            .stages
            .binary_search_by(|s| (s.kind, s.crate_name).cmp(&key))
        {
            self.stages.insert(i, d);
        }
    }

    /// Adds every stage registered at link time by crates this binary links.
    pub fn add_linked(&mut self) {
        for r in inventory::iter::<Registration>() {
            self.add((r.0)());
        }
    }

    /// Every record of kind `kind` (more than one for a conflict).
    fn records(&self, kind: &str) -> &[StageDescriptor] {
        let start = self.stages.partition_point(|s| s.kind < kind);
        let end = start + self.stages[start..].partition_point(|s| s.kind == kind);
        &self.stages[start..end]
    }

    /// The stage of kind `kind`; `None` when it is unknown or registered twice.
    pub fn get(&self, kind: &str) -> Option<&StageDescriptor> {
        match self.records(kind) {
            [d] => Some(d),
            _ => None,
        }
    }

    /// The stage of kind `kind`, or an error: the known kinds and how plug-ins are linked
    /// for an unknown kind, every package for a kind registered twice.
    pub fn lookup(&self, kind: &str) -> Result<&StageDescriptor, RegistryError> {
        match self.records(kind) {
            [d] => Ok(d),
            [] => Err(RegistryError::Unknown {
                kind: kind.to_string(),
                suggestion: closest(kind, self.kinds()),
                known: self.kinds().collect(),
            }),
            several => Err(RegistryError::Duplicate(Conflict {
                kind: several[0].kind,
                packages: several.iter().map(|d| d.crate_name).collect(),
            })),
        }
    }

    /// The kinds registered by more than one package, sorted; empty when all is well.
    /// Each one's `Display` is the warning to show.
    pub fn conflicts(&self) -> Vec<Conflict> {
        self.stages
            .chunk_by(|a, b| a.kind == b.kind)
            .filter(|c| c.len() > 1)
            .map(|c| Conflict {
                kind: c[0].kind,
                packages: c.iter().map(|d| d.crate_name).collect(),
            })
            .collect()
    }

    /// Every kind once, sorted.
    pub fn kinds(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.stages
            .chunk_by(|a, b| a.kind == b.kind)
            .map(|c| c[0].kind)
    }

    /// Every descriptor, sorted by kind then package: a kind in [`Registry::conflicts`]
    /// comes once per package that registers it, so that a listing shows them all.
    pub fn iter(&self) -> impl Iterator<Item = &StageDescriptor> {
        self.stages.iter()
    }

    /// Number of kinds.
    pub fn len(&self) -> usize {
        self.kinds().count()
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
    fn a_kind_from_two_packages_is_kept_as_a_conflict_that_only_lookup_refuses() {
        let mut r = Registry::from_descriptors([descriptor()]);
        r.add_linked(); // finds the same record through inventory: no conflict
        assert_eq!(r.len(), 1);
        assert!(r.conflicts().is_empty());
        let mut other = descriptor();
        other.crate_name = "someone-else";
        r.add(other);
        assert_eq!(
            r.conflicts(),
            [Conflict {
                kind: "test.nudge",
                packages: vec!["coarsen-stage", "someone-else"]
            }]
        );
        assert_eq!(
            r.conflicts()[0].to_string(),
            "stage kind `test.nudge` is registered twice: by `coarsen-stage` and by \
             `someone-else`; a pipeline that uses it fails until only one of them is linked"
        );
        // Still one kind, listed once per package; unusable by name.
        assert_eq!(r.len(), 1);
        assert_eq!(r.kinds().collect::<Vec<_>>(), ["test.nudge"]);
        assert_eq!(r.iter().count(), 2);
        assert!(r.get("test.nudge").is_none());
        assert_eq!(
            r.lookup("test.nudge").unwrap_err().to_string(),
            "stage kind `test.nudge` is registered twice: by `coarsen-stage` and by \
             `someone-else`; link only one of them into this binary"
        );
        // A third package: every one is named.
        let mut third = descriptor();
        third.crate_name = "a-third";
        r.add(third);
        assert_eq!(
            r.lookup("test.nudge").unwrap_err().to_string(),
            "stage kind `test.nudge` is registered 3 times: by `a-third`, by `coarsen-stage` \
             and by `someone-else`; link only one of them into this binary"
        );
    }

    #[test]
    fn a_mistyped_kind_gets_the_nearest_one() {
        let r = Registry::from_descriptors([descriptor()]);
        let e = r.lookup("test.nudg").unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown stage kind `test.nudg` (did you mean `test.nudge`?); known kinds: test.nudge"
        );
        assert!(
            descriptor()
                .example_toml()
                .contains("kind = \"test.nudge\"")
        );
    }

    /// Most often a plug-in the binary links but never names (`use … as _;` forgotten).
    #[test]
    fn an_unknown_kind_like_no_known_one_says_how_plugins_are_linked() {
        let r = Registry::from_descriptors([descriptor()]);
        let e = r.lookup("smooth.taubin").unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown stage kind `smooth.taubin`; known kinds: test.nudge. A third-party stage \
             must be linked into the binary and named there (`use my_stage as _;`): see \
             docs/writing-a-stage.md"
        );
    }

    #[test]
    fn every_issue_of_a_key_names_the_key() {
        let d = descriptor();
        let issues = (d.build)(&table("times = 11")).err().unwrap();
        assert_eq!(issues[0].message, "times: must be in 1..=10, got 11");
        let issues = (d.build)(&table("dx = true")).err().unwrap();
        assert!(
            issues[0].message.starts_with("dx: invalid type"),
            "{}",
            issues[0].message
        );
    }
}
