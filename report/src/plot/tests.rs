//! The chart layout, its SVG and its raster.

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
            ..Default::default()
        }],
        bands: vec![(2.0, 4.0, false), (4.0, 6.0, true)],
        note: "shaded: the bands",
        caption: "cf. the paper's Fig. 1",
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
    // The canvas and, under it, one row of legend, the note and the caption.
    assert_eq!((w, h), (1800, (2.0 * (H + 3.0 * LEGEND_ROW + 6.0)) as u32));
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

/// The rendered pixels of `sc` and a reader of the pixel at scene coordinates.
fn pixels(sc: &Scene) -> impl Fn(f64, f64) -> Rgb {
    let (w, _, px) = rasterise(sc).unwrap();
    move |x: f64, y: f64| {
        let s = PNG_SCALE as f64;
        let i = ((y * s) as usize * w as usize + (x * s) as usize) * 3;
        Rgb(px[i], px[i + 1], px[i + 2])
    }
}

#[test]
fn the_note_and_the_caption_are_under_the_legend_clear_of_the_data() {
    let (chart, t) = demo();
    let sc = layout(&chart, &t);
    let notes: Vec<(f64, &str)> = sc
        .prims
        .iter()
        .filter_map(|p| match p {
            Prim::Text { y, text, class, .. } if *class == class::NOTE => Some((*y, text.as_str())),
            _ => None,
        })
        .collect();
    assert_eq!(
        notes.iter().map(|n| n.1).collect::<Vec<_>>(),
        ["shaded: the bands", "cf. the paper's Fig. 1"]
    );
    // Below the x axis label and the legend's row, inside the canvas.
    assert!(notes.iter().all(|(y, _)| *y > H + LEGEND_ROW && *y < sc.h));
    // Where the note used to be written, inside the plot area, no text: nothing darker
    // than the dotted grid.
    let at = pixels(&sc);
    for x in (L as usize + 3..L as usize + 150).step_by(2) {
        for y in (H - B) as usize - 16..(H - B) as usize - 2 {
            let c = at(x as f64, y as f64);
            assert!(c.0.min(c.1).min(c.2) >= 150, "({x}, {y}): {c:?}");
        }
    }
    // The note's grey is drawn under the legend.
    let grey = (0..60).any(|dx| {
        let c = at(L + dx as f64, notes[0].0 - 4.0);
        c != Rgb(255, 255, 255) && c.0 == c.1
    });
    assert!(grey);
    // A long note is wrapped at words within the canvas.
    let long = ["word"; 60].join(" ");
    let lines = wrap(&long, W - R - L);
    assert!(lines.len() > 1 && lines.iter().all(|l| text_width(l) <= W - R - L));
    assert_eq!(lines.join(" "), long);
}

