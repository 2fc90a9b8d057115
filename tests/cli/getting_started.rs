//! What a new user starts with: `tiltsim new` templates that validate and run, `--set` for
//! words, choices, switches and lists, and shell completions that the shell accepts
//! (`tiltsim inspect` against FMPy's reading of the same FMU is in the `outside` tests).

use std::path::Path;

use tiltsim_suite::{run, scenario, temp_dir, tiltsim, Tiltsim};

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

#[test]
fn every_new_template_validates_and_runs_and_an_existing_file_is_kept() {
    let dir = temp_dir("new-templates");
    for (c, label) in [
        ("passive", "no tilt control"),
        ("pi", "PI"),
        ("lqg", "LQG servo"),
        ("mpc", "MPC with Kalman filter"),
    ] {
        let file = dir.join(format!("t-{c}.toml"));
        let (code, out, err) = run(&[
            "new",
            &format!("t-{c}"),
            "--controller",
            c,
            "--out",
            s(&file),
        ]);
        assert_eq!(code, 0, "{c}: {err}");
        assert!(out.contains(&format!("t-{c}.toml ({label});")), "{out}");
        let (code, out, err) = run(&["validate", s(&file)]);
        assert_eq!(code, 0, "{c}: {err}");
        // Spelled as the file writes it.
        assert!(
            out.contains(&format!("controller {c}, actuator ")),
            "{c}: {out}"
        );
        let out_dir = dir.join(format!("run-{c}"));
        Tiltsim::run(&file)
            .transport_in_process()
            .duration(0.5)
            .out(&out_dir)
            .quiet()
            .success();
        let resolved: toml::Table =
            toml::from_str(&std::fs::read_to_string(out_dir.join("scenario.toml")).unwrap())
                .unwrap();
        assert_eq!(resolved["controller"]["mode"].as_str(), Some(c));
        // The passive vehicle has no drive to command: its bar is the ideal one.
        let model = if c == "passive" { "ideal" } else { "bldc" };
        assert_eq!(resolved["actuator"]["model"].as_str(), Some(model), "{c}");
    }
    // An existing file is never overwritten; a name a scenario cannot have is refused.
    let kept = dir.join("t-mpc.toml");
    let before = std::fs::read(&kept).unwrap();
    let (code, _, err) = run(&["new", "t-mpc", "--out", s(&kept)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("t-mpc.toml"), "{err}");
    assert_eq!(std::fs::read(&kept).unwrap(), before);
    let (code, _, err) = run(&["new", "a/b", "--out", s(&dir.join("x.toml"))]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("name"), "{err}");
}

#[test]
fn an_edited_template_is_refused_naming_the_fields_written_never_a_derived_one() {
    let dir = temp_dir("edited-template");
    let file = dir.join("short.toml");
    let (code, _, err) = run(&["new", "short", "--out", s(&file)]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&file).unwrap();
    // What is checked is how a bad file reads, so the file itself is edited.
    let edit = |from: &str, to: &str| {
        assert!(text.contains(from), "the template has no `{from}`");
        std::fs::write(&file, text.replace(from, to)).unwrap();
        let (code, _, err) = run(&["validate", s(&file)]);
        assert_eq!(code, 2, "{err}");
        err
    };
    // The track's own field is named with what it allows; the run's duration, which the file
    // leaves to the track, is not.
    let err = edit("straight_before_m = 135.0", "straight_before_m = -9000.0");
    assert!(
        err.contains("field `track.straight_before_m` = -9000: allowed a number in [0, 100000] m"),
        "{err}"
    );
    assert!(!err.contains("duration"), "{err}");
    let err = edit("speed_kmh = 162.0", "speed_kmh = -162.0");
    assert!(err.contains("field `track.speed_kmh` = -162"), "{err}");
    assert!(!err.contains("duration"), "{err}");
}

#[test]
fn set_takes_choices_switches_and_lists_and_names_what_is_allowed() {
    let dir = temp_dir("set-words");
    let sc = scenario("paper-lqg.toml");
    let out = dir.join("ideal");
    Tiltsim::run(&sc)
        .transport_in_process()
        .duration(0.2)
        .set("actuator.model", "ideal")
        .set("run.pin_cpus", false)
        .set(
            "controller.lqg.q_diag",
            "[0.1, 2000, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 1000]",
        )
        .out(&out)
        .quiet()
        .success();
    let resolved: toml::Table =
        toml::from_str(&std::fs::read_to_string(out.join("scenario.toml")).unwrap()).unwrap();
    assert_eq!(resolved["actuator"]["model"].as_str(), Some("ideal"));
    assert_eq!(resolved["run"]["pin_cpus"].as_bool(), Some(false));
    assert_eq!(
        resolved["controller"]["lqg"]["q_diag"][1].as_float(),
        Some(2000.0)
    );
    for (set, words) in [
        (
            "controller.mode=fuzzy",
            vec!["controller.mode", "lqg", "mpc"],
        ),
        ("run.pin_cpus=maybe", vec!["run.pin_cpus", "true or false"]),
        ("actuator.model=5", vec!["actuator.model"]),
    ] {
        let err = Tiltsim::run(&sc)
            .args(["--set", set])
            .out(dir.join("bad"))
            .failure(2);
        for w in words {
            assert!(err.contains(w), "{set}: `{w}` not in {err}");
        }
    }
}

#[test]
fn the_bash_completion_script_is_accepted_by_bash_and_completes_every_command() {
    let (code, script, err) = run(&["completions", "bash"]);
    assert_eq!(code, 0, "{err}");
    // Every command the program has, by the function clap_complete writes for it (dashes
    // become `__subcmd__`), and an option of `run`.
    for cmd in [
        "run",
        "validate",
        "new",
        "compare",
        "plot",
        "sweep__subcmd__merge",
        "replay__subcmd__timing",
        "export__subcmd__fmu",
        "inspect",
        "completions",
        "clean",
    ] {
        let f = format!("tiltsim__subcmd__{cmd})");
        assert!(script.contains(&f), "{cmd} not completed (no `{f}`)");
    }
    assert!(script.contains("--free-run"));
    let file = temp_dir("completions").join("tiltsim.bash");
    std::fs::write(&file, &script).unwrap();
    let out = std::process::Command::new("bash")
        .args(["-n", s(&file)])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (code, _, err) = run(&["completions", "tcsh"]);
    assert_eq!(code, 2, "{err}");
}

#[test]
fn a_run_from_a_terminal_draws_a_progress_bar_and_a_piped_or_quiet_one_does_not() {
    let dir = temp_dir("progress-bar");
    let sc = scenario("paper-lqg.toml");
    let cmd = |out: &str, quiet: bool| {
        format!(
            "{} run {} --transport in-process --duration 1 --out {}{}",
            tiltsim().display(),
            s(&sc),
            s(&dir.join(out)),
            if quiet { " -q" } else { "" }
        )
    };
    // util-linux `script` gives the run a terminal (a pseudo-terminal) for its output.
    let on_terminal = |c: String| {
        let out = std::process::Command::new("script")
            .args(["-qec", &c, "/dev/null"])
            .stdin(std::process::Stdio::null())
            .output()
            .expect("util-linux `script` (Debian's bsdutils) gives the run a terminal");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let shown = on_terminal(cmd("bar", false));
    assert!(shown.contains("% of 1.0 s simulated"), "no bar: {shown}");
    // The bar is cleared when the run ends; the run's report follows.
    assert!(
        shown.contains("paper-lqg (LQG servo, switched BLDC drive): completed,"),
        "{shown}"
    );
    let quiet = on_terminal(cmd("quiet", true));
    assert!(!quiet.contains("% of"), "a quiet run drew a bar: {quiet}");
    let out = Tiltsim::run(&sc)
        .transport_in_process()
        .duration(1)
        .out(dir.join("piped"))
        .success();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("% of"), "a piped run drew a bar: {err}");
}

/// The rows of docs/scenarios.md's key tables: (section as its heading names it, key,
/// default cell, range cell).
fn key_rows(doc: &str) -> Vec<(String, String, String, String)> {
    let mut rows = Vec::new();
    let mut section = String::new();
    for l in doc.lines() {
        if let Some(h) = l.strip_prefix("### `[").and_then(|h| h.strip_suffix("]`")) {
            section = h.to_string();
        } else if l.starts_with('#') {
            // Another heading (the route files' columns): no longer a key table.
            section.clear();
        } else if l.starts_with("| `") && !section.is_empty() {
            let cells: Vec<&str> = l.trim_matches('|').split(" | ").map(str::trim).collect();
            assert_eq!(
                cells.len(),
                5,
                "docs/scenarios.md: a key row of five cells: {l}"
            );
            rows.push((
                section.clone(),
                cells[0].trim_matches('`').to_string(),
                cells[1].to_string(),
                cells[3].to_string(),
            ));
        }
    }
    rows
}

/// A range cell's numeric ends, `[0, 1e5]` or `(0, 3600] whole` → (lo, lo closed, hi).
fn numeric_range(cell: &str) -> Option<(f64, bool, f64)> {
    let closed_lo = cell.starts_with('[');
    let inner = cell.strip_prefix(['[', '('])?;
    let (inner, _) = inner.split_once([']', ')'])?;
    let (lo, hi) = inner.split_once(", ")?;
    Some((lo.parse().ok()?, closed_lo, hi.parse().ok()?))
}

#[test]
fn docs_scenarios_gives_every_key_its_default_and_ranges_the_checks_hold_to() {
    use tiltsim_scenario::scenario::Scenario;
    let doc = std::fs::read_to_string(tiltsim_suite::root().join("docs/scenarios.md")).unwrap();
    let rows = key_rows(&doc);
    let defaults = toml::Value::try_from(Scenario::default()).unwrap();
    let mut checked = 0;
    for (path, value) in leaves(&defaults, "") {
        let (section, key) = path.rsplit_once('.').unwrap();
        let heading = if section.starts_with("links.") {
            "links.<link>"
        } else {
            section
        };
        let Some((_, _, default, range)) = rows.iter().find(|(s, k, ..)| s == heading && k == key)
        else {
            panic!("docs/scenarios.md has no row for `{path}` under `[{heading}]`");
        };
        // The default as the code has it.
        let first = default.split(' ').next().unwrap();
        match &value {
            toml::Value::Float(_) | toml::Value::Integer(_) => {
                let want = value.as_float().or(value.as_integer().map(|i| i as f64));
                assert_eq!(
                    first.parse::<f64>().ok(),
                    want,
                    "`{path}`: default {default}"
                );
            }
            toml::Value::String(s) => assert_eq!(default, &format!("`{s}`"), "`{path}`"),
            toml::Value::Boolean(b) => assert_eq!(default, &b.to_string(), "`{path}`"),
            toml::Value::Array(a) => {
                let listed: Vec<f64> = default
                    .trim_matches(['[', ']'])
                    .split(", ")
                    .map(|x| x.parse().unwrap())
                    .collect();
                let want: Vec<f64> = a.iter().map(|x| x.as_float().unwrap()).collect();
                assert_eq!(listed, want, "`{path}`");
            }
            other => panic!("`{path}`: {other:?}"),
        }
        // A numeric range holds the default, and the checks refuse a value past either end.
        if let Some((lo, lo_closed, hi)) = numeric_range(range) {
            let whole = value.is_integer();
            assert_eq!(whole, range.contains("] whole"), "`{path}`: {range}");
            let d: f64 = first.parse().unwrap();
            assert!(
                d <= hi && (d > lo || (lo_closed && d == lo)),
                "`{path}`: {d} outside {range}"
            );
            // Probed on a free run, where every key's own range applies (a lock-step run
            // also wants `run.controller_busy_wait_s` = 0).
            let mut base = Scenario::default();
            base.run.execution = tiltsim_scenario::scenario::Execution::Free;
            let names_key = |v: f64| {
                let text = if whole {
                    format!("{}", v as i64)
                } else {
                    format!("{v:e}")
                };
                match base.with_setting(&path, &text) {
                    Err(_) => true,
                    Ok(s) => s
                        .validate()
                        .iter()
                        .any(|e| e.to_string().contains(&format!("`{path}`"))),
                }
            };
            // Just past each end is refused, an open end too, and (where the cell says no
            // more) a closed end is taken: the range is the checks' own, not a looser one.
            let step = |x: f64| {
                if whole {
                    1.0
                } else {
                    x.abs().max(1e-300) * 1e-6
                }
            };
            let exact = range.ends_with(']') || range.ends_with("] whole");
            assert!(names_key(hi + step(hi)), "`{path}` above {range} is taken");
            if !(whole && lo - step(lo) < 0.0) {
                assert!(names_key(lo - step(lo)), "`{path}` below {range} is taken");
            }
            if lo_closed {
                assert!(
                    !exact || !names_key(lo),
                    "`{path}` = {lo} refused; docs: {range}"
                );
            } else {
                assert!(names_key(lo), "`{path}` = {lo} taken; docs: {range}");
            }
            assert!(
                !exact || !names_key(hi),
                "`{path}` = {hi} refused; docs: {range}"
            );
            checked += 1;
        }
    }
    // Most keys have a numeric range; a table that lost its ranges would check none.
    assert!(checked > 80, "{checked} ranges checked");
}

/// Every scalar or list of numbers in `v` with its dotted path (lists of tables, the
/// scenario's name and description left out).
fn leaves(v: &toml::Value, prefix: &str) -> Vec<(String, toml::Value)> {
    let mut out = Vec::new();
    if let toml::Value::Table(t) = v {
        for (k, x) in t {
            let path = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            match x {
                toml::Value::Table(_) => out.extend(leaves(x, &path)),
                toml::Value::Array(a) if a.iter().any(|e| e.is_table()) || a.is_empty() => {}
                _ if prefix.is_empty() => {}
                _ => out.push((path, x.clone())),
            }
        }
    }
    out
}
