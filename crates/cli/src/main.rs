//! The `coarsen` binary.

fn main() -> std::process::ExitCode {
    // Before anything allocates much: freed memory is kept for reuse.
    coarsen_malloc::reuse_freed_memory();
    coarsen_cli::main()
}
