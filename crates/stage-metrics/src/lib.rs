//! The `metrics` stage: measures the current mesh against the run's original input and adds
//! every figure of `coarsen-metrics` to the run report. It never changes the mesh, so it
//! may stand anywhere in a pipeline (after each stage of interest, or at the end).

use coarsen_metrics::{FidelityOptions, MetricsOptions, measure};
use coarsen_stage::{Context, Contract, Mesh, ParamIssue, Params, Stage, StageError, params};

params! {
    /// Parameters of `metrics`.
    pub struct MetricsParams {
        /// Distance samples per face on each mesh's faces (each direction sampled on its
        /// own mesh, plus every used vertex and points along every edge).
        pub samples_per_face: u32 = 100,
        /// At least this many distance samples on each mesh's faces.
        pub min_face_samples: u64 = 1_000_000,
        /// Measure fidelity against the original input (Hausdorff, mean, RMS, flips); false
        /// reports only the mesh's own quality and validity.
        pub fidelity: bool = true,
    }
}

impl Params for MetricsParams {
    fn validate(&self) -> Vec<ParamIssue> {
        let mut v = Vec::new();
        coarsen_stage::params::check_range(
            &mut v,
            "samples_per_face",
            self.samples_per_face,
            1,
            10_000,
        );
        coarsen_stage::params::check_range(
            &mut v,
            "min_face_samples",
            self.min_face_samples,
            0,
            1_000_000_000,
        );
        v
    }
}

/// The `metrics` stage.
pub struct MetricsStage(MetricsParams);

impl Stage for MetricsStage {
    type Params = MetricsParams;
    const KIND: &'static str = "metrics";
    const SUMMARY: &'static str = "Adds shape quality, fidelity to the input and validity figures of the current mesh to the report.";

    fn new(params: MetricsParams) -> Self {
        MetricsStage(params)
    }

    fn contract(&self) -> Contract {
        Contract::default()
    }

    fn run(&self, mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let opts = MetricsOptions {
            fidelity: FidelityOptions {
                samples_per_face: self.0.samples_per_face,
                min_face_samples: self.0.min_face_samples,
            },
        };
        let original = self.0.fidelity.then_some(cx.original);
        // One spinner: the sampling is a single parallel sweep.
        cx.progress.begin("metrics: sampling distances", 0);
        let report = measure(original, &mesh, &opts);
        cx.progress.end();
        let report = report.map_err(|e| StageError::Input(e.to_string()))?;
        cx.report.figure("quality", &report.quality);
        if let Some(f) = &report.fidelity {
            cx.report.figure("fidelity", f);
        }
        cx.report.figure("validity", &report.validity);
        Ok(mesh)
    }
}

coarsen_stage::export_stage!(MetricsStage);

#[cfg(test)]
mod tests {
    use super::*;
    use coarsen_stage::StageReport;

    #[test]
    fn measures_against_the_original_without_changing_the_mesh() {
        let original = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let mut coarse = coarsen_shapes::icosphere(1.0, 2).unwrap();
        coarse.positions.iter_mut().for_each(|p| *p *= 1.01);
        let mut report = StageReport::default();
        let stage = MetricsStage::new(MetricsParams::default());
        let out = stage
            .run(coarse.clone(), &mut Context::new(&original, &mut report))
            .unwrap();
        assert_eq!(out, coarse);
        let fidelity = report.get("fidelity").unwrap();
        let h = fidelity["hausdorff_pct"].as_f64().unwrap();
        assert!(h > 0.1 && h < 5.0, "{h}");
        assert_eq!(report.get("validity").unwrap()["n_faces"], 320);
    }

    #[test]
    fn fidelity_can_be_switched_off() {
        let m = coarsen_shapes::icosphere(1.0, 1).unwrap();
        let mut report = StageReport::default();
        let stage = MetricsStage::new(MetricsParams {
            fidelity: false,
            ..Default::default()
        });
        stage
            .run(m.clone(), &mut Context::new(&m, &mut report))
            .unwrap();
        assert!(report.get("fidelity").is_none());
        assert!(report.get("quality").is_some());
    }
}
