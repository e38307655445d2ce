//! The `coarsen` binary.

fn main() -> std::process::ExitCode {
    coarsen_cli::main()
}
