//! Plots of a finished run (`DIR/plots/*.svg` and `*.png`).
//!
//! A chart is laid out once into a [`Scene`] of primitives (filled rectangles, polylines,
//! text) and written as SVG (vector, for papers). The PNG (for a quick look anywhere) is that
//! same SVG rendered by `resvg`, anti-aliased, at twice its size, with the DejaVu Sans font
//! that the `dejavu` crate ships, so both files always show the same thing and a fresh machine
//! needs no font installed.

use std::path::{Path, PathBuf};

pub mod cite;
pub mod markup;
mod png;
mod run;
mod scatter;
mod svg;
mod timing;

pub use png::{rasterise, write_png};
pub use run::{write_run_plots, RunTitle, SECTION_NOTE};
pub use scatter::{write_scatter, write_trade_off_plot, Series};
pub use svg::to_svg;
pub use timing::TimingFigures;

/// One line of a chart. Labels may hold subscripts and superscripts ([`markup`]).
#[derive(Default)]
pub struct Line<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Values, one per time sample.
    pub y: Vec<f64>,
    /// Colour as `#rrggbb`.
    pub colour: &'a str,
    /// Dashed (limits, references).
    pub dashed: bool,
    /// A marker at each sample (few samples: the points of a grid).
    pub markers: bool,
    /// Drawn as steps: each value held until the next sample's abscissa, where the line
    /// jumps vertically (an empirical distribution function).
    pub steps: bool,
    /// No line: an open square around each finite sample, picking out points of another
    /// line (the samples of a sweep that raised a validity flag); NaN elsewhere.
    pub outline: bool,
}

/// One chart. Its text may hold subscripts and superscripts ([`markup`]).
#[derive(Default)]
pub struct Chart<'a> {
    /// Title: what is shown, and the run, compare or sweep it belongs to.
    pub title: &'a str,
    /// X axis label with unit.
    pub x_label: &'a str,
    /// Y axis label with unit.
    pub y_label: &'a str,
    /// Lines.
    pub lines: Vec<Line<'a>>,
    /// Shaded x ranges (start, end, darker).
    pub bands: Vec<(f64, f64, bool)>,
    /// Note written under the legend (what the bands mean); empty: none.
    pub note: &'a str,
    /// Caption under the note (the paper's figure of the same quantity); empty: none.
    pub caption: &'a str,
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
        /// What the text is, as the SVG's `class` ([`class`]); empty for other text.
        class: &'static str,
    },
}

/// The `class` of a chart's text elements in its SVG, for style sheets and for tools that
/// read the figure.
pub mod class {
    /// The title.
    pub const TITLE: &str = "title";
    /// The x axis label.
    pub const X_LABEL: &str = "x-label";
    /// The y axis label.
    pub const Y_LABEL: &str = "y-label";
    /// A note or caption under the legend.
    pub const NOTE: &str = "note";
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
        class: "",
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
    let legend_h = footer(
        &mut p,
        chart.lines.iter().map(Entry::of),
        &[chart.note, chart.caption],
    );
    // The white background covers the legend too.
    if let Some(Prim::Rect { h, .. }) = p.first_mut() {
        *h = H + legend_h;
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

/// Colour of the notes and captions under a chart.
const NOTE_GREY: Rgb = Rgb(0x55, 0x55, 0x66);
/// Side of a data marker (px).
const MARKER: f64 = 7.0;

/// An estimate of the width of `s` at the 12 px font (DejaVu Sans averages about 0.6 em).
fn text_width(s: &str) -> f64 {
    markup::width_in_chars(s) * 7.2
}

/// A square marker of side [`MARKER`] centred on (x, y).
fn marker(x: f64, y: f64, colour: Rgb) -> Prim {
    Prim::Rect {
        x: x - MARKER / 2.0,
        y: y - MARKER / 2.0,
        w: MARKER,
        h: MARKER,
        fill: Some(colour),
        stroke: None,
    }
}

/// Side of the open square around a picked-out sample (px).
const OUTLINE: f64 = 13.0;

/// An open square of side [`OUTLINE`] centred on (x, y), drawn as a closed path.
fn outline(x: f64, y: f64, colour: Rgb) -> Prim {
    let h = OUTLINE / 2.0;
    Prim::Path {
        pts: vec![
            (x - h, y - h),
            (x + h, y - h),
            (x + h, y + h),
            (x - h, y + h),
            (x - h, y - h),
        ],
        colour,
        width: 2.0,
        dash: None,
    }
}

/// A legend entry: how a line is drawn.
pub(crate) struct Entry<'a> {
    pub label: &'a str,
    pub colour: &'a str,
    pub dashed: bool,
    pub marker: bool,
    /// An open square and no line ([`Line::outline`]).
    pub outline: bool,
}

impl<'a> Entry<'a> {
    fn of(l: &Line<'a>) -> Self {
        Entry {
            label: l.label,
            colour: l.colour,
            dashed: l.dashed,
            marker: l.markers,
            outline: l.outline,
        }
    }
}

/// Draws the footer under the chart, clear of the data: the legend's entries left to right,
/// wrapped into rows across the canvas, then each non-empty line of `notes` in grey, wrapped
/// at words. Returns the height it adds to the scene.
pub(crate) fn footer<'a>(
    p: &mut Vec<Prim>,
    entries: impl Iterator<Item = Entry<'a>>,
    notes: &[&str],
) -> f64 {
    let mut x = L;
    let mut rows = 0.0;
    for e in entries {
        let Entry {
            label,
            colour,
            dashed,
            marker: with_marker,
            outline: open,
        } = e;
        let w = LEGEND_LINE + 5.0 + text_width(label);
        if rows == 0.0 {
            rows = 1.0;
        } else if x > L && x + w > W - R {
            x = L;
            rows += 1.0;
        }
        let y = H + 2.0 + LEGEND_ROW * (rows - 1.0);
        let colour = Rgb::hex(colour);
        if open {
            p.push(outline(x + LEGEND_LINE / 2.0, y, colour));
        } else {
            p.push(Prim::Path {
                pts: vec![(x, y), (x + LEGEND_LINE, y)],
                colour,
                width: 2.0,
                dash: dashed.then_some((6.0, 4.0)),
            });
        }
        if with_marker {
            p.push(marker(x + LEGEND_LINE / 2.0, y, colour));
        }
        p.push(text(x + LEGEND_LINE + 5.0, y + 4.0, label, Anchor::Start));
        x += w + LEGEND_GAP;
    }
    for line in notes.iter().flat_map(|n| wrap(n, W - R - L)) {
        let y = H + 2.0 + LEGEND_ROW * rows;
        p.push(Prim::Text {
            x: L,
            y: y + 4.0,
            text: line,
            size: 12.0,
            anchor: Anchor::Start,
            vertical: false,
            bold: false,
            colour: NOTE_GREY,
            class: class::NOTE,
        });
        rows += 1.0;
    }
    if rows > 0.0 {
        LEGEND_ROW * rows + 6.0
    } else {
        0.0
    }
}

