//! Text and the colour bar drawn into a picture: an 8×8 bitmap font (font8x8's public
//! domain glyphs) scaled by whole pixels.

use crate::Image;

/// The glyph of `c`: printable ASCII and the degree sign; anything else draws as `?`.
fn glyph(c: char) -> [u8; 8] {
    match c {
        '°' => font8x8::legacy::LATIN_LEGACY[0x10],
        c if c.is_ascii() && !c.is_ascii_control() => font8x8::legacy::BASIC_LEGACY[c as usize],
        _ => font8x8::legacy::BASIC_LEGACY[b'?' as usize],
    }
}

/// Width in pixels of `text` at scale `k`.
pub(crate) fn width(text: &str, k: u32) -> u32 {
    8 * k * text.chars().count() as u32
}

/// Draws `text` with its top-left corner at `(x, y)` in `color`, each font pixel a
/// `k × k` square; what falls outside the image is left out.
pub(crate) fn draw(img: &mut Image, text: &str, x: i64, y: i64, k: u32, color: [u8; 3]) {
    for (i, c) in text.chars().enumerate() {
        let rows = glyph(c);
        let x0 = x + (8 * k as usize * i) as i64;
        for (ry, bits) in rows.iter().enumerate() {
            for rx in 0..8 {
                if bits >> rx & 1 == 0 {
                    continue;
                }
                for dy in 0..k as i64 {
                    for dx in 0..k as i64 {
                        let (px, py) = (x0 + rx * k as i64 + dx, y + ry as i64 * k as i64 + dy);
                        img.set(px, py, color);
                    }
                }
            }
        }
    }
}

/// The label of tick value `x` on a scale whose ticks are `step` apart: enough decimals
/// to tell neighbouring ticks apart (two more than the step's first digit needs), in
/// scientific notation below 0.001.
pub(crate) fn tick_label(x: f64, step: f64) -> String {
    let step = step.abs();
    if x == 0.0 {
        return "0".into();
    }
    if x.abs() < 1e-2 || step.is_nan() || step <= 0.0 {
        return format!("{x:.2e}");
    }
    let decimals = (-step.log10()).ceil() as i64 + 2;
    format!("{x:.*}", decimals.clamp(0, 6) as usize)
}

/// What the colour bar shows.
pub(crate) struct Bar<'a> {
    /// The values at the bar's ends (in the attribute's units).
    pub lo: f64,
    pub hi: f64,
    /// Tick labels show value × `factor` (e.g. model units as percents of a diagonal).
    pub factor: f64,
    /// The caption under the ticks; each `; ` starts a new line.
    pub label: &'a str,
    /// Values lie below `lo`, above `hi`: the end ticks read `<lo`, `>hi`.
    pub clipped: [bool; 2],
}

impl Bar<'_> {
    fn lines(&self) -> impl Iterator<Item = &str> {
        self.label.split("; ")
    }
}

/// Height in pixels of the bar's strip at font scale `k`.
pub(crate) fn bar_height(bar: &Bar<'_>, k: u32) -> u32 {
    (38 + 10 * bar.lines().count() as u32) * k
}

