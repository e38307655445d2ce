//! The clustering energies: one trait, one impl per energy.
//!
//! Every energy is a sum over clusters of a term computed from the cluster's running sums
//! ([`Sums`]), so moving one face between two clusters changes the energy in O(1).

use coarsen_geom::{DVec3, triangle};

/// Running sums of one cluster's faces: count, mass, Σ w·y and Σ w·‖y‖².
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sums {
    /// Number of faces.
    pub count: f64,
    /// Total mass Σ w.
    pub mass: f64,
    /// Σ w·y over the face centroids y.
    pub first: DVec3,
    /// Σ w·‖y‖².
    pub second: f64,
}

impl Sums {
    /// The sums of one face of mass `w` and centroid `y`.
    #[inline]
    pub fn of(w: f64, y: DVec3) -> Self {
        Sums {
            count: 1.0,
            mass: w,
            first: w * y,
            second: w * y.length_squared(),
        }
    }

    /// These sums with `o` added.
    #[inline]
    pub fn plus(self, o: Sums) -> Sums {
        Sums {
            count: self.count + o.count,
            mass: self.mass + o.mass,
            first: self.first + o.first,
            second: self.second + o.second,
        }
    }

    /// These sums with `o` removed.
    #[inline]
    pub fn minus(self, o: Sums) -> Sums {
        Sums {
            count: self.count - o.count,
            mass: self.mass - o.mass,
            first: self.first - o.first,
            second: self.second - o.second,
        }
    }

    /// The weighted spread Σ w·‖y − z‖² about the mass centroid z (0 for an empty or
    /// massless cluster).
    #[inline]
    pub fn spread(&self) -> f64 {
        if self.mass > 0.0 {
            self.second - self.first.length_squared() / self.mass
        } else {
            0.0
        }
    }

    /// The mass centroid, or the origin for a massless cluster.
    #[inline]
    pub fn centroid_or_zero(&self) -> DVec3 {
        self.centroid().unwrap_or(DVec3::ZERO)
    }

    /// The mass centroid z = Σ w·y / Σ w, if the cluster has mass.
    pub fn centroid(&self) -> Option<DVec3> {
        (self.mass > 0.0).then(|| self.first / self.mass)
    }
}

/// One face as the energies see it: its mass and centroid (half the memory of its
/// [`Sums`], which the move tests read for every face they price).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FacePoint {
    /// Mass w.
    pub mass: f64,
    /// Centroid y.
    pub centroid: DVec3,
}

impl FacePoint {
    /// The sums of this face alone ([`Sums::of`]).
    #[inline]
    pub fn sums(&self) -> Sums {
        Sums::of(self.mass, self.centroid)
    }
}

/// Every face's [`FacePoint`], kept in a table or worked out from its corners when asked.
pub(crate) enum FaceData<'a> {
    /// One entry per face (layout numbering).
    Kept(Vec<FacePoint>),
    /// Worked out from the corners.
    Derived(Derived<'a>),
}

impl FaceData<'_> {
    /// Face `f`'s mass (by `energy`) and centroid.
    #[inline]
    pub(crate) fn point<E: Energy + ?Sized>(&self, f: usize, energy: &E) -> FacePoint {
        match self {
            FaceData::Kept(table) => table[f],
            FaceData::Derived(d) => d.point(f, energy),
        }
    }
}

/// Faces in the mesh's own order at density 1, their [`FacePoint`]s worked out from the
/// corners: face `f` is `corners[f]`, its corners' positions normalised as
/// `(p - center) * scale`, the same arithmetic as a table's. For a few passes over many
/// faces (the post-process's finest level), where a table of 32 bytes a face would set
/// the run's peak memory.
pub(crate) struct Derived<'a> {
    pub corners: &'a [[u32; 3]],
    pub positions: &'a [DVec3],
    pub center: DVec3,
    pub scale: f64,
}

impl Derived<'_> {
    /// Face `f`'s mass (by `energy`) and centroid.
    #[inline]
    pub(crate) fn point<E: Energy + ?Sized>(&self, f: usize, energy: &E) -> FacePoint {
        let [a, b, c] =
            self.corners[f].map(|v| (self.positions[v as usize] - self.center) * self.scale);
        FacePoint {
            mass: energy.face_mass(triangle::area(a, b, c), 1.0),
            centroid: triangle::centroid(a, b, c),
        }
    }
}

/// Where the passes read each face's [`FacePoint`]: a table, or corners and an energy.
pub(crate) trait FacePoints: Sync {
    /// Face `f`'s mass and centroid.
    fn point(&self, f: usize) -> FacePoint;
}

impl FacePoints for [FacePoint] {
    #[inline]
    fn point(&self, f: usize) -> FacePoint {
        self[f]
    }
}

/// [`Derived`] with the energy that gives the masses.
pub(crate) struct WithEnergy<'a, E: ?Sized>(pub &'a Derived<'a>, pub &'a E);

