//! The sweep's files read back, and shards joined into the unsharded sweep's files.

use std::path::{Path, PathBuf};

use tiltsim_assessment::comfort::METRICS;
use tiltsim_scenario::scenario::Scenario;

use super::outputs::{series_time, SERIES_COLUMNS};
use super::{check_params, identity, Plan, Row, SampleStatus, Shard, SweepError, SweepFile};

pub(super) fn parse_f64s<'a>(
    fields: impl Iterator<Item = &'a str>,
    what: &str,
) -> Result<Vec<f64>, String> {
    fields
        .map(|x| {
            x.parse::<f64>()
                .map_err(|_| format!("{what}: `{x}` is not a number"))
        })
        .collect()
}

/// The records of CSV `bytes` read from `path`, each with where it is (file and line).
pub(super) fn records(
    path: &Path,
    bytes: &[u8],
) -> Result<Vec<(String, csv::StringRecord)>, String> {
    let mut rd = csv::ReaderBuilder::new().flexible(true).from_reader(bytes);
    rd.records()
        .enumerate()
        .map(|(i, r)| {
            let at = format!("{} line {}", path.display(), i + 2);
            r.map(|r| (at.clone(), r)).map_err(|e| format!("{at}: {e}"))
        })
        .collect()
}

/// One record of `samples.csv`.
pub(super) fn sample_row(at: &str, f: &csv::StringRecord, ncol: usize) -> Result<Row, String> {
    let want = 3 + ncol + METRICS.len();
    if f.len() != want {
        return Err(format!("{at}: {} fields, expected {want}", f.len()));
    }
    let status = &f[1 + ncol];
    Ok(Row {
        sample: f[0]
            .parse()
            .map_err(|_| format!("{at}: bad sample index `{}`", &f[0]))?,
        params: parse_f64s(f.iter().skip(1).take(ncol), at)?,
        status: SampleStatus::parse(status)
            .ok_or_else(|| format!("{at}: status `{status}` is neither completed nor failed"))?,
        metrics: parse_f64s(f.iter().skip(2 + ncol).take(METRICS.len()), at)?,
        flags: f[want - 1]
            .split("; ")
            .filter(|x| !x.is_empty())
            .map(str::to_string)
            .collect(),
        series: Vec::new(),
    })
}

/// A sweep's (or shard's) outputs as read back and verified: its meta, base scenario and rows,
/// each row with where it is in `samples.csv`.
pub struct Outputs {
    /// The directory.
    pub dir: PathBuf,
    /// `sweep.json`.
    pub meta: SweepFile,
    /// `scenario.toml`.
    pub base: Scenario,
    /// The rows with their place (`DIR/samples.csv line N`).
    pub rows: Vec<(String, Row)>,
    /// The samples `series.csv` has a line for.
    pub series: std::collections::BTreeSet<usize>,
    /// Lines of `series.csv` for samples not in `samples.csv`, each as its error.
    pub orphans: Vec<String>,
}

/// Reads a sweep's (or shard's) outputs back, each file checked against the checksum
/// `sweep.json` holds for it and the fingerprint against the scenario, plan and build.
pub fn read_outputs(dir: &Path) -> Result<Outputs, SweepError> {
    outputs(dir).map_err(SweepError::Files)
}

pub(super) fn outputs(dir: &Path) -> Result<Outputs, String> {
    let meta_path = dir.join("sweep.json");
    let meta = read_meta(&meta_path)?;
    let verified = |name: &str| read_verified(dir, &meta_path, &meta, name);
    let scenario_path = dir.join("scenario.toml");
    let scenario = String::from_utf8(verified("scenario.toml")?)
        .map_err(|e| format!("{}: {e}", scenario_path.display()))?;
    if identity::fingerprint(&scenario, &meta.plan, &meta.build) != meta.fingerprint {
        return Err(format!(
            "{}: its fingerprint is not that of its scenario.toml, plan and build",
            meta_path.display()
        ));
    }
    let base = Scenario::parse(&scenario, &scenario_path).map_err(|e| e.to_string())?;
    let ncol = meta.plan.columns().len();
    let samples_path = dir.join("samples.csv");
    let mut rows = records(&samples_path, &verified("samples.csv")?)?
        .iter()
        .map(|(at, f)| sample_row(at, f, ncol).map(|r| (at.clone(), r)))
        .collect::<Result<Vec<_>, _>>()?;
    let series_path = dir.join("series.csv");
    let (seen, blocks) = read_series(&series_path, &verified("series.csv")?)?;
    let mut orphans = Vec::new();
    for (j, series) in blocks {
        match rows.iter_mut().find(|(_, r)| r.sample == j) {
            Some(row) => row.1.series = series,
            None => orphans.push(format!(
                "{}: sample {j} is not in samples.csv",
                series_path.display()
            )),
        }
    }
    Ok(Outputs {
        dir: dir.to_path_buf(),
        meta,
        base,
        rows,
        series: seen,
        orphans,
    })
}

