//! `coarsen-bench fingerprints`: one hash of the output bytes per shipped pipeline and
//! mesh, for telling whether a change kept every output the same.
//!
//! ```sh
//! cargo run --release -p coarsen-bench -- fingerprints --out before.txt      # on main
//! cargo run --release -p coarsen-bench -- fingerprints --check before.txt    # after the change
//! ```
//!
//! Every shipped pipeline runs through the facade (as `coarsen run` does) on every mesh of
//! the data folder at one vertex target, and the collapse pipelines also at paper 2's 95 %
//! removed; `--big` adds the bunny subdivided three times (4.4M faces) with the pipelines
//! of the scale section. A line is `mesh pipeline target hash vertices faces`, the hash
//! FNV-1a of the output as binary PLY.

use anyhow::{Context as _, Result, bail};
use coarsen::Target;
use std::fmt::Write as _;
use std::path::Path;

/// The collapse pipelines, also run at 95 % of the faces removed.
const COLLAPSE: &[&str] = &["qem", "svec"];

/// The pipelines run on the 4.4M-face bunny with `--big`, and their targets.
const BIG: &[(&str, Target)] = &[
    ("qem", Target::Faces(60_000)),
    ("svec", Target::Faces(60_000)),
    ("uniform-cvt", Target::Vertices(30_000)),
    ("adaptive-cvt", Target::Vertices(30_000)),
    ("goal", Target::Vertices(30_000)),
];

/// The vertex target of the runs on a mesh of `n` vertices: a tenth, within 200..=3000.
fn vertex_target(n: usize) -> u64 {
    (n as u64 / 10).clamp(200, 3000)
}

/// The fingerprint lines of every case, in a fixed order.
pub fn lines(data: &Path, big: bool) -> Result<Vec<String>> {
    let mut files: Vec<_> = std::fs::read_dir(data)
        .with_context(|| data.display().to_string())?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| coarsen::Format::from_path(p).is_some())
        .collect();
    files.sort();
    if files.is_empty() {
        bail!("{}: no mesh files", data.display());
    }
    let mut out = Vec::new();
    for file in &files {
        let name = file.file_name().unwrap_or_default().to_string_lossy();
        let mesh = coarsen::read(file)?;
        let mut cases: Vec<(&str, Target)> = coarsen::pipelines()
            .iter()
            .map(|p| (p.name, Target::Vertices(vertex_target(mesh.n_vertices()))))
            .collect();
        cases.extend(COLLAPSE.iter().map(|&p| (p, Target::Ratio(0.95))));
        for (pipeline, target) in cases {
            eprintln!("fingerprints · {name} · {pipeline} · {target}");
            out.push(line(&name, &mesh, pipeline, target));
        }
    }
    if big {
        let bunny = files
            .iter()
            .find(|f| f.ends_with("stanford-bunny.obj"))
            .context("--big needs stanford-bunny.obj in the data folder")?;
        let cleaned = coarsen::clean(coarsen::open(bunny, &Default::default())?, false)?;
        let big = crate::scale::big_mesh(&cleaned.mesh)?;
        for &(pipeline, target) in BIG {
            eprintln!("fingerprints · bunny ×3 · {pipeline} · {target}");
            out.push(line("bunny-subdivided-3", &big, pipeline, target));
        }
    }
    Ok(out)
}

/// One case's line; a failed run is a line too (`failed: …`), so that a change that makes
/// a run fail, or stop failing, shows.
fn line(name: &str, mesh: &coarsen::Mesh, pipeline: &str, target: Target) -> String {
    let target_text = match target {
        Target::Vertices(n) => format!("v{n}"),
        Target::Faces(n) => format!("f{n}"),
        Target::Ratio(r) => format!("r{r}"),
    };
    let run = coarsen::Remesher::new()
        .pipeline(pipeline)
        .target(target)
        .sanity(false)
        .run(mesh);
    match run {
        Ok((out, _)) => {
            let mut bytes = Vec::new();
            let written =
                coarsen_io::write_to(&out, coarsen::Format::Ply, &mut bytes, &Default::default());
            match written {
                Ok(()) => format!(
                    "{name} {pipeline} {target_text} {:016x} {} {}",
                    fnv1a(&bytes),
                    out.n_vertices(),
                    out.n_faces()
                ),
                Err(e) => format!("{name} {pipeline} {target_text} failed: {e}"),
            }
        }
        Err(e) => format!(
            "{name} {pipeline} {target_text} failed: {}",
            e.to_string().replace('\n', " ")
        ),
    }
}

/// FNV-1a, 64 bits.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The lines of `now` that differ from `before` (by case), and cases only one side has.
pub fn differences(before: &str, now: &[String]) -> Vec<String> {
    let key = |l: &str| l.split_whitespace().take(3).collect::<Vec<_>>().join(" ");
    let old: std::collections::BTreeMap<String, &str> =
        before.lines().map(|l| (key(l), l)).collect();
    let mut diffs = Vec::new();
    for l in now {
        match old.get(&key(l)) {
            Some(o) if *o == l => {}
            Some(o) => {
                let mut s = String::new();
                let _ = write!(s, "- {o}\n+ {l}");
                diffs.push(s);
            }
            None => diffs.push(format!("+ {l} (new case)")),
        }
    }
    let new: std::collections::BTreeSet<String> = now.iter().map(|l| key(l)).collect();
    diffs.extend(
        old.iter()
            .filter(|(k, _)| !new.contains(*k))
            .map(|(_, l)| format!("- {l} (case gone)")),
    );
    diffs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_name_changed_new_and_gone_cases() {
        let before = "a qem v200 00ff 10 16\nb qem v200 00aa 10 16\nc svec r0.95 0001 4 4\n";
        let now = vec![
            "a qem v200 00ff 10 16".to_string(),
            "b qem v200 00ab 10 16".to_string(),
            "d qem v200 0002 4 4".to_string(),
        ];
        let d = differences(before, &now);
        assert_eq!(
            d,
            [
                "- b qem v200 00aa 10 16\n+ b qem v200 00ab 10 16",
                "+ d qem v200 0002 4 4 (new case)",
                "- c svec r0.95 0001 4 4 (case gone)",
            ]
        );
        assert!(
            differences(
                before,
                &before.lines().map(String::from).collect::<Vec<_>>()
            )
            .is_empty()
        );
    }

    #[test]
    fn targets_are_a_tenth_within_bounds() {
        assert_eq!(vertex_target(35_947), 3000);
        assert_eq!(vertex_target(10_044), 1004);
        assert_eq!(vertex_target(507), 200);
    }
}
