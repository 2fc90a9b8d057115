//! `tiltsim falsify` with requirements as engineers write them, several at once: on signals
//! over time, on validity and on a metric. Each requirement's margin at the worst timing is
//! computed again here from the worst replay's own files (`timeseries.csv`, `summary.json`),
//! by the formulas' definitions, and the verdict and exit status follow from them. The timing
//! margin's bracket and counterexample, and each bound's share of the worst.

use std::path::Path;

use tiltsim_suite::{csv_table, temp_dir, Tiltsim};

fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

/// The named columns of a run's `timeseries.csv`, as floats.
fn columns(dir: &Path, names: &[&str]) -> Vec<Vec<f64>> {
    let table = csv_table(&std::fs::read_to_string(dir.join("timeseries.csv")).unwrap());
    let at: Vec<usize> = names
        .iter()
        .map(|n| table[0].iter().position(|c| c == n).unwrap())
        .collect();
    at.iter()
        .map(|&i| table[1..].iter().map(|r| r[i].parse().unwrap()).collect())
        .collect()
}

/// Seven seconds of the paper's LQG: the straight, then the first transition curve, which ends
/// at 5.4 s, and the curve; the measurement up to 60 ms late.
fn falsify(dir: &Path, out: &str, requirements: &[&str]) -> Tiltsim {
    let b = dir.join("b.toml");
    std::fs::write(&b, "[measurement]\ndelay_ms = [0, 60]\njitter_ms = 10\n").unwrap();
    let mut c = Tiltsim::command(["falsify"])
        .arg(tiltsim_suite::scenario("paper-lqg.toml"))
        .arg("--bounds")
        .arg(&b)
        .args(["--set", "run.duration_s=7", "--budget", "4", "--jobs", "2"]);
    for r in requirements {
        c = c.args(["--requirement", r]);
    }
    c.out(dir.join(out))
}

/// A signal requirement any motion breaks, one no run can break, a temporal one after the
/// transition's end, a validity one and a metric: the broken one alone is named, exit 3; each
/// margin is its definition on the worst replay's rows; the combined margin is the least of
/// the margins over their bounds; every evaluation's verdict agrees with its margin.
#[test]
fn several_requirements_are_judged_each_by_its_definition() {
    let dir = temp_dir("falsify-requirements");
    let reqs = [
        "always |lat_acc| < 100",
        "always |lat_acc| < 0.000001",
        "always (transition_end -> always[0,1] |theta_v - theta_ref| < 10deg)",
        "no bump_stop",
        "p_ct < 1000",
    ];
    let err = falsify(&dir, "o", &reqs).failure(3);
    assert!(
        err.contains("`always |lat_acc| < 0.000001`")
            && !err.contains("`always |lat_acc| < 100`")
            && err.contains("worst/timing.csv"),
        "{err}"
    );
    let out = dir.join("o");
    let r = read_json(&out.join("result.json"));
    assert_eq!(
        (r["verdict"].as_str(), r["violated"].as_bool()),
        (Some("violated"), Some(true))
    );
    let worst = out.join("worst");
    let cols = columns(&worst, &["lat_acc", "theta_v", "theta_ref", "curvature"]);
    let (lat, theta_v, theta_ref, curv) = (&cols[0], &cols[1], &cols[2], &cols[3]);
    let peak = lat.iter().fold(0.0f64, |m, a| m.max(a.abs()));
    // The first row after the ramp: the curvature stops changing.
    let end = (2..curv.len())
        .find(|&k| curv[k] == curv[k - 1] && curv[k - 1] != curv[k - 2])
        .unwrap();
    assert_eq!(end, 5401, "the transition ends at 5.4 s");
    let after = (end..=end + 1000)
        .map(|k| (theta_v[k] - theta_ref[k]).abs())
        .fold(0.0f64, f64::max);
    let summary = read_json(&worst.join("summary.json"));
    let bump = summary["flags"]["bump_stop"]["raised"].as_bool().unwrap();
    let p_ct = r["worst_run_metric"].as_f64().unwrap();
    let expected = [
        (100.0 - peak, true),
        (0.000001 - peak, false),
        (10f64.to_radians() - after, true),
        (if bump { -1.0 } else { 1.0 }, !bump),
        (1000.0 - p_ct, p_ct < 1000.0),
    ];
    let judged = r["requirements"].as_array().unwrap();
    assert_eq!(judged.len(), reqs.len(), "{r}");
    for ((j, (margin, holds)), text) in judged.iter().zip(expected).zip(reqs) {
        let got = j["margin"].as_f64().unwrap();
        assert!(
            (got - margin).abs() <= 1e-12 * margin.abs().max(1.0),
            "{text}: {got} against {margin}"
        );
        assert_eq!(j["holds"].as_bool(), Some(holds), "{text}");
    }
    let scales = [100.0, 0.000001, 10f64.to_radians(), 1.0, 1000.0];
    let combined = expected
        .iter()
        .zip(scales)
        .map(|((m, _), s)| m / s)
        .fold(f64::INFINITY, f64::min);
    let got = r["margin"].as_f64().unwrap();
    assert!(
        (got - combined).abs() <= 1e-9 * combined.abs(),
        "{got} against {combined}"
    );
    // Every evaluation: broken exactly where its margin is negative (its least scaled margin
    // is the broken lateral-acceleration bound's, far from zero).
    let table = csv_table(&std::fs::read_to_string(out.join("progress.csv")).unwrap());
    let col = |n: &str| table[0].iter().position(|c| c == n).unwrap();
    let (m, v, e) = (col("margin"), col("violated"), col("error"));
    assert!(table.len() > 4);
    for row in &table[1..] {
        assert!(row[e].is_empty(), "{row:?}");
        let margin: f64 = row[m].parse().unwrap();
        assert_eq!(row[v] == "true", margin < 0.0, "{row:?}");
    }
}

