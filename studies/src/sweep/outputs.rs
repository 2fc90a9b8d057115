//! The sweep's files (`samples.csv`, `series.csv`, `table.md`/`table.csv`, `sweep.json`,
//! `plots/`), each written by one function from the rows alone.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use tiltsim_assessment::comfort::{metric, METRICS};
use tiltsim_report::table4::fmt;
use tiltsim_scenario::scenario::Scenario;

use super::{identity, Plan, Row, Shard, PERTURBED, SERIES_DT};

/// What `sweep.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepFile {
    /// Scenario name.
    pub scenario: String,
    /// The plan.
    pub plan: Plan,
    /// `i/n` for a shard's output, absent for a whole (or merged) sweep.
    pub shard: Option<String>,
    /// Samples in this output.
    pub samples: Vec<usize>,
    /// The sweep was interrupted: `samples` are those that had finished (present only then).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub interrupted: bool,
    /// The build of tiltsim that computed the samples ([`identity::build`]).
    pub build: String,
    /// The fingerprint of base scenario, plan and build ([`identity::fingerprint`]), the same
    /// for every shard of one sweep.
    pub fingerprint: String,
    /// SHA-256 of each result file as written, checked by `sweep-merge` before it reads one.
    pub sha256: std::collections::BTreeMap<String, String>,
}

/// Checks rows before they are written: each sample of the plan and the shard at most once,
/// every metric there, and (unless interrupted) every sample of the shard present.
pub(super) fn check_rows(
    plan: &Plan,
    shard: Option<Shard>,
    rows: &[Row],
    interrupted: bool,
) -> std::io::Result<()> {
    let bad = |m: String| Err(std::io::Error::other(m));
    let mine = shard
        .unwrap_or(Shard { index: 0, count: 1 })
        .samples(plan.len());
    for (k, r) in rows.iter().enumerate() {
        if mine.binary_search(&r.sample).is_err() {
            return bad(format!("sample {} is not in this sweep's plan", r.sample));
        }
        if k > 0 && rows[k - 1].sample >= r.sample {
            return bad(format!("sample {} twice or out of order", r.sample));
        }
        if r.metrics.len() != METRICS.len() {
            return bad(format!("sample {}: {} metrics", r.sample, r.metrics.len()));
        }
    }
    if !interrupted && rows.len() != mine.len() {
        return bad(format!("{} of {} samples finished", rows.len(), mine.len()));
    }
    Ok(())
}

/// Linear-interpolation percentile (type 7) of sorted values.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let h = (sorted.len() - 1) as f64 * p;
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// A CSV file in memory, written by the `csv` crate.
pub(super) fn csv_text(records: impl IntoIterator<Item = Vec<String>>) -> String {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in records {
        // Writing into memory cannot fail.
        let _ = w.write_record(&r);
    }
    w.into_inner()
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

pub(super) fn numbers(v: &[f64]) -> impl Iterator<Item = String> + '_ {
    v.iter().map(|x| x.to_string())
}

/// `samples.csv`: each sample's parameters, status and metrics.
pub(super) fn samples_csv(plan: &Plan, rows: &[Row]) -> String {
    let cols = plan.columns();
    let head = std::iter::once(SAMPLE_COLUMN.to_string())
        .chain(cols.iter().map(|c| c.to_string()))
        .chain(std::iter::once("status".to_string()))
        .chain(METRICS.iter().map(|m| m.key.to_string()))
        .chain(std::iter::once(FLAGS_COLUMN.to_string()))
        .collect();
    let body = rows.iter().map(|r| {
        let params = (0..cols.len()).map(|k| r.params.get(k).copied().unwrap_or(f64::NAN));
        std::iter::once(r.sample.to_string())
            .chain(params.map(|v| v.to_string()))
            .chain(std::iter::once(r.status.to_string()))
            .chain(numbers(&r.metrics))
            .chain(std::iter::once(r.flags.join("; ")))
            .collect()
    });
    csv_text(std::iter::once(head).chain(body))
}

