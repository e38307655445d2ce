//! Fuzz target: every shipped pipeline, with a fuzzed target and fuzzed parameters, on a
//! small fuzzed mesh cleaned as the CLI cleans a loaded file. A run must return an error
//! or a mesh that passes the sanity check — never panic, hang or blow up (with
//! `COARSEN_FUZZ_STRICT` set, an error a stage calls internal counts as a crash too).
//!
//! The mesh is built as meshoptimizer's simplifier fuzzer builds its own: a fixed grid of
//! vertices (8 per row, at most 64) with fuzzed triangle indices, here also with fuzzed
//! perturbations of the coordinates and an optional extreme scale. Input layout (bytes
//! past the end read as 0):
//!
//! | bytes | meaning |
//! | --- | --- |
//! | 0 | shipped pipeline, index modulo their count |
//! | 1, 2–3 | target: none / vertices / faces / ratio (byte 1 mod 4), value from a `u16` |
//! | 4 | bit 0: weld on load; bit 1: scale every coordinate by `2^(8·(byte 5 as i8))`; bit 2: the runner renumbers the mesh along its Morton curve (as it does large inputs) |
//! | 6 | number of `--set` overrides (mod 4), each 6 bytes: stage, key, 4 value bytes |
//! | next | vertex count `n` = 3 + byte mod 62 |
//! | 2 per vertex | perturbation: height `(b0 as i8) / 32`, shear `(b1 as i8) / 256` |
//! | rest | triangles, 3 bytes each (indices mod `n`), at most 128 |
//!
//! Parameters that set the amount of work (`max_faces`, `max_passes`, `times`, …) are
//! capped so that one execution takes milliseconds.
#![no_main]

use coarsen_mesh::{DVec3, Mesh, hygiene, sanity, scale};
use coarsen_pipeline::{Overrides, Pipeline, RunError, RunOptions, parse_set};
use coarsen_stage::{Registry, StageError, Target};
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static REGISTRY: LazyLock<Registry> = LazyLock::new(coarsen_builtin::registry);

/// With `COARSEN_FUZZ_STRICT` set, a stage's `StageError::Internal` (an error the stage
/// itself calls a bug) is a crash too; by default only panics and invalid outputs are.
static STRICT: LazyLock<bool> = LazyLock::new(|| std::env::var_os("COARSEN_FUZZ_STRICT").is_some());

/// The bar every stage output meets: the runner's own (`sanity_check` at hygiene's
/// degenerate-area threshold, exactly zero area, so that an untouched input passes).
const OUTPUT_BAR: sanity::SanityOptions = sanity::SanityOptions {
    require_manifold: false,
    require_oriented: false,
    degenerate_area_rel: 0.0,
};

/// Caps applied before the fuzzed overrides: key and largest value.
const WORK_CAPS: &[(&str, i64)] = &[
    ("max_faces", 4096),
    ("max_passes", 20),
    ("times", 2),
    ("max_repair_rounds", 40),
    ("relax_passes", 8),
    ("samples_per_face", 3),
    ("clusters", 100),
];

/// Every string value some built-in stage accepts, and a few it does not.
const WORDS: &[&str] = &[
    "shu2009",
    "valette2004",
    "meyer",
    "angle-deficit",
    "signed",
    "absolute",
    "neighbors",
    "geodesic",
    "barycentric",
    "incident-sum",
    "closest-vertex",
    "centroid",
    "projected",
    "quadric",
    "hybrid_curvature",
    "gaussian_curvature",
    "mean_curvature",
    "color",
    "",
    "nonsense",
];

/// Floats worth trying, picked by a byte; other bytes give a value in [0, 4).
const FLOATS: &[f64] = &[
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    2.0,
    1e-300,
    1e300,
    -1e9,
    1e9,
    f64::MIN_POSITIVE,
    0.999_999,
];

/// Reads bytes from the front; past the end every byte is 0.
struct Cursor<'a>(&'a [u8]);

impl Cursor<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }

    fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }

    fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
}

fn target(c: &mut Cursor) -> Option<Target> {
    let kind = c.u8() % 4;
    let v = c.u16();
    match kind {
        1 => Some(Target::Vertices(u64::from(v % 100))),
        2 => Some(Target::Faces(u64::from(v % 300))),
        3 => Some(Target::Ratio(match v {
            65530.. => [1.0, -0.5, 1.5, f64::NAN, f64::INFINITY, 0.0][usize::from(v - 65530)],
            _ => f64::from(v) / 65530.0,
        })),
        _ => None,
    }
}

/// A TOML literal for parameter `key` whose default is `default`.
fn value(key: &str, default: &toml::Value, bytes: u32) -> String {
    let b = bytes.to_le_bytes();
    match default {
        toml::Value::Integer(_) => {
            let cap = WORK_CAPS
                .iter()
                .find(|(k, _)| *k == key)
                .map_or(1000, |&(_, c)| c + 1);
            let raw = i64::from(bytes);
            // Mostly in range; now and then a negative or huge value the check must refuse.
            match b[3] {
                255 => format!("{}", -(raw & 0xffff)),
                254 => format!("{}", i64::MAX - (raw & 0xff)),
                _ => format!("{}", (raw & 0xffff) % cap),
            }
        }
        toml::Value::Float(_) => {
            let i = usize::from(b[0]);
            let x = FLOATS
                .get(i)
                .copied()
                .unwrap_or_else(|| f64::from(u16::from_le_bytes([b[1], b[2]])) / 16384.0);
            let x = if b[3] & 1 == 1 { -x } else { x };
            // TOML spells infinities and NaN as words; Rust's `{:?}` of a finite f64 is TOML.
            format!("{x:?}")
        }
        toml::Value::Boolean(_) => format!("{}", b[0] & 1 == 1),
        _ => format!("{:?}", WORDS[usize::from(b[0]) % WORDS.len()]),
    }
}

