//! Plots of a finished run (`DIR/plots/*.svg` and `*.png`).
//!
//! A chart is laid out once into a [`Scene`] of primitives (filled rectangles, polylines,
//! text) and written as SVG (vector, for papers). The PNG (for a quick look anywhere) is that
//! same SVG rendered by `resvg`, anti-aliased, at twice its size, with the DejaVu Sans font
//! that the `dejavu` crate ships, so both files always show the same thing and a fresh machine
//! needs no font installed.

use std::path::{Path, PathBuf};

mod png;
mod run;
mod scatter;
mod svg;
mod timing;

pub use png::{rasterise, write_png};
pub use run::{write_run_plots, RunTitle, SECTION_NOTE};
pub use scatter::{write_scatter, Series};
pub use svg::to_svg;
pub use timing::write_timing_plots;

/// One line of a chart.
pub struct Line<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Values, one per time sample.
    pub y: Vec<f64>,
    /// Colour as `#rrggbb`.
    pub colour: &'a str,
    /// Dashed (limits, references).
    pub dashed: bool,
}

/// One chart.
pub struct Chart<'a> {
    /// Title.
    pub title: &'a str,
    /// X axis label with unit.
    pub x_label: &'a str,
    /// Y axis label with unit.
    pub y_label: &'a str,
    /// Lines.
    pub lines: Vec<Line<'a>>,
    /// Shaded x ranges (start, end, darker).
    pub bands: Vec<(f64, f64, bool)>,
    /// Note written inside the plot area, bottom left (what the bands mean).
    pub note: &'a str,
}

/// An RGB colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    /// Parses `#rrggbb`; anything else is black.
    pub fn hex(s: &str) -> Rgb {
        let v = s
            .strip_prefix('#')
            .filter(|h| h.len() == 6)
            .and_then(|h| u32::from_str_radix(h, 16).ok())
            .unwrap_or(0);
        Rgb((v >> 16) as u8, (v >> 8) as u8, v as u8)
    }
    fn css(self) -> String {
        format!("#{:02x}{:02x}{:02x}", self.0, self.1, self.2)
    }
}

/// Horizontal text anchor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Anchor {
    /// Text starts at x.
    Start,
    /// Text is centred on x.
    Middle,
    /// Text ends at x.
    End,
}

/// A drawing primitive in scene units (SVG pixels).
#[derive(Debug, Clone)]
pub enum Prim {
    /// A rectangle, filled and/or outlined.
    Rect {
        x: f64,
        y: f64,
        w: f64,
        h: f64,
        fill: Option<Rgb>,
        stroke: Option<Rgb>,
    },
    /// A polyline.
    Path {
        pts: Vec<(f64, f64)>,
        colour: Rgb,
        width: f64,
        /// (on, off) dash lengths.
        dash: Option<(f64, f64)>,
    },
    /// A line of text with its baseline at y.
    Text {
        x: f64,
        y: f64,
        text: String,
        size: f64,
        anchor: Anchor,
        /// Rotated 90° counter-clockwise (y axis labels).
        vertical: bool,
        bold: bool,
        colour: Rgb,
    },
}

/// A laid-out chart.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Width (px).
    pub w: f64,
    /// Height (px).
    pub h: f64,
    /// Primitives in drawing order.
    pub prims: Vec<Prim>,
}

const W: f64 = 900.0;
const H: f64 = 420.0;
const L: f64 = 80.0;
const R: f64 = 20.0;
const T: f64 = 40.0;
const B: f64 = 60.0;
const BLACK: Rgb = Rgb(0, 0, 0);

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

fn text(x: f64, y: f64, s: impl Into<String>, anchor: Anchor) -> Prim {
    Prim::Text {
        x,
        y,
        text: s.into(),
        size: 12.0,
        anchor,
        vertical: false,
        bold: false,
        colour: BLACK,
    }
}

