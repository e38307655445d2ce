//! One function per subcommand.

use crate::load::{self, Input};
use crate::{BatchArgs, Failure, LodArgs, RunArgs, TargetArgs, batch, html, progress};
use anyhow::Context as _;
use coarsen_io::{PlyEncoding, WriteOptions};
use coarsen_mesh::Mesh;
use coarsen_mesh::Topology;
use coarsen_pipeline::StageRecord;
use coarsen_pipeline::{Overrides, Pipeline, RunOptions, parse_set};
use coarsen_stage::{Registry, Target};
use std::path::{Path, PathBuf};

type CmdResult = Result<(), Failure>;

fn registry() -> Result<Registry, Failure> {
    coarsen_builtin::registry().map_err(|e| Failure::Runtime(e.into()))
}

fn overrides(target: &TargetArgs, sets: &[String]) -> Result<Overrides, Failure> {
    let target = match (target.vertices, target.faces, target.ratio) {
        (Some(n), _, _) => Some(Target::Vertices(n)),
        (_, Some(n), _) => Some(Target::Faces(n)),
        (_, _, Some(r)) => Some(Target::Ratio(r)),
        _ => None,
    };
    let sets = sets
        .iter()
        .map(|s| parse_set(s))
        .collect::<Result<Vec<_>, _>>()
        .map_err(Failure::Usage)?;
    Ok(Overrides { target, sets })
}

/// A pipeline from a file path, or from the shipped pipelines by name.
fn load_pipeline(
    spec: &str,
    registry: &Registry,
    overrides: &Overrides,
) -> Result<Pipeline, Failure> {
    let path = Path::new(spec);
    let parsed = if path.exists() {
        Pipeline::from_path(path, registry, overrides)
    } else if let Some(text) = coarsen_builtin::pipeline(spec) {
        Pipeline::parse(
            text,
            &format!("<shipped pipeline {spec}>"),
            registry,
            overrides,
        )
    } else {
        let names: Vec<_> = coarsen_builtin::PIPELINES.iter().map(|(n, _)| *n).collect();
        return Err(Failure::Usage(format!(
            "no pipeline file `{spec}` and no shipped pipeline of that name (shipped: {})",
            names.join(", ")
        )));
    };
    parsed.map_err(|d| Failure::Usage(format!("pipeline has errors:\n{d}")))
}

fn write_options(ascii: bool) -> WriteOptions {
    WriteOptions {
        ply_encoding: if ascii {
            PlyEncoding::Ascii
        } else {
            PlyEncoding::BinaryLittleEndian
        },
        ..Default::default()
    }
}

/// Writes `bytes` to `path` through a temporary file and a rename.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    Ok(coarsen_io::write_bytes(path, bytes)?)
}

