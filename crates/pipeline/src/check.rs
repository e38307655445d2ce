//! The whole-pipeline checks that need every stage's contract: attribute flow and target.

use crate::{Diagnostic, Pipeline};
use coarsen_stage::AttrRef;

/// Follows the attributes from the declared inputs through every stage; reports each read
/// of an attribute that nothing earlier provides (or provides with another kind), and each
/// stage that needs a target when the run has none.
pub(crate) fn check_flow(p: &Pipeline) -> Vec<Diagnostic> {
    let mut diags = Vec::new();
    let mut available: Vec<(AttrRef, String)> = p
        .inputs
        .iter()
        .map(|a| (a.clone(), "the pipeline's declared inputs".to_string()))
        .collect();
    for (i, s) in p.stages.iter().enumerate() {
        let contract = s.stage.contract();
        let who = format!("stage {} `{}`", i + 1, s.kind);
        for read in &contract.reads {
            match available.iter().find(|(a, _)| a.domain == read.domain && a.name == read.name) {
                None => diags.push(Diagnostic {
                    origin: s.origin.clone(),
                    message: format!(
                        "{who} reads {read}, which no earlier stage writes (if the input file carries it, \
                         declare it in [pipeline] inputs)"
                    ),
                }),
                Some((a, from)) if a.kind != read.kind => diags.push(Diagnostic {
                    origin: s.origin.clone(),
                    message: format!("{who} reads {read}, but {from} provides it as {}", a.kind),
                }),
                Some(_) => {}
            }
        }
        if contract.needs.target && p.target.is_none() {
            diags.push(Diagnostic {
                origin: s.origin.clone(),
                message: format!(
                    "{who} needs a target: set `target` in [pipeline] or pass --vertices, --faces or --ratio"
                ),
            });
        }
        available.retain(|(a, _)| !contract.clears.contains(&a.domain));
        for w in contract.writes {
            available.retain(|(a, _)| !(a.domain == w.domain && a.name == w.name));
            available.push((w, who.clone()));
        }
    }
    diags
}
