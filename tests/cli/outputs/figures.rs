//! The figures as a reader sees them: every title names what is shown and the run, compare or
//! sweep it belongs to, every axis label ends with its unit, no markup is written as text,
//! the paper's figures are named only in captions of the runs that correspond, notes stand
//! under the plot, the Monte Carlo distribution is a step function and the grid's comfort
//! figure marks each swept value.

use std::path::{Path, PathBuf};

use tiltsim_suite::*;

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// One text element of an SVG: its class, baseline y (0 for rotated text) and the text a
/// reader sees (subscripts and superscripts inline), with the raw content.
#[derive(Debug)]
struct Text {
    class: String,
    y: f64,
    text: String,
    raw: String,
}

/// The value of attribute `name` in the tag `tag`.
fn attr<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let at = tag.find(&format!(" {name}=\""))? + name.len() + 3;
    tag[at..].split('"').next()
}

/// `raw` without its tags.
fn untagged(raw: &str) -> String {
    let mut out = String::new();
    let mut inside = false;
    for c in raw.chars() {
        match c {
            '<' => inside = true,
            '>' => inside = false,
            _ if !inside => out.push(c),
            _ => {}
        }
    }
    out.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&")
}

fn texts(svg: &str) -> Vec<Text> {
    svg.split("<text ")
        .skip(1)
        .map(|t| {
            let (tag, rest) = t.split_once('>').unwrap();
            let raw = rest.split("</text>").next().unwrap().to_string();
            Text {
                class: attr(tag, "class").unwrap_or("").to_string(),
                y: attr(tag, "y").map_or(0.0, |y| y.parse().unwrap()),
                text: untagged(&raw),
                raw,
            }
        })
        .collect()
}

