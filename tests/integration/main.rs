//! Coarsen's integration tests: one binary (ripgrep style), one module per concern.

mod cad;
mod cli;
mod data;
mod facade;
mod fidelity;
mod fields;
mod gltf;
mod hostile;
mod html;
mod lod;
mod malformed;
mod pipelines;
mod plugin;
mod properties;