/// `s` broken at spaces into lines no wider than `width` (a longer word is a line of its
/// own); none for an empty `s`.
fn wrap(s: &str, width: f64) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in s.split(' ').filter(|w| !w.is_empty()) {
        match lines.last_mut() {
            Some(l) if text_width(l) + text_width(word) + 7.2 <= width => {
                l.push(' ');
                l.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    lines
}

/// The data ranges of a chart and their mapping to the drawing area.
struct Frame {
    x0: f64,
    x1: f64,
    lo: f64,
    hi: f64,
}

impl Frame {
    /// The range of the finite `x` (widened by 3 % each side when a line has markers) and the
    /// y range of every line, padded by 5 %.
    fn new(chart: &Chart, x: &[f64]) -> Self {
        let finite = x.iter().copied().filter(|v| v.is_finite());
        let (mut x0, mut x1) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        if x0 > x1 {
            (x0, x1) = (0.0, 1.0);
        }
        if chart.lines.iter().any(|l| l.markers || l.outline) {
            // Markers at the ends stand clear of the frame.
            let pad = 0.03 * (x1 - x0).max(1e-9);
            (x0, x1) = (x0 - pad, x1 + pad);
        }
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

    /// The data, decimated to at most about 2 points per pixel; steps and markers where a
    /// line asks for them.
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
            let mut pts: Vec<(f64, f64)> = Vec::new();
            let mut marks = Vec::new();
            for i in (0..x.len().min(l.y.len())).step_by(step) {
                if l.y[i].is_finite() {
                    let (px, py) = (self.xs(x[i]), self.ys(l.y[i]));
                    // A step: the value before holds up to this abscissa, then jumps.
                    if let Some(&(x0, held)) = pts.last().filter(|_| l.steps) {
                        if x0 != px && held != py {
                            pts.push((px, held));
                        }
                    }
                    pts.push((px, py));
                    marks.push((px, py));
                } else if !pts.is_empty() && !l.outline {
                    // A gap in the data breaks the line (a point alone draws none).
                    p.push(path(std::mem::take(&mut pts)));
                }
            }
            if l.outline {
                p.extend(marks.into_iter().map(|(x, y)| outline(x, y, colour)));
                continue;
            }
            p.push(path(pts));
            if l.markers {
                p.extend(marks.into_iter().map(|(x, y)| marker(x, y, colour)));
            }
        }
    }
}

/// The title's font size: 15 px, smaller for a title that would not fit across the plot
/// (DejaVu Sans Bold averages about 0.66 em a character), but not below 10 px.
fn title_size(title: &str) -> f64 {
    let width = markup::width_in_chars(title) * 0.66;
    (15.0f64).min((W - L - R) / width.max(1.0)).max(10.0)
}

/// Axis labels and the title.
fn labels(p: &mut Vec<Prim>, chart: &Chart) {
    let mut x_label = text((L + W - R) / 2.0, H - 15.0, chart.x_label, Anchor::Middle);
    if let Prim::Text { class: c, .. } = &mut x_label {
        *c = class::X_LABEL;
    }
    p.push(x_label);
    p.push(Prim::Text {
        x: 18.0,
        y: (T + H - B) / 2.0,
        text: chart.y_label.into(),
        size: 12.0,
        anchor: Anchor::Middle,
        vertical: true,
        bold: false,
        colour: BLACK,
        class: class::Y_LABEL,
    });
    p.push(Prim::Text {
        x: L,
        y: 24.0,
        text: chart.title.into(),
        size: title_size(chart.title),
        anchor: Anchor::Start,
        vertical: false,
        bold: true,
        colour: BLACK,
        class: class::TITLE,
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
    tiltsim_rundir::files::write_atomic(&svg, to_svg(&sc))?;
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
    tiltsim_rundir::files::write_atomic(&svg, to_svg(&all))?;
    let png = dir.join(format!("{name}.png"));
    write_png(&all, &png)?;
    Ok([svg, png])
}

/// `p` moved down by `dy`.
fn shifted(mut p: Prim, dy: f64) -> Prim {
    match &mut p {
        Prim::Rect { y, .. } | Prim::Text { y, .. } => *y += dy,
        Prim::Path { pts, .. } => pts.iter_mut().for_each(|(_, y)| *y += dy),
    }
    p
}

/// Colours given to runs, lines or sweep samples in turn.
pub const PALETTE: [&str; 8] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
];

#[cfg(test)]
mod tests;
