//! Topology built from the arrays (CSR).
/// Placeholder replaced by the topology module.
pub struct Topology;
