//! `coarsen-sharp`: the `coarsen` command with `density.sharp` linked in.

// Naming the crate is what links it, and with it the stage's registration: a crate that
// is only a dependency and never named is left out by the linker.
use sharp_density as _;

fn main() -> std::process::ExitCode {
    coarsen_cli::main()
}
