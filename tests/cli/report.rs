//! What `tiltsim run` prints: EN 12299's P_CT first (the numbers of `summary.json`), the flags
//! in words and where the files are; the paper's form labelled as a reproduction; no command
//! line for a passive vehicle; the transport and timing in one line, every figure with `-v`;
//! and the README's first command printing what the README shows.

use std::path::Path;

use tiltsim_suite::{root, scenario, summary, temp_dir, Tiltsim};

/// The line of `out` that starts (after its indent) with `start`.
fn line<'a>(out: &'a str, start: &str) -> Option<&'a str> {
    out.lines().find(|l| l.trim_start().starts_with(start))
}

/// The number printed after `word ` in `text` (`standing 34.29 %` → "34.29").
fn number_after<'a>(text: &'a str, word: &str) -> &'a str {
    let (_, rest) = text
        .split_once(&format!("{word} "))
        .unwrap_or_else(|| panic!("no `{word}` in {text}"));
    rest.split([' ', ',', ';']).next().unwrap()
}

/// `value` as the report prints it, with `decimals` after the point.
fn printed(value: &serde_json::Value, decimals: usize) -> String {
    format!("{:.*}", decimals, value.as_f64().expect("a number"))
}

/// `line` with every run of digits as one `#`: what stays of a timing line from run to run
/// (`7.784 s wall (2.2x` and `0.21 s wall (80.1x` alike).
fn shape(line: &str) -> String {
    let mut out = String::new();
    for c in line.chars() {
        if c.is_ascii_digit() {
            if !out.ends_with('#') {
                out.push('#');
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// Lines the report prints only with `-v`.
const INTERNALS: [&str; 4] = [
    "pids:",
    "coordination overhead per tick:",
    "compute per call:",
    "link latency:",
];

fn report_of(sc: &str, out: &Path, extra: &[&str]) -> String {
    let done = Tiltsim::run(sc)
        .transport_ipc()
        .out(out)
        .args(extra)
        .success();
    String::from_utf8(done.stdout).expect("utf-8")
}

#[test]
fn the_report_leads_with_the_standards_p_ct_of_summary_json_and_the_flags() {
    let dir = temp_dir("report-lead");
    let out = dir.join("passive");
    let text = report_of("paper-passive.toml", &out, &[]);
    let lines: Vec<&str> = text.lines().collect();
    // What ran, then the standard's P_CT, then the flags, then where the files are.
    assert!(
        lines[0].starts_with("paper-passive (no tilt control, ideal bar): completed, 16800 steps"),
        "{text}"
    );
    assert!(
        lines[1].starts_with("  P_CT, EN 12299 (per transition, 0.3 Hz filtered): standing "),
        "{text}"
    );
    assert!(
        lines[2].starts_with("  validity flags: none raised"),
        "{text}"
    );
    assert!(
        lines[3].starts_with(&format!("  wrote {}/: timeseries.csv", out.display())),
        "{text}"
    );
    // One number each, standing and seated, and they are summary.json's to the printed digits.
    let s = summary(&out);
    let p_ct = &s["comfort"]["p_ct_en12299"];
    assert_eq!(
        number_after(lines[1], "standing"),
        printed(&p_ct["standing_pct"], 2)
    );
    assert_eq!(
        number_after(lines[1], "seated"),
        printed(&p_ct["seated_pct"], 2)
    );
    // The paper's form is there, as a reproduction, with summary.json's numbers; the standard's
    // line names no other P_CT.
    assert_eq!(lines[1].matches('%').count(), 2, "{}", lines[1]);
    let paper = line(&text, "reproduction of the paper's Table 4 form").expect("the paper's form");
    assert_eq!(
        number_after(paper, "standing"),
        printed(&s["comfort"]["p_ct_paper"]["standing_pct"], 2)
    );
    // A passive vehicle commands nothing: no command line, no command in any line.
    assert!(line(&text, "command:").is_none(), "{text}");
    assert!(!text.contains("delta_a"), "{text}");
    // The transport and timing in one line, the internals not at all.
    assert_eq!(
        text.lines().filter(|l| l.starts_with("  run:")).count(),
        1,
        "{text}"
    );
    for l in INTERNALS {
        assert!(!text.contains(l), "`{l}` without -v: {text}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_tilting_run_prints_its_command_and_verbose_prints_every_timing_figure() {
    let dir = temp_dir("report-verbose");
    let out = dir.join("lqg");
    let text = report_of("paper-lqg.toml", &out, &["-v", "--duration", "2"]);
    let s = summary(&out);
    let command = line(&text, "command:").expect("the command line");
    let peak_deg = s["results"]["delta_a_peak_rad"]
        .as_f64()
        .unwrap()
        .to_degrees();
    assert_eq!(number_after(command, "peak"), format!("{peak_deg:.3}"));
    // Every internal line, once for the run or once for each of its three participants.
    for l in &INTERNALS[..2] {
        assert_eq!(text.matches(l).count(), 1, "`{l}`: {text}");
    }
    for l in &INTERNALS[2..] {
        assert_eq!(text.matches(l).count(), 3, "`{l}`: {text}");
    }
    assert!(!line(&text, "run:").unwrap().contains("-v"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_readme_shows_what_its_first_command_prints() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let after = readme
        .split_once("cargo run --release -- run scenarios/paper-passive.toml\n```\n")
        .expect("the README's first command")
        .1;
    let block = after
        .split_once("```\n")
        .and_then(|(_, b)| b.split_once("\n```"))
        .expect("the output the README shows after it")
        .0;
    // Run from a directory of its own, as the README's command is from the checkout: the
    // default output directory out/paper-passive is then the one the README names.
    let dir = temp_dir("report-readme");
    let done = Tiltsim::run(scenario("paper-passive.toml"))
        .to_command()
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    let text = String::from_utf8(done.stdout).unwrap();
    let shown: Vec<&str> = block.lines().collect();
    let printed: Vec<&str> = text.lines().collect();
    assert_eq!(
        shown.len(),
        printed.len(),
        "README:\n{block}\nprinted:\n{text}"
    );
    for (s, p) in shown.iter().zip(&printed) {
        if s.starts_with("  run:") {
            // Wall time and overhead are this machine's; the words are not.
            assert_eq!(shape(s), shape(p));
        } else {
            assert_eq!(s, p);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_misspelt_choice_is_answered_with_the_closest_one() {
    let dir = temp_dir("report-suggest");
    let file = dir.join("x.toml");
    // An enumerated option of the command line: clap's own check misses a swap in a short name.
    let err = Tiltsim::command(["new", "x", "--controller", "mcp", "--out"])
        .arg(&file)
        .failure(2);
    assert!(err.contains("a similar value exists: 'mpc'"), "{err}");
    assert!(
        err.contains("[possible values: passive, pi, lqg, mpc]"),
        "{err}"
    );
    // The same choice in a scenario file and in --set, and a misspelt key.
    std::fs::write(&file, "[controller]\nmode = \"mcp\"\n").unwrap();
    let err = Tiltsim::command(["validate"]).arg(&file).failure(2);
    assert!(
        err.contains("x.toml") && err.contains("did you mean `mpc`?"),
        "{err}"
    );
    std::fs::write(&file, "[run]\nsede = 3\n").unwrap();
    let err = Tiltsim::command(["validate"]).arg(&file).failure(2);
    assert!(err.contains("did you mean `seed`?"), "{err}");
    let err = Tiltsim::run("paper-lqg.toml")
        .set("controller.mode", "lgq")
        .out(dir.join("never"))
        .failure(2);
    assert!(err.contains("did you mean `lqg`?"), "{err}");
    // A word far from every choice gets no guess.
    let err = Tiltsim::run("paper-lqg.toml")
        .set("controller.mode", "fuzzy")
        .out(dir.join("never"))
        .failure(2);
    assert!(!err.contains("did you mean"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--no-plots` draws no figure and says nothing of one; the run's files are the same, and
/// `tiltsim plot DIR` draws the figures afterwards from them.
#[test]
fn no_plots_draws_nothing_and_plot_draws_them_later() {
    let dir = temp_dir("report-no-plots");
    let (with, without) = (dir.join("with"), dir.join("without"));
    let _ = report_of("paper-passive.toml", &with, &[]);
    let text = report_of("paper-passive.toml", &without, &["--no-plots"]);
    let svgs = |d: &Path| {
        std::fs::read_dir(d.join("plots"))
            .map(|r| r.filter_map(Result::ok).count())
            .unwrap_or(0)
    };
    assert!(svgs(&with) > 0);
    assert_eq!(svgs(&without), 0, "{text}");
    assert!(
        !text.contains("plots/") && text.contains("draws the figures"),
        "{text}"
    );
    for f in ["timeseries.csv", "events.csv"] {
        assert!(
            std::fs::read(with.join(f)).unwrap() == std::fs::read(without.join(f)).unwrap(),
            "{f}"
        );
    }
    Tiltsim::command(["plot"]).arg(&without).success();
    assert_eq!(svgs(&without), svgs(&with));
    let _ = std::fs::remove_dir_all(&dir);
}