pub fn run(args: RunArgs, quiet: bool) -> CmdResult {
    let registry = registry()?;
    let overrides = overrides(&args.target, &args.sets)?;
    let pipeline = load_pipeline(&args.pipeline, &registry, &overrides)?;
    load::ensure_not_input(args.input.as_deref(), &args.output)?;
    if let Some(record) = &args.progressive {
        check_progressive(&pipeline, record, args.input.as_deref(), &args.output)?;
    }
    let (input, name) = match &args.input {
        Some(path) => (load::load(path, args.weld)?, path.display().to_string()),
        None => (
            Input {
                mesh: coarsen_shapes::demo(),
                notes: vec!["built-in demo mesh".into()],
                scale_exponent: 0,
            },
            "demo".into(),
        ),
    };
    let bars = progress::Bars::new(quiet);
    let pictures = args.html.is_some() || args.snapshots.is_some();
    let recorder = pictures.then(|| {
        let r = html::Recorder::new(args.snapshots.is_some(), 520, args.view, &input.mesh);
        r.picture("input".into(), &input.mesh, None, false);
        r
    });
    let observe = |record: &StageRecord, mesh: &Mesh| {
        if let Some(r) = &recorder {
            r.observe(record, mesh);
        }
    };
    let original = args.html.is_some().then(|| input.mesh.clone());
    let slot = std::sync::Mutex::new(None);
    let opts = RunOptions {
        sanity: args.sanity || RunOptions::default().sanity,
        progress: &bars,
        after_stage: recorder
            .as_ref()
            .map(|_| &observe as &dyn Fn(&StageRecord, &Mesh)),
        progressive: args.progressive.as_ref().map(|_| &slot),
        ..RunOptions::default()
    };
    let (mesh, mut report) = pipeline
        .run(input.mesh, opts)
        .map_err(anyhow::Error::from)?;
    report.input = name;
    report.input_notes = input.notes;
    let record = match &args.progressive {
        Some(_) => Some(take_record(&pipeline, slot, &mesh)?),
        None => None,
    };
    let mesh = load::restore(mesh, input.scale_exponent);
    let record = record.map(|mut r| {
        // The record speaks the input's units and describes the mesh as written.
        r.scale_by_power_of_two(-input.scale_exponent);
        r.coarse = coarsen_collapse::fingerprint(&mesh);
        r
    });
    coarsen_io::write_path(&mesh, &args.output, &write_options(args.ascii))?;
    if let (Some(path), Some(record)) = (&args.progressive, &record) {
        coarsen_lod::write(path, record).context("writing the progressive record")?;
    }
    if let Some(path) = &args.report {
        write_atomically(path, report.to_json().as_bytes())?;
    }
    if let Some(r) = &recorder {
        r.picture("output".into(), &mesh, None, true);
        if let Some(dir) = &args.snapshots {
            r.write_all(dir)?;
        }
        if let (Some(path), Some(original)) = (&args.html, &original) {
            let metrics = coarsen_metrics::measure(Some(original), &mesh, &Default::default());
            let mut notes = r.errors.borrow().clone();
            if let Err(e) = &metrics {
                notes.push(format!("metrics not available: {e}"));
            }
            let page = html::page(&report, metrics.as_ref().ok(), &r.pictures.borrow(), &notes);
            write_atomically(path, page.as_bytes())?;
        }
    }
    if !quiet {
        out!("{}", report.summary());
        outln!("wrote {}", args.output.display());
        if let (Some(path), Some(record)) = (&args.progressive, &record) {
            outln!(
                "wrote {} (levels 0 to {}: {} to {} vertices; `coarsen lod` rebuilds them)",
                path.display(),
                coarsen_lod::levels(record),
                mesh.n_vertices(),
                coarsen_lod::level_vertices(record, coarsen_lod::levels(record))
            );
        }
    }
    Ok(())
}

/// Before any work: `--progressive` needs a stage that records its collapses, and a file
/// of its own.
fn check_progressive(
    pipeline: &Pipeline,
    record: &Path,
    input: Option<&Path>,
    output: &Path,
) -> Result<(), Failure> {
    if pipeline.recording_stage().is_none() {
        let kinds: Vec<_> = pipeline.stages.iter().map(|s| s.kind).collect();
        return Err(Failure::Usage(format!(
            "--progressive needs a stage that records its collapses (simplify.qem, simplify.svec), \
             but pipeline `{}` has none (stages: {})",
            pipeline.name,
            kinds.join(" → ")
        )));
    }
    if record == output {
        return Err(Failure::Usage(format!(
            "--progressive and --output name the same file `{}`",
            record.display()
        )));
    }
    load::ensure_not_input(input, record)?;
    Ok(())
}

