//! `tiltsim compare SCENARIO...`: several runs laid out like the paper's Table 4, with the
//! ideal-tilt reference and the validity flags.

use std::path::{Path, PathBuf};

use super::common::{interrupt_and_exe, load, write_json, TransportArg};
use super::error::{CliError, CliResult};
use tiltsim_master::engine::{RunOptions, Status};
use tiltsim_master::scenario::Scenario;
use tiltsim_report::compare::Entry;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// Scenario files (TOML).
    #[arg(required = true)]
    scenarios: Vec<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "out/compare")]
    out: PathBuf,
    /// Transport for every run, overriding run.transport.
    #[arg(long, value_enum)]
    transport: Option<TransportArg>,
}

/// Runs one scenario into `out/<name>`; its table entry.
fn one(file: &Path, s: Scenario, out: &Path, base: &RunOptions) -> Result<Entry, CliError> {
    let dir = out.join(&s.name);
    // Each run of a compare is a run: its own lock, an earlier run's files removed.
    let _lock = tiltsim_master::outdir::claim_run(&dir, "compare")
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    let mut opts = base.clone();
    opts.out_dir = dir.clone();
    let summary = tiltsim_report::analysis::run(&s, &file.display().to_string(), &opts)
        .map_err(|e| CliError::of_run(e, &format!("{}: ", file.display())))?;
    write_json(&dir.join("summary.json"), &summary)?;
    println!(
        "{}: {:?}, P_CT standing {:.2} %, peak lateral acceleration {:.2} %g",
        s.name, summary.status, summary.comfort.p_ct.standing, summary.comfort.lat_acc_peak_pct_g
    );
    match summary.status {
        Status::Completed | Status::Degraded => {}
        Status::Interrupted => return Err(CliError::Interrupted("interrupted".into())),
        Status::Failed => {
            let why = summary.error.as_deref().unwrap_or("run failed");
            return Err(CliError::Failed(format!("{}: {why}", s.name)));
        }
    }
    let ideal = tiltsim_report::analysis::ideal_tilt(&s, &dir);
    Ok(tiltsim_report::compare::entry(s, summary, ideal))
}

/// Runs the command.
pub fn exec(a: CompareArgs) -> CliResult {
    let loaded = load_all(&a)?;
    let invalid = |e: tiltsim_master::outdir::OutDirError| CliError::Invalid(e.to_string());
    // The compare holds its directory; an earlier compare's runs and tables there go first.
    let _lock =
        tiltsim_master::outdir::claim(&a.out, tiltsim_master::outdir::Kind::Compare, "compare")
            .map_err(invalid)?;
    clear_earlier(&a.out)?;
    let mut manifest = tiltsim_report::compare::Manifest {
        trade_off: Vec::new(),
        runs: loaded
            .iter()
            .map(|(f, s)| tiltsim_report::compare::ManifestRun {
                dir: s.name.clone(),
                scenario: f.display().to_string(),
            })
            .collect(),
    };
    write_json(&a.out.join("compare.json"), &manifest)?;
    let (interrupt, exe) = interrupt_and_exe()?;
    let mut base = RunOptions::new(a.out.clone(), exe);
    base.interrupt = interrupt;
    let mut entries = Vec::new();
    for (file, s) in loaded {
        entries.push(one(&file, s, &a.out, &base)?);
    }
    manifest.trade_off = tiltsim_report::compare::trade_off_points(&entries);
    write_results(&manifest.trade_off, &entries, &a.out)?;
    write_json(&a.out.join("compare.json"), &manifest)?;
    println!(
        "wrote {0}/table.md, {0}/table.csv and {0}/plots/compare_*.svg|png",
        a.out.display()
    );
    Ok(())
}

/// The scenarios compared, each with its file, on the transport asked for; scenarios of one
/// name get distinct directories and labels: `name`, `name-2`, ...
fn load_all(a: &CompareArgs) -> Result<Vec<(PathBuf, Scenario)>, CliError> {
    let mut loaded = Vec::new();
    for f in &a.scenarios {
        let mut s = load(f)?;
        if let Some(t) = a.transport {
            s.run.transport = t.into();
        }
        loaded.push((f.clone(), s));
    }
    let names: Vec<String> = loaded.iter().map(|(_, s)| s.name.clone()).collect();
    for ((file, s), name) in loaded
        .iter_mut()
        .zip(tiltsim_report::compare::distinct_names(&names))
    {
        if name != s.name {
            eprintln!(
                "note: {}: `{}` is also the name of another scenario compared (or of a file of the compare): this one runs in {} and is labelled {name}",
                file.display(),
                s.name,
                a.out.join(&name).display()
            );
            s.name = name;
        }
    }
    Ok(loaded)
}

/// Removes an earlier compare's runs (each claimed first, so a live one is never touched) and
/// tables from `out`.
fn clear_earlier(out: &Path) -> Result<(), CliError> {
    let invalid = |e: tiltsim_master::outdir::OutDirError| CliError::Invalid(e.to_string());
    if let Some(old) = tiltsim_report::compare::Manifest::read(out) {
        for r in old.runs {
            let dir = out.join(&r.dir);
            if r.dir.contains(['/', '\\']) || r.dir.starts_with('.') || !dir.is_dir() {
                continue;
            }
            drop(tiltsim_master::outdir::claim_run(&dir, "compare").map_err(invalid)?);
            tiltsim_master::outdir::remove_if_empty(&dir);
        }
    }
    tiltsim_master::outdir::clear_compare_results(out).map_err(invalid)?;
    Ok(())
}

/// Writes the compare's tables and figures into `out`.
fn write_results(
    trade_off: &[tiltsim_report::compare::TradeOffPoint],
    entries: &[Entry],
    out: &Path,
) -> CliResult {
    let (md, csv) = tiltsim_report::compare::tables(entries);
    for (name, text) in [("table.md", &md), ("table.csv", &csv)] {
        let p = out.join(name);
        tiltsim_master::files::write_atomic(&p, text)
            .map_err(|e| CliError::Failed(e.to_string()))?;
    }
    let runs: Vec<_> = entries
        .iter()
        .map(|e| {
            (
                e.scenario.name.clone(),
                e.scenario.clone(),
                out.join(&e.scenario.name),
            )
        })
        .collect();
    tiltsim_report::analysis::write_compare_plots(&runs, out)
        .map_err(|e| CliError::Failed(format!("{}: {e}", out.join("plots").display())))?;
    tiltsim_report::compare::write_trade_off_plot(trade_off, out)
        .map_err(|e| CliError::Failed(format!("{}: {e}", out.join("plots").display())))?;
    Ok(())
}