/// The column of `samples.csv` that lists the validity flags a sample raised (not `flags`,
/// which pandas reserves: `DataFrame.flags`).
pub const FLAGS_COLUMN: &str = "validity_flags";

/// The column of `samples.csv` and `series.csv` that holds the sample's index (not `sample`,
/// which pandas reserves: `DataFrame.sample`).
pub const SAMPLE_COLUMN: &str = "sample_id";

/// The columns of `series.csv`.
pub const SERIES_COLUMNS: [&str; 3] = [SAMPLE_COLUMN, "time", "lat_acc"];

/// The time of point `i` of a sample's series (s): `i`·[`SERIES_DT`], the double nearest to
/// it.
pub fn series_time(i: usize) -> f64 {
    tiltsim_formats::table::tick_time(i as u64, SERIES_DT)
}

/// `series.csv`, tidy (one line per sample and time): each sample's lateral acceleration at
/// 0, [`SERIES_DT`], 2·[`SERIES_DT`], ... as far as it ran, in the shortest form that reads
/// back exactly (as `timeseries.csv`).
pub(super) fn series_csv(rows: &[Row]) -> String {
    let mut text = SERIES_COLUMNS.join(",") + "\n";
    for r in rows {
        for (i, v) in r.series.iter().enumerate() {
            let _ = writeln!(
                text,
                "{},{},{}",
                r.sample,
                tiltsim_formats::table::fmt_f64(series_time(i)),
                tiltsim_formats::table::fmt_f64(*v)
            );
        }
    }
    text
}

/// `columns.csv` of a sweep: each column of `samples.csv` and `series.csv` with its unit
/// (see `tiltsim_formats::columns`).
pub(super) fn columns_csv(plan: &Plan) -> String {
    use tiltsim_formats::columns::Column;
    let s = "samples.csv";
    let mut all = vec![Column::new(s, SAMPLE_COLUMN, "", "Sample index")];
    for c in plan.columns() {
        all.push(match plan {
            Plan::MonteCarlo { .. } => Column::new(s, &c, "1", "Factor on the nominal value"),
            Plan::Grid { .. } => Column::new(
                s,
                &c,
                "",
                "The swept scenario value, in the unit of its key (docs/scenarios.md, Keys)",
            ),
        });
    }
    all.push(Column::new(s, "status", "", "completed or failed"));
    all.extend(
        METRICS
            .iter()
            .map(|m| Column::new(s, m.key, m.unit, m.label)),
    );
    all.push(Column::new(
        s,
        FLAGS_COLUMN,
        "",
        "The validity flags the run raised, separated by `; `",
    ));
    all.extend([
        Column::new("series.csv", SAMPLE_COLUMN, "", "Sample index"),
        Column::new("series.csv", "time", "s", "Simulated time"),
        Column::new(
            "series.csv",
            "lat_acc",
            "m/s2",
            "Passenger lateral acceleration, eq 13",
        ),
    ]);
    tiltsim_formats::columns::csv_text(&all)
}

/// The statistics `table.md` and `table.csv` give of a metric over samples: their number,
/// then the median, 5th and 95th percentiles, lowest and highest (NaN for no samples).
fn distribution(rows: &[&Row], m: usize) -> (usize, [f64; 5]) {
    let mut v: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.metrics.get(m).copied())
        .collect();
    v.sort_by(|a, b| a.total_cmp(b));
    (
        v.len(),
        [0.5, 0.05, 0.95, 0.0, 1.0].map(|p| percentile(&v, p)),
    )
}

/// The suffix of `table.csv`'s columns over the samples that raised no validity flag.
pub const UNFLAGGED_SUFFIX: &str = "_unflagged";

/// How many flagged samples `table.md` names one by one (`samples.csv` names them all).
const FLAGGED_LISTED: usize = 20;