/// The record the pipeline's last collapse stage handed back; an error when a later stage
/// changed the mesh it describes.
fn take_record(
    pipeline: &Pipeline,
    slot: std::sync::Mutex<Option<coarsen_stage::Handback>>,
    out: &Mesh,
) -> Result<coarsen_lod::Progressive, Failure> {
    let (index, kind) = pipeline
        .recording_stage()
        .ok_or_else(|| anyhow::anyhow!("no stage records its collapses"))?;
    let handed = slot.into_inner().unwrap_or_else(|e| e.into_inner());
    let record = handed
        .and_then(|b| b.downcast::<coarsen_lod::Progressive>().ok())
        .ok_or_else(|| {
            anyhow::anyhow!(
                "stage {} `{kind}` handed back no progressive record (a bug in coarsen)",
                index + 1
            )
        })?;
    if record.coarse != coarsen_collapse::fingerprint(out) {
        let later: Vec<_> = pipeline.stages[index + 1..]
            .iter()
            .map(|s| format!("`{}`", s.kind))
            .collect();
        return Err(Failure::Runtime(anyhow::anyhow!(
            "--progressive: the record of stage {} `{kind}` does not describe the run's output, \
             because a later stage ({}) changed the mesh; end the pipeline with the collapse stage \
             (nothing was written)",
            index + 1,
            later.join(", ")
        )));
    }
    Ok(*record)
}

pub fn lod(args: LodArgs, quiet: bool) -> CmdResult {
    load::ensure_not_input(Some(&args.coarse), &args.output)?;
    load::ensure_not_input(Some(&args.record), &args.output)?;
    let record_name = args.record.display().to_string();
    let record = coarsen_lod::read(&args.record).with_context(|| record_name.clone())?;
    let coarse = load::load_raw(&args.coarse)?.mesh;
    let usage = |e: coarsen_lod::LodError| match e {
        coarsen_lod::LodError::NoLevel { .. } | coarsen_lod::LodError::NoVertexCount { .. } => {
            Failure::Usage(format!("{record_name}: {e}"))
        }
        e => Failure::Runtime(anyhow::Error::from(e).context(format!(
            "rebuilding from {} and {record_name}",
            args.coarse.display()
        ))),
    };
    let level = match (args.level, args.vertices) {
        (Some(k), _) => k,
        (None, Some(n)) => coarsen_lod::level_with_vertices(&record, n).map_err(usage)?,
        (None, None) => return Err(Failure::Usage("give --level or --vertices".into())),
    };
    let mesh = coarsen_lod::rebuild(&coarse, &record, level).map_err(usage)?;
    coarsen_io::write_path(&mesh, &args.output, &write_options(args.ascii))?;
    if !quiet {
        outln!(
            "level {level} of {}: {} vertices, {} faces; wrote {}",
            coarsen_lod::levels(&record),
            mesh.n_vertices(),
            mesh.n_faces(),
            args.output.display()
        );
    }
    Ok(())
}

pub fn batch(args: BatchArgs, quiet: bool) -> CmdResult {
    let registry = registry()?;
    let pipeline = load_pipeline(
        &args.pipeline,
        &registry,
        &overrides(&args.target, &args.sets)?,
    )?;
    let format = batch::format_arg(&args.format)?;
    std::fs::create_dir_all(&args.out).with_context(|| args.out.display().to_string())?;
    let jobs = args.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let rows = batch::run(&batch::Batch {
        inputs: &args.inputs,
        out: &args.out,
        pipeline: &pipeline,
        format,
        force: args.force,
        shard: args.shard,
        jobs,
        weld: args.weld,
        quiet,
    })?;
    let suffix = args
        .shard
        .map(|s| format!("-{}-of-{}", s.index, s.count))
        .unwrap_or_default();
    let json = serde_json::to_string_pretty(&rows).map_err(anyhow::Error::from)?;
    write_atomically(
        &args.out.join(format!("summary{suffix}.json")),
        json.as_bytes(),
    )?;
    write_atomically(
        &args.out.join(format!("summary{suffix}.csv")),
        batch::csv(&rows).as_bytes(),
    )?;
    if !quiet {
        out!("{}", batch::table(&rows));
    }
    let failed = rows.iter().filter(|r| r.status == "failed").count();
    if failed > 0 {
        return Err(Failure::Runtime(anyhow::anyhow!(
            "{failed} of {} files failed (see the summary)",
            rows.len()
        )));
    }
    Ok(())
}

