//! The `metrics` stage: measures the current mesh against the run's original input and adds
//! every figure of `coarsen-metrics` to the run report. It never changes the mesh's
//! geometry, so it may stand anywhere in a pipeline (after each stage of interest, or at
//! the end); with `fields` it adds the figures element by element as attribute columns
//! (`coarsen_metrics::fields`), which a PLY output carries for MeshLab or ParaView.

use coarsen_metrics::fields::{
    FACE_DISTANCE, FACE_FLIPPED, FACE_MIN_ANGLE, FACE_QUALITY, VERTEX_DISTANCE,
};
use coarsen_metrics::{FidelityOptions, MetricsOptions, measure, measure_with_fields};
use coarsen_stage::{
    AttrKind, AttrRef, Context, Contract, Mesh, ParamIssue, Params, Stage, StageError, params,
};

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
        /// Add the fields to the mesh: vertex `quality` (distance to the input, in model
        /// units), face `distance` (largest over the face), `min_angle` (degrees),
        /// `quality` (Frey–Borouchaki Q) and `flipped` (1 when turned over); needs
        /// `fidelity`.
        pub fields: bool = false,
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
        if self.fields && !self.fidelity {
            v.push(ParamIssue::new(
                "fields",
                "the fields are distances to the input: they need fidelity = true",
            ));
        }
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
        if !self.0.fields {
            return Contract {
                carries_wedges: true,
                ..Contract::default()
            };
        }
        let mut writes = vec![AttrRef::vertex(VERTEX_DISTANCE, AttrKind::Scalar)];
        for name in [FACE_DISTANCE, FACE_MIN_ANGLE, FACE_QUALITY] {
            writes.push(AttrRef::face(name, AttrKind::Scalar));
        }
        writes.push(AttrRef::face(FACE_FLIPPED, AttrKind::Label));
        Contract {
            writes,
            carries_wedges: true,
            ..Contract::default()
        }
    }

    fn run(&self, mut mesh: Mesh, cx: &mut Context<'_>) -> Result<Mesh, StageError> {
        let opts = MetricsOptions {
            fidelity: FidelityOptions {
                samples_per_face: self.0.samples_per_face,
                min_face_samples: self.0.min_face_samples,
            },
        };
        let original = self.0.fidelity.then_some(cx.original);
        // One spinner: the sampling is a single parallel sweep.
        cx.progress.begin("metrics: sampling distances", 0);
        let report = if self.0.fields {
            measure_with_fields(cx.original, &mesh, &opts).map(|(report, fields)| {
                fields.output.attach(&mut mesh);
                report
            })
        } else {
            measure(original, &mesh, &opts)
        };
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
    fn fields_are_added_as_columns_and_the_geometry_kept() {
        let original = coarsen_shapes::icosphere(1.0, 3).unwrap();
        let coarse = coarsen_shapes::icosphere(1.0, 1).unwrap();
        let mut report = StageReport::default();
        let stage = MetricsStage::new(MetricsParams {
            fields: true,
            ..Default::default()
        });
        let written: Vec<String> = stage
            .contract()
            .writes
            .iter()
            .map(|a| a.name.clone())
            .collect();
        assert_eq!(
            written,
            ["quality", "distance", "min_angle", "quality", "flipped"]
        );
        let out = stage
            .run(coarse.clone(), &mut Context::new(&original, &mut report))
            .unwrap();
        assert_eq!(
            (&out.positions, &out.faces),
            (&coarse.positions, &coarse.faces)
        );
        // The coarse sphere's vertices lie on the fine one: distance 0 there, and its
        // faces cut inside, up to the reported output → input maximum.
        let d = out.vertex_attrs.scalar("quality").unwrap();
        assert!(d.iter().all(|&x| x < 1e-9), "{d:?}");
        let faces = out.face_attrs.scalar("distance").unwrap();
        let largest = faces.iter().copied().fold(0.0, f64::max);
        let pct = report.get("fidelity").unwrap()["backward_max_pct"]
            .as_f64()
            .unwrap();
        assert!((100.0 * largest / original.bbox().diagonal() - pct).abs() < 1e-9);
        assert!(
            out.face_attrs
                .scalar("min_angle")
                .unwrap()
                .iter()
                .all(|&a| a > 50.0)
        );
        let off = MetricsParams {
            fields: true,
            fidelity: false,
            ..Default::default()
        };
        assert_eq!(off.validate()[0].field, "fields");
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
