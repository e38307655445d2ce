//! Parsing a pipeline file and its command-line overrides into checked, built stages.

use crate::{Diagnostic, Diagnostics, check};
use coarsen_stage::{AttrRef, DynStage, Registry, Target};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::ops::Range;
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    pipeline: Option<Spanned<RawHeader>>,
    #[serde(default)]
    stage: Vec<Spanned<RawStage>>,
}

type RawStage = BTreeMap<Spanned<String>, Spanned<toml::Value>>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHeader {
    name: Option<String>,
    description: Option<String>,
    target: Option<Target>,
    #[serde(default)]
    inputs: Vec<AttrRef>,
}

/// A `--set SELECTOR.KEY=VALUE` override: SELECTOR is a stage `id` or a stage kind.
#[derive(Clone, Debug, PartialEq)]
pub struct SetOverride {
    /// The stage id or kind.
    pub selector: String,
    /// The parameter.
    pub key: String,
    /// The value, parsed as TOML (a bare word is taken as a string).
    pub value: toml::Value,
    /// The option as given, for messages.
    pub raw: String,
}

/// Parses `cluster.cvt.r=0.5` (the key is the part after the last dot).
pub fn parse_set(raw: &str) -> Result<SetOverride, String> {
    let (path, value) = raw
        .split_once('=')
        .ok_or_else(|| format!("--set {raw}: expected STAGE.PARAM=VALUE"))?;
    let (selector, key) = path.trim().rsplit_once('.').ok_or_else(|| {
        format!("--set {raw}: expected STAGE.PARAM=VALUE (no `.` before the parameter)")
    })?;
    if selector.is_empty() || key.is_empty() {
        return Err(format!("--set {raw}: expected STAGE.PARAM=VALUE"));
    }
    let value = value.trim();
    let parsed = toml::from_str::<toml::Table>(&format!("v = {value}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    Ok(SetOverride {
        selector: selector.to_string(),
        key: key.to_string(),
        value: parsed,
        raw: raw.to_string(),
    })
}

/// What the command line changes in a pipeline file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides {
    /// Replaces the file's target.
    pub target: Option<Target>,
    /// Parameter overrides, applied in order.
    pub sets: Vec<SetOverride>,
}

/// One built stage of a pipeline.
pub struct PipelineStage {
    /// The stage's kind.
    pub kind: &'static str,
    /// The optional `id` the file gave it.
    pub id: Option<String>,
    /// The built stage.
    pub stage: Box<dyn DynStage>,
    /// Where its table starts (`file:line:column`).
    pub origin: String,
}

/// A checked pipeline, ready to run.
pub struct Pipeline {
    /// Name (the header's, else the file stem).
    pub name: String,
    /// One-paragraph description.
    pub description: String,
    /// The run target, after overrides.
    pub target: Option<Target>,
    /// Attributes the input file is declared to carry.
    pub inputs: Vec<AttrRef>,
    /// The stages, in order.
    pub stages: Vec<PipelineStage>,
}

struct Locator<'a> {
    file: &'a str,
    line_starts: Vec<usize>,
}

impl<'a> Locator<'a> {
    fn new(file: &'a str, text: &str) -> Self {
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Locator { file, line_starts }
    }

    fn at(&self, span: Option<Range<usize>>) -> String {
        match span {
            Some(span) => {
                let line = self.line_starts.partition_point(|&s| s <= span.start);
                let col = span.start - self.line_starts[line - 1] + 1;
                format!("{}:{line}:{col}", self.file)
            }
            None => self.file.to_string(),
        }
    }
}

/// What the `[pipeline]` header gives (with the defaults and the command line's target).
struct Header {
    name: String,
    description: String,
    target: Option<Target>,
    inputs: Vec<AttrRef>,
}

/// One parse of a pipeline file: what it reads besides the file, and the problems found.
struct Parser<'a> {
    loc: &'a Locator<'a>,
    registry: &'a Registry,
    overrides: &'a Overrides,
    /// The ids the file's stages give.
    ids: Vec<String>,
    /// Per `--set`: whether some stage took it.
    set_used: Vec<bool>,
    diags: Vec<Diagnostic>,
}

