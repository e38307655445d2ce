//! `coarsen` as the integration tests run it: the real CLI plus the example plug-in and
//! the tests' own misbehaving stage.

use coarsen_stage_smooth as _;
use coarsen_tests as _;

fn main() -> std::process::ExitCode {
    coarsen_cli::main()
}
