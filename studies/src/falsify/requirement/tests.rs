//! Requirements: the parser's reading and refusals, the robustness of temporal formulas against
//! their definition evaluated directly (every row, every window, no sliding queue), and the
//! judgement of metric, validity and several requirements at once.

use rand::{Rng as _, SeedableRng as _};
use tiltsim_assessment::comfort::Comfort;
use tiltsim_formats::table::Row;
use tiltsim_scenario::scenario::Scenario;

use super::robustness::satisfaction;
use super::signals::Trace;
use super::stl::{Expr, Formula};
use super::{Judged, Requirement, Validity};
use crate::falsify::objective::{Cmp, Objective};

fn scenario() -> Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("scenarios")
        .join("paper-passive.toml");
    Scenario::load(&path).unwrap()
}

/// Rows whose `lat_acc` and `theta_v` are random, and whose curvature ramps on rows 20..40
/// and 70..75 (two transitions).
fn rows(n: usize, seed: u64) -> Vec<Row> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|k| {
            let curvature = match k {
                0..20 => 0.0,
                20..40 => (k - 19) as f64 * 1e-5,
                40..70 => 20e-5,
                70..75 => 20e-5 - (k - 69) as f64 * 4e-5,
                _ => 0.0,
            };
            Row {
                step: k as u64,
                time: k as f64 * 1e-3,
                lat_acc: rng.random_range(-2.0..2.0),
                theta_v: rng.random_range(-0.02..0.02),
                curvature,
                ..Default::default()
            }
        })
        .collect()
}

/// The formula's robustness at row `k` by its definition, windows scanned row by row.
fn direct(f: &Formula, t: &Trace, k: usize) -> f64 {
    let n = t.len();
    let window = |w: super::stl::Window| {
        (k..n).filter(move |&j| {
            let d = (j - k) as f64 * t.dt;
            d >= w.from_s - 1e-9 && w.to_s.is_none_or(|to| d <= to + 1e-9)
        })
    };
    match f {
        Formula::Pred { expr, cmp, bound } => {
            let v = value(expr, t, k);
            match cmp {
                Cmp::Less | Cmp::LessEq => bound - v,
                Cmp::Greater | Cmp::GreaterEq => v - bound,
            }
        }
        Formula::Event(e) => {
            if t.truth(*e)[k] {
                f64::INFINITY
            } else {
                f64::NEG_INFINITY
            }
        }
        Formula::Not(a) => -direct(a, t, k),
        Formula::And(a, b) => direct(a, t, k).min(direct(b, t, k)),
        Formula::Or(a, b) => direct(a, t, k).max(direct(b, t, k)),
        Formula::Always(w, a) => window(*w).fold(f64::INFINITY, |m, j| m.min(direct(a, t, j))),
        Formula::Eventually(w, a) => {
            window(*w).fold(f64::NEG_INFINITY, |m, j| m.max(direct(a, t, j)))
        }
    }
}

fn value(e: &Expr, t: &Trace, k: usize) -> f64 {
    match e {
        Expr::Signal(s) => t.values(*s)[k],
        Expr::Abs(a) => value(a, t, k).abs(),
        Expr::Sum(terms) => terms.iter().map(|(s, e)| s * value(e, t, k)).sum(),
    }
}

fn formula(text: &str) -> Formula {
    match Requirement::parse(text).unwrap() {
        Requirement::Signal { formula, .. } => formula,
        other => panic!("{text} read as {other:?}"),
    }
}

/// Every row's robustness of formulas with nested windows, bounded and not, equals the
/// definition evaluated directly, and the truth computed beside it agrees with its sign.
#[test]
fn robustness_is_the_definition_at_every_row() {
    let s = scenario();
    let formulas = [
        "always |lat_acc| < 1.2",
        "eventually[0.005, 0.012] lat_acc >= 1.5",
        "always[0,0.01] (lat_acc < 1 or eventually[0.002,0.004] theta_v > 0.5deg)",
        "always (transition_end -> always[0, 0.003] |theta_v - tilt_error| <= 0.01)",
        "not eventually[0.03, inf] (transition and -lat_acc > 1.9)",
        "always[0.01,0.05] (transition_start -> eventually |lat_acc| < 0.1 m/s2)",
    ];
    for seed in 0..4 {
        let r = rows(120, seed);
        let t = Trace::new(&s, &r);
        for text in formulas {
            let f = formula(text);
            let sat = satisfaction(&f, &t);
            for k in 0..r.len() {
                let d = direct(&f, &t, k);
                assert_eq!(sat.margin[k], d, "{text}, seed {seed}, row {k}");
                if d != 0.0 {
                    assert_eq!(sat.holds[k], d > 0.0, "{text}, seed {seed}, row {k}");
                }
            }
        }
    }
}

/// `always |x| < c` over a run is c − max|x| (its closed form), and the transitions are found
/// where the curvature ramps.
#[test]
fn closed_forms_and_transitions() {
    let s = scenario();
    let r = rows(100, 7);
    let t = Trace::new(&s, &r);
    let peak = r.iter().map(|x| x.lat_acc.abs()).fold(0.0, f64::max);
    let (m, holds) = super::robustness::at_start(&formula("always |lat_acc| < 2.5"), &t).unwrap();
    assert_eq!(m, 2.5 - peak);
    assert!(holds);
    let starts: Vec<usize> = t
        .truth(super::signals::Event::TransitionStart)
        .iter()
        .enumerate()
        .filter_map(|(k, h)| h.then_some(k))
        .collect();
    let ends: Vec<usize> = t
        .truth(super::signals::Event::TransitionEnd)
        .iter()
        .enumerate()
        .filter_map(|(k, h)| h.then_some(k))
        .collect();
    assert_eq!(starts, [20, 70]);
    assert_eq!(ends, [40, 75]);
    // 0.5° is 0.5·π/180 rad; 0.1 g is 0.980665 m/s².
    let Formula::Always(_, p) = formula("always theta_v < 0.5deg") else {
        panic!()
    };
    assert!(
        matches!(*p, Formula::Pred { bound, .. } if bound == 0.5 * std::f64::consts::PI / 180.0)
    );
    let Formula::Always(_, p) = formula("always lat_acc < 0.1g") else {
        panic!()
    };
    assert!(matches!(*p, Formula::Pred { bound, .. } if (bound - 0.980665).abs() < 1e-15));
}

