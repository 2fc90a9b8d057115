//! SVG plots of a finished run (`DIR/plots/*.svg`), written without a plotting library: line
//! charts with axes, ticks, units, legends, and the track sections shaded (transitions light,
//! steady curve darker).

use std::fmt::Write as _;
use std::path::Path;

/// One line of a chart.
pub struct Line<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Values, one per time sample.
    pub y: Vec<f64>,
    /// SVG colour.
    pub colour: &'a str,
    /// Dashed (limits, references).
    pub dashed: bool,
}

/// One chart.
pub struct Chart<'a> {
    /// Title.
    pub title: &'a str,
    /// Y axis label with unit.
    pub y_label: &'a str,
    /// Lines.
    pub lines: Vec<Line<'a>>,
}

const W: f64 = 900.0;
const H: f64 = 420.0;
const L: f64 = 80.0;
const R: f64 = 20.0;
const T: f64 = 40.0;
const B: f64 = 60.0;

fn nice_step(span: f64) -> f64 {
    let raw = span / 6.0;
    let mag = 10f64.powf(raw.log10().floor());
    let n = raw / mag;
    mag * if n < 1.5 {
        1.0
    } else if n < 3.5 {
        2.0
    } else if n < 7.5 {
        5.0
    } else {
        10.0
    }
}