/// `table.md` and `table.csv` of a Monte Carlo sweep: each metric's distribution over the
/// completed samples, and again over those that raised no validity flag (a flagged sample's
/// comfort may not describe a working tilt system, so a reader sees whether the flagged ones
/// move the distribution); the flagged samples are named with their flags.
pub(super) fn monte_carlo_tables(
    base: &Scenario,
    spread: f64,
    seed: u64,
    rows: &[Row],
) -> (String, String) {
    let ok: Vec<&Row> = rows.iter().filter(|r| r.status.completed()).collect();
    let clean: Vec<&Row> = ok.iter().copied().filter(|r| r.flags.is_empty()).collect();
    let mut md = format!(
        "# Robustness sweep of `{}`\n\nMonte Carlo over the true vehicle: {} masses, \
         inertias and suspension parameters each scaled by U(1 − {s}, 1 + {s}) (seed \
         {seed}); the controller keeps the nominal design. {} of {} samples completed; \
         {} of them raised no validity flag.\n\n\
         | metric | median | p5 | p95 | min | max | median, unflagged | p5, unflagged | p95, unflagged |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        base.name,
        PERTURBED.len(),
        ok.len(),
        rows.len(),
        clean.len(),
        s = spread
    );
    let stats = ["n", "p50", "p5", "p95", "lowest", "highest"];
    let head = stats
        .iter()
        .map(|s| s.to_string())
        .chain(stats.iter().map(|s| format!("{s}{UNFLAGGED_SUFFIX}")));
    let mut records = vec![std::iter::once("metric".to_string()).chain(head).collect()];
    for (m, metric) in METRICS.iter().enumerate() {
        let (n, q) = distribution(&ok, m);
        let (n_clean, c) = distribution(&clean, m);
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            metric.label,
            fmt(q[0]),
            fmt(q[1]),
            fmt(q[2]),
            fmt(q[3]),
            fmt(q[4]),
            fmt(c[0]),
            fmt(c[1]),
            fmt(c[2])
        );
        let mut rec = vec![metric.key.to_string(), n.to_string()];
        rec.extend(numbers(&q));
        rec.push(n_clean.to_string());
        rec.extend(numbers(&c));
        records.push(rec);
    }
    md.push_str(&flagged_note(rows, true));
    (md, csv_text(records))
}

/// What `table.md` says of the flagged samples: how many raised each flag, and which they
/// are (the first [`FLAGGED_LISTED`]); that none did otherwise. `unflagged`: the table has
/// columns without them.
fn flagged_note(rows: &[Row], unflagged: bool) -> String {
    let flagged: Vec<&Row> = rows.iter().filter(|r| !r.flags.is_empty()).collect();
    if flagged.is_empty() {
        return "\nNo sample raised a validity flag.\n".into();
    }
    let left_out = if unflagged {
        ": the \"unflagged\" columns leave them out"
    } else {
        ""
    };
    let mut kinds: Vec<&str> = flagged
        .iter()
        .flat_map(|r| r.flags.iter().map(String::as_str))
        .collect();
    kinds.sort_unstable();
    kinds.dedup();
    let counts: Vec<String> = kinds
        .iter()
        .map(|k| {
            let n = flagged
                .iter()
                .filter(|r| r.flags.iter().any(|f| f == k))
                .count();
            format!("{k} {n}")
        })
        .collect();
    let named: Vec<String> = flagged
        .iter()
        .take(FLAGGED_LISTED)
        .map(|r| format!("{} ({})", r.sample, r.flags.join(", ")))
        .collect();
    let more = if flagged.len() > FLAGGED_LISTED {
        format!(", and {} more", flagged.len() - FLAGGED_LISTED)
    } else {
        String::new()
    };
    format!(
        "\n{} of {} samples raised a validity flag ({}; samples.csv names them){left_out}. \
         Flagged samples: {}{more}.\n\n",
        flagged.len(),
        rows.len(),
        counts.join(", "),
        named.join(", ")
    )
}