/// Lays out `chart` over `x` (one abscissa per sample, shared by every line).
pub fn layout(chart: &Chart, x: &[f64]) -> Scene {
    let f = Frame::new(chart, x);
    let mut p = vec![Prim::Rect {
        x: 0.0,
        y: 0.0,
        w: W,
        h: H,
        fill: Some(Rgb(255, 255, 255)),
        stroke: None,
    }];
    f.bands(&mut p, &chart.bands);
    f.x_axis(&mut p);
    f.y_axis(&mut p);
    labels(&mut p, chart);
    f.lines(&mut p, chart, x);
    let legend_h = legend(
        &mut p,
        chart.lines.iter().map(|l| (l.label, l.colour, l.dashed)),
    );
    // The white background covers the legend too.
    if let Some(Prim::Rect { h, .. }) = p.first_mut() {
        *h = H + legend_h;
    }
    if !chart.note.is_empty() {
        p.push(Prim::Text {
            x: L + 6.0,
            y: H - B - 6.0,
            text: chart.note.into(),
            size: 12.0,
            anchor: Anchor::Start,
            vertical: false,
            bold: false,
            colour: Rgb(0x55, 0x55, 0x66),
        });
    }
    Scene {
        w: W,
        h: H + legend_h,
        prims: p,
    }
}

/// Width of a legend entry's sample line and the gap to its text, and between entries (px).
const LEGEND_LINE: f64 = 25.0;
const LEGEND_GAP: f64 = 22.0;
/// Height of a legend row (px).
const LEGEND_ROW: f64 = 18.0;

/// An estimate of the width of `s` at the 12 px font (DejaVu Sans averages about 0.6 em).
fn text_width(s: &str) -> f64 {
    s.chars().count() as f64 * 7.2
}

/// Draws the legend under the chart, clear of the data: entries (label, colour, dashed) left
/// to right, wrapped into rows across the canvas. Returns the height it adds to the scene.
pub(crate) fn legend<'a>(
    p: &mut Vec<Prim>,
    entries: impl Iterator<Item = (&'a str, &'a str, bool)>,
) -> f64 {
    let mut x = L;
    let mut row = 0.0;
    let mut any = false;
    for (label, colour, dashed) in entries {
        any = true;
        let w = LEGEND_LINE + 5.0 + text_width(label);
        if x > L && x + w > W - R {
            x = L;
            row += 1.0;
        }
        let y = H + 2.0 + LEGEND_ROW * row;
        p.push(Prim::Path {
            pts: vec![(x, y), (x + LEGEND_LINE, y)],
            colour: Rgb::hex(colour),
            width: 2.0,
            dash: dashed.then_some((6.0, 4.0)),
        });
        p.push(text(x + LEGEND_LINE + 5.0, y + 4.0, label, Anchor::Start));
        x += w + LEGEND_GAP;
    }
    if any {
        LEGEND_ROW * (row + 1.0) + 6.0
    } else {
        0.0
    }
}

/// The data ranges of a chart and their mapping to the drawing area.
struct Frame {
    x0: f64,
    x1: f64,
    lo: f64,
    hi: f64,
}

