//! The refinement criterion of paper 1: D(t), its statistics, the threshold δ, and the
//! density ratio λ of the stopping rule.

use coarsen_mesh::Mesh;
use serde::Serialize;

/// D(t) = (F(v₁) + F(v₂) + F(v₃)) / 3 for every face.
pub(crate) fn face_values(mesh: &Mesh, field: &[f64]) -> Vec<f64> {
    mesh.faces
        .iter()
        .map(|f| (field[f[0] as usize] + field[f[1] as usize] + field[f[2] as usize]) / 3.0)
        .collect()
}

/// Mean and sample standard deviation (m − 1; 0 for fewer than two values), in two passes.
fn mean_std(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let (m, sum) = values
        .clone()
        .fold((0usize, 0.0), |(n, s), x| (n + 1, s + x));
    if m == 0 {
        return (0.0, 0.0);
    }
    let mean = sum / m as f64;
    if m < 2 {
        return (mean, 0.0);
    }
    let ss: f64 = values.map(|x| (x - mean) * (x - mean)).sum();
    (mean, (ss / (m - 1) as f64).sqrt())
}

/// Mean D̄, sample standard deviation D̃ (m − 1), the truncation range and δ.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Criterion {
    /// Mean D̄ of D(t) over the faces (of the truncated values when so asked).
    pub mean: f64,
    /// Sample standard deviation D̃ (divided by m − 1; 0 for fewer than two faces; of the
    /// truncated values when so asked).
    pub std: f64,
    /// Lower end D̄ − 2D̃ of the truncation range.
    pub low: f64,
    /// Upper end D̄ + 2D̃ of the truncation range.
    pub high: f64,
    /// Threshold δ = D̄ + α·D̃: faces with D(t) > δ are red.
    pub delta: f64,
}

impl Criterion {
    /// The statistics of `d` (one value per face) and δ for `alpha`.
    ///
    /// The truncation range is D̄ ± 2D̃ of the raw values. With `truncated = false` (the
    /// spec's literal order) δ uses those same D̄ and D̃; truncating then changes no colour
    /// whenever `alpha < 2`, since δ lies inside the range. With `truncated = true`, D̄ and D̃
    /// are recomputed from the truncated values before δ (and the A₁/A₂ split) use them, so
    /// that a few extreme values (scan noise) no longer inflate D̃ and raise δ.
    pub(crate) fn new(d: &[f64], alpha: f64, truncated: bool) -> Criterion {
        let (mean, std) = mean_std(d.iter().copied());
        let (low, high) = (mean - 2.0 * std, mean + 2.0 * std);
        let (mean, std) = if truncated {
            mean_std(d.iter().map(|x| x.clamp(low, high)))
        } else {
            (mean, std)
        };
        Criterion {
            mean,
            std,
            low,
            high,
            delta: mean + alpha * std,
        }
    }

    /// D clamped to the truncation range.
    #[inline]
    pub fn truncate(&self, d: f64) -> f64 {
        d.clamp(self.low, self.high)
    }
}

/// Triangle density in A₁ (D(t) > D̄) and A₂ (the rest), and their ratio λ.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Density {
    /// n(A₁): faces with D(t) > D̄.
    pub n1: usize,
    /// s(A₁): their total area.
    pub s1: f64,
    /// n(A₂): the other faces.
    pub n2: usize,
    /// s(A₂): their total area.
    pub s2: f64,
}

impl Density {
    /// The split of the faces by `d` (one value per face) against `mean`. (Truncating D
    /// first would change nothing: clamping to a range that holds `mean` keeps each side.)
    pub(crate) fn new(d: &[f64], areas: &[f64], mean: f64) -> Density {
        let mut out = Density {
            n1: 0,
            s1: 0.0,
            n2: 0,
            s2: 0.0,
        };
        for (&d, &a) in d.iter().zip(areas) {
            if d > mean {
                out.n1 += 1;
                out.s1 += a;
            } else {
                out.n2 += 1;
                out.s2 += a;
            }
        }
        out
    }

    /// τ(A₁) = n(A₁)/s(A₁), triangles per unit area where the field is high (`None` when
    /// A₁ has no area).
    pub fn tau1(&self) -> Option<f64> {
        (self.s1 > 0.0).then(|| self.n1 as f64 / self.s1)
    }

    /// τ(A₂) = n(A₂)/s(A₂), triangles per unit area elsewhere (`None` when A₂ has no area).
    pub fn tau2(&self) -> Option<f64> {
        (self.s2 > 0.0).then(|| self.n2 as f64 / self.s2)
    }

    /// λ = τ(A₁)/τ(A₂); `None` when either set is empty or has no area (a constant field).
    pub fn lambda(&self) -> Option<f64> {
        match (self.tau1(), self.tau2()) {
            (Some(t1), Some(t2)) if self.n1 > 0 && self.n2 > 0 => Some(t1 / t2),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_use_the_sample_deviation_and_alpha() {
        let c = Criterion::new(&[1.0, 2.0, 3.0, 4.0], 0.8, false);
        assert_eq!(c.mean, 2.5);
        let std = (5.0f64 / 3.0).sqrt();
        assert!((c.std - std).abs() < 1e-15);
        assert!((c.delta - (2.5 + 0.8 * std)).abs() < 1e-15);
        assert_eq!(c.truncate(100.0), c.high);
        assert_eq!(c.truncate(-100.0), c.low);
        assert_eq!(c.truncate(2.0), 2.0);
        let one = Criterion::new(&[7.0], 0.8, false);
        assert_eq!((one.mean, one.std, one.delta), (7.0, 0.0, 7.0));
    }

    #[test]
    fn truncated_statistics_shrink_the_spread_of_an_outlier() {
        // Twenty zeros and one 100: the raw D̄ + 2D̃ ≈ 48.4 clamps the outlier, after which
        // the spread, and so δ, is about half.
        let mut d = vec![0.0; 20];
        d.push(100.0);
        let raw = Criterion::new(&d, 0.8, false);
        let cut = Criterion::new(&d, 0.8, true);
        assert_eq!((raw.low, raw.high), (cut.low, cut.high));
        assert!((raw.mean - 100.0 / 21.0).abs() < 1e-12);
        assert!((raw.std - (100.0 / 21.0f64.sqrt())).abs() < 1e-9);
        assert!((cut.mean - raw.high / 21.0).abs() < 1e-12);
        assert!(cut.std < 0.5 * raw.std && cut.delta < 0.5 * raw.delta);
    }

    #[test]
    fn lambda_is_the_ratio_of_densities_and_undefined_for_a_constant_field() {
        // A₁: 3 faces on area 1; A₂: 1 face on area 2 → τ₁ = 3, τ₂ = 0.5, λ = 6.
        let d = Density::new(&[5.0, 5.0, 5.0, 1.0], &[0.5, 0.25, 0.25, 2.0], 2.0);
        assert_eq!((d.n1, d.n2), (3, 1));
        assert_eq!((d.tau1(), d.tau2()), (Some(3.0), Some(0.5)));
        assert_eq!(d.lambda(), Some(6.0));
        let flat = Density::new(&[1.0, 1.0], &[1.0, 1.0], 1.0);
        assert_eq!(flat.lambda(), None);
    }
}
