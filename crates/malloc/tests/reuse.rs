//! A big block freed by the main thread is reused without its pages being faulted in
//! again. Runs without the test harness: the harness would run it on a thread of its own,
//! whose malloc arena hands a heap that falls empty back to the system whatever the
//! settings (the programs' big tables are mostly the main thread's).

/// Minor page faults of this process so far (field 10 of `/proc/self/stat`).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn minor_faults() -> u64 {
    let stat = std::fs::read_to_string("/proc/self/stat").expect("/proc/self/stat");
    // The command name (field 2) is in parentheses and may hold spaces.
    let rest = &stat[stat.rfind(')').expect("a command name") + 2..];
    rest.split_whitespace()
        .nth(7)
        .and_then(|x| x.parse().ok())
        .expect("a fault count")
}

/// Allocates `bytes`, writes every page, frees it; the minor faults that took.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn faults_of_a_block(bytes: usize) -> u64 {
    let before = minor_faults();
    let mut v = vec![0u8; bytes];
    for i in (0..bytes).step_by(4096) {
        v[i] = 1;
    }
    std::hint::black_box(&v);
    drop(v);
    minor_faults() - before
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn main() {
    // 320 MiB: above the 32 MiB up to which glibc may serve a block from its heap anyway,
    // and above the 256 MiB of free space the settings kept at the top of the heap before
    // they kept all of it (a block that size was handed back when freed).
    const BYTES: usize = 320 << 20;
    let pages = (BYTES / 4096) as u64;
    // Without the settings every round faults the whole block in again (unless the system
    // backs every mapping with huge pages: then few faults either way).
    let plain: Vec<u64> = (0..2).map(|_| faults_of_a_block(BYTES)).collect();
    let huge = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled")
        .is_ok_and(|s| s.contains("[always]"));
    assert!(
        huge || plain.iter().all(|&f| f >= pages / 2),
        "without the settings: {plain:?} faults for {pages} pages"
    );
    assert!(
        coarsen_malloc::reuse_freed_memory(),
        "the settings did not take"
    );
    // The first round takes the block from the system; the next ones reuse it.
    let reused: Vec<u64> = (0..3).map(|_| faults_of_a_block(BYTES)).collect();
    assert!(
        reused[1..].iter().all(|&f| f < pages / 10),
        "with the settings: {reused:?} faults for {pages} pages"
    );
    println!("test a_big_block_freed_is_reused ... ok ({plain:?} → {reused:?} faults)");
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn main() {
    assert!(!coarsen_malloc::reuse_freed_memory());
    println!("test reuse_freed_memory_changes_nothing_here ... ok");
}