impl Frame {
    /// The x range of `x` and the y range of every line, padded by 5 %.
    fn new(chart: &Chart, x: &[f64]) -> Self {
        let (x0, x1) = (
            x.first().copied().unwrap_or(0.0),
            x.last().copied().unwrap_or(1.0),
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
        Frame {
            x0,
            x1,
            lo: lo - pad,
            hi: hi + pad,
        }
    }

    fn xs(&self, v: f64) -> f64 {
        L + (v - self.x0) / (self.x1 - self.x0).max(1e-12) * (W - L - R)
    }

    fn ys(&self, y: f64) -> f64 {
        T + (self.hi - y) / (self.hi - self.lo) * (H - T - B)
    }

    /// Shaded sections (light or dark) behind the data.
    fn bands(&self, p: &mut Vec<Prim>, bands: &[(f64, f64, bool)]) {
        for &(a, b, dark) in bands {
            let (a, b) = (self.xs(a.max(self.x0)), self.xs(b.min(self.x1)));
            if b > a {
                p.push(Prim::Rect {
                    x: a,
                    y: T,
                    w: b - a,
                    h: H - T - B,
                    fill: Some(if dark {
                        Rgb(0xdd, 0xe6, 0xf2)
                    } else {
                        Rgb(0xee, 0xf2, 0xf7)
                    }),
                    stroke: None,
                });
            }
        }
    }

    /// Ticks and numbers under the plot.
    fn x_axis(&self, p: &mut Vec<Prim>) {
        let st = nice_step(self.x1 - self.x0);
        let mut v = (self.x0 / st).ceil() * st;
        while v <= self.x1 + 1e-9 {
            p.push(Prim::Path {
                pts: vec![(self.xs(v), H - B), (self.xs(v), H - B + 5.0)],
                colour: BLACK,
                width: 1.0,
                dash: None,
            });
            let label = format!("{}", (v * 1e6).round() / 1e6);
            p.push(text(self.xs(v), H - B + 18.0, label, Anchor::Middle));
            v += st;
        }
    }

    /// Dotted grid lines with their numbers, and the plot's frame.
    fn y_axis(&self, p: &mut Vec<Prim>) {
        let sy = nice_step(self.hi - self.lo);
        let mut y = (self.lo / sy).ceil() * sy;
        while y <= self.hi + 1e-12 {
            p.push(Prim::Path {
                pts: vec![(L, self.ys(y)), (W - R, self.ys(y))],
                colour: Rgb(0xbb, 0xbb, 0xbb),
                width: 1.0,
                dash: Some((2.0, 3.0)),
            });
            let label = (y / sy).round() * sy;
            // Round away binary noise (0.30000000000000004); + 0.0 turns -0 into 0.
            let label = (label * 1e9).round() / 1e9 + 0.0;
            p.push(text(
                L - 6.0,
                self.ys(y) + 4.0,
                format!("{label}"),
                Anchor::End,
            ));
            y += sy;
        }
        p.push(Prim::Rect {
            x: L,
            y: T,
            w: W - L - R,
            h: H - T - B,
            fill: None,
            stroke: Some(BLACK),
        });
    }

    /// The data, decimated to at most about 2 points per pixel.
    fn lines(&self, p: &mut Vec<Prim>, chart: &Chart, x: &[f64]) {
        let step = (x.len() / 1600).max(1);
        for l in &chart.lines {
            let colour = Rgb::hex(l.colour);
            let dash = l.dashed.then_some((6.0, 4.0));
            let path = |pts| Prim::Path {
                pts,
                colour,
                width: 1.3,
                dash,
            };
            let mut pts = Vec::new();
            for i in (0..x.len().min(l.y.len())).step_by(step) {
                if l.y[i].is_finite() {
                    pts.push((self.xs(x[i]), self.ys(l.y[i])));
                } else if pts.len() > 1 {
                    // A gap in the data breaks the line.
                    p.push(path(std::mem::take(&mut pts)));
                }
            }
            p.push(path(pts));
        }
    }
}

/// Axis labels and the title.
fn labels(p: &mut Vec<Prim>, chart: &Chart) {
    p.push(text(
        (L + W - R) / 2.0,
        H - 15.0,
        chart.x_label,
        Anchor::Middle,
    ));
    p.push(Prim::Text {
        x: 18.0,
        y: (T + H - B) / 2.0,
        text: chart.y_label.into(),
        size: 12.0,
        anchor: Anchor::Middle,
        vertical: true,
        bold: false,
        colour: BLACK,
    });
    p.push(Prim::Text {
        x: L,
        y: 24.0,
        text: chart.title.into(),
        size: 15.0,
        anchor: Anchor::Start,
        vertical: false,
        bold: true,
        colour: BLACK,
    });
}

/// Writes `dir/NAME.svg` and `dir/NAME.png`; returns both paths.
pub fn write_chart(
    dir: &Path,
    name: &str,
    chart: &Chart,
    x: &[f64],
) -> std::io::Result<[PathBuf; 2]> {
    let sc = layout(chart, x);
    let svg = dir.join(format!("{name}.svg"));
    tiltsim_master::files::write_atomic(&svg, to_svg(&sc))?;
    let png = dir.join(format!("{name}.png"));
    write_png(&sc, &png)?;
    Ok([svg, png])
}

/// Writes `dir/NAME.svg` and `dir/NAME.png`: `charts` laid out one above the other over the
/// same `x` (panels of one figure, each with its own y axis and legend); returns both paths.
pub fn write_panels(
    dir: &Path,
    name: &str,
    charts: &[Chart],
    x: &[f64],
) -> std::io::Result<[PathBuf; 2]> {
    let mut all = Scene {
        w: W,
        h: 0.0,
        prims: Vec::new(),
    };
    for chart in charts {
        let sc = layout(chart, x);
        let dy = all.h;
        all.prims
            .extend(sc.prims.into_iter().map(|p| shifted(p, dy)));
        all.h += sc.h;
    }
    let svg = dir.join(format!("{name}.svg"));
    tiltsim_master::files::write_atomic(&svg, to_svg(&all))?;
    let png = dir.join(format!("{name}.png"));
    write_png(&all, &png)?;
    Ok([svg, png])
}

/// `p` moved down by `dy`.
fn shifted(p: Prim, dy: f64) -> Prim {
    match p {
        Prim::Rect {
            x,
            y,
            w,
            h,
            fill,
            stroke,
        } => Prim::Rect {
            x,
            y: y + dy,
            w,
            h,
            fill,
            stroke,
        },
        Prim::Path {
            pts,
            colour,
            width,
            dash,
        } => Prim::Path {
            pts: pts.into_iter().map(|(x, y)| (x, y + dy)).collect(),
            colour,
            width,
            dash,
        },
        Prim::Text {
            x,
            y,
            text,
            size,
            anchor,
            vertical,
            bold,
            colour,
        } => Prim::Text {
            x,
            y: y + dy,
            text,
            size,
            anchor,
            vertical,
            bold,
            colour,
        },
    }
}

/// Colours given to runs, lines or sweep samples in turn.
pub const PALETTE: [&str; 8] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
];