impl Parser<'_> {
    /// The header's fields, defaulted (the name from `file`'s stem), the target the
    /// command line's if it gives one, checked.
    fn header(&mut self, raw: Option<Spanned<RawHeader>>, file: &str) -> Header {
        let (header, header_span) = match raw {
            Some(h) => {
                let span = h.span();
                (Some(h.into_inner()), Some(span))
            }
            None => (None, None),
        };
        let stem = std::path::Path::new(file)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let name = header.as_ref().and_then(|h| h.name.clone()).unwrap_or(stem);
        let description = header
            .as_ref()
            .and_then(|h| h.description.clone())
            .unwrap_or_default();
        let inputs = header
            .as_ref()
            .map(|h| h.inputs.clone())
            .unwrap_or_default();
        let overridden = self.overrides.target;
        let target = overridden.or(header.as_ref().and_then(|h| h.target));
        if let Some(t) = target
            && let Err(message) = t.check()
        {
            let origin = match overridden {
                Some(_) => "command line".into(),
                None => self.loc.at(header_span),
            };
            self.diags.push(Diagnostic { origin, message });
        }
        Header {
            name,
            description,
            target,
            inputs,
        }
    }

    /// One `[[stage]]` table built by its kind's descriptor, the command line's `--set`
    /// values applied; `None` (with the problems noted) when it cannot be.
    fn stage(&mut self, raw_stage: Spanned<RawStage>) -> Option<PipelineStage> {
        let loc = self.loc;
        let stage_span = raw_stage.span();
        let mut table = raw_stage.into_inner();
        let origin = loc.at(Some(stage_span.clone()));
        let kind_value = take(&mut table, "kind");
        let id_value = take(&mut table, "id");
        let Some((kind_span, kind_value)) = kind_value else {
            self.diags.push(Diagnostic {
                origin,
                message: "[[stage]] has no `kind`".into(),
            });
            return None;
        };
        let Some(kind) = kind_value.as_str() else {
            self.diags.push(Diagnostic {
                origin: loc.at(Some(kind_span)),
                message: "`kind` must be a string".into(),
            });
            return None;
        };
        let id = match id_value {
            Some((_, toml::Value::String(s))) => Some(s),
            Some((span, _)) => {
                self.diags.push(Diagnostic {
                    origin: loc.at(Some(span)),
                    message: "`id` must be a string".into(),
                });
                None
            }
            None => None,
        };
        let descriptor = match self.registry.lookup(kind) {
            Ok(d) => d,
            Err(e) => {
                self.diags.push(Diagnostic {
                    origin: loc.at(Some(kind_span)),
                    message: e.to_string(),
                });
                return None;
            }
        };
        let mut spans: BTreeMap<String, Range<usize>> = BTreeMap::new();
        let mut params = toml::Table::new();
        for (k, v) in table {
            spans.insert(k.get_ref().clone(), k.span());
            params.insert(k.into_inner(), v.into_inner());
        }
        let overridden = self.apply_sets(descriptor.kind, id.as_deref(), &mut params);
        match (descriptor.build)(&params) {
            Ok(stage) => Some(PipelineStage {
                kind: descriptor.kind,
                id,
                stage,
                origin,
            }),
            Err(issues) => {
                for issue in issues {
                    let (origin, message) = match issue.key.as_deref() {
                        // `--set kind.key=value` already names the key: not twice.
                        Some(k) if overridden.contains_key(k) => (
                            format!("--set {}", overridden[k]),
                            issue
                                .message
                                .strip_prefix(&format!("{k}: "))
                                .unwrap_or(&issue.message),
                        ),
                        Some(k) => (
                            loc.at(spans.get(k).cloned().or(Some(stage_span.clone()))),
                            issue.message.as_str(),
                        ),
                        None => (loc.at(Some(stage_span.clone())), issue.message.as_str()),
                    };
                    self.diags.push(Diagnostic {
                        origin,
                        message: format!("{}: {message}", descriptor.kind),
                    });
                }
                None
            }
        }
    }

    /// Puts the command line's `--set` values for the stage of `kind` and `id` into its
    /// `params` (they replace the file's); returns them by key, as written.
    fn apply_sets(
        &mut self,
        kind: &str,
        id: Option<&str>,
        params: &mut toml::Table,
    ) -> BTreeMap<String, String> {
        let mut overridden = BTreeMap::new();
        for (i, set) in self.overrides.sets.iter().enumerate() {
            let hit = if self.ids.contains(&set.selector) {
                id == Some(set.selector.as_str())
            } else {
                set.selector == kind
            };
            if hit {
                self.set_used[i] = true;
                params.insert(set.key.clone(), set.value.clone());
                overridden.insert(set.key.clone(), set.raw.clone());
            }
        }
        overridden
    }

    /// A problem for each `--set` that no stage took.
    fn unused_sets(&mut self) {
        for (set, &used) in self.overrides.sets.iter().zip(&self.set_used) {
            if !used {
                self.diags.push(Diagnostic {
                    origin: format!("--set {}", set.raw),
                    message: format!(
                        "no stage of this pipeline has the id or kind `{}`",
                        set.selector
                    ),
                });
            }
        }
    }
}

