//! The sweep's figures (`plots/`): the lateral-acceleration envelope and the distribution of
//! P_CT of a Monte Carlo sweep, the lateral acceleration and comfort against the value of a
//! grid, each sample that raised a validity flag marked.

use std::path::{Path, PathBuf};

use tiltsim_assessment::comfort::metric;
use tiltsim_report::plot::{Chart, Line, PALETTE};
use tiltsim_scenario::scenario::Scenario;

use super::outputs::{percentile, series_time};
use super::{Plan, Row};

pub(super) fn line<'a>(
    label: &'a str,
    y: Vec<f64>,
    colour: &'static str,
    dashed: bool,
) -> Line<'a> {
    Line {
        label,
        y,
        colour,
        dashed,
        ..Default::default()
    }
}

pub(super) fn column(ok: &[&Row], key: &str) -> Vec<f64> {
    let m = metric(key);
    ok.iter()
        .map(|r| r.metrics.get(m).copied().unwrap_or(f64::NAN))
        .collect()
}

/// The empirical distribution function of `values` for a step line: the sorted values with
/// a point 5 % of their range beyond each end (so that the first and last jumps show), and
/// the share of values at or below each (%), 0 before the smallest and 100 after the largest.
pub(super) fn ecdf(values: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut x: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    x.sort_by(|a, b| a.total_cmp(b));
    let (Some(&lo), Some(&hi)) = (x.first(), x.last()) else {
        return (Vec::new(), Vec::new());
    };
    let n = x.len();
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.05 * lo.abs().max(1.0)
    };
    x.insert(0, lo - pad);
    x.push(hi + pad);
    let mut share: Vec<f64> = (0..=n).map(|i| 100.0 * i as f64 / n as f64).collect();
    share.push(100.0);
    (x, share)
}

/// The 5th, 50th and 95th percentiles of the samples' lateral acceleration at each time.
fn envelope(rows: &[&Row], n: usize) -> [Vec<f64>; 3] {
    let mut env = [Vec::new(), Vec::new(), Vec::new()];
    for i in 0..n {
        let mut v: Vec<f64> = rows.iter().map(|r| r.series[i]).collect();
        v.sort_by(|a, b| a.total_cmp(b));
        for (k, p) in [0.05, 0.5, 0.95].iter().enumerate() {
            env[k].push(percentile(&v, *p));
        }
    }
    env
}

/// The colour of the lines and marks of the samples that raised no validity flag, and of the
/// squares around those that raised one.
const UNFLAGGED_COLOUR: &str = "#2ca02c";
const FLAGGED_COLOUR: &str = "#000000";

/// The legend of the squares around flagged samples.
const FLAGGED_LABEL: &str = "raised a validity flag";

/// What a sweep's figure says of its flagged samples (how many; what is drawn without
/// them), after the note on the shaded sections when `sections`.
fn flag_note(ok: &[&Row], without: &str, sections: bool) -> String {
    let flagged = ok.iter().filter(|r| !r.flags.is_empty()).count();
    let what = match flagged {
        0 => "no sample raised a validity flag".to_string(),
        f if f == ok.len() => format!("every sample ({f}) raised a validity flag"),
        f => format!(
            "{f} of {} samples raised a validity flag; {without}",
            ok.len()
        ),
    };
    if sections {
        format!("{}; {what}", tiltsim_report::plot::SECTION_NOTE)
    } else {
        what
    }
}

/// The lateral-acceleration envelope (5th, 50th, 95th percentile at each time, and the median
/// of the samples that raised no validity flag when some did) and the empirical distribution
/// of P_CT (also without the flagged samples, each flagged sample marked), titled with the
/// base scenario and the spread.
pub(super) fn monte_carlo_plots(
    dir: &Path,
    (base, spread): (&Scenario, f64),
    ok: &[&Row],
    t: &[f64],
    bands: Vec<(f64, f64, bool)>,
) -> std::io::Result<Vec<PathBuf>> {
    let clean: Vec<&Row> = ok.iter().copied().filter(|r| r.flags.is_empty()).collect();
    let some_flagged = !clean.is_empty() && clean.len() < ok.len();
    let [p5, p50, p95] = envelope(ok, t.len());
    let sweep = format!(
        "Sweep of {} (±{} %, {} samples)",
        base.name,
        (spread * 100.0 * 1e6).round() / 1e6,
        ok.len()
    );
    let title = format!("{sweep}: passenger lateral acceleration across the perturbed vehicles");
    let fig = tiltsim_report::plot::cite::robustness_figure(base, spread);
    let caption = tiltsim_report::plot::cite::caption(&[(&base.name, fig)]);
    let note = flag_note(
        ok,
        "the line \"median, unflagged samples\" leaves them out",
        true,
    );
    let mut lines = vec![
        line("95th percentile", p95, "#d62728", true),
        line("median", p50, "#1f77b4", false),
        line("5th percentile", p5, "#2ca02c", true),
    ];
    if some_flagged {
        let [_, median, _] = envelope(&clean, t.len());
        lines.push(line("median, unflagged samples", median, "#9467bd", true));
    }
    let chart = Chart {
        title: &title,
        x_label: "time (s)",
        y_label: "lateral acceleration (m/s²)",
        lines,
        bands,
        note: &note,
        caption: &caption,
    };
    let mut files =
        tiltsim_report::plot::write_chart(dir, "sweep_lateral_acceleration", &chart, t)?.to_vec();
    let title = format!("{sweep}: distribution of P_{{CT}} standing over the samples");
    files.extend(p_ct_distribution(dir, &title, ok)?);
    Ok(files)
}