/// `sweep.json` at `meta_path`.
fn read_meta(meta_path: &Path) -> Result<SweepFile, String> {
    let text =
        std::fs::read_to_string(meta_path).map_err(|e| format!("{}: {e}", meta_path.display()))?;
    serde_json::from_str(&text).map_err(|e| {
        format!(
            "{}: {e} (not the sweep.json of a sweep of this version of tiltsim: run the sweep again)",
            meta_path.display()
        )
    })
}

/// The bytes of file `name` in `dir`, checked against the checksum `meta` (read from
/// `meta_path`) holds for it.
fn read_verified(
    dir: &Path,
    meta_path: &Path,
    meta: &SweepFile,
    name: &str,
) -> Result<Vec<u8>, String> {
    let p = dir.join(name);
    let bytes = std::fs::read(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    let want = meta
        .sha256
        .get(name)
        .ok_or_else(|| format!("{}: no checksum of {name}", meta_path.display()))?;
    if identity::sha256(&bytes) != *want {
        return Err(format!(
            "{}: changed since the sweep wrote it (its SHA-256 is not the one {} records)",
            p.display(),
            meta_path.display()
        ));
    }
    Ok(bytes)
}

/// `series.csv` (its `bytes`, read from `path`): the samples it has lines for, and each
/// sample's series in the order of the file.
#[allow(clippy::type_complexity)]
fn read_series(
    path: &Path,
    bytes: &[u8],
) -> Result<(std::collections::BTreeSet<usize>, Vec<(usize, Vec<f64>)>), String> {
    let head = csv::ReaderBuilder::new()
        .from_reader(bytes)
        .headers()
        .map(|h| h.iter().map(str::to_string).collect::<Vec<_>>())
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if head != SERIES_COLUMNS {
        return Err(format!(
            "{} line 1: the columns are not {}",
            path.display(),
            SERIES_COLUMNS.join(",")
        ));
    }
    // One block of lines per sample, its times 0, SERIES_DT, ... in order.
    let mut seen = std::collections::BTreeSet::new();
    let mut current: Option<(usize, Vec<f64>)> = None;
    let mut blocks = Vec::new();
    for (at, f) in records(path, bytes)? {
        if f.len() != SERIES_COLUMNS.len() {
            return Err(format!("{at}: {} fields, expected 3", f.len()));
        }
        let j: usize = f[0]
            .parse()
            .map_err(|_| format!("{at}: bad sample index `{}`", &f[0]))?;
        let v = parse_f64s(f.iter().skip(1), &at)?;
        if current.as_ref().is_none_or(|(c, _)| *c != j) {
            if !seen.insert(j) {
                return Err(format!("{at}: sample {j} appears twice"));
            }
            blocks.extend(current.take());
            current = Some((j, Vec::new()));
        }
        let (_, series) = current.get_or_insert((j, Vec::new()));
        let want = series_time(series.len());
        if v[0].to_bits() != want.to_bits() {
            return Err(format!(
                "{at}: sample {j} at time {} where {} follows",
                v[0],
                tiltsim_formats::table::fmt_f64(want)
            ));
        }
        series.push(v[1]);
    }
    blocks.extend(current);
    Ok((seen, blocks))
}

/// Redraws the figures of the sweep (or shard) in `dir` from its verified outputs; returns the
/// files written.
pub fn redraw(dir: &Path) -> Result<Vec<PathBuf>, SweepError> {
    let o = read_outputs(dir)?;
    let rows: Vec<Row> = o.rows.into_iter().map(|(_, r)| r).collect();
    super::figures::write_plots(dir, &o.base, &o.meta.plan, &rows)
        .map_err(|e| SweepError::Files(format!("{}: {e}", dir.join("plots").display())))
}

/// Joins shard outputs: each verified ([`read_outputs`]), all of one sweep (fingerprint:
/// scenario, plan, build), each shard of one split once, every sample of the plan exactly once
/// with the plan's parameters. Errors name the directory or the file and line.
pub fn merge(dirs: &[PathBuf]) -> Result<(Scenario, Plan, String, Vec<Row>), SweepError> {
    let mut all = Vec::new();
    for d in dirs {
        all.push(read_outputs(d)?);
    }
    join(all).map_err(SweepError::Merge)
}

pub(super) fn join(shards: Vec<Outputs>) -> Result<(Scenario, Plan, String, Vec<Row>), String> {
    let first = shards.first().ok_or("no shard directories given")?;
    let (base, plan) = (first.base.clone(), first.meta.plan.clone());
    let n = plan.len();
    let split = shard_of(first)?.count;
    let mut taken: Vec<Option<PathBuf>> = vec![None; split];
    let mut rows: Vec<Row> = Vec::new();
    for o in &shards {
        same_sweep(o, first)?;
        let sh = shard_of(o)?;
        let name = format!("{}/{}", sh.index, sh.count);
        if sh.count != split {
            return Err(format!(
                "{} is shard {name}, {} is shard {}: shards of different splits",
                o.dir.display(),
                first.dir.display(),
                shard_name(first)
            ));
        }
        if let Some(other) = &taken[sh.index] {
            return Err(format!(
                "{} and {} are both shard {name}",
                other.display(),
                o.dir.display()
            ));
        }
        taken[sh.index] = Some(o.dir.clone());
        check_shard_rows(o, &base, &plan, &sh.samples(n), &name)?;
        rows.extend(o.rows.iter().map(|(_, r)| r.clone()));
    }
    rows.sort_by_key(|r| r.sample);
    all_samples_present(&rows, n, &taken)?;
    Ok((base, plan, first.meta.build.clone(), rows))
}

/// The shard `o` says it is (a whole sweep when it says none).
fn shard_of(o: &Outputs) -> Result<Shard, String> {
    match &o.meta.shard {
        None => Ok(Shard { index: 0, count: 1 }),
        Some(t) => Shard::parse(t).map_err(|_| {
            format!(
                "{}: shard `{t}` is not I/N",
                o.dir.join("sweep.json").display()
            )
        }),
    }
}

/// Whether shard `o` belongs to the sweep of shard `first`: finished, and of one plan, base
/// scenario, build and fingerprint.
fn same_sweep(o: &Outputs, first: &Outputs) -> Result<(), String> {
    let (d, m) = (&o.dir, &o.meta);
    let (d0, m0) = (&first.dir, &first.meta);
    if m.interrupted {
        return Err(format!(
            "{}: the sweep there was interrupted (sweep.json: \"interrupted\": true): start it again with the same arguments to finish it, then merge",
            d.display()
        ));
    }
    if m.plan != m0.plan {
        return Err(format!(
            "{}: a different sweep plan than {}",
            d.display(),
            d0.display()
        ));
    }
    if o.base != first.base {
        return Err(format!(
            "{}: a different base scenario than {}",
            d.display(),
            d0.display()
        ));
    }
    if m.build != m0.build {
        return Err(format!(
            "{}: computed by another build of tiltsim ({}) than {} ({}): run the shards with one build",
            d.display(),
            m.build,
            d0.display(),
            m0.build
        ));
    }
    if m.fingerprint != m0.fingerprint {
        return Err(format!(
            "{}: another sweep than {} (fingerprint differs)",
            d.display(),
            d0.display()
        ));
    }
    Ok(())
}

/// Whether the rows of shard `o` (shard `name`, samples `mine` of the plan) are each of its
/// samples once, with the plan's parameters and a line of series, all of them, and those its
/// `sweep.json` lists.
fn check_shard_rows(
    o: &Outputs,
    base: &Scenario,
    plan: &Plan,
    mine: &[usize],
    name: &str,
) -> Result<(), String> {
    let (d, n) = (&o.dir, plan.len());
    let mut seen = std::collections::BTreeSet::new();
    for (at, r) in &o.rows {
        if r.sample >= n {
            return Err(format!(
                "{at}: sample {} is not in the plan ({n} samples)",
                r.sample
            ));
        }
        if mine.binary_search(&r.sample).is_err() {
            return Err(format!("{at}: sample {} is not in shard {name}", r.sample));
        }
        if !seen.insert(r.sample) {
            return Err(format!("{at}: sample {} appears twice", r.sample));
        }
        check_params(base, plan, r).map_err(|e| format!("{at}: {e}"))?;
        if !o.series.contains(&r.sample) {
            return Err(format!(
                "{at}: sample {} has no line in {}",
                r.sample,
                d.join("series.csv").display()
            ));
        }
    }
    let absent: Vec<usize> = mine.iter().filter(|j| !seen.contains(j)).copied().collect();
    if !absent.is_empty() {
        return Err(format!(
            "{}: {} of the {} samples of shard {name} missing (first: {:?})",
            d.join("samples.csv").display(),
            absent.len(),
            mine.len(),
            &absent[..absent.len().min(5)]
        ));
    }
    if let Some(e) = o.orphans.first() {
        return Err(e.clone());
    }
    if o.meta.samples != seen.iter().copied().collect::<Vec<_>>() {
        return Err(format!(
            "{}: its list of samples is not that of samples.csv",
            d.join("sweep.json").display()
        ));
    }
    Ok(())
}

/// Whether the joined `rows` (in sample order) hold every one of the `n` samples; else the
/// shards of the split not `taken` are named.
fn all_samples_present(rows: &[Row], n: usize, taken: &[Option<PathBuf>]) -> Result<(), String> {
    let split = taken.len();
    let missing: Vec<usize> = (0..n)
        .filter(|j| rows.binary_search_by_key(j, |r| r.sample).is_err())
        .collect();
    if !missing.is_empty() {
        let absent: Vec<String> = (0..split)
            .filter(|i| taken[*i].is_none())
            .map(|i| format!("{i}/{split}"))
            .collect();
        return Err(format!(
            "{} of {n} samples missing (first: {:?}): shard {} absent",
            missing.len(),
            &missing[..missing.len().min(5)],
            absent.join(", ")
        ));
    }
    Ok(())
}

pub(super) fn shard_name(o: &Outputs) -> String {
    o.meta
        .shard
        .clone()
        .unwrap_or_else(|| "0/1 (a whole sweep)".into())
}