pub fn render(
    meshes: &[PathBuf],
    output: &Path,
    opts: &coarsen_render::RenderOptions,
) -> CmdResult {
    for m in meshes {
        load::ensure_not_input(Some(m), output)?;
    }
    let loaded = meshes
        .iter()
        .map(|m| load::load(m, false))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let refs: Vec<&coarsen_mesh::Mesh> = loaded.iter().map(|l| &l.mesh).collect();
    let image = coarsen_render::render(&refs, opts).map_err(anyhow::Error::from)?;
    let png = image.to_png().map_err(anyhow::Error::from)?;
    write_atomically(output, &png)?;
    Ok(())
}

pub fn stages(markdown: bool) -> CmdResult {
    let registry = registry()?;
    let mut out = String::new();
    for d in registry.iter() {
        let defaults = (d.defaults)();
        if markdown {
            out.push_str(&format!(
                "## `{}`\n\n{}\n\n_Crate: `{}`._\n\n",
                d.kind, d.summary, d.crate_name
            ));
            let fields = (d.fields)();
            if fields.is_empty() {
                out.push_str("No parameters.\n\n");
                continue;
            }
            out.push_str("| parameter | type | default | meaning |\n| --- | --- | --- | --- |\n");
            for f in fields {
                let default = defaults
                    .get(f.name)
                    .map(|v| v.to_string())
                    .unwrap_or_else(|| "(none)".into());
                let doc = f.doc.split_whitespace().collect::<Vec<_>>().join(" ");
                out.push_str(&format!(
                    "| `{}` | `{}` | `{}` | {} |\n",
                    f.name, f.ty, default, doc
                ));
            }
            out.push('\n');
        } else {
            out.push_str(&format!(
                "{}  ({})\n    {}\n",
                d.kind, d.crate_name, d.summary
            ));
            for f in (d.fields)() {
                let default = defaults
                    .get(f.name)
                    .map(|v| v.to_string())
                    .unwrap_or_else(|| "(none)".into());
                let doc = f.doc.split_whitespace().collect::<Vec<_>>().join(" ");
                out.push_str(&format!("    {:<18} = {:<10} {}\n", f.name, default, doc));
            }
            out.push('\n');
        }
    }
    out!("{out}");
    Ok(())
}

pub fn check(spec: &str, target: &TargetArgs, sets: &[String], quiet: bool) -> CmdResult {
    let registry = registry()?;
    let p = load_pipeline(spec, &registry, &overrides(target, sets)?)?;
    if !quiet {
        let kinds: Vec<_> = p.stages.iter().map(|s| s.kind).collect();
        let target = p
            .target
            .map(|t| t.to_string())
            .unwrap_or_else(|| "none".into());
        outln!(
            "{spec}: ok — pipeline `{}`, target {target}, stages: {}",
            p.name,
            kinds.join(" → ")
        );
    }
    Ok(())
}