/// `sweep_p_ct`: the empirical distribution function of P_CT standing over the completed
/// samples, each flagged sample ringed on it, and (when some but not all raised a flag) the
/// distribution over the unflagged samples alone.
fn p_ct_distribution(dir: &Path, title: &str, ok: &[&Row]) -> std::io::Result<[PathBuf; 2]> {
    const KEY: &str = "p_ct_en12299_standing_pct";
    let (p, share) = ecdf(&column(ok, KEY));
    let clean: Vec<&Row> = ok.iter().copied().filter(|r| r.flags.is_empty()).collect();
    let values = column(ok, KEY);
    let flagged: Vec<f64> = values
        .iter()
        .zip(ok)
        .filter(|(_, r)| !r.flags.is_empty())
        .map(|(v, _)| *v)
        .collect();
    // Each flagged value is one abscissa of the distribution; a square where it steps up.
    let rings: Vec<f64> = p
        .iter()
        .zip(&share)
        .enumerate()
        .map(|(i, (x, s))| {
            let inner = i > 0 && i + 1 < p.len();
            if inner && flagged.contains(x) {
                *s
            } else {
                f64::NAN
            }
        })
        .collect();
    let mut lines = vec![Line {
        steps: true,
        ..line("all completed samples", share, "#1f77b4", false)
    }];
    if !clean.is_empty() && clean.len() < ok.len() {
        let c = column(&clean, KEY);
        let n = c.iter().filter(|v| v.is_finite()).count().max(1) as f64;
        let below: Vec<f64> = p
            .iter()
            .map(|x| 100.0 * c.iter().filter(|v| *v <= x).count() as f64 / n)
            .collect();
        lines.push(Line {
            steps: true,
            ..line("unflagged samples", below, UNFLAGGED_COLOUR, true)
        });
    }
    if !flagged.is_empty() {
        lines.push(Line {
            outline: true,
            ..line(FLAGGED_LABEL, rings, FLAGGED_COLOUR, false)
        });
    }
    let note = flag_note(ok, "the line \"unflagged samples\" leaves them out", false);
    let chart = Chart {
        title,
        x_label: "P_{CT} standing, EN 12299 per transition (%)",
        y_label: "samples at or below this P_{CT} (%)",
        lines,
        note: &note,
        ..Default::default()
    };
    tiltsim_report::plot::write_chart(dir, "sweep_p_ct", &chart, &p)
}

/// A swept key as an axis label with its unit: the unit of the participant parameter it sets,
/// else the one its name ends with.
pub(super) fn key_label(key: &str) -> String {
    let unit = match tiltsim_fmi::units::param_unit(key) {
        Some("1") => "dimensionless".to_string(),
        Some("") => "weight".to_string(),
        Some(u) => u
            .replace("m2", "m²")
            .replace("m3", "m³")
            .replace("s2", "s²")
            .replace('.', "·"),
        None => {
            const SUFFIXES: [(&str, &str); 12] = [
                ("_ticks", "ticks"),
                ("_probability", "dimensionless"),
                ("_kmh", "km/h"),
                ("_deg", "deg"),
                ("_rad", "rad"),
                ("_pct", "%"),
                ("_hz", "Hz"),
                ("_mm", "mm"),
                ("_ms", "ms"),
                ("_us", "µs"),
                ("_s", "s"),
                ("_m", "m"),
            ];
            let found = SUFFIXES.iter().find(|(s, _)| key.ends_with(s));
            found
                .map_or("as in the scenario file", |(_, u)| u)
                .to_string()
        }
    };
    format!("{key} ({unit})")
}

