//! The `coarsen` command line: the only crate that knows the terminal.
//!
//! `coarsen_cli::main()` is the whole program; a third-party binary that links its own stage
//! crates (`use my_stage as _;`) and calls it gets those stages too.

/// `print!` to standard output that ends the process quietly (exit 0) when the reader has
/// gone away (`coarsen … | head`), instead of panicking.
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = write!(std::io::stdout().lock(), $($t)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
        }
    }};
}

/// [`out!`] with a newline.
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout().lock(), $($t)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
        }
    }};
}

mod batch;
mod commands;
mod html;
mod load;
mod maps;
mod plots;
mod progress;
mod viewer;

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// Coarsen big, badly shaped triangle meshes into small, well-shaped ones.
#[derive(Parser, Debug)]
#[command(
    name = "coarsen",
    version,
    about,
    long_about = None,
    after_help = "With no command, `coarsen [INPUT] -o OUT --vertices N` runs the adaptive-cvt pipeline (paper 1) on INPUT, or on the built-in demo mesh."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Print nothing but errors (no progress bars either).
    #[arg(short, long, global = true)]
    quiet: bool,
    /// Log what happens on standard error: -v info, -vv debug, -vvv trace.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    /// Refuse input files with more triangles than this (also more than 3·N vertices, or
    /// more than 256·N bytes), before their content is read.
    #[arg(long, global = true, value_name = "N", default_value_t = load::DEFAULT_MAX_FACES)]
    max_faces: u64,
    /// In glTF files (`.gltf`, `.glb`), read only the instances of the mesh called NAME
    /// (default: every mesh of the scene).
    #[arg(long, global = true, value_name = "NAME")]
    gltf_mesh: Option<String>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a pipeline on a mesh (on the built-in demo mesh when no input is given).
    Run(RunArgs),
    /// Run a pipeline over many files (folders are searched recursively), in parallel.
    Batch(BatchArgs),
    /// List every registered stage with its summary, parameters and defaults.
    Stages {
        /// Print Markdown (the format of docs/stages.md).
        #[arg(long)]
        markdown: bool,
    },
    /// Check a pipeline file without loading any mesh.
    Check {
        /// Pipeline file, or the name of a shipped pipeline.
        pipeline: String,
        #[command(flatten)]
        target: TargetArgs,
        /// Override a stage parameter: STAGE.PARAM=VALUE (STAGE is a kind or an id).
        #[arg(long = "set", value_name = "STAGE.PARAM=VALUE")]
        sets: Vec<String>,
    },
    /// Print counts, bounding box, topology and triangle-angle summary of a mesh.
    Info {
        /// The mesh file (OBJ, PLY, STL, OFF).
        mesh: PathBuf,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
        /// Report the file as it is, without load-time clean-up.
        #[arg(long, conflicts_with = "weld")]
        raw: bool,
        /// Weld exactly coincident vertices during clean-up (always done for STL).
        #[arg(long)]
        weld: bool,
    },
    /// Convert a mesh file to another format (chosen by the output's extension).
    Convert {
        /// The input mesh.
        input: PathBuf,
        /// The output mesh (.obj, .ply, .stl, .off).
        output: PathBuf,
        /// Write ASCII PLY instead of binary.
        #[arg(long)]
        ascii: bool,
        /// Apply load-time clean-up before writing.
        #[arg(long)]
        clean: bool,
    },
    /// Render one mesh, or two side by side with one camera (before/after), to a PNG image.
    Render {
        /// The mesh, or BEFORE and AFTER.
        #[arg(required = true, num_args = 1..=2)]
        meshes: Vec<PathBuf>,
        /// The PNG file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// Colour by this vertex or face attribute (scalars on a perceptual map, labels by
        /// hue); `distance` (to the other mesh, or a `--fields` file's), `min_angle` and
        /// `quality` (Q) are measured and drawn blue (good) to red (bad) with a colour bar.
        #[arg(long)]
        attribute: Option<String>,
        /// With a measured attribute: paint the worst PERCENT of each mesh's faces magenta.
        #[arg(long, value_name = "PERCENT", num_args = 0..=1, default_missing_value = "1",
              value_parser = parse_percent)]
        worst: Option<f64>,
        /// Draw the edges (faint on a dense mesh, with its outline).
        #[arg(long)]
        wireframe: bool,
        /// Smooth shading (interpolated vertex normals) instead of flat.
        #[arg(long)]
        smooth: bool,
        /// Camera: auto (the broad side), front, side, top or iso.
        #[arg(long, default_value = "auto")]
        view: coarsen_render::View,
        /// 1, or 4 for a 2×2 sheet (the view, the other side, from above, from below).
        #[arg(long, default_value_t = 1, value_parser = parse_views)]
        views: u32,
        /// Size of each panel, WIDTHxHEIGHT.
        #[arg(long, default_value = "800x800", value_parser = parse_size)]
        size: (u32, u32),
        /// Samples per pixel along each axis, for anti-aliasing (1 for none).
        #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=4))]
        supersample: u32,
        /// Draw each mesh's sharp features over it (edges over 40° or marked by the file:
        /// red; boundary: blue; of three or more faces: purple; corners: yellow dots).
        #[arg(long)]
        features: bool,
        /// Draw the texture on meshes with texture coordinates: `image` (the default: the
        /// material's PNG texture, else the checkerboard) or `checker` (a UV checkerboard,
        /// which shows where seams hold).
        #[arg(long, value_name = "KIND", num_args = 0..=1, default_missing_value = "image",
              value_parser = parse_texture)]
        texture: Option<coarsen_render::Texturing>,
    },
    /// Rebuild a level of detail from a coarse mesh and its progressive record (`run
    /// --progressive`) by undoing collapses: level 0 is the coarse mesh, the last level the input.
    Lod(LodArgs),
    /// Compare a mesh with the input it came from: shape quality, fidelity, validity.
    Metrics {
        /// The original mesh.
        input: PathBuf,
        /// The mesh to measure (e.g. another tool's output).
        output: PathBuf,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
        /// Distance samples per face on each mesh's faces (each direction is sampled on its
        /// own mesh, plus every used vertex and points along every edge).
        #[arg(long, default_value_t = coarsen_metrics::SAMPLES_PER_FACE, value_parser = clap::value_parser!(u32).range(1..=10_000))]
        samples_per_face: u32,
        /// At least this many distance samples on each mesh's faces.
        #[arg(long, default_value_t = coarsen_metrics::MIN_FACE_SAMPLES, value_name = "N")]
        min_samples: u64,
        /// Write the output with its fields to this PLY file: vertex `quality` (distance
        /// to the input), face `distance`, `min_angle`, `quality` (Q) and `flipped`.
        #[arg(long, value_name = "FILE.ply")]
        fields: Option<PathBuf>,
        /// Write the input with its fields (distances to the output) to this PLY file.
        #[arg(long, value_name = "FILE.ply")]
        input_fields: Option<PathBuf>,
    },
}