/// The grid mesh; `flags` and `scale_byte` are bytes 4 and 5 of the layout.
fn mesh(c: &mut Cursor, flags: u8, scale_byte: u8) -> (Mesh, bool, i32) {
    let n = 3 + usize::from(c.u8() % 62);
    let positions: Vec<DVec3> = (0..n)
        .map(|i| {
            let height = f64::from(c.u8() as i8) / 32.0;
            let shear = f64::from(c.u8() as i8) / 256.0;
            DVec3::new((i % 8) as f64 + shear, (i / 8) as f64 - 0.5 * shear, height)
        })
        .collect();
    let mut faces = Vec::new();
    while !c.0.is_empty() && faces.len() < 128 {
        let n = n as u32;
        faces.push([
            u32::from(c.u8()) % n,
            u32::from(c.u8()) % n,
            u32::from(c.u8()) % n,
        ]);
    }
    let k = if flags & 2 == 2 {
        8 * i32::from(scale_byte as i8)
    } else {
        0
    };
    (Mesh::new(positions, faces), flags & 1 == 1, k)
}

fuzz_target!(|data: &[u8]| {
    let mut c = Cursor(data);
    let pipelines = coarsen_builtin::PIPELINES;
    let (name, text) = pipelines[usize::from(c.u8()) % pipelines.len()];
    let target = target(&mut c);
    let (flags, scale_byte) = (c.u8(), c.u8());
    let n_sets = c.u8() % 4;
    let set_bytes: Vec<(u8, u8, u32)> = (0..n_sets).map(|_| (c.u8(), c.u8(), c.u32())).collect();
    let (mut mesh, weld, k) = mesh(&mut c, flags, scale_byte);

    // The CLI's load path: exact rescale of extreme sizes, then hygiene.
    scale::scale_by_power_of_two(&mut mesh, k);
    let e = scale::normalizing_exponent(&mesh);
    scale::scale_by_power_of_two(&mut mesh, e);
    let opts = hygiene::HygieneOptions {
        weld,
        ..Default::default()
    };
    let Ok((mesh, _)) = hygiene::clean(mesh, &opts) else {
        return;
    };
    if mesh.n_faces() == 0 {
        return; // the CLI refuses such a file
    }

    // The stages of the chosen pipeline, for the parameter overrides.
    let file: toml::Table = toml::from_str(text).expect("shipped pipelines are TOML");
    let kinds: Vec<&str> = file["stage"]
        .as_array()
        .expect("shipped pipelines have stages")
        .iter()
        .filter_map(|s| s.get("kind")?.as_str())
        .collect();
    let mut sets = Vec::new();
    for kind in &kinds {
        let defaults = (REGISTRY.get(kind).expect("registered").defaults)();
        for (key, cap) in WORK_CAPS {
            if let Some(toml::Value::Integer(d)) = defaults.get(*key)
                && *d > *cap
            {
                sets.push(format!("{kind}.{key}={cap}"));
            }
        }
    }
    for (stage, key, bytes) in set_bytes {
        let kind = kinds[usize::from(stage) % kinds.len()];
        let defaults = (REGISTRY.get(kind).expect("registered").defaults)();
        if defaults.is_empty() {
            continue;
        }
        let (key, default) = defaults
            .iter()
            .nth(usize::from(key) % defaults.len())
            .expect("in range");
        sets.push(format!("{kind}.{key}={}", value(key, default, bytes)));
    }
    let overrides = Overrides {
        target,
        sets: sets.iter().filter_map(|s| parse_set(s).ok()).collect(),
    };
    let Ok(pipeline) = Pipeline::parse(text, name, &REGISTRY, &overrides) else {
        return; // refused parameters or target: an error, as it should be
    };
    let opts = RunOptions {
        sanity: true,
        reorder_min_faces: if flags & 4 == 4 {
            0
        } else {
            RunOptions::default().reorder_min_faces
        },
        ..Default::default()
    };
    match pipeline.run(mesh, opts) {
        Ok((out, _)) => {
            if let Err(e) = sanity::sanity_check_with(&out, &OUTPUT_BAR) {
                panic!("{name} with {sets:?}, target {target:?}: invalid output: {e}");
            }
        }
        Err(e @ RunError::Invalid { .. }) => {
            panic!("{name} with {sets:?}, target {target:?}: {e}");
        }
        Err(
            e @ RunError::Stage {
                error: StageError::Internal(_),
                ..
            },
        ) if *STRICT => {
            panic!("{name} with {sets:?}, target {target:?}: {e}");
        }
        Err(_) => {}
    }
});