/// `sweep_lateral_acceleration` of a grid: a line per value, titled `sweep`.
fn grid_lateral_acceleration(
    dir: &Path,
    sweep: &str,
    ok: &[&Row],
    t: &[f64],
    bands: Vec<(f64, f64, bool)>,
) -> std::io::Result<[PathBuf; 2]> {
    // The key is in the title; each legend entry names its value and any flag it raised (its
    // line dashed).
    let labels: Vec<String> = ok
        .iter()
        .map(|r| {
            let value = r.params.first().copied().unwrap_or(f64::NAN);
            if r.flags.is_empty() {
                format!("{value}")
            } else {
                format!("{value} (flagged: {})", r.flags.join(", "))
            }
        })
        .collect();
    let lat_title = format!("{sweep}: passenger lateral acceleration for each value");
    let chart = Chart {
        title: &lat_title,
        x_label: "time (s)",
        y_label: "lateral acceleration (m/s²)",
        lines: ok
            .iter()
            .zip(&labels)
            .enumerate()
            .map(|(k, (r, label))| {
                line(
                    label,
                    r.series[..t.len()].to_vec(),
                    PALETTE[k % PALETTE.len()],
                    !r.flags.is_empty(),
                )
            })
            .collect(),
        bands,
        note: tiltsim_report::plot::SECTION_NOTE,
        ..Default::default()
    };
    tiltsim_report::plot::write_chart(dir, "sweep_lateral_acceleration", &chart, t)
}

/// The lateral acceleration for each swept value, and comfort against the value: P_CT and
/// the peak lateral acceleration in panels of their own, a marker at each swept value.
pub(super) fn grid_plots(
    dir: &Path,
    (base, key): (&Scenario, &str),
    ok: &[&Row],
    t: &[f64],
    bands: Vec<(f64, f64, bool)>,
) -> std::io::Result<Vec<PathBuf>> {
    let sweep = format!("Sweep of {} over {key}", base.name);
    let mut files = grid_lateral_acceleration(dir, &sweep, ok, t, bands)?.to_vec();
    let x: Vec<f64> = ok
        .iter()
        .map(|r| r.params.first().copied().unwrap_or(f64::NAN))
        .collect();
    let x_label = key_label(key);
    let marked = |label, key, colour| Line {
        markers: true,
        ..line(label, column(ok, key), colour, false)
    };
    // A square around each flagged sample's point on the panel's first line.
    let ringed = |key| {
        let y = column(ok, key)
            .into_iter()
            .zip(ok)
            .map(|(v, r)| if r.flags.is_empty() { f64::NAN } else { v })
            .collect();
        Line {
            outline: true,
            ..line(FLAGGED_LABEL, y, FLAGGED_COLOUR, false)
        }
    };
    let any_flagged = ok.iter().any(|r| !r.flags.is_empty());
    let with_rings = |mut lines: Vec<Line<'static>>, key| {
        if any_flagged {
            lines.push(ringed(key));
        }
        lines
    };
    let p_ct_title = format!("{sweep}: comfort P_{{CT}}, EN 12299 per transition");
    let peak_title = format!("{sweep}: peak passenger lateral acceleration");
    let panels = [
        Chart {
            title: &p_ct_title,
            x_label: &x_label,
            y_label: "P_{CT} (%)",
            lines: with_rings(
                vec![
                    marked("standing", "p_ct_en12299_standing_pct", "#1f77b4"),
                    marked("seated", "p_ct_en12299_seated_pct", "#2ca02c"),
                ],
                "p_ct_en12299_standing_pct",
            ),
            ..Default::default()
        },
        Chart {
            title: &peak_title,
            x_label: &x_label,
            y_label: "peak lateral acceleration (%g)",
            lines: with_rings(
                vec![marked("peak", "lat_acc_peak_pct_g", "#d62728")],
                "lat_acc_peak_pct_g",
            ),
            ..Default::default()
        },
    ];
    files.extend(tiltsim_report::plot::write_panels(
        dir,
        "sweep_comfort",
        &panels,
        &x,
    )?);
    Ok(files)
}

pub(super) fn write_plots(
    out: &Path,
    base: &Scenario,
    plan: &Plan,
    rows: &[Row],
) -> std::io::Result<Vec<PathBuf>> {
    let dir = out.join("plots");
    std::fs::create_dir_all(&dir)?;
    let ok: Vec<&Row> = rows.iter().filter(|r| r.status.completed()).collect();
    let n = ok.iter().map(|r| r.series.len()).min().unwrap_or(0);
    let t: Vec<f64> = (0..n).map(series_time).collect();
    let bands = tiltsim_report::analysis::bands(base);
    match plan {
        Plan::MonteCarlo { spread, .. } => monte_carlo_plots(&dir, (base, *spread), &ok, &t, bands),
        Plan::Grid { key, .. } => grid_plots(&dir, (base, key), &ok, &t, bands),
    }
}