fn parse_texture(s: &str) -> Result<coarsen_render::Texturing, String> {
    match s.trim() {
        "image" => Ok(coarsen_render::Texturing::Image),
        "checker" => Ok(coarsen_render::Texturing::Checker),
        _ => Err(format!("expected `image` or `checker`, got `{s}`")),
    }
}

fn parse_views(s: &str) -> Result<u32, String> {
    match s.trim() {
        "1" => Ok(1),
        "4" => Ok(4),
        _ => Err(format!("expected 1 or 4 views, got `{s}`")),
    }
}

fn parse_percent(s: &str) -> Result<f64, String> {
    match s.trim().trim_end_matches('%').parse::<f64>() {
        Ok(p) if p > 0.0 && p <= 100.0 => Ok(p),
        _ => Err(format!("expected a percent in (0, 100], got `{s}`")),
    }
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, got `{s}`"))?;
    let n = |t: &str| {
        t.trim()
            .parse::<u32>()
            .map_err(|_| format!("bad size `{s}`"))
    };
    Ok((n(w)?, n(h)?))
}

/// The run target from the command line.
#[derive(Args, Debug, Clone, Default)]
struct TargetArgs {
    /// Target vertex count.
    #[arg(long, group = "target")]
    vertices: Option<u64>,
    /// Target face count.
    #[arg(long, group = "target")]
    faces: Option<u64>,
    /// Fraction of the input's faces to remove, in [0, 1) (0.7 removes 70 %).
    #[arg(long, group = "target")]
    ratio: Option<f64>,
}

