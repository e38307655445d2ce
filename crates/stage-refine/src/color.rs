//! A perceptual colour map for showing the field on the refined mesh.
//!
//! Viridis (van der Walt & Smith, 2015, the matplotlib default): perceptually uniform,
//! readable in grey scale and by colour-blind viewers; dark blue-violet for low values,
//! green in the middle, light yellow for high ones — the light-is-curved convention of
//! paper 1's Fig. 1. Piecewise linear between eleven published key colours (at 0, 0.1, …, 1).

/// The key colours of viridis at 0, 0.1, …, 1.
const VIRIDIS: [[u8; 3]; 11] = [
    [0x44, 0x01, 0x54],
    [0x48, 0x24, 0x75],
    [0x41, 0x44, 0x87],
    [0x35, 0x5f, 0x8d],
    [0x2a, 0x78, 0x8e],
    [0x21, 0x91, 0x8c],
    [0x22, 0xa8, 0x84],
    [0x44, 0xbf, 0x70],
    [0x7a, 0xd1, 0x51],
    [0xbd, 0xdf, 0x26],
    [0xfd, 0xe7, 0x25],
];

/// The viridis colour of `t` in `[0, 1]` (clamped; NaN maps to 0).
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let w = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [0, 1, 2].map(|k| (a[k] as f64 + w * (b[k] as f64 - a[k] as f64)).round() as u8)
}

/// The colour of each value of `values` on viridis over `[low, high]` (values outside are
/// clamped; an empty or inverted range maps everything to the middle colour).
pub fn colorize(values: &[f64], low: f64, high: f64) -> Vec<[u8; 3]> {
    let span = high - low;
    values
        .iter()
        .map(|&v| {
            if span > 0.0 && span.is_finite() {
                viridis((v - low) / span)
            } else {
                viridis(0.5)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_runs_from_dark_violet_to_light_yellow_and_clamps() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
        assert_eq!(viridis(0.5), [0x21, 0x91, 0x8c]);
        // Halfway between the first two keys.
        assert_eq!(viridis(0.05), [70, 19, 101]);
        let luminance =
            |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
        let l: Vec<f64> = (0..=20)
            .map(|i| luminance(viridis(i as f64 / 20.0)))
            .collect();
        assert!(l.windows(2).all(|w| w[1] > w[0]), "brightness rises: {l:?}");
    }

    #[test]
    fn colorize_maps_the_range_ends_and_survives_an_empty_range() {
        assert_eq!(
            colorize(&[1.0, 3.0, 5.0], 1.0, 5.0),
            vec![viridis(0.0), viridis(0.5), viridis(1.0)]
        );
        assert_eq!(colorize(&[2.0], 1.0, 1.0), vec![viridis(0.5)]);
    }
}
