//! Big blocks from `HugeBlocks` are marked for transparent huge pages.

#[global_allocator]
static ALLOCATOR: coarsen_malloc::HugeBlocks = coarsen_malloc::HugeBlocks;

/// The `VmFlags` of the mapping of this process that holds address `a`, from
/// `/proc/self/smaps`.
#[cfg(target_os = "linux")]
fn flags_at(a: usize) -> Vec<String> {
    let smaps = std::fs::read_to_string("/proc/self/smaps").expect("/proc/self/smaps");
    let mut inside = false;
    for line in smaps.lines() {
        if let Some((range, _)) = line.split_once(' ')
            && let Some((lo, hi)) = range.split_once('-')
            && let (Ok(lo), Ok(hi)) = (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
        {
            inside = (lo..hi).contains(&a);
        } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
            return flags.split_whitespace().map(str::to_owned).collect();
        }
    }
    panic!("no mapping holds {a:#x}");
}

#[cfg(target_os = "linux")]
#[test]
fn big_blocks_are_marked_for_huge_pages() {
    if !std::path::Path::new("/sys/kernel/mm/transparent_hugepage/enabled").exists() {
        println!("skipped: this kernel has no transparent huge pages");
        return;
    }
    // A process may be barred from huge pages (`prctl(PR_SET_THP_DISABLE)`, some
    // containers); the advice is then refused.
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    if status
        .lines()
        .any(|l| l.split_whitespace().eq(["THP_enabled:", "0"]))
    {
        println!("skipped: this process may not use transparent huge pages");
        return;
    }
    let big = vec![1u8; 3 * coarsen_malloc::HUGE_MIN];
    // A byte in the block's 2 MiB-aligned interior: its mapping carries the mark (`hg`).
    let middle = big.as_ptr() as usize + big.len() / 2;
    assert!(
        flags_at(middle).iter().any(|f| f == "hg"),
        "{:?}",
        flags_at(middle)
    );
    // Its content is untouched.
    assert!(big.iter().all(|&b| b == 1));
    // A block grown past the threshold is marked too.
    let mut grown = vec![2u8; 1 << 16];
    grown.resize(4 * coarsen_malloc::HUGE_MIN, 3);
    let middle = grown.as_ptr() as usize + grown.len() / 2;
    assert!(flags_at(middle).iter().any(|f| f == "hg"));
    assert_eq!((grown[0], grown[grown.len() - 1]), (2, 3));
}