/// Requirements that hold everywhere evaluated: exit 0, "not falsified within N evaluations",
/// every requirement named with its margin; a bad requirement exits 2 naming it and what is
/// allowed, before anything runs.
#[test]
fn requirements_kept_are_not_falsified_and_bad_ones_are_refused() {
    let dir = temp_dir("falsify-requirements-kept");
    let out = falsify(
        &dir,
        "o",
        &[
            "always |lat_acc| < 100",
            "valid",
            "eventually[0,7] |lat_acc| > 0",
        ],
    )
    .success();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("not falsified within 8 evaluations"),
        "{stdout}"
    );
    for r in [
        "always |lat_acc| < 100",
        "valid",
        "eventually[0,7] |lat_acc| > 0",
    ] {
        assert!(
            stdout.contains(&format!("requirement `{r}` at the worst timing: holds")),
            "{stdout}"
        );
    }
    let r = read_json(&dir.join("o").join("result.json"));
    assert_eq!(r["verdict"], "not-falsified");
    for (bad, says) in [
        (
            "always |lat_acc| < 1deg",
            "`deg` is not a unit of a signal in `m/s2`",
        ),
        ("always wobble < 1", "`wobble` is not a signal"),
        ("no wobble", "`wobble` is not a flag"),
    ] {
        let err = falsify(&dir, "bad", &["valid", bad]).failure(2);
        assert!(
            err.contains(&format!("--requirement `{bad}`"))
                && err.contains(says)
                && err.contains("allowed"),
            "{err}"
        );
        assert!(!dir.join("bad").join("result.json").exists());
    }
}

