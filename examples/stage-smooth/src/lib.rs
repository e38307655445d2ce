//! An example of a third-party coarsen stage: Taubin λ|μ smoothing (`smooth.taubin`).
//!
//! Nothing in coarsen's own crates names this crate. It registers itself at link time with
//! [`export_stage!`](coarsen::plugin::export_stage), from the stage API the facade
//! re-exports (`coarsen::plugin`: no dependency on coarsen's inner crates); a binary that
//! wants it links it with `use coarsen_stage_smooth as _;` (see `src/bin/coarsen-smooth.rs`,
//! a `coarsen` that also knows this stage). `examples/stage-template` is the same outside
//! the workspace, and `docs/writing-a-stage.md` walks through both.
//!
//! Taubin (1995): alternate a shrinking Laplacian step with factor λ > 0 and an inflating one
//! with μ < −λ, so that the surface is smoothed without shrinking. Uniform (umbrella) weights;
//! boundary vertices stay put unless `move_boundary` is set.

use coarsen::plugin::{
    Context, Contract, DVec3, Mesh, ParamIssue, Params, Stage, StageError, params,
};

params! {
    /// Parameters of `smooth.taubin`.
    pub struct SmoothParams {
        /// Number of λ|μ step pairs.
        pub iterations: u32 = 10,
        /// Shrinking factor λ of the first step of each pair, in (0, 1].
        pub lambda: f64 = 0.5,
        /// Inflating factor μ of the second step, negative with |μ| > λ.
        pub mu: f64 = -0.53,
        /// Let boundary vertices move too (they are kept in place by default).
        pub move_boundary: bool = false,
    }
}

impl Params for SmoothParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut v = Vec::new();
        // `!(a && b)` so that NaN is refused.
        if !(self.lambda > 0.0 && self.lambda <= 1.0) {
            v.push(ParamIssue::new(
                "lambda",
                format!("must be in (0, 1], got {}", self.lambda),
            ));
        }
        if !(self.mu < -self.lambda && self.mu >= -1.0) {
            v.push(ParamIssue::new(
                "mu",
                format!("must be in [-1, -lambda), got {}", self.mu),
            ));
        }
        coarsen::plugin::check_range(&mut v, "iterations", self.iterations, 0, 10_000);
        v
    }
}

/// The `smooth.taubin` stage.
pub struct Smooth(SmoothParams);

impl Stage for Smooth {
    type Params = SmoothParams;
    const KIND: &'static str = "smooth.taubin";
    const SUMMARY: &'static str =
        "Taubin λ|μ smoothing: removes noise without shrinking (example plug-in).";

    fn new(params: SmoothParams) -> Self {
        Smooth(params)
    }

    fn contract(&self) -> Contract {
        Contract::default()
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let (offsets, neighbours, boundary) = one_rings(&mesh);
        let mut next = mesh.positions.clone();
        cx.progress.begin("smoothing", self.0.iterations as u64);
        for i in 0..self.0.iterations {
            for factor in [self.0.lambda, self.0.mu] {
                for (v, out) in next.iter_mut().enumerate() {
                    let ring = &neighbours[offsets[v] as usize..offsets[v + 1] as usize];
                    if ring.is_empty() || (boundary[v] && !self.0.move_boundary) {
                        *out = mesh.positions[v];
                        continue;
                    }
                    let mean = ring
                        .iter()
                        .map(|&n| mesh.positions[n as usize])
                        .sum::<DVec3>()
                        / ring.len() as f64;
                    *out = mesh.positions[v] + factor * (mean - mesh.positions[v]);
                }
                std::mem::swap(&mut mesh.positions, &mut next);
            }
            cx.progress.advance(i as u64 + 1, "");
        }
        cx.progress.end();
        cx.report.figure("iterations", self.0.iterations);
        Ok(mesh)
    }
}

/// One-ring neighbours (CSR: offsets, flat list) and a boundary flag per vertex.
fn one_rings(mesh: &Mesh) -> (Vec<u32>, Vec<u32>, Vec<bool>) {
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.faces.len() * 3);
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b)));
        }
    }
    edges.sort_unstable();
    let n = mesh.n_vertices();
    let mut boundary = vec![false; n];
    let mut unique: Vec<(u32, u32)> = Vec::with_capacity(edges.len() / 2);
    for run in edges.chunk_by(|a, b| a == b) {
        let (a, b) = run[0];
        if a == b {
            continue;
        }
        if run.len() == 1 {
            boundary[a as usize] = true;
            boundary[b as usize] = true;
        }
        unique.push((a, b));
    }
    let mut offsets = vec![0u32; n + 1];
    for &(a, b) in &unique {
        offsets[a as usize + 1] += 1;
        offsets[b as usize + 1] += 1;
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut neighbours = vec![0u32; offsets[n] as usize];
    for &(a, b) in &unique {
        neighbours[fill[a as usize] as usize] = b;
        fill[a as usize] += 1;
        neighbours[fill[b as usize] as usize] = a;
        fill[b as usize] += 1;
    }
    (offsets, neighbours, boundary)
}

coarsen::plugin::export_stage!(Smooth);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen::plugin::StageReport;

    #[test]
    fn smoothing_a_noisy_sphere_reduces_roughness_without_shrinking_much() {
        let clean = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let mut noisy = clean.clone();
        for (i, p) in noisy.positions.iter_mut().enumerate() {
            // Deterministic radial noise of ±3 %.
            let s = if i % 2 == 0 { 1.03 } else { 0.97 };
            *p *= s;
        }
        // Spread of the radii about their mean: noise, whatever the overall size.
        let roughness = |m: &Mesh| {
            let r: Vec<f64> = m.positions.iter().map(|p| p.length()).collect();
            let mean = r.iter().sum::<f64>() / r.len() as f64;
            (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt()
        };
        let mut report = StageReport::default();
        let out = Smooth::new(SmoothParams::default())
            .run(noisy.clone(), &mut Context::new(&noisy, &mut report))
            .unwrap();
        assert!(
            roughness(&out) < 0.5 * roughness(&noisy),
            "{} vs {}",
            roughness(&out),
            roughness(&noisy)
        );
        let mean_radius =
            out.positions.iter().map(|p| p.length()).sum::<f64>() / out.n_vertices() as f64;
        assert!(mean_radius > 0.97, "shrank to {mean_radius}");
    }

    #[test]
    fn boundary_vertices_stay_put_by_default() {
        // 2---3
        // | \ |
        // 0---1   plus a lifted centre would move; every vertex here is on the boundary.
        let m = Mesh::new(
            vec![Default::default(), DVec3::X, DVec3::Y, DVec3::ONE],
            vec![[0, 1, 2], [1, 3, 2]],
        );
        let mut report = StageReport::default();
        let out = Smooth::new(SmoothParams::default())
            .run(m.clone(), &mut Context::new(&m, &mut report))
            .unwrap();
        assert_eq!(out.positions, m.positions);
    }
}