/// Draws the colour bar into the strip of `img` starting at row `top`: the gradient of
/// `color` from `lo` (left) to `hi` (right), five ticks with their values, the caption.
pub(crate) fn draw_bar(
    img: &mut Image,
    top: u32,
    k: u32,
    bar: &Bar<'_>,
    color: impl Fn(f64) -> [f32; 3],
) {
    let (w, ink) = (img.width as i64, [30u8, 30, 34]);
    let bar_w = (w * 8 / 10).min(900 * k as i64).max(2);
    let (x0, y0, h) = ((w - bar_w) / 2, top as i64 + 6 * k as i64, 12 * k as i64);
    for x in 0..bar_w {
        let v = bar.lo + (bar.hi - bar.lo) * x as f64 / (bar_w - 1) as f64;
        let c = color(v).map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
        for y in 0..h {
            img.set(x0 + x, y0 + y, c);
        }
    }
    let ticks_y = y0 + h + 4 * k as i64;
    for i in 0..5 {
        let x = x0 + (bar_w - 1) * i / 4;
        for y in y0 + h..ticks_y {
            img.set(x, y, ink);
        }
        let v = bar.lo + (bar.hi - bar.lo) * i as f64 / 4.0;
        let mut s = tick_label(v * bar.factor, (bar.hi - bar.lo) / 4.0 * bar.factor);
        if i == 0 && bar.clipped[0] {
            s.insert(0, '<');
        } else if i == 4 && bar.clipped[1] {
            s.insert(0, '>');
        }
        let tw = width(&s, k) as i64;
        let tx = (x - tw / 2).clamp(0, (w - tw).max(0));
        draw(img, &s, tx, ticks_y + k as i64, k, ink);
    }
    let mut ly = ticks_y + 12 * k as i64;
    for line in bar.lines() {
        // A line too wide for the picture at scale `k` is drawn at scale 1.
        let k_line = if width(line, k) as i64 + 4 > w { 1 } else { k };
        let lw = width(line, k_line) as i64;
        draw(img, line, ((w - lw) / 2).max(2), ly, k_line, ink);
        ly += 10 * k as i64;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blank(w: u32, h: u32) -> Image {
        Image {
            width: w,
            height: h,
            rgb: vec![255; (w * h * 3) as usize],
        }
    }

    #[test]
    fn text_inks_pixels_inside_its_box_only() {
        let mut img = blank(40, 20);
        draw(&mut img, "1.5°", 2, 3, 1, [0, 0, 0]);
        let inked: Vec<(u32, u32)> = (0..20)
            .flat_map(|y| (0..40).map(move |x| (x, y)))
            .filter(|&(x, y)| img.pixel(x, y) == [0, 0, 0])
            .collect();
        assert!(inked.len() > 20);
        assert!(
            inked
                .iter()
                .all(|&(x, y)| (2..2 + 32).contains(&x) && (3..11).contains(&y))
        );
        // Off the edges: clipped, no panic.
        draw(&mut img, "88", -5, 15, 2, [0, 0, 0]);
    }

    #[test]
    fn tick_labels_tell_neighbouring_ticks_apart() {
        assert_eq!(tick_label(0.0, 0.1), "0");
        assert_eq!(tick_label(0.149, 0.149), "0.149");
        assert_eq!(tick_label(0.298, 0.149), "0.298");
        assert_eq!(tick_label(45.0, 15.0), "45.0");
        assert_eq!(tick_label(120.0, 300.0), "120");
        assert_eq!(tick_label(0.00106, 0.00035), "1.06e-3");
        assert_eq!(tick_label(0.0106, 0.0035), "0.01060");
        assert_eq!(tick_label(2.0, f64::NAN), "2.00e0");
    }

    #[test]
    fn the_bar_runs_through_the_map_from_left_to_right() {
        let bar = Bar {
            lo: 0.0,
            hi: 1.0,
            factor: 100.0,
            label: "distance; second line",
            clipped: [false, true],
        };
        assert_eq!(bar_height(&bar, 2), 2 * bar_height(&bar, 1));
        let mut img = blank(200, bar_height(&bar, 1));
        draw_bar(&mut img, 0, 1, &bar, |v| [v as f32, 0.0, 1.0 - v as f32]);
        let (left, right) = (img.pixel(22, 10), img.pixel(177, 10));
        assert!(left[2] > 240 && left[0] < 15, "{left:?}");
        assert!(right[0] > 240 && right[2] < 15, "{right:?}");
        let dark = img.rgb.chunks(3).filter(|c| c == &[30, 30, 34]).count();
        assert!(dark > 50, "ticks and captions drawn: {dark}");
    }
}
