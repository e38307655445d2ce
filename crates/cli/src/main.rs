//! The `coarsen` binary.

/// Big blocks on huge pages (see `coarsen-malloc`).
#[global_allocator]
static ALLOCATOR: coarsen_malloc::HugeBlocks = coarsen_malloc::HugeBlocks;

fn main() -> std::process::ExitCode {
    // Before anything allocates much: freed memory is kept for reuse.
    coarsen_malloc::reuse_freed_memory();
    coarsen_cli::main()
}
