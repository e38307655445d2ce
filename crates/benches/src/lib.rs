//! `coarsen-benches`: the benchmarks of coarsen's crates, in `benches/` (criterion, and the
//! simplifiers against meshoptimizer in `qem`), and the meshes they share.
//!
//! ```sh
//! cargo bench -p coarsen-benches                       # every benchmark
//! cargo bench -p coarsen-benches --bench qem -- scale  # QEM and SVEC against meshoptimizer at 4.4M faces
//! ```
//!
//! They live apart from the crates they measure so that `cargo test` builds none of their
//! dependencies (criterion, meshoptimizer and their trees). The timing tools among them
//! (`throughput`, `scale`, `build_timing`) take their input after `--`.

pub mod meshes;

/// The arguments of a timing tool run as a bench target (`cargo bench -p coarsen-benches
/// --bench NAME -- ARGS`), without the program's name and the `--bench` cargo adds; `None`,
/// after printing `usage`, when cargo ran the tool among all the benchmarks and its first
/// argument is not one of its own (`mine`).
pub fn tool_args(usage: &str, mine: impl Fn(&str) -> bool) -> Option<Vec<String>> {
    let all: Vec<String> = std::env::args().skip(1).collect();
    let under_cargo = all.iter().any(|a| a == "--bench");
    let args: Vec<String> = all.into_iter().filter(|a| a != "--bench").collect();
    if under_cargo && !args.first().is_some_and(|a| mine(a)) {
        eprintln!("{usage} (nothing to time: skipped)");
        return None;
    }
    Some(args)
}

/// User plus system CPU seconds of this process so far, all threads (Linux's
/// `/proc/self/stat`, in ticks of 1/100 s); NaN where it cannot be read.
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // The fields after the command name, which is in parentheses and may hold spaces:
    // utime and stime are the 12th and 13th of them.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let field = |i: usize| {
        rest.split_whitespace()
            .nth(i)
            .and_then(|x| x.parse::<f64>().ok())
    };
    match (field(11), field(12)) {
        (Some(user), Some(system)) => (user + system) / 100.0,
        _ => f64::NAN,
    }
}