#[derive(Args, Debug)]
struct RunArgs {
    /// Pipeline file, or the name of a shipped pipeline (see `coarsen run --help`).
    pipeline: String,
    /// The input mesh; the built-in demo mesh when omitted.
    input: Option<PathBuf>,
    /// Where to write the result (.ply, .obj, .stl, .off, .gltf, .glb).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    target: TargetArgs,
    /// Override a stage parameter: STAGE.PARAM=VALUE (STAGE is a kind or an id).
    #[arg(long = "set", value_name = "STAGE.PARAM=VALUE")]
    sets: Vec<String>,
    /// Write the run report as JSON to this file.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Weld exactly coincident vertices on load (default: only for STL).
    #[arg(long)]
    weld: bool,
    /// Run the mesh sanity check after every stage (always on in debug builds).
    #[arg(long)]
    sanity: bool,
    /// Write ASCII PLY instead of binary.
    #[arg(long)]
    ascii: bool,
    /// Write a self-contained HTML report (pictures, metrics against the input, timings).
    #[arg(long, value_name = "FILE")]
    html: Option<PathBuf>,
    /// Write a picture after every stage (and of every attribute a stage adds) to this folder.
    #[arg(long, value_name = "DIR")]
    snapshots: Option<PathBuf>,
    /// Camera of the pictures: auto (the broad side), front, side, top or iso.
    #[arg(long, default_value = "auto")]
    view: coarsen_render::View,
    /// Write the progressive record of the pipeline's last collapse stage to this file
    /// (for `coarsen lod`); the output must be that stage's mesh.
    #[arg(long, value_name = "FILE")]
    progressive: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct LodArgs {
    /// The coarse mesh `coarsen run --progressive` wrote (PLY, OBJ or OFF).
    coarse: PathBuf,
    /// The progressive record written with it.
    record: PathBuf,
    /// The level: how many collapses to undo (0 = the coarse mesh).
    #[arg(long, group = "which", required = true)]
    level: Option<usize>,
    /// The level with this many vertices.
    #[arg(long, group = "which", required = true)]
    vertices: Option<usize>,
    /// Where to write the level (.ply, .obj, .off, .stl).
    #[arg(short, long)]
    output: PathBuf,
    /// Write ASCII PLY instead of binary.
    #[arg(long)]
    ascii: bool,
}

#[derive(Args, Debug)]
struct BatchArgs {
    /// Mesh files and folders (searched recursively for .obj, .ply, .stl, .off).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output folder; outputs keep their path relative to the input folder.
    #[arg(long)]
    out: PathBuf,
    /// Pipeline file, or the name of a shipped pipeline.
    #[arg(long, default_value = "demo")]
    pipeline: String,
    #[command(flatten)]
    target: TargetArgs,
    /// Override a stage parameter: STAGE.PARAM=VALUE (STAGE is a kind or an id).
    #[arg(long = "set", value_name = "STAGE.PARAM=VALUE")]
    sets: Vec<String>,
    /// Files processed at once (default: the number of cores).
    #[arg(short, long)]
    jobs: Option<usize>,
    /// Redo outputs that exist and are newer than their input.
    #[arg(long)]
    force: bool,
    /// Process only shard I of N (0 ≤ I < N), a stable subset, for job arrays.
    #[arg(long, value_name = "I/N")]
    shard: Option<batch::Shard>,
    /// Output format: ply, obj, stl or off.
    #[arg(long, default_value = "ply")]
    format: String,
    /// Weld exactly coincident vertices on load (always done for STL).
    #[arg(long)]
    weld: bool,
    /// Stop a file's run after this many seconds and report it failed; the batch goes on.
    #[arg(long, value_name = "SECONDS", value_parser = parse_timeout)]
    timeout: Option<f64>,
}

fn parse_timeout(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(t) if t > 0.0 && t.is_finite() && t < 1e9 => Ok(t),
        _ => Err(format!("expected a number of seconds above 0, got `{s}`")),
    }
}

/// A failure, sorted by its exit code.
#[derive(Debug)]
pub enum Failure {
    /// Bad usage, bad pipeline file or parameters: exit code 2.
    Usage(String),
    /// The run itself failed (bad mesh file, stage error): exit code 1.
    Runtime(anyhow::Error),
}

