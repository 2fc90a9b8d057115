//! Scatter charts: points of several series over their common ranges, optionally joined.

use std::path::{Path, PathBuf};

use super::{labels, legend, text, to_svg, write_png, Anchor, Chart, Frame, Line, Prim, Rgb};
use super::{Scene, H, W};

/// One series of a scatter chart: points (x, y), drawn as squares, joined in order when
/// `joined` (a front along a swept parameter), each labelled when `labels` are given.
pub struct Series<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Colour as `#rrggbb`.
    pub colour: &'a str,
    /// The points.
    pub points: Vec<(f64, f64)>,
    /// Text next to each point (empty: none).
    pub labels: Vec<String>,
    /// Join the points in order.
    pub joined: bool,
}

/// Writes `dir/NAME.svg|png`: a scatter chart of `series` over their common ranges.
pub fn write_scatter(
    dir: &Path,
    name: &str,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> std::io::Result<[PathBuf; 2]> {
    let (xr, ys) = ranges(series);
    let range = Chart {
        title,
        x_label,
        y_label,
        lines: vec![Line {
            label: "",
            y: ys,
            colour: "#000000",
            dashed: false,
        }],
        bands: Vec::new(),
        note: "",
    };
    let f = Frame::new(&range, &xr);
    let mut p = vec![Prim::Rect {
        x: 0.0,
        y: 0.0,
        w: W,
        h: H,
        fill: Some(Rgb(255, 255, 255)),
        stroke: None,
    }];
    f.x_axis(&mut p);
    f.y_axis(&mut p);
    labels(&mut p, &range);
    for se in series {
        draw_series(&mut p, &f, se);
    }
    let legend_h = legend(&mut p, series.iter().map(|s| (s.label, s.colour, false)));
    // The white background covers the legend too.
    if let Some(Prim::Rect { h, .. }) = p.first_mut() {
        *h = H + legend_h;
    }
    let sc = Scene {
        w: W,
        h: H + legend_h,
        prims: p,
    };
    let svg = dir.join(format!("{name}.svg"));
    tiltsim_master::files::write_atomic(&svg, to_svg(&sc))?;
    let png = dir.join(format!("{name}.png"));
    write_png(&sc, &png)?;
    Ok([svg, png])
}

/// The x range of the finite points of `series`, padded by 8 % each side ([0, 1] when there
/// are none), and their y values (the chart's y range is theirs).
fn ranges(series: &[Series]) -> ([f64; 2], Vec<f64>) {
    let pts = series.iter().flat_map(|s| s.points.iter().copied());
    let (mut x0, mut x1) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut ys = Vec::new();
    for (x, y) in pts.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        x0 = x0.min(x);
        x1 = x1.max(x);
        ys.push(y);
    }
    if !x0.is_finite() {
        (x0, x1) = (0.0, 1.0);
    }
    let pad = 0.08 * (x1 - x0).max(1e-6);
    ([x0 - pad, x1 + pad], ys)
}

/// Draws series `se` in frame `f`: its points as squares, joined in order when asked, each
/// with its label.
fn draw_series(p: &mut Vec<Prim>, f: &Frame, se: &Series) {
    let colour = Rgb::hex(se.colour);
    let xy: Vec<(f64, f64)> = se
        .points
        .iter()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .map(|&(x, y)| (f.xs(x), f.ys(y)))
        .collect();
    if se.joined && xy.len() > 1 {
        p.push(Prim::Path {
            pts: xy.clone(),
            colour,
            width: 1.3,
            dash: None,
        });
    }
    for (i, &(x, y)) in xy.iter().enumerate() {
        p.push(Prim::Rect {
            x: x - 3.5,
            y: y - 3.5,
            w: 7.0,
            h: 7.0,
            fill: Some(colour),
            stroke: None,
        });
        if let Some(t) = se.labels.get(i).filter(|t| !t.is_empty()) {
            p.push(text(x + 6.0, y - 6.0, t.clone(), Anchor::Start));
        }
    }
}
