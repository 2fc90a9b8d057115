//! The SVG writer: a [`Scene`]'s primitives as SVG elements.

use std::fmt::Write as _;

use super::markup::{spans, Shift, SCRIPT_SCALE};
use super::{Anchor, Prim, Rgb, Scene};

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The content of a text element: `text` escaped, its subscripts and superscripts as
/// `tspan`s lowered or raised at a smaller size (see [`super::markup`]).
fn rich(text: &str, size: f64) -> String {
    let mut s = String::new();
    for (shift, t) in spans(text) {
        let shift = match shift {
            Shift::Base => {
                s.push_str(&escape(&t));
                continue;
            }
            Shift::Sub => "sub",
            Shift::Super => "super",
        };
        let _ = write!(
            s,
            r#"<tspan baseline-shift="{shift}" font-size="{}">{}</tspan>"#,
            size * SCRIPT_SCALE,
            escape(&t)
        );
    }
    s
}

/// Writes the scene as SVG.
pub fn to_svg(sc: &Scene) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" font-family="DejaVu Sans" font-size="12">"#,
        sc.w, sc.h
    );
    for prim in &sc.prims {
        match prim {
            Prim::Rect {
                x,
                y,
                w,
                h,
                fill,
                stroke,
            } => {
                let fill = fill.map_or("none".into(), Rgb::css);
                let stroke = stroke.map_or(String::new(), |c| format!(r#" stroke="{}""#, c.css()));
                let _ = writeln!(
                    s,
                    r#"<rect x="{x:.1}" y="{y:.1}" width="{w:.1}" height="{h:.1}" fill="{fill}"{stroke}/>"#
                );
            }
            Prim::Path {
                pts,
                colour,
                width,
                dash,
            } => {
                if pts.len() < 2 {
                    continue;
                }
                let mut d = String::new();
                for (i, (x, y)) in pts.iter().enumerate() {
                    let _ = write!(d, "{}{x:.1},{y:.1} ", if i == 0 { "M" } else { "L" });
                }
                let dash = dash.map_or(String::new(), |(a, b)| {
                    format!(r#" stroke-dasharray="{a},{b}""#)
                });
                let _ = writeln!(
                    s,
                    r#"<path d="{}" fill="none" stroke="{}" stroke-width="{width}"{dash}/>"#,
                    d.trim_end(),
                    colour.css()
                );
            }
            Prim::Text {
                x,
                y,
                text,
                size,
                anchor,
                vertical,
                bold,
                colour,
                class,
            } => {
                let anchor = match anchor {
                    Anchor::Start => "start",
                    Anchor::Middle => "middle",
                    Anchor::End => "end",
                };
                let place = if *vertical {
                    format!(r#"transform="translate({x:.1},{y:.1}) rotate(-90)""#)
                } else {
                    format!(r#"x="{x:.1}" y="{y:.1}""#)
                };
                let weight = if *bold { r#" font-weight="bold""# } else { "" };
                let class = if class.is_empty() {
                    String::new()
                } else {
                    format!(r#" class="{class}""#)
                };
                let _ = writeln!(
                    s,
                    r#"<text {place} font-size="{size}" text-anchor="{anchor}" fill="{}"{weight}{class}>{}</text>"#,
                    colour.css(),
                    rich(text, *size)
                );
            }
        }
    }
    s.push_str("</svg>\n");
    s
}