/// The points of the paths drawn in `colour`.
fn paths_in(sc: &Scene, colour: Rgb) -> Vec<Vec<(f64, f64)>> {
    sc.prims
        .iter()
        .filter_map(|p| match p {
            Prim::Path { pts, colour: c, .. } if *c == colour && pts.len() > 2 => Some(pts.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_step_line_holds_each_value_until_the_next_abscissa_then_jumps() {
    // An empirical distribution function: the smallest value twice, from 0.
    let x = [1.0, 1.0, 2.0, 4.0];
    let chart = Chart {
        title: "t",
        lines: vec![Line {
            label: "ecdf",
            y: vec![0.0, 1.0, 2.0, 3.0],
            colour: "#00ff00",
            steps: true,
            ..Default::default()
        }],
        ..Default::default()
    };
    let sc = layout(&chart, &x);
    let paths = paths_in(&sc, Rgb(0, 255, 0));
    assert_eq!(paths.len(), 1);
    let pts = &paths[0];
    assert_eq!(pts.len(), 6, "each abscissa twice: {pts:?}");
    for pair in pts.chunks(2) {
        // At each abscissa the line rises (SVG y grows downwards).
        assert_eq!(pair[0].0, pair[1].0);
        assert!(pair[1].1 < pair[0].1);
    }
    for seg in pts[1..].chunks(2).filter(|s| s.len() == 2) {
        // Between abscissae it holds its value.
        assert_eq!(seg[0].1, seg[1].1);
        assert!(seg[1].0 > seg[0].0);
    }
    // Without steps the same data is a polyline through the points.
    let mut plain = chart;
    plain.lines[0].steps = false;
    assert_eq!(paths_in(&layout(&plain, &x), Rgb(0, 255, 0))[0].len(), 4);
}

#[test]
fn a_marked_line_has_a_marker_at_each_point_and_in_its_legend() {
    let x = [0.1, 0.3, 0.5, 0.7, 0.9];
    let chart = Chart {
        title: "t",
        lines: vec![Line {
            label: "P",
            y: vec![3.0, 2.0, f64::NAN, 1.5, 1.0],
            colour: "#0000ff",
            markers: true,
            ..Default::default()
        }],
        ..Default::default()
    };
    let sc = layout(&chart, &x);
    let markers: Vec<(f64, f64)> = sc
        .prims
        .iter()
        .filter_map(|p| match p {
            Prim::Rect {
                x,
                y,
                w,
                fill: Some(c),
                ..
            } if *c == Rgb(0, 0, 255) && *w == MARKER => {
                Some((*x + MARKER / 2.0, *y + MARKER / 2.0))
            }
            _ => None,
        })
        .collect();
    // One per finite point, on the data, and one in the legend under the canvas.
    assert_eq!(markers.len(), 5, "{markers:?}");
    let f = Frame::new(&chart, &x);
    for (k, i) in [0, 1, 3, 4].into_iter().enumerate() {
        assert_eq!(markers[k], (f.xs(x[i]), f.ys(chart.lines[0].y[i])));
    }
    assert!(markers[4].1 > H);
    let at = pixels(&sc);
    // None where the value is missing.
    assert_eq!(at(f.xs(0.5), f.ys(1.75)), Rgb(255, 255, 255));
    assert_eq!(at(markers[0].0 + 2.0, markers[0].1 + 2.0), Rgb(0, 0, 255));
}

/// The rows (scene units) holding ink of a text drawn alone at 40 px, baseline at y = 60.
fn ink_rows(s: &str) -> (f64, f64) {
    let sc = Scene {
        w: 200.0,
        h: 100.0,
        prims: vec![Prim::Text {
            x: 10.0,
            y: 60.0,
            text: s.into(),
            size: 40.0,
            anchor: Anchor::Start,
            vertical: false,
            bold: false,
            colour: BLACK,
            class: "",
        }],
    };
    let at = pixels(&sc);
    let inked = |y: f64| (0..380).any(|x| at(x as f64 * 0.5, y) != Rgb(255, 255, 255));
    let rows: Vec<f64> = (0..200)
        .map(|y| y as f64 * 0.5)
        .filter(|&y| inked(y))
        .collect();
    (rows[0], rows[rows.len() - 1])
}

#[test]
fn subscripts_and_superscripts_are_lowered_and_raised_not_written_as_markup() {
    let chart = Chart {
        title: "θ_{v}^{d} reference",
        y_label: "bar angle δ_{a} (deg)",
        lines: vec![Line {
            label: "θ_{v}^{d} reference (eq 18)",
            y: vec![0.0, 1.0],
            ..Default::default()
        }],
        ..Default::default()
    };
    let svg = to_svg(&layout(&chart, &[0.0, 1.0]));
    assert!(svg.contains(concat!(
        r#"θ<tspan baseline-shift="sub" font-size="9">v</tspan>"#,
        r#"<tspan baseline-shift="super" font-size="9">d</tspan> reference (eq 18)"#
    )));
    assert!(svg.contains(r#"δ<tspan baseline-shift="sub" font-size="9">a</tspan> (deg)"#));
    assert!(!svg.contains("_{") && !svg.contains("^{") && !svg.contains("^d"));
    assert_eq!(
        svg.matches("<tspan").count(),
        svg.matches("</tspan>").count()
    );
    // The PNG draws them: x with a raised x reaches higher than xx, with a lowered x lower.
    let (top, bottom) = ink_rows("xx");
    assert!(ink_rows("x^{x}").0 < top - 3.0, "superscript raised");
    assert!(ink_rows("x_{x}").1 > bottom + 3.0, "subscript lowered");
}

#[test]
fn a_long_title_is_set_smaller_to_fit_across_the_plot() {
    assert_eq!(
        title_size("paper-lqg (LQG): carbody roll relative to the track"),
        15.0
    );
    let long = "Sweep of paper-lqg (±22 %, 20 samples): passenger lateral acceleration across the perturbed vehicles";
    let size = title_size(long);
    assert!((10.0..15.0).contains(&size));
    assert!(markup::width_in_chars(long) * 0.66 * size <= W - L - R + 1e-9);
}

#[test]
fn a_compare_is_named_by_its_runs_within_a_title() {
    use crate::analysis::compare_name;
    assert_eq!(compare_name(&["a", "b"]), "Compare of a, b");
    let many = [
        "paper-passive",
        "paper-pi",
        "paper-lqg",
        "paper-mpc",
        "pi-drive",
    ];
    assert_eq!(
        compare_name(&many),
        "Compare of paper-passive, paper-pi, paper-lqg and 2 more"
    );
    let one = "a-scenario-with-a-name-longer-than-any-title-would-hold";
    assert_eq!(
        compare_name(&[one, "b"]),
        format!("Compare of {one} and 1 more")
    );
}

#[test]
fn an_outlined_line_rings_its_finite_points_and_draws_no_line() {
    let x = [0.1, 0.3, 0.5, 0.7, 0.9];
    let ring = Rgb(0, 0, 0x80);
    let chart = Chart {
        title: "t",
        lines: vec![
            Line {
                label: "all",
                y: vec![3.0, 2.0, 1.8, 1.5, 1.0],
                colour: "#00ff00",
                ..Default::default()
            },
            Line {
                label: "picked",
                y: vec![f64::NAN, 2.0, f64::NAN, 1.5, f64::NAN],
                colour: "#000080",
                outline: true,
                ..Default::default()
            },
        ],
        ..Default::default()
    };
    let sc = layout(&chart, &x);
    let f = Frame::new(&chart, &x);
    let rings = paths_in(&sc, ring);
    // A closed square centred on each picked point, one in the legend, and no polyline
    // joining the two picked points across the gap.
    assert_eq!(rings.len(), 3, "{rings:?}");
    for (k, i) in [1, 3].into_iter().enumerate() {
        let square = &rings[k];
        assert_eq!(square.len(), 5);
        assert_eq!(square[0], square[4]);
        let centre = (
            (square[0].0 + square[2].0) / 2.0,
            (square[0].1 + square[2].1) / 2.0,
        );
        assert_eq!(centre, (f.xs(x[i]), f.ys(chart.lines[1].y[i])));
        assert_eq!(square[2].0 - square[0].0, OUTLINE);
    }
    let legend_centre = (rings[2][0].1 + rings[2][2].1) / 2.0;
    assert!(legend_centre > H, "the legend's square is under the canvas");
}

#[test]
fn a_lone_point_before_a_gap_is_not_joined_across_it() {
    let x = [0.1, 0.3, 0.5, 0.7];
    let chart = Chart {
        title: "t",
        lines: vec![Line {
            label: "gappy",
            y: vec![1.0, f64::NAN, 2.0, 3.0],
            colour: "#00ff00",
            ..Default::default()
        }],
        ..Default::default()
    };
    let sc = layout(&chart, &x);
    let f = Frame::new(&chart, &x);
    let drawn: Vec<Vec<(f64, f64)>> = sc
        .prims
        .iter()
        .filter_map(|p| match p {
            Prim::Path { pts, colour, .. }
                if *colour == Rgb(0, 255, 0) && pts.len() > 1 && pts[0].1 <= H =>
            {
                Some(pts.clone())
            }
            _ => None,
        })
        .collect();
    // Only the run of points after the gap is a line.
    assert_eq!(
        drawn,
        vec![vec![(f.xs(0.5), f.ys(2.0)), (f.xs(0.7), f.ys(3.0))]]
    );
}