/// The timing margin: a requirement the lock-step run keeps and the bounds given break is
/// bracketed by bisection within 1/2⁴ of the scale; the counterexample at the upper end
/// replays to a P_CT that breaks it, under bounds scaled as documented (delays rounded down
/// to whole ticks). Each bound's share of the worst: with the measurement's delay range its
/// only bound, the worst without it is the lock-step timing, so its objective is the nominal
/// run's P_CT bit for bit.
#[test]
fn the_timing_margin_brackets_the_requirement_and_the_worst_owes_its_delay() {
    let dir = temp_dir("falsify-margin");
    let b = dir.join("b.toml");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(&b, "[measurement]\ndelay_ms = [0, 60]\n").unwrap();
    let out = dir.join("o");
    let run = |req: &str| {
        Tiltsim::command(["falsify"])
            .arg(tiltsim_suite::scenario("paper-lqg.toml"))
            .arg("--bounds")
            .arg(&b)
            .args(["--set", "run.duration_s=7", "--budget", "6", "--jobs", "2"])
            .args(["--requirement", req, "--margin", "--margin-steps", "4"])
            .out(&out)
    };
    // The first search tells the nominal and the worst at scale 1; the bound between them.
    let probe = dir.join("probe");
    Tiltsim::command(["falsify"])
        .arg(tiltsim_suite::scenario("paper-lqg.toml"))
        .arg("--bounds")
        .arg(&b)
        .args(["--set", "run.duration_s=7", "--budget", "6", "--jobs", "2"])
        .out(&probe)
        .success();
    let p = read_json(&probe.join("result.json"));
    let (nominal, worst) = (
        p["nominal_metric"].as_f64().unwrap(),
        p["worst_metric"].as_f64().unwrap(),
    );
    assert!(worst > nominal, "{p}");
    let share = &p["sensitivity"][0];
    assert_eq!(
        (share["link"].as_str(), share["parameter"].as_str()),
        (Some("measurement"), Some("delay_ms"))
    );
    assert_eq!(share["objective_without"].as_f64(), Some(nominal));
    assert_eq!(share["drop"].as_f64(), Some(worst - nominal));
    // Beside it, the jitter (the range's width when not given) taken away: a constant delay.
    let shares = p["sensitivity"].as_array().unwrap();
    assert_eq!(shares.len(), 2, "{p}");
    assert_eq!(shares[1]["parameter"].as_str(), Some("jitter_ms"));
    assert!(shares[1]["drop"].as_f64().unwrap() <= share["drop"].as_f64().unwrap());

    let bound = 0.5 * (nominal + worst);
    run(&format!("p_ct < {bound}")).failure(3);
    let r = read_json(&out.join("result.json"));
    let m = &r["timing_margin"];
    let (held, broken) = (
        m["holds_up_to_scale"].as_f64().unwrap(),
        m["broken_at_scale"].as_f64().unwrap(),
    );
    assert!(held < broken && broken - held <= 1.0 / 16.0 + 1e-12, "{m}");
    assert!(m["steps"].as_array().unwrap().len() >= 6, "{m}");
    for s in m["steps"].as_array().unwrap() {
        let k = s["scale"].as_f64().unwrap();
        let violated = s["violated"].as_bool().unwrap();
        assert_eq!(
            violated,
            s["worst_metric"].as_f64().unwrap() >= bound,
            "{s}"
        );
        assert!(
            if k <= held {
                !violated
            } else {
                k < broken || violated
            },
            "{s}"
        );
    }
    let scaled: toml::Value =
        toml::from_str(&std::fs::read_to_string(out.join("margin/worst/bounds.toml")).unwrap())
            .unwrap();
    let top = scaled["measurement"]["delay_ms"][1].as_float().unwrap();
    assert_eq!(top, (broken * 60.0 + 1e-9).floor(), "{scaled}");
    let replay = dir.join("replay");
    Tiltsim::command(["replay-timing"])
        .arg(out.join("margin/worst"))
        .args(["--no-plots", "-q"])
        .out(&replay)
        .success();
    let summary = read_json(&replay.join("summary.json"));
    let p_ct = summary["comfort"]["p_ct_en12299"]["standing_pct"]
        .as_f64()
        .unwrap();
    assert!(p_ct >= bound, "{p_ct} against {bound}");
}