/// Bad requirements are refused naming the text, what is wrong and what is allowed.
#[test]
fn bad_requirements_name_what_is_wrong() {
    let cases = [
        (
            "always |lat_acc| < 0.5deg",
            "`deg` is not a unit of a signal in `m/s2`; allowed: m/s2, g",
        ),
        (
            "always lat_acc + theta_v < 1",
            "a sum of signals in `m/s2` and in `rad`",
        ),
        ("always speed < 3", "`speed` is not a signal"),
        ("always[3,1] lat_acc < 1", "0 ≤ FROM ≤ TO"),
        ("always (lat_acc < 1", "`)` expected at the end"),
        (
            "lat_acc < 1.2",
            "`lat_acc` is a signal: say when, e.g. `always lat_acc < 1.2`",
        ),
        ("no wobble", "`wobble` is not a flag"),
        ("always transition < 1", "`transition` is true or false"),
        ("always lat_acc < 1 1", "unexpected `1`"),
        ("p_ct = 3", "no comparison"),
        ("p_ct < x", "not a finite number"),
    ];
    for (text, want) in cases {
        let e = Requirement::parse(text).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("--requirement `{text}`: "))
                && e.contains(want)
                && e.contains("allowed"),
            "{text}: {e}"
        );
    }
}

fn judged<'a>(c: &'a Comfort, valid: bool, raised: &'a [&'a str], t: &'a Trace<'a>) -> Judged<'a> {
    Judged {
        comfort: c,
        comfort_valid: valid,
        raised,
        trace: t,
    }
}

/// Metric margins and strictness, flags, and several requirements: the verdict is any broken,
/// the margin the least of the margins each over its bound's magnitude.
#[test]
fn several_requirements_at_once() {
    let s = scenario();
    let r = rows(100, 3);
    let t = Trace::new(&s, &r);
    let mut c = Comfort::default();
    c.p_ct_en12299.standing = 30.0;
    let one = Objective::requirement("p_ct < 35").unwrap();
    let sc = one.score(&judged(&c, true, &[], &t));
    assert_eq!(
        (sc.margin, sc.violated, sc.objective, sc.metric),
        (5.0, false, -5.0, 30.0)
    );
    for (text, violated) in [
        ("p_ct < 30", true),
        ("p_ct <= 30", false),
        ("p_ct >= 30", false),
    ] {
        let sc = Objective::requirement(text)
            .unwrap()
            .score(&judged(&c, true, &[], &t));
        assert_eq!(sc.violated, violated, "{text}");
    }
    let peak = r.iter().map(|x| x.lat_acc.abs()).fold(0.0, f64::max);
    let all =
        Objective::requirements(&["p_ct < 40", "always |lat_acc| < 4; no oscillation"]).unwrap();
    assert_eq!(
        all.describe(),
        "p_ct_en12299_standing_pct < 40; always |lat_acc| < 4; no oscillation"
    );
    assert_eq!(Objective::requirement(&all.describe()).unwrap(), all);
    let sc = all.score(&judged(&c, true, &["bump stop"], &t));
    let expected = (10.0 / 40.0_f64).min((4.0 - peak) / 4.0).min(1.0);
    assert_eq!((sc.margin, sc.violated), (expected, false));
    let sc = all.score(&judged(&c, false, &["oscillation"], &t));
    assert_eq!((sc.margin, sc.violated), (-1.0, true));
    assert_eq!(
        sc.checks.iter().map(|k| k.holds).collect::<Vec<_>>(),
        [true, true, false]
    );
    assert_eq!(
        Requirement::parse("valid").unwrap(),
        Requirement::Validity(Validity::Valid)
    );
    let v = Objective::requirement("valid").unwrap();
    assert!(v.score(&judged(&c, false, &[], &t)).violated);
    assert!(!v.score(&judged(&c, true, &["bump stop"], &t)).violated);
    let nf = Objective::requirement("no flags").unwrap();
    assert!(nf.score(&judged(&c, true, &["bump stop"], &t)).violated);
}

/// A long trace with a long window costs each row once: the sliding extremes agree with the
/// suffix extremes of an unbounded window where the window reaches past the end.
#[test]
fn long_windows_agree_with_unbounded_ones() {
    let s = scenario();
    let r = rows(5000, 11);
    let t = Trace::new(&s, &r);
    let bounded = satisfaction(&formula("always[0.5, 100] lat_acc < 1.9"), &t);
    let unbounded = satisfaction(&formula("always[0.5, inf] lat_acc < 1.9"), &t);
    assert_eq!(bounded.margin, unbounded.margin);
    assert_eq!(bounded.holds, unbounded.holds);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for _ in 0..20 {
        let k = rng.random_range(0..r.len());
        let f = formula("eventually[0.1, 0.4] lat_acc > 1.99");
        assert_eq!(satisfaction(&f, &t).margin[k], direct(&f, &t, k));
    }
}
