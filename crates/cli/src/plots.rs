//! The HTML report's plots of how each stage went, as inline SVG: the CVT energy and the
//! faces moved per pass (each clustering level a line), and the collapse cost against the
//! collapses of the simplifiers. Drawn from the figures the stages put in the run report.

use coarsen_pipeline::RunReport;
use serde_json::Value;
use std::fmt::Write as _;

/// One line of a plot: its name and its points.
type Series = (String, Vec<(f64, f64)>);

/// Line colours, one per series in turn.
const COLOURS: [&str; 6] = [
    "#3a78c2", "#c2553a", "#4a9a4a", "#8a5ac2", "#c29a3a", "#555555",
];

/// A plot's frame: size and margins in pixels.
const W: f64 = 480.0;
const H: f64 = 220.0;
const LEFT: f64 = 64.0;
const BOTTOM: f64 = 36.0;
const TOP: f64 = 24.0;
const RIGHT: f64 = 24.0;

/// A line chart of `series`: `x` linear, `y` linear or logarithmic (points at or below 0
/// left out), with tick labels, the axes' names and a legend when there are several lines.
pub fn line_chart(
    title: &str,
    x_name: &str,
    y_name: &str,
    series: &[Series],
    log_y: bool,
) -> String {
    let fy = |y: f64| if log_y { y.log10() } else { y };
    let points = || {
        series
            .iter()
            .flat_map(|(_, p)| p.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite() && (!log_y || *y > 0.0))
    };
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in points() {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(fy(y)), y1.max(fy(y)));
    }
    if !(x0 <= x1 && y0 <= y1) {
        return String::new();
    }
    if x1 == x0 {
        x1 = x0 + 1.0;
    }
    if y1 == y0 {
        (y0, y1) = (y0 - 0.5, y1 + 0.5);
    }
    let sx = |x: f64| LEFT + (x - x0) / (x1 - x0) * (W - LEFT - RIGHT);
    let sy = |y: f64| H - BOTTOM - (fy(y) - y0) / (y1 - y0) * (H - BOTTOM - TOP);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"plot\" width=\"{W}\" height=\"{H}\" role=\"img\" aria-label=\"{t}\">\
         <text x=\"{LEFT}\" y=\"14\" font-size=\"12\" font-weight=\"bold\">{t}</text>\
         <rect x=\"{LEFT}\" y=\"{TOP}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#999\"/>",
        W - LEFT - RIGHT,
        H - BOTTOM - TOP,
        t = escape(title)
    );
    for i in 0..=4 {
        let x = x0 + (x1 - x0) * f64::from(i) / 4.0;
        let _ = write!(
            s,
            "<text x=\"{:.1}\" y=\"{}\" font-size=\"10\" text-anchor=\"middle\">{}</text>",
            sx(x),
            H - BOTTOM + 13.0,
            short(x)
        );
        let t = y0 + (y1 - y0) * f64::from(i) / 4.0;
        let y = if log_y { 10f64.powf(t) } else { t };
        let _ = write!(
            s,
            "<text x=\"{}\" y=\"{:.1}\" font-size=\"10\" text-anchor=\"end\">{}</text>",
            LEFT - 4.0,
            sy(y) + 3.0,
            short(y)
        );
    }
    let _ = write!(
        s,
        "<text x=\"{:.1}\" y=\"{}\" font-size=\"11\" text-anchor=\"middle\">{}</text>\
         <text x=\"12\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\" transform=\"rotate(-90 12 {:.1})\">{}</text>",
        (LEFT + W - RIGHT) / 2.0,
        H - 6.0,
        escape(x_name),
        (TOP + H - BOTTOM) / 2.0,
        (TOP + H - BOTTOM) / 2.0,
        escape(&format!("{y_name}{}", if log_y { " (log)" } else { "" }))
    );
    for (k, (name, pts)) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let path: Vec<String> = pts
            .iter()
            .filter(|(x, y)| x.is_finite() && y.is_finite() && (!log_y || *y > 0.0))
            .map(|&(x, y)| format!("{:.1},{:.1}", sx(x), sy(y)))
            .collect();
        let _ = write!(
            s,
            "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\" points=\"{}\"><title>{}</title></polyline>",
            path.join(" "),
            escape(name)
        );
        if series.len() > 1 {
            let _ = write!(
                s,
                "<text x=\"{}\" y=\"{:.1}\" font-size=\"10\" text-anchor=\"end\" fill=\"{colour}\">{}</text>",
                W - RIGHT - 4.0,
                TOP + 12.0 + 12.0 * k as f64,
                escape(name)
            );
        }
    }
    s.push_str("</svg>");
    s
}