impl Pipeline {
    /// Parses and checks a pipeline file; `file` names it in diagnostics.
    ///
    /// Every problem is reported, not only the first; nothing is run.
    pub fn parse(
        text: &str,
        file: &str,
        registry: &Registry,
        overrides: &Overrides,
    ) -> Result<Pipeline, Diagnostics> {
        let loc = Locator::new(file, text);
        let raw: RawFile = toml::from_str(text).map_err(|e| {
            let message = e.message().trim().to_string();
            Diagnostics(vec![Diagnostic {
                origin: loc.at(e.span()),
                message,
            }])
        })?;
        let mut p = Parser {
            loc: &loc,
            registry,
            overrides,
            // A --set selector names a stage id when some stage has that id, else a kind.
            ids: raw
                .stage
                .iter()
                .filter_map(|s| s.get_ref().iter().find(|(k, _)| k.get_ref() == "id"))
                .filter_map(|(_, v)| v.get_ref().as_str().map(str::to_string))
                .collect(),
            set_used: vec![false; overrides.sets.len()],
            diags: Vec::new(),
        };
        let header = p.header(raw.pipeline, file);
        if raw.stage.is_empty() {
            p.diags.push(Diagnostic {
                origin: file.to_string(),
                message: "the pipeline has no [[stage]] table".into(),
            });
        }
        let stages: Vec<PipelineStage> = raw
            .stage
            .into_iter()
            .filter_map(|raw_stage| p.stage(raw_stage))
            .collect();
        p.unused_sets();
        let Header {
            name,
            description,
            target,
            inputs,
        } = header;
        let pipeline = Pipeline {
            name,
            description,
            target,
            inputs,
            stages,
        };
        // The data flow can only be checked when every stage was built.
        let mut diags = p.diags;
        if diags.is_empty() {
            diags.extend(check::check_flow(&pipeline));
        }
        if diags.is_empty() {
            Ok(pipeline)
        } else {
            Err(Diagnostics(diags))
        }
    }

    /// Reads and parses the pipeline file at `path`.
    pub fn from_path(
        path: &std::path::Path,
        registry: &Registry,
        overrides: &Overrides,
    ) -> Result<Pipeline, Diagnostics> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| {
            Diagnostics(vec![Diagnostic {
                origin: name.clone(),
                message: format!("cannot read: {e}"),
            }])
        })?;
        Self::parse(&text, &name, registry, overrides)
    }
}

/// Removes `key` from the table; returns its value and the value's span.
fn take(table: &mut RawStage, key: &str) -> Option<(Range<usize>, toml::Value)> {
    let k = table.keys().find(|k| k.get_ref() == key)?.clone();
    let v = table.remove(&k)?;
    Some((v.span(), v.into_inner()))
}

impl std::fmt::Debug for PipelineStage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PipelineStage")
            .field("kind", &self.kind)
            .field("id", &self.id)
            .field("params", &self.stage.params())
            .field("origin", &self.origin)
            .finish()
    }
}

impl std::fmt::Debug for Pipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("name", &self.name)
            .field("target", &self.target)
            .field("inputs", &self.inputs)
            .field("stages", &self.stages)
            .finish_non_exhaustive()
    }
}