/// The frames of the plot areas: (top, bottom) of each.
fn frames(svg: &str) -> Vec<(f64, f64)> {
    svg.lines()
        .filter(|l| l.starts_with("<rect") && l.contains(r##"fill="none" stroke="#000000""##))
        .map(|l| {
            let y: f64 = attr(l, "y").unwrap().parse().unwrap();
            (y, y + attr(l, "height").unwrap().parse::<f64>().unwrap())
        })
        .collect()
}

/// The points of each path drawn in `colour`.
fn paths(svg: &str, colour: &str) -> Vec<Vec<(f64, f64)>> {
    svg.lines()
        .filter(|l| l.starts_with("<path") && l.contains(&format!(r#"stroke="{colour}""#)))
        .map(|l| {
            attr(l, "d")
                .unwrap()
                .split(' ')
                .map(|p| {
                    let (x, y) = p[1..].split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .collect()
}

/// The filled squares of side 7 (data markers) in `colour`.
fn markers(svg: &str, colour: &str) -> usize {
    svg.lines()
        .filter(|l| {
            l.starts_with("<rect")
                && l.contains(r#"width="7.0" height="7.0""#)
                && l.contains(&format!(r#"fill="{colour}""#))
        })
        .count()
}

/// Checks every figure in `dir/plots/` as a reader sees it: its title names `whose` and no
/// paper figure, each axis label ends with its one unit, no markup is left as text, notes
/// and captions are under the plot areas, and any paper figure is in a caption "cf. the
/// paper's ...". Returns the SVGs by file name.
fn check_figures(dir: &Path, whose: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir.join("plots")).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !name.ends_with(".svg") {
            continue;
        }
        let svg = std::fs::read_to_string(e.path()).unwrap();
        let frames = frames(&svg);
        assert!(!frames.is_empty(), "{name}: a plot area");
        let texts = texts(&svg);
        let count = |class: &str| texts.iter().filter(|t| t.class == class).count();
        // One title and one label per axis for each panel.
        for class in ["title", "x-label", "y-label"] {
            assert_eq!(count(class), frames.len(), "{name}: {class}");
        }
        for t in &texts {
            let what = format!("{name}: {:?}", t.text);
            assert!(!t.raw.contains("_{") && !t.raw.contains("^{"), "{what}");
            assert!(!t.text.contains("^d") && !t.text.contains('^'), "{what}");
            match t.class.as_str() {
                "title" => {
                    assert!(t.text.contains(whose), "{what} names {whose}");
                    assert!(!t.text.contains("Fig"), "{what}");
                }
                "x-label" | "y-label" => {
                    // Exactly one parenthesised unit, at the end.
                    let unit = t.text.rsplit_once('(').map(|(_, u)| u);
                    let unit = unit.and_then(|u| u.strip_suffix(')')).unwrap_or("");
                    assert!(!unit.trim().is_empty(), "{what}: no unit");
                    assert_eq!(t.text.matches('(').count(), 1, "{what}: one unit");
                }
                "note" => {
                    // Under every plot area's bottom edge, clear of its data.
                    let clear = frames
                        .iter()
                        .all(|(top, bottom)| t.y < *top || t.y > *bottom);
                    assert!(clear, "{what} at y = {} inside a plot {frames:?}", t.y);
                }
                _ => assert!(!t.text.contains("Fig"), "{what}"),
            }
            if t.text.contains("Fig") {
                assert!(t.text.starts_with("cf. the paper's Fig"), "{what}");
            }
        }
        out.push((name, svg));
    }
    out.sort();
    out
}

/// The caption of figure `name` among `svgs` (empty when none).
fn caption(svgs: &[(String, String)], name: &str) -> String {
    let svg = &svgs.iter().find(|(n, _)| n == name).expect(name).1;
    texts(svg)
        .into_iter()
        .filter(|t| t.class == "note" && t.text.starts_with("cf. "))
        .map(|t| t.text)
        .collect::<Vec<_>>()
        .join(" | ")
}

fn run_to(out: &Path, scenario_file: &str, extra: &[&str]) {
    Tiltsim::run(scenario_file)
        .out(out)
        .quiet()
        .args(extra)
        .success();
}

#[test]
fn run_and_compare_figures_read_as_labelled() {
    let dir = temp_dir("figures-runs");
    let in_process = ["--transport", "in-process"];
    let passive = dir.join("passive");
    run_to(&passive, "paper-passive.toml", &in_process);
    let svgs = check_figures(&passive, "paper-passive");
    let names: Vec<&str> = svgs.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["body_roll.svg", "lateral_acceleration.svg"]);
    assert_eq!(
        caption(&svgs, "lateral_acceleration.svg"),
        "cf. the paper's Fig. 8b"
    );
    assert_eq!(caption(&svgs, "body_roll.svg"), "cf. the paper's Fig. 8a");
    // The reference roll is θ_v with a subscript v and a superscript d.
    let roll = &svgs[0].1;
    assert!(roll.contains(r#"<tspan baseline-shift="super" font-size="9">d</tspan> reference"#));
    // The passive vehicle has no estimator: no estimate is drawn (it would be the measurement
    // as received, drawn over it), and the measured trace is there.
    assert!(!roll.contains("estimate"), "passive: an estimate drawn");
    assert!(
        paths(roll, "#2ca02c").is_empty(),
        "passive: an estimate line"
    );
    assert!(
        paths(roll, "#bbbbbb").iter().any(|p| p.len() > 100),
        "no measured trace"
    );

    // A run of our own tuning names no paper figure; its latency histogram names the run.
    let drive = dir.join("drive");
    run_to(
        &drive,
        "pi-drive.toml",
        &["--transport", "in-process", "--trace"],
    );
    let svgs = check_figures(&drive, "pi-drive");
    assert!(svgs.iter().any(|(n, _)| n == "latency_histogram.svg"));
    let roll = &svgs.iter().find(|(n, _)| n == "body_roll.svg").unwrap().1;
    assert!(!roll.contains("estimate"), "the PI has no estimator");
    for (name, svg) in svgs {
        assert!(!svg.contains("Fig"), "{name}");
    }

    let cmp = dir.join("cmp");
    let (a, b) = (scenario("pi-drive.toml"), scenario("paper-lqg.toml"));
    let (code, _, err) = run(&[
        "compare",
        s(&a),
        s(&b),
        "--out",
        s(&cmp),
        "--transport",
        "in-process",
    ]);
    assert_eq!(code, 0, "{err}");
    let svgs = check_figures(&cmp, "Compare of pi-drive, paper-lqg");
    assert_eq!(svgs.len(), 3);
    // Only the paper's own set-up is set beside the paper's figure.
    assert_eq!(
        caption(&svgs, "compare_lateral_acceleration.svg"),
        "cf. the paper's Figs 14-15 for paper-lqg"
    );
    assert_eq!(
        caption(&svgs, "compare_body_roll.svg"),
        "cf. the paper's Fig. 16 for paper-lqg"
    );
    let svgs = check_figures(&cmp.join("paper-lqg"), "paper-lqg (LQG)");
    // The LQG's Kalman filter estimates the roll: its estimate is drawn.
    let roll = &svgs.iter().find(|(n, _)| n == "body_roll.svg").unwrap().1;
    assert!(roll.contains("estimate") && !paths(roll, "#2ca02c").is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_monte_carlo_distribution_is_a_step_function() {
    let dir = temp_dir("figures-mc");
    let sc = scenario("paper-lqg.toml");
    let out = dir.join("mc");
    let (code, _, err) = run_strings(&mc_args(s(&sc), &out, "6", None));
    assert_eq!(code, 0, "{err}");
    let svgs = check_figures(&out, "Sweep of paper-lqg (±22 %, 6 samples)");
    assert_eq!(
        caption(&svgs, "sweep_lateral_acceleration.svg"),
        "cf. the paper's Fig. 21"
    );
    let cdf = &svgs.iter().find(|(n, _)| n == "sweep_p_ct.svg").unwrap().1;
    let lines = paths(cdf, "#1f77b4");
    let pts = &lines
        .iter()
        .find(|p| p.len() > 2)
        .expect("the distribution")
        .clone();
    // From 0 % left of the smallest value: each value's abscissa twice, the line rising
    // there by one sample (SVG y grows downwards), flat in between, to 100 % at the right.
    assert_eq!(pts.len(), 2 * 6 + 2, "{pts:?}");
    for k in 0..6 {
        let (up, from) = (pts[1 + 2 * k], pts[2 * k]);
        let to = pts[2 + 2 * k];
        assert_eq!(from.1, up.1, "flat up to the value");
        assert_eq!(up.0, to.0, "a jump at the value");
        assert!(to.1 < up.1 && up.0 > from.0, "{pts:?}");
    }
    let steps: Vec<f64> = (0..6)
        .map(|k| pts[1 + 2 * k].1 - pts[2 + 2 * k].1)
        .collect();
    assert!(
        steps.iter().all(|d| (d - steps[0]).abs() < 0.15),
        "{steps:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_grid_comfort_figure_marks_each_value_with_one_unit_per_axis() {
    let dir = temp_dir("figures-grid");
    let sc = scenario("paper-lqg.toml");
    let out = dir.join("grid");
    let (code, _, err) = run(&[
        "sweep",
        s(&sc),
        "--grid",
        "controller.rho=0.2,0.3,0.5,0.7",
        "--jobs",
        "1",
        "--out",
        s(&out),
        "--quiet",
    ]);
    assert_eq!(code, 0, "{err}");
    let svgs = check_figures(&out, "Sweep of paper-lqg over controller.rho");
    let comfort = &svgs
        .iter()
        .find(|(n, _)| n == "sweep_comfort.svg")
        .unwrap()
        .1;
    // P_CT and the peak acceleration in panels of their own: % and %g never share an axis.
    let labels: Vec<String> = texts(comfort)
        .into_iter()
        .filter(|t| t.class.ends_with("label"))
        .map(|t| t.text)
        .collect();
    assert_eq!(
        labels,
        [
            "controller.rho (dimensionless)",
            "PCT (%)",
            "controller.rho (dimensionless)",
            "peak lateral acceleration (%g)"
        ]
    );
    // A marker at each of the 4 values on each line, and one in its legend entry.
    for colour in ["#1f77b4", "#2ca02c", "#d62728"] {
        assert_eq!(markers(comfort, colour), 4 + 1, "{colour}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_free_runs_timing_notes_stand_under_the_plot() {
    let dir = temp_dir("figures-free");
    let out: PathBuf = dir.join("free");
    let pre = prefix("figures-free");
    run_to(
        &out,
        "pi-drive.toml",
        &["--free-run", "--duration", "1", "--ipc-prefix", &pre],
    );
    let svgs = check_figures(&out, "pi-drive");
    let late = &svgs
        .iter()
        .find(|(n, _)| n == "timing_lateness.svg")
        .unwrap()
        .1;
    let note = texts(late).into_iter().find(|t| t.class == "note").unwrap();
    // Below the x axis label, that is below every line of data.
    let x_label = texts(late)
        .into_iter()
        .find(|t| t.class == "x-label")
        .unwrap();
    assert!(note.y > x_label.y, "{note:?}");
    assert!(note.text.starts_with("lateness: "), "{note:?}");
    assert!(leftovers(&pre).is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_trade_off_figure_names_its_controllers_and_its_units() {
    let dir = temp_dir("figures-trade-off");
    // 20 s of the straight (4 windows of 5 s) keeps the test short; `compare` takes files,
    // not `--set`.
    let straight = scenario_with(
        "straight-lqg.toml",
        "duration_s = 300.0",
        "duration_s = 20.0",
        "figures-trade-off",
    );
    let curve = scenario("paper-lqg.toml");
    let out = dir.join("cmp");
    let (code, _, err) = run(&[
        "compare",
        s(&curve),
        s(&straight),
        "--out",
        s(&out),
        "--transport",
        "in-process",
    ]);
    assert_eq!(code, 0, "{err}");
    let svgs = check_figures(&out, "Compare of ");
    let trade = &svgs.iter().find(|(n, _)| n == "trade_off.svg").unwrap().1;
    let texts = texts(trade);
    let find = |class: &str| {
        texts
            .iter()
            .find(|t| t.class == class)
            .unwrap()
            .text
            .clone()
    };
    assert_eq!(
        find("title"),
        "Compare of LQG: curving comfort against straight-track ride"
    );
    assert_eq!(
        find("y-label"),
        "NMV lateral part on the straight, 6·aYP95Wd (dimensionless)"
    );
    // The point is a marker, as is its legend entry.
    assert_eq!(markers(trade, "#1f77b4"), 2);
    let _ = std::fs::remove_dir_all(&dir);
}