#[cfg(test)]
mod tests {
    use super::png::PNG_SCALE;
    use super::*;

    fn demo() -> (Chart<'static>, Vec<f64>) {
        let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.1).collect();
        let chart = Chart {
            title: "t",
            x_label: "time (s)",
            y_label: "y (m)",
            lines: vec![Line {
                label: "sin",
                y: t.iter().map(|x| x.sin()).collect(),
                colour: "#ff0000",
                dashed: false,
            }],
            bands: vec![(2.0, 4.0, false), (4.0, 6.0, true)],
            note: "n",
        };
        (chart, t)
    }

    #[test]
    fn a_chart_is_well_formed_svg_with_its_labels() {
        let (chart, t) = demo();
        let s = to_svg(&layout(&chart, &t));
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"));
        assert_eq!(s.matches("<svg").count(), 1);
        assert!(s.contains("time (s)") && s.contains("y (m)") && s.contains(">sin<"));
        // Every opened text element is closed.
        assert_eq!(s.matches("<text").count(), s.matches("</text>").count());
        assert_eq!(nice_step(10.0), 2.0);
        assert_eq!(nice_step(0.3), 0.05);
    }

    #[test]
    fn the_raster_draws_the_line_bands_and_text_where_the_scene_puts_them() {
        let (chart, t) = demo();
        let (w, h, px) = rasterise(&layout(&chart, &t)).unwrap();
        // The canvas and, under it, one row of legend.
        assert_eq!((w, h), (1800, (2.0 * (H + LEGEND_ROW + 6.0)) as u32));
        let at = |x: f64, y: f64| {
            let s = PNG_SCALE as f64;
            let i = ((y * s) as usize * w as usize + (x * s) as usize) * 3;
            Rgb(px[i], px[i + 1], px[i + 2])
        };
        // The sine at t = π/2 (its maximum) is at the top of the padded range.
        let xs = |v: f64| L + v / 9.9 * (W - L - R);
        let top = T + 0.05 / 1.1 * (H - T - B);
        let hit =
            (-3..=3).any(|d| at(xs(std::f64::consts::FRAC_PI_2), top + d as f64) == Rgb(255, 0, 0));
        assert!(hit, "the red line passes through its maximum");
        // The steady-curve band is shaded, the light band too, outside neither.
        assert_eq!(at(xs(5.0), 200.0), Rgb(0xdd, 0xe6, 0xf2));
        assert_eq!(at(xs(3.0), 250.0), Rgb(0xee, 0xf2, 0xf7));
        // The title is drawn in black at its place.
        let title = (0..40).any(|dx| at(L + dx as f64, 20.0) == BLACK);
        assert!(title);
    }
}