/// Renders `chart` over time `t` (s) with shaded `sections` (start, end, is_curve).
pub fn svg(chart: &Chart, t: &[f64], sections: &[(f64, f64, bool)]) -> String {
    let (t0, t1) = (
        t.first().copied().unwrap_or(0.0),
        t.last().copied().unwrap_or(1.0),
    );
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for l in &chart.lines {
        for v in l.y.iter().filter(|v| v.is_finite()) {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    if !lo.is_finite() {
        (lo, hi) = (-1.0, 1.0);
    }
    if hi - lo < 1e-12 {
        (lo, hi) = (lo - 1.0, hi + 1.0);
    }
    let pad = 0.05 * (hi - lo);
    (lo, hi) = (lo - pad, hi + pad);
    let xs = |x: f64| L + (x - t0) / (t1 - t0).max(1e-12) * (W - L - R);
    let ys = |y: f64| T + (hi - y) / (hi - lo) * (H - T - B);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{W}" height="{H}" fill="white"/>"#);
    for &(a, b, curve) in sections {
        let fill = if curve { "#dde6f2" } else { "#eef2f7" };
        let _ = writeln!(
            s,
            r#"<rect x="{:.1}" y="{T}" width="{:.1}" height="{:.1}" fill="{fill}"/>"#,
            xs(a),
            xs(b) - xs(a),
            H - T - B
        );
    }
    // Axes and ticks.
    let _ = writeln!(
        s,
        r#"<rect x="{L}" y="{T}" width="{:.1}" height="{:.1}" fill="none" stroke="black"/>"#,
        W - L - R,
        H - T - B
    );
    let st = nice_step(t1 - t0);
    let mut x = (t0 / st).ceil() * st;
    while x <= t1 + 1e-9 {
        let _ = writeln!(
            s,
            r#"<line x1="{0:.1}" y1="{1:.1}" x2="{0:.1}" y2="{2:.1}" stroke="black"/><text x="{0:.1}" y="{3:.1}" text-anchor="middle">{4}</text>"#,
            xs(x),
            H - B,
            H - B + 5.0,
            H - B + 18.0,
            (x * 1e6).round() / 1e6
        );
        x += st;
    }
    let sy = nice_step(hi - lo);
    let mut y = (lo / sy).ceil() * sy;
    while y <= hi + 1e-12 {
        let _ = writeln!(
            s,
            r##"<line x1="{0:.1}" y1="{1:.1}" x2="{2:.1}" y2="{1:.1}" stroke="#bbbbbb" stroke-dasharray="2,3"/><text x="{3:.1}" y="{4:.1}" text-anchor="end">{5}</text>"##,
            L,
            ys(y),
            W - R,
            L - 6.0,
            ys(y) + 4.0,
            (y / sy).round() * sy
        );
        y += sy;
    }
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">time (s)</text>"#,
        (L + W - R) / 2.0,
        H - 15.0
    );
    let _ = writeln!(
        s,
        r#"<text transform="translate(18,{:.1}) rotate(-90)" text-anchor="middle">{}</text>"#,
        (T + H - B) / 2.0,
        chart.y_label
    );
    let _ = writeln!(
        s,
        r#"<text x="{L}" y="24" font-size="15" font-weight="bold">{}</text>"#,
        chart.title
    );
    // Lines, decimated to at most ~2 points per pixel.
    let step = (t.len() / 1600).max(1);
    for (k, l) in chart.lines.iter().enumerate() {
        let mut d = String::new();
        for i in (0..t.len().min(l.y.len())).step_by(step) {
            if l.y[i].is_finite() {
                let _ = write!(
                    d,
                    "{}{:.1},{:.1} ",
                    if d.is_empty() { "M" } else { "L" },
                    xs(t[i]),
                    ys(l.y[i])
                );
            }
        }
        let dash = if l.dashed {
            r#" stroke-dasharray="6,4""#
        } else {
            ""
        };
        let _ = writeln!(
            s,
            r#"<path d="{d}" fill="none" stroke="{}" stroke-width="1.3"{dash}/>"#,
            l.colour
        );
        let ly = T + 14.0 + 16.0 * k as f64;
        let _ = writeln!(
            s,
            r#"<line x1="{0:.1}" y1="{1:.1}" x2="{2:.1}" y2="{1:.1}" stroke="{3}" stroke-width="2"{dash}/><text x="{4:.1}" y="{5:.1}">{6}</text>"#,
            W - R - 230.0,
            ly,
            W - R - 205.0,
            l.colour,
            W - R - 200.0,
            ly + 4.0,
            l.label
        );
    }
    let _ = writeln!(
        s,
        r##"<text x="{:.1}" y="{:.1}" fill="#556">shaded: transitions (light), steady curve (dark)</text>"##,
        L + 6.0,
        H - B - 6.0
    );
    s.push_str("</svg>\n");
    s
}

/// Writes the standard set of plots for a run into `dir/plots/`; returns the files written.
pub fn write_run_plots(
    dir: &Path,
    cols: &[&str],
    rows: &[Vec<f64>],
    sections: &[(f64, f64, bool)],
    u_max: f64,
) -> std::io::Result<Vec<std::path::PathBuf>> {
    let col = |name: &str| -> Vec<f64> {
        let i = cols.iter().position(|c| *c == name).unwrap_or(0);
        rows.iter().map(|r| r[i]).collect()
    };
    let t = col("t");
    let deg = |v: Vec<f64>| v.into_iter().map(f64::to_degrees).collect::<Vec<_>>();
    let line = |label, y, colour, dashed| Line {
        label,
        y,
        colour,
        dashed,
    };
    let n = t.len();
    let charts = [
        (
            "lateral_acceleration",
            Chart {
                title: "Passenger lateral acceleration (eq 13; Figs 8b, 14-15)",
                y_label: "lateral acceleration (m/s²)",
                lines: vec![line("ÿ", col("lat_acc"), "#1f77b4", false)],
            },
        ),
        (
            "body_roll",
            Chart {
                title: "Carbody roll relative to the track (Figs 8a, 12-13, 16)",
                y_label: "roll (deg)",
                lines: vec![
                    line("θ_v measured", deg(col("theta_v_meas")), "#bbbbbb", false),
                    line("θ_v", deg(col("theta_v")), "#1f77b4", false),
                    line("θ̂_v estimate", deg(col("theta_v_hat")), "#2ca02c", false),
                    line(
                        "θ_v^d reference (eq 18)",
                        deg(col("theta_ref")),
                        "#d62728",
                        true,
                    ),
                ],
            },
        ),
        (
            "control",
            Chart {
                title: "Anti-roll bar: command and achieved angle with limits (Fig. 17)",
                y_label: "bar angle δ_a (deg)",
                lines: vec![
                    line("δ_a command", deg(col("delta_a_cmd")), "#ff7f0e", false),
                    line("δ_a achieved", deg(col("delta_a")), "#1f77b4", false),
                    line("+u_max", vec![u_max; n], "#d62728", true),
                    line("−u_max", vec![-u_max; n], "#d62728", true),
                ],
            },
        ),
        (
            "motor",
            Chart {
                title: "BLDC motor: electromagnetic torque and current (Fig. 18)",
                y_label: "torque (N·m), current (A)",
                lines: vec![
                    line("torque (N·m)", col("motor_torque"), "#9467bd", false),
                    line(
                        "current T_e/k_t (A)",
                        col("motor_current"),
                        "#8c564b",
                        false,
                    ),
                ],
            },
        ),
    ];
    let out = dir.join("plots");
    std::fs::create_dir_all(&out)?;
    let mut files = Vec::new();
    for (name, chart) in charts {
        let p = out.join(format!("{name}.svg"));
        std::fs::write(&p, svg(&chart, &t, sections))?;
        files.push(p);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_is_well_formed_svg_with_its_labels() {
        let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
        let chart = Chart {
            title: "t",
            y_label: "y (m)",
            lines: vec![Line {
                label: "sin",
                y: t.iter().map(|x| x.sin()).collect(),
                colour: "red",
                dashed: false,
            }],
        };
        let s = svg(&chart, &t, &[(2.0, 4.0, false), (4.0, 6.0, true)]);
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"));
        assert_eq!(s.matches("<svg").count(), 1);
        assert!(s.contains("time (s)") && s.contains("y (m)") && s.contains(">sin<"));
        // Every opened text element is closed.
        assert_eq!(s.matches("<text").count(), s.matches("</text>").count());
        assert_eq!(nice_step(10.0), 2.0);
        assert_eq!(nice_step(0.3), 0.05);
    }
}
