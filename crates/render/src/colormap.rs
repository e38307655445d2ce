//! Colour maps: a perceptual map for scalars, distinct hues for labels.

/// Control points of a viridis-like map (dark blue → green → yellow), lightness increasing.
const STOPS: [[f32; 3]; 6] = [
    [0.267, 0.005, 0.329],
    [0.253, 0.265, 0.530],
    [0.164, 0.471, 0.558],
    [0.134, 0.659, 0.518],
    [0.478, 0.821, 0.3185],
    [0.993, 0.906, 0.144],
];

/// The colour of `x` on the scalar map stretched over `[lo, hi]` (clamped).
pub fn scalar_color(x: f64, lo: f64, hi: f64) -> [f32; 3] {
    let t = if hi > lo && x.is_finite() {
        ((x - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let s = t * (STOPS.len() - 1) as f64;
    let i = (s.floor() as usize).min(STOPS.len() - 2);
    let f = (s - i as f64) as f32;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    [
        a[0] + f * (b[0] - a[0]),
        a[1] + f * (b[1] - a[1]),
        a[2] + f * (b[2] - a[2]),
    ]
}

/// Control points of a cool-to-warm map (blue → light grey → red), for how bad a value is.
const BADNESS: [[f32; 3]; 5] = [
    [0.230, 0.299, 0.754],
    [0.552, 0.690, 0.996],
    [0.865, 0.865, 0.865],
    [0.958, 0.604, 0.483],
    [0.706, 0.016, 0.150],
];

/// The colour of badness `t` in `[0, 1]` (clamped; not finite counts as 0): blue for
/// good, red for bad.
pub fn badness_color(t: f64) -> [f32; 3] {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = t * (BADNESS.len() - 1) as f64;
    let i = (s.floor() as usize).min(BADNESS.len() - 2);
    let f = (s - i as f64) as f32;
    let (a, b) = (BADNESS[i], BADNESS[i + 1]);
    std::array::from_fn(|k| a[k] + f * (b[k] - a[k]))
}

/// The colour of the highlighted worst faces: magenta, on neither end of the badness map.
pub const HIGHLIGHT: [f32; 3] = [0.85, 0.0, 0.85];

/// A distinct colour for label `l`: hues a golden-ratio turn apart, alternating lightness.
pub fn label_color(l: u32) -> [f32; 3] {
    let h = (l as f64 * 0.618_033_988_749_895).fract();
    let (s, v) = if l.is_multiple_of(2) {
        (0.65, 0.95)
    } else {
        (0.55, 0.75)
    };
    hsv(h, s, v)
}

fn hsv(h: f64, s: f64, v: f64) -> [f32; 3] {
    let i = (h * 6.0).floor();
    let f = h * 6.0 - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - f * s), v * (1.0 - (1.0 - f) * s));
    let (r, g, b) = match i as i64 % 6 {
        0 => (v, t, p),
        1 => (q, v, p),
        2 => (p, v, t),
        3 => (p, q, v),
        4 => (t, p, v),
        _ => (v, p, q),
    };
    [r as f32, g as f32, b as f32]
}

/// The 2nd and 98th percentiles of the finite values, so a few outliers do not wash out the map.
pub(crate) fn robust_range(v: &[f64]) -> (f64, f64) {
    let mut finite: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if finite.is_empty() {
        return (0.0, 1.0);
    }
    finite.sort_by(f64::total_cmp);
    let at = |q: f64| finite[((finite.len() - 1) as f64 * q).round() as usize];
    (at(0.02), at(0.98))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lightness(c: [f32; 3]) -> f32 {
        0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
    }

    #[test]
    fn scalar_map_is_monotone_in_lightness_and_clamped() {
        let mut last = -1.0;
        for i in 0..=100 {
            let l = lightness(scalar_color(i as f64, 0.0, 100.0));
            assert!(l > last, "step {i}");
            last = l;
        }
        assert_eq!(scalar_color(-5.0, 0.0, 1.0), scalar_color(0.0, 0.0, 1.0));
        assert_eq!(
            scalar_color(f64::NAN, 0.0, 1.0),
            scalar_color(0.5, 0.0, 1.0)
        );
    }

    #[test]
    fn neighbouring_labels_get_clearly_different_colours() {
        for l in 0..50 {
            let (a, b) = (label_color(l), label_color(l + 1));
            let d: f32 = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum();
            assert!(d > 0.15, "labels {l} and {}: {a:?} {b:?}", l + 1);
        }
    }

    #[test]
    fn badness_runs_from_blue_to_red_through_grey() {
        let (good, mid, bad) = (badness_color(0.0), badness_color(0.5), badness_color(1.0));
        assert!(good[2] > good[0] && bad[0] > bad[2]);
        assert!((mid[0] - mid[2]).abs() < 1e-6);
        assert_eq!(badness_color(f64::NAN), good);
        assert_eq!(badness_color(7.0), bad);
    }

    #[test]
    fn robust_range_ignores_outliers() {
        let mut v: Vec<f64> = (0..100).map(f64::from).collect();
        v.push(1e9);
        v.push(f64::NAN);
        let (lo, hi) = robust_range(&v);
        assert!(lo >= 0.0 && hi < 100.0, "{lo} {hi}");
    }
}
