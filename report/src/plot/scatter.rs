//! Scatter charts: points of several series over their common ranges, optionally joined.

use std::path::{Path, PathBuf};

use super::{
    footer, labels, marker, text, to_svg, write_png, Anchor, Chart, Frame, Line, Prim, Rgb,
};
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
            ..Default::default()
        }],
        ..Default::default()
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
    let legend_h = footer(
        &mut p,
        series.iter().map(|s| super::Entry {
            label: s.label,
            colour: s.colour,
            dashed: false,
            marker: true,
            outline: false,
        }),
        &[],
    );
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
    tiltsim_rundir::files::write_atomic(&svg, to_svg(&sc))?;
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
        p.push(marker(x, y, colour));
        if let Some(t) = se.labels.get(i).filter(|t| !t.is_empty()) {
            p.push(text(x + 6.0, y - 6.0, t.clone(), Anchor::Start));
        }
    }
}

/// `out/plots/trade_off.{svg,png}`: each controller's P_CT on the curve against its lateral
/// mean comfort on the straight (nothing when no curve run has a straight twin).
pub fn write_trade_off_plot(
    points: &[crate::table4::TradeOffPoint],
    out: &std::path::Path,
) -> std::io::Result<Vec<std::path::PathBuf>> {
    if points.is_empty() {
        return Ok(Vec::new());
    }
    let series: Vec<Series> = points
        .iter()
        .enumerate()
        .map(|(k, t)| Series {
            label: &t.controller,
            colour: super::PALETTE[k % super::PALETTE.len()],
            points: vec![(t.p_ct_en12299_standing_pct, t.n_mv_lateral)],
            labels: vec![t.controller.clone()],
            joined: false,
        })
        .collect();
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots)?;
    let names: Vec<&str> = points.iter().map(|t| t.controller.as_str()).collect();
    let title = format!(
        "{}: curving comfort against straight-track ride",
        crate::analysis::compare_name(&names)
    );
    Ok(write_scatter(
        &plots,
        "trade_off",
        &title,
        "P_{CT} standing on the curve, EN 12299 per transition (%)",
        "N_{MV} lateral part on the straight, 6·a_{YP95}^{Wd} (dimensionless)",
        &series,
    )?
    .to_vec())
}