/// The plots of a run's stages, titled, in stage order.
pub fn stage_plots(report: &RunReport) -> Vec<String> {
    let mut out = Vec::new();
    for st in &report.stages {
        let name = format!("stage {} `{}`", st.index, st.kind);
        let f = &st.figures;
        let levels = |key: &str, one: &str| -> Vec<Vec<f64>> {
            match f.get(key).and_then(numbers_2d) {
                Some(levels) => levels,
                None => f.get(one).and_then(numbers).into_iter().collect(),
            }
        };
        let energy = levels("energy_per_pass_per_level", "energy_per_pass");
        if !energy.is_empty() {
            let moves = levels("moves_per_pass_per_level", "moves_per_pass");
            // Each level's energy over its own first pass's, so the levels share an axis.
            let relative: Vec<Vec<f64>> = energy
                .iter()
                .map(|e| {
                    e.iter()
                        .map(|x| x / e.first().copied().unwrap_or(1.0))
                        .collect()
                })
                .collect();
            let title = format!("{name}: CVT energy per pass (over the first pass's)");
            out.push(line_chart(
                &title,
                "pass",
                "energy",
                &by_level(&relative),
                false,
            ));
            let title = format!("{name}: faces moved per pass");
            out.push(line_chart(
                &title,
                "pass",
                "faces moved",
                &by_level(&moves),
                true,
            ));
        }
        if let Some(curve) = f.get("cost_curve").and_then(numbers_2d) {
            let pts: Vec<(f64, f64)> = curve
                .iter()
                .filter(|b| b.len() == 2)
                .map(|b| (b[0], b[1]))
                .collect();
            let title = format!("{name}: collapse cost against collapses");
            let series = [("largest cost in each bin".to_string(), pts)];
            out.push(line_chart(&title, "collapses", "cost", &series, true));
        }
    }
    out.retain(|s| !s.is_empty());
    out
}

/// Each level's values against the pass number (from 1), named by level when several.
fn by_level(levels: &[Vec<f64>]) -> Vec<Series> {
    levels
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let name = if levels.len() > 1 {
                format!("level {}", k + 1)
            } else {
                "passes".into()
            };
            (
                name,
                v.iter()
                    .enumerate()
                    .map(|(i, &y)| ((i + 1) as f64, y))
                    .collect(),
            )
        })
        .collect()
}

fn numbers(v: &Value) -> Option<Vec<f64>> {
    v.as_array()?.iter().map(Value::as_f64).collect()
}

fn numbers_2d(v: &Value) -> Option<Vec<Vec<f64>>> {
    v.as_array()?.iter().map(numbers).collect()
}

/// A tick value in few characters.
fn short(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{x:.1e}")
    } else if a >= 100.0 {
        format!("{x:.0}")
    } else {
        format!("{x:.3}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_has_one_line_per_series_inside_its_frame() {
        let a = (
            "level 1".to_string(),
            vec![(1.0, 10.0), (2.0, 5.0), (3.0, 1.0)],
        );
        let b = ("level 2".to_string(), vec![(1.0, 8.0), (2.0, 0.0)]);
        let svg = line_chart("t <x>", "pass", "moved", &[a, b], true);
        assert_eq!(svg.matches("<polyline").count(), 2);
        assert!(svg.contains("t &lt;x&gt;") && svg.contains("moved (log)"));
        // The zero is left out of a log axis: level 2 has one point.
        let level2 = svg.split("<polyline").nth(2).unwrap();
        let points = level2
            .split("points=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap();
        assert_eq!(points.split(' ').count(), 1);
        // Every point inside the frame.
        for p in svg.split("points=\"").skip(1) {
            for xy in p.split('"').next().unwrap().split(' ') {
                let (x, y) = xy.split_once(',').unwrap();
                let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
                assert!((LEFT..=W - RIGHT).contains(&x) && (TOP..=H - BOTTOM).contains(&y));
            }
        }
        assert_eq!(line_chart("empty", "x", "y", &[], false), "");
        assert_eq!(
            (short(0.25), short(1500.0), short(2e-5)),
            ("0.25".into(), "1500".into(), "2.0e-5".into())
        );
    }
}