impl<E: Energy + ?Sized> FacePoints for WithEnergy<'_, E> {
    #[inline]
    fn point(&self, f: usize) -> FacePoint {
        self.0.point(f, self.1)
    }
}

/// A clustering energy: per-face masses and a per-cluster term from the running sums.
pub trait Energy: Send + Sync {
    /// The name a pipeline file gives the energy.
    fn name(&self) -> &'static str;
    /// The mass of a face of (normalised) `area` and `density` ρ at its centroid.
    fn face_mass(&self, area: f64, density: f64) -> f64;
    /// The energy term of one cluster.
    fn cluster(&self, s: &Sums) -> f64;
}

/// Below this, the cube of a whole number is exact in `f64` (its cube is under 2⁵³).
const EXACT_CUBE: f64 = 208_063.0;

/// Paper 1's Eq.(7): E⁽³⁾ = Σᵢ mᵢʳ (Σ‖yₜ‖² − ‖Σyₜ‖²/mᵢ), every face of mass 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shu2009 {
    /// The exponent r on the face count mᵢ (0 = uniform).
    pub r: f64,
}

impl Energy for Shu2009 {
    fn name(&self) -> &'static str {
        "shu2009"
    }

    fn face_mass(&self, _area: f64, _density: f64) -> f64 {
        1.0
    }

    #[inline]
    fn cluster(&self, s: &Sums) -> f64 {
        if s.count <= 0.0 {
            return 0.0;
        }
        // The common exponents without `powf`, which would dominate the move tests. `m` is
        // a whole number, so below [`EXACT_CUBE`] m·m·m is exact: what `powf` gives.
        let m = s.count;
        let scale = match self.r {
            0.0 => 1.0,
            0.5 => m.sqrt(),
            1.0 => m,
            2.0 => m * m,
            3.0 if m < EXACT_CUBE => m * m * m,
            r => m.powf(r),
        };
        scale * s.spread()
    }
}

/// Valette & Chassery 2004, Eq.(1) on faces: Σᵢ Σₜ wₜ‖yₜ − zᵢ‖² with wₜ = ρ(yₜ)·sₜ.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Valette2004;

impl Energy for Valette2004 {
    fn name(&self) -> &'static str {
        "valette2004"
    }

    fn face_mass(&self, area: f64, density: f64) -> f64 {
        area * density
    }

    #[inline]
    fn cluster(&self, s: &Sums) -> f64 {
        s.spread()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_give_the_spread_about_the_centroid() {
        let pts = [DVec3::X, -DVec3::X, DVec3::Y * 3.0];
        let s = pts
            .iter()
            .fold(Sums::default(), |s, &p| s.plus(Sums::of(2.0, p)));
        let z = s.centroid().unwrap();
        let direct: f64 = pts.iter().map(|p| 2.0 * (*p - z).length_squared()).sum();
        assert!((s.spread() - direct).abs() < 1e-12);
        let back = s.minus(Sums::of(2.0, pts[2]));
        assert!((back.spread() - 4.0).abs() < 1e-12);
        assert_eq!(Sums::default().spread(), 0.0);
    }

    #[test]
    fn shu_exponent_scales_by_the_face_count() {
        let s = Sums::of(1.0, DVec3::ZERO).plus(Sums::of(1.0, DVec3::X));
        let e0 = Shu2009 { r: 0.0 }.cluster(&s);
        let e2 = Shu2009 { r: 2.0 }.cluster(&s);
        assert!((e0 - 0.5).abs() < 1e-12);
        assert!((e2 - 4.0 * 0.5).abs() < 1e-12);
        assert_eq!(Shu2009 { r: 2.0 }.face_mass(7.0, 3.0), 1.0);
    }

    /// r = 3 without `powf` gives `powf`'s bits, up to the largest exact cube and past it.
    #[test]
    fn shu_cube_is_powf_bit_for_bit() {
        let base = Sums::of(1.0, DVec3::ZERO).plus(Sums::of(1.0, DVec3::X * 0.3));
        let counts = (1..2000).chain([65_535, 131_072, 208_062, 208_063, 208_064, 3_000_001]);
        for m in counts {
            let s = Sums {
                count: f64::from(m),
                ..base
            };
            let want = f64::from(m).powf(3.0) * s.spread();
            assert_eq!(
                Shu2009 { r: 3.0 }.cluster(&s).to_bits(),
                want.to_bits(),
                "{m}"
            );
        }
    }

    #[test]
    fn valette_mass_is_area_times_density() {
        assert_eq!(Valette2004.face_mass(2.0, 1.5), 3.0);
        let s = Sums::of(3.0, DVec3::ZERO).plus(Sums::of(1.0, DVec3::X * 4.0));
        // centroid at x = 1: 3·1 + 1·9 = 12
        assert!((Valette2004.cluster(&s) - 12.0).abs() < 1e-12);
    }
}
