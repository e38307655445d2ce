//! `coarsen` as the integration tests run it: the real CLI plus the example plug-in.

use coarsen_stage_smooth as _;

fn main() -> std::process::ExitCode {
    coarsen_cli::main()
}