impl From<coarsen_io::IoError> for Failure {
    fn from(e: coarsen_io::IoError) -> Self {
        Failure::Runtime(e.into())
    }
}

impl From<anyhow::Error> for Failure {
    fn from(e: anyhow::Error) -> Self {
        Failure::Runtime(e)
    }
}

/// The pipeline `coarsen [INPUT] -o OUT --vertices N` runs when no command is named.
pub const DEFAULT_PIPELINE: &str = coarsen::DEFAULT_PIPELINE;

/// `args` with `run adaptive-cvt` put in front of the first argument after the global
/// options when that argument names no command but an option or a file (anything with a
/// dot or a slash, or an existing path); otherwise unchanged, so that a mistyped command
/// still gets clap's suggestion.
fn with_default_command(mut args: Vec<std::ffi::OsString>) -> Vec<std::ffi::OsString> {
    use clap::CommandFactory;
    let mut i = 1;
    while let Some(a) = args.get(i).and_then(|a| a.to_str()) {
        let verbose = a.len() > 1 && a.starts_with('-') && a[1..].chars().all(|c| c == 'v');
        match a {
            "-q" | "--quiet" | "--verbose" => i += 1,
            "--max-faces" => i += 2,
            _ if verbose || a.starts_with("--max-faces=") => i += 1,
            _ => break,
        }
    }
    let Some(first) = args.get(i) else {
        return args;
    };
    let text = first.to_string_lossy();
    let command = Cli::command();
    let named = matches!(&*text, "help" | "-h" | "--help" | "-V" | "--version")
        || command
            .get_subcommands()
            .any(|c| c.get_name() == text || c.get_all_aliases().any(|a| a == text));
    let file_or_option = text.starts_with('-')
        || text.contains('.')
        || text.contains('/')
        || std::path::Path::new(first).exists();
    if !named && file_or_option {
        args.splice(i..i, ["run".into(), DEFAULT_PIPELINE.into()]);
    }
    args
}

/// Runs the command line and returns the process exit code: 0 success, 1 runtime failure,
/// 2 usage or pipeline error.
pub fn main() -> ExitCode {
    main_from(std::env::args_os())
}

/// [`main`] with the command line given (the program name first), e.g. for a benchmark
/// that runs `coarsen` in child processes of its own.
pub fn main_from<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let args: Vec<std::ffi::OsString> = args.into_iter().map(Into::into).collect();
    let cli = match Cli::try_parse_from(with_default_command(args)) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::from(2)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    let quiet = cli.quiet;
    load::set_max_faces(cli.max_faces);
    if let Some(name) = cli.gltf_mesh {
        load::set_gltf_mesh(name);
    }
    progress::init_logs(cli.verbose);
    let result = match cli.command {
        Command::Run(args) => commands::run(args, quiet),
        Command::Batch(args) => commands::batch(args, quiet),
        Command::Stages { markdown } => commands::stages(markdown),
        Command::Check {
            pipeline,
            target,
            sets,
        } => commands::check(&pipeline, &target, &sets, quiet),
        Command::Info {
            mesh,
            json,
            raw,
            weld,
        } => commands::info(&mesh, json, raw, weld),
        Command::Convert {
            input,
            output,
            ascii,
            clean,
        } => commands::convert(&input, &output, ascii, clean),
        Command::Render {
            meshes,
            output,
            attribute,
            worst,
            wireframe,
            smooth,
            view,
            views,
            size,
            supersample,
            features,
            texture,
        } => {
            let opts = coarsen_render::RenderOptions {
                width: size.0,
                height: size.1,
                view,
                views,
                smooth,
                wireframe,
                attribute,
                scale: None,
                supersample,
                features,
                texture: texture.unwrap_or_default(),
            };
            commands::render(&meshes, &output, opts, worst)
        }
        Command::Lod(args) => commands::lod(args, quiet),
        Command::Metrics {
            input,
            output,
            json,
            samples_per_face,
            min_samples,
            fields,
            input_fields,
        } => {
            let fidelity = coarsen_metrics::FidelityOptions {
                samples_per_face,
                min_face_samples: min_samples,
            };
            let files = commands::FieldFiles {
                output: fields,
                input: input_fields,
            };
            commands::metrics(&input, &output, json, fidelity, &files)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Usage(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(2)
        }
        Err(Failure::Runtime(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}