pub fn info(path: &Path, json: bool, raw: bool, weld: bool) -> CmdResult {
    let input = if raw {
        load::load_raw(path)?
    } else {
        load::load(path, weld)?
    };
    let mesh = &input.mesh;
    let topo = Topology::build(mesh).summary(mesh);
    let quality = coarsen_metrics::quality(mesh).map_err(anyhow::Error::from)?;
    let bbox = mesh.bbox();
    if json {
        let v = serde_json::json!({
            "file": path.display().to_string(),
            "notes": input.notes,
            "bbox_min": [bbox.min.x, bbox.min.y, bbox.min.z],
            "bbox_max": [bbox.max.x, bbox.max.y, bbox.max.z],
            "bbox_diagonal": bbox.diagonal(),
            "area": mesh.area(),
            "attributes": attribute_list(mesh),
            "topology": topo,
            "quality": quality,
        });
        outln!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(anyhow::Error::from)?
        );
        return Ok(());
    }
    outln!("{}", path.display());
    for n in &input.notes {
        outln!("  note: {n}");
    }
    outln!("  vertices           {}", mesh.n_vertices());
    outln!("  faces              {}", mesh.n_faces());
    outln!(
        "  bbox               [{:.6}, {:.6}, {:.6}] – [{:.6}, {:.6}, {:.6}] (diagonal {:.6})",
        bbox.min.x,
        bbox.min.y,
        bbox.min.z,
        bbox.max.x,
        bbox.max.y,
        bbox.max.z,
        bbox.diagonal()
    );
    outln!("  area               {:.6}", mesh.area());
    print_topology(&topo);
    outln!(
        "  angles             min {:.2}°, mean of minimum {:.2}°, {:.2} % of faces under 30°",
        quality.alpha_min_deg,
        quality.alpha_avg_deg,
        quality.p_lt30_pct
    );
    outln!(
        "  quality (Q)        min {:.3}, mean {:.3}",
        quality.q_min,
        quality.q_avg
    );
    let attrs = attribute_list(mesh);
    if !attrs.is_empty() {
        outln!("  attributes         {}", attrs.join(", "));
    }
    Ok(())
}

fn print_topology(t: &coarsen_mesh::topology::TopologySummary) {
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    let genus = match t.genus_total {
        Some(g) => g.to_string(),
        None => "undefined (non-manifold)".into(),
    };
    outln!(
        "  referenced vertices {} ({} unreferenced)",
        t.n_vertices,
        t.n_isolated_vertices
    );
    outln!(
        "  edges              {} ({} on the boundary)",
        t.n_edges,
        t.n_boundary_edges
    );
    outln!("  components         {}", t.n_components);
    outln!("  boundary loops     {}", t.n_boundary_loops);
    outln!("  genus              {genus}");
    outln!("  euler              {}", t.euler);
    outln!(
        "  manifold           {} ({} non-manifold edges, {} non-manifold vertices)",
        yes_no(t.manifold),
        t.n_non_manifold_edges,
        t.n_non_manifold_vertices
    );
    outln!("  oriented           {}", yes_no(t.consistently_oriented));
    outln!("  degenerate faces   {}", t.n_degenerate_faces);
}

fn attribute_list(mesh: &coarsen_mesh::Mesh) -> Vec<String> {
    let v = mesh
        .vertex_attrs
        .iter()
        .map(|(n, a)| format!("vertex {} `{n}`", a.kind()));
    let f = mesh
        .face_attrs
        .iter()
        .map(|(n, a)| format!("face {} `{n}`", a.kind()));
    v.chain(f).collect()
}

pub fn convert(input: &Path, output: &Path, ascii: bool, clean: bool) -> CmdResult {
    load::ensure_not_input(Some(input), output)?;
    let loaded = if clean {
        load::load(input, false)?
    } else {
        load::load_raw(input)?
    };
    let mesh = load::restore(loaded.mesh, loaded.scale_exponent);
    coarsen_io::write_path(&mesh, output, &write_options(ascii))?;
    Ok(())
}

pub fn metrics(input: &Path, output: &Path, json: bool, samples_per_face: u32) -> CmdResult {
    let a = load::load(input, false)?;
    let b = load::load(output, false)?;
    let opts = coarsen_metrics::MetricsOptions {
        fidelity: coarsen_metrics::FidelityOptions { samples_per_face },
    };
    let report =
        coarsen_metrics::measure(Some(&a.mesh), &b.mesh, &opts).map_err(anyhow::Error::from)?;
    if json {
        outln!(
            "{}",
            serde_json::to_string_pretty(&report).map_err(anyhow::Error::from)?
        );
    } else {
        outln!("{} against {}\n", output.display(), input.display());
        out!("{}", report.to_markdown());
    }
    Ok(())
}
