//! One function per subcommand.

use crate::load;
use crate::{
    BatchArgs, Failure, LodArgs, RunArgs, TargetArgs, batch, html, maps, progress, viewer,
};
use anyhow::Context as _;
use coarsen_io::{PlyEncoding, WriteOptions};
use coarsen_mesh::Mesh;
use coarsen_mesh::Topology;
use coarsen_pipeline::RunOptions;
use coarsen_pipeline::StageRecord;
use coarsen_stage::Target;
use std::path::{Path, PathBuf};

type CmdResult = Result<(), Failure>;

/// A facade error as a failure: usage (exit 2) or runtime (exit 1).
fn failure(e: coarsen::Error) -> Failure {
    match e {
        coarsen::Error::NoRecordingStage { pipeline, stages } => Failure::Usage(format!(
            "--progressive needs a stage that records its collapses (simplify.qem, \
             simplify.svec), but pipeline `{pipeline}` has none (stages: {stages})"
        )),
        coarsen::Error::RecordNotOfOutput { .. } => {
            Failure::Runtime(anyhow::anyhow!("--progressive: {e} (nothing was written)"))
        }
        e if e.is_usage() => Failure::Usage(e.to_string()),
        e => Failure::Runtime(e.into()),
    }
}

/// The run the command line asks for: a pipeline file or shipped pipeline's name, the
/// target and the `--set` overrides.
fn remesher<'a>(spec: &str, target: &TargetArgs, sets: &[String]) -> coarsen::Remesher<'a> {
    let target = match (target.vertices, target.faces, target.ratio) {
        (Some(n), _, _) => Some(Target::Vertices(n)),
        (_, Some(n), _) => Some(Target::Faces(n)),
        (_, _, Some(r)) => Some(Target::Ratio(r)),
        _ => None,
    };
    let mut r = coarsen::Remesher::new().pipeline(spec);
    if let Some(t) = target {
        r = r.target(t);
    }
    sets.iter().fold(r, |r, s| r.assign(s))
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
    let remesher = remesher(&args.pipeline, &args.target, &args.sets)
        .weld(args.weld)
        .sanity(args.sanity || RunOptions::default().sanity)
        .progressive(args.progressive.is_some());
    let pipeline = remesher.check().map_err(failure)?;
    load::ensure_not_input(args.input.as_deref(), &args.output)?;
    if let Some(record) = &args.progressive {
        if record == &args.output {
            return Err(Failure::Usage(format!(
                "--progressive and --output name the same file `{}`",
                record.display()
            )));
        }
        load::ensure_not_input(args.input.as_deref(), record)?;
    }
    let input = match &args.input {
        Some(path) => load::open(path)?,
        None => coarsen::Input::demo(),
    };
    let name = input.name.clone();
    let input = coarsen::clean(input, args.weld).map_err(failure)?;
    let bars = progress::Bars::new(quiet);
    let pictures = args.html.is_some() || args.snapshots.is_some();
    // The input the report's viewer shows (decimated when big), known before the run so
    // that the first clustering's clusters can be carried to its faces.
    let shown = args
        .html
        .is_some()
        .then(|| viewer::ShownInput::of(&input.mesh));
    let recorder = pictures.then(|| {
        let r = html::Recorder::new(
            args.snapshots.is_some(),
            520,
            args.view,
            &input.mesh,
            shown
                .as_ref()
                .map(|s| s.decimated.as_ref().unwrap_or(&input.mesh)),
        );
        r.picture("input".into(), &input.mesh, None, false);
        r
    });
    let observe = |record: &StageRecord, mesh: &Mesh| {
        if let Some(r) = &recorder {
            r.observe(record, mesh);
        }
    };
    let original = args.html.is_some().then(|| input.mesh.clone());
    let mut remesher = remesher.progress(&bars);
    if recorder.is_some() {
        remesher = remesher.after_stage(&observe);
    }
    let done = remesher
        .run_cleaned(&pipeline, &name, input)
        .map_err(failure)?;
    let (mesh, mut report) = (done.mesh, done.report);
    let opts = write_options(args.ascii);
    coarsen_io::write_path(&mesh, &args.output, &opts)?;
    if let Some(format) = coarsen_io::Format::from_path(&args.output) {
        report
            .notes
            .extend(coarsen_io::left_out(&mesh, format, &opts));
    }
    if let (Some(path), Some(record)) = (&args.progressive, &done.progressive) {
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
            let measured =
                coarsen_metrics::measure_with_fields(original, &mesh, &Default::default());
            let viewer = measured.as_ref().ok().map(|(_, fields)| {
                html::maps_of(r, original, &mesh, fields);
                let shown = shown.unwrap_or_else(|| viewer::ShownInput::of(original));
                viewer::for_report(original, shown, &mesh, fields, r.clusters.borrow().as_ref())
            });
            let metrics = measured.map(|(m, _)| m);
            let input_quality = coarsen_metrics::quality(original).ok();
            let mut notes = r.errors.borrow().clone();
            if let Err(e) = &metrics {
                notes.push(format!("metrics not available: {e}"));
            }
            let page = html::page(
                &report,
                metrics.as_ref().ok(),
                input_quality.as_ref(),
                viewer.as_deref(),
                &r.pictures.borrow(),
                &notes,
            );
            write_atomically(path, page.as_bytes())?;
        }
    }
    if !quiet {
        out!("{}", report.summary());
        outln!("wrote {}", args.output.display());
        if let (Some(path), Some(record)) = (&args.progressive, &done.progressive) {
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
    let pipeline = remesher(&args.pipeline, &args.target, &args.sets)
        .check()
        .map_err(failure)?;
    let pipeline = std::sync::Arc::new(pipeline);
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
        timeout: args.timeout.map(std::time::Duration::from_secs_f64),
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
    mut opts: coarsen_render::RenderOptions,
    worst: Option<f64>,
) -> CmdResult {
    for m in meshes {
        load::ensure_not_input(Some(m), output)?;
    }
    let field = opts.attribute.as_deref().and_then(maps::Field::named);
    if worst.is_some() && field.is_none() {
        return Err(Failure::Usage(
            "--worst needs --attribute distance, min_angle or quality".into(),
        ));
    }
    let loaded = match field {
        Some(maps::Field::Distance) if meshes.len() == 2 => {
            let (a, b) = (load::open(&meshes[0])?, load::open(&meshes[1])?);
            let fidelity = Default::default();
            let (_, a, b) = coarsen::measure_fields(a, b, &fidelity).map_err(failure)?;
            vec![a, b]
        }
        _ => meshes
            .iter()
            .map(|m| load::load(m, false).map(|l| l.mesh))
            .collect::<anyhow::Result<Vec<_>>>()?,
    };
    let mut loaded = loaded;
    if let Some(field) = field {
        opts.scale = Some(maps::prepare(field, &mut loaded, worst).map_err(Failure::Usage)?);
    }
    let refs: Vec<&coarsen_mesh::Mesh> = loaded.iter().collect();
    let image = coarsen_render::render(&refs, &opts).map_err(anyhow::Error::from)?;
    let png = image.to_png().map_err(anyhow::Error::from)?;
    write_atomically(output, &png)?;
    Ok(())
}

pub fn stages(markdown: bool) -> CmdResult {
    let registry = coarsen::registry();
    for conflict in registry.conflicts() {
        eprintln!("warning: {conflict}");
    }
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
    let p = remesher(spec, target, sets).check().map_err(failure)?;
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
    let adjacency = Topology::build(mesh);
    let topo = adjacency.summary(mesh);
    let feature_opts = coarsen_features::FeatureOptions::default();
    let features = coarsen_features::Features::detect(mesh, &adjacency, &feature_opts).counts();
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
            "features": {"options": feature_opts, "counts": features},
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
    let marked = match features.marked_edges {
        0 => String::new(),
        n => format!(", {n} marked by the input"),
    };
    outln!(
        "  features           {} sharp edges (over {}°), {} boundary, {} of 3+ faces{marked}; {} curves ({} closed), {} corners",
        features.sharp_edges,
        feature_opts.angle_deg,
        features.boundary_edges,
        features.junction_edges,
        features.curves,
        features.closed_curves,
        features.corners
    );
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
    let seams = mesh.wedges.split_vertices();
    let c = mesh.wedges.attrs().iter().map(move |(n, a)| {
        format!(
            "per-corner {} `{n}` ({seams} vertices on seams or hard edges)",
            a.kind()
        )
    });
    let m = (!mesh.materials.is_empty()).then(|| "materials".to_string());
    v.chain(f).chain(c).chain(m).collect()
}

pub fn convert(input: &Path, output: &Path, ascii: bool, clean: bool) -> CmdResult {
    load::ensure_not_input(Some(input), output)?;
    let loaded = if clean {
        load::load(input, false)?
    } else {
        load::load_raw(input)?
    };
    let mesh = loaded.restore(loaded.mesh.clone());
    let opts = write_options(ascii);
    coarsen_io::write_path(&mesh, output, &opts)?;
    if let Some(format) = coarsen_io::Format::from_path(output) {
        for w in coarsen_io::left_out(&mesh, format, &opts) {
            eprintln!("warning: {w}");
        }
    }
    Ok(())
}

/// Where `coarsen metrics` writes the meshes with their fields.
pub struct FieldFiles {
    /// The output with its fields (`--fields`).
    pub output: Option<PathBuf>,
    /// The input with its fields (`--input-fields`).
    pub input: Option<PathBuf>,
}

impl FieldFiles {
    /// Refuses a fields file that is not PLY (only PLY holds the scalar columns) or that
    /// names a mesh being read.
    fn check(&self, input: &Path, output: &Path) -> CmdResult {
        for path in self.output.iter().chain(&self.input) {
            if coarsen_io::Format::from_path(path) != Some(coarsen_io::Format::Ply) {
                return Err(Failure::Usage(format!(
                    "fields are written as PLY (scalar properties): `{}` does not end in .ply",
                    path.display()
                )));
            }
            load::ensure_not_input(Some(input), path)?;
            load::ensure_not_input(Some(output), path)?;
        }
        if self.output.is_some() && self.output == self.input {
            return Err(Failure::Usage(
                "--fields and --input-fields name the same file".into(),
            ));
        }
        Ok(())
    }
}

pub fn metrics(
    input: &Path,
    output: &Path,
    json: bool,
    fidelity: coarsen_metrics::FidelityOptions,
    files: &FieldFiles,
) -> CmdResult {
    files.check(input, output)?;
    let opts = coarsen_metrics::MetricsOptions { fidelity };
    let (a, b) = (load::open(input)?, load::open(output)?);
    let report = if files.output.is_none() && files.input.is_none() {
        coarsen::measure(a, b, &opts).map_err(failure)?
    } else {
        let (report, in_mesh, out_mesh) = coarsen::measure_fields(a, b, &opts).map_err(failure)?;
        let binary = write_options(false);
        for (path, mesh) in [(&files.output, &out_mesh), (&files.input, &in_mesh)] {
            if let Some(path) = path {
                coarsen_io::write_path(mesh, path, &binary)?;
            }
        }
        report
    };
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
