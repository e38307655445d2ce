//! `coarsen` with the example `smooth.taubin` stage linked in: the whole third-party path.
//!
//! Naming the crate (`use … as _`) is what makes the linker keep its registration.

use coarsen_stage_smooth as _;

fn main() -> std::process::ExitCode {
    coarsen_cli::main()
}