/// `table.md` and `table.csv` of a grid sweep: the metrics at each value.
pub(super) fn grid_tables(base: &Scenario, key: &str, rows: &[Row]) -> (String, String) {
    let mut md = format!(
        "# Sweep of `{}` over `{key}`\n\n| {key} | status | lat. acc. peak (%g) | \
         P_CT EN 12299 standing (%) | P_CT EN 12299 seated (%) | P_CT standing, paper's form (%) \
         | roll speed peak (rad/s) | jerk peak (%g/s) | validity flags |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        base.name
    );
    let shown = [
        "lat_acc_peak_pct_g",
        "p_ct_en12299_standing_pct",
        "p_ct_en12299_seated_pct",
        "p_ct_paper_standing_pct",
        "roll_speed_peak_rad_s",
        "jerk_peak_pct_g_s",
    ];
    let head = [key.to_string(), "status".to_string()]
        .into_iter()
        .chain(METRICS.iter().map(|m| m.key.to_string()))
        .chain(std::iter::once(FLAGS_COLUMN.to_string()))
        .collect();
    let mut records = vec![head];
    for r in rows {
        let value = r.params.first().copied().unwrap_or(f64::NAN);
        let _ = write!(md, "| {value} | {} |", r.status);
        for k in shown {
            let v = r.metrics.get(metric(k)).copied().unwrap_or(f64::NAN);
            let _ = write!(md, " {} |", fmt(v));
        }
        let flags = if r.flags.is_empty() {
            "none".to_string()
        } else {
            format!("**{}**", r.flags.join(", "))
        };
        let _ = writeln!(md, " {flags} |");
        let mut rec = vec![value.to_string(), r.status.to_string()];
        rec.extend(numbers(&r.metrics));
        rec.push(r.flags.join("; "));
        records.push(rec);
    }
    md.push_str(&flagged_note(rows, false));
    (md, csv_text(records))
}

/// Writes every output file of a sweep (or shard) from its rows, computed by `build`. The rows
/// are checked first and every file is made in memory before any is written, so an earlier
/// complete table is never replaced by a truncated one; `sweep.json`, which holds the others'
/// checksums, is written last.
pub fn write_outputs(
    out: &Path,
    base: &Scenario,
    plan: &Plan,
    shard: Option<Shard>,
    rows: &[Row],
    interrupted: bool,
    build: &str,
) -> std::io::Result<Vec<PathBuf>> {
    check_rows(plan, shard, rows, interrupted)?;
    let scenario = toml::to_string(base).unwrap_or_default();
    let (md, tcsv) = match plan {
        Plan::MonteCarlo { spread, seed, .. } => monte_carlo_tables(base, *spread, *seed, rows),
        Plan::Grid { key, .. } => grid_tables(base, key, rows),
    };
    let texts = [
        ("scenario.toml", scenario.clone()),
        ("samples.csv", samples_csv(plan, rows)),
        ("series.csv", series_csv(rows)),
        ("table.md", md),
        ("table.csv", tcsv),
        ("columns.csv", columns_csv(plan)),
    ];
    let meta = SweepFile {
        scenario: base.name.clone(),
        plan: plan.clone(),
        shard: shard.map(|s| format!("{}/{}", s.index, s.count)),
        samples: rows.iter().map(|r| r.sample).collect(),
        interrupted,
        build: build.to_string(),
        fingerprint: identity::fingerprint(&scenario, plan, build),
        sha256: texts
            .iter()
            .map(|(n, t)| (n.to_string(), identity::sha256(t.as_bytes())))
            .collect(),
    };
    std::fs::create_dir_all(out)?;
    let mut files = Vec::new();
    let mut put = |name: &str, text: &str| -> std::io::Result<()> {
        let p = out.join(name);
        tiltsim_rundir::files::write_atomic(&p, text)?;
        files.push(p);
        Ok(())
    };
    for (name, text) in &texts {
        put(name, text)?;
    }
    put(
        "sweep.json",
        &(serde_json::to_string_pretty(&meta).unwrap_or_default() + "\n"),
    )?;
    files.extend(super::figures::write_plots(out, base, plan, rows)?);
    Ok(files)
}
