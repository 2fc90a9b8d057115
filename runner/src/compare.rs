//! A comparison run into a directory, as `tiltsim compare` and the Python package's
//! `compare` make it: each scenario runs into `out/<name>`, then the Table 4 tables
//! (`table.md`, `table.csv` with its `columns.csv`), the figures and `compare.json` are
//! written. The caller prints.

use std::path::{Path, PathBuf};

use tiltsim_master::engine::{RunOptions, Status, Summary};
use tiltsim_rundir::outdir::{self, Lock, OutDirError};
use tiltsim_scenario::scenario::Scenario;

use tiltsim_report::table4::{Entry, Manifest, ManifestRun};

/// Why a comparison did not finish.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// The directory or a scenario cannot be used; the message names which and why.
    #[error("{0}")]
    Invalid(String),
    /// A run failed or a file could not be written.
    #[error("{0}")]
    Failed(String),
    /// Interrupted; the runs finished before stay on disk.
    #[error("{0}")]
    Interrupted(String),
}

fn invalid(e: OutDirError) -> CompareError {
    CompareError::Invalid(e.to_string())
}

fn write_json<T: serde::Serialize>(path: &Path, v: &T) -> Result<(), CompareError> {
    let text = serde_json::to_string_pretty(v).unwrap_or_default() + "\n";
    tiltsim_rundir::files::write_atomic(path, text).map_err(|e| CompareError::Failed(e.to_string()))
}

/// Gives scenarios of one name distinct directories and labels (`name`, `name-2`, ...);
/// returns a note for each one renamed.
pub fn distinct(loaded: &mut [(PathBuf, Scenario)], out: &Path) -> Vec<String> {
    let names: Vec<String> = loaded.iter().map(|(_, s)| s.name.clone()).collect();
    let mut notes = Vec::new();
    for ((file, s), name) in loaded
        .iter_mut()
        .zip(tiltsim_report::table4::distinct_names(&names))
    {
        if name != s.name {
            notes.push(format!(
                "{}: `{}` is also the name of another scenario compared (or of a file of the compare): this one runs in {} and is labelled {name}",
                file.display(),
                s.name,
                out.join(&name).display()
            ));
            s.name = name;
        }
    }
    notes
}

/// A comparison under way in its directory, which it holds until dropped.
pub struct Comparison {
    out: PathBuf,
    manifest: Manifest,
    entries: Vec<Entry>,
    _lock: Lock,
}

impl Comparison {
    /// Claims `out` for the scenarios of `loaded` (already made distinct, [`distinct`]),
    /// removes an earlier compare's runs and tables there, and writes `compare.json`.
    pub fn start(out: &Path, loaded: &[(PathBuf, Scenario)]) -> Result<Self, CompareError> {
        let lock = outdir::claim(out, outdir::Kind::Compare, "compare").map_err(invalid)?;
        clear_earlier(out)?;
        let manifest = Manifest {
            trade_off: Vec::new(),
            runs: loaded
                .iter()
                .map(|(f, s)| ManifestRun {
                    dir: s.name.clone(),
                    scenario: f.display().to_string(),
                })
                .collect(),
        };
        write_json(&out.join("compare.json"), &manifest)?;
        Ok(Comparison {
            out: out.to_path_buf(),
            manifest,
            entries: Vec::new(),
            _lock: lock,
        })
    }

    /// Runs `s` (from `file`) into `out/<name>` with `base`'s options; returns its summary.
    /// A failed or interrupted run ends the comparison with an error naming it.
    pub fn run(
        &mut self,
        file: &Path,
        s: Scenario,
        base: &RunOptions,
    ) -> Result<&Summary, CompareError> {
        let dir = self.out.join(&s.name);
        // Each run of a compare is a run: its own lock, an earlier run's files removed.
        let _lock = outdir::claim_run(&dir, "compare").map_err(invalid)?;
        let mut opts = base.clone();
        opts.out_dir = dir.clone();
        let mut job = crate::pipeline::Job::new(&s, file.display().to_string(), opts);
        job.claim = false;
        let done = crate::pipeline::carry_out(job).map_err(|e| match e {
            crate::pipeline::JobError::Run(tiltsim_master::engine::RunError::Interrupted {
                ..
            }) => CompareError::Interrupted(format!("{}: {e}", file.display())),
            e => CompareError::Failed(format!("{}: {e}", file.display())),
        })?;
        for w in &done.warnings {
            tracing::warn!("{w}");
        }
        let summary = done.summary;
        match summary.status {
            Status::Completed | Status::Degraded => {}
            Status::Interrupted => {
                return Err(CompareError::Interrupted(format!(
                    "interrupted during {}: the runs before it are kept in {}",
                    s.name,
                    self.out.display()
                )))
            }
            Status::Failed => {
                let why = summary.error.as_deref().unwrap_or("run failed");
                return Err(CompareError::Failed(format!("{}: {why}", s.name)));
            }
        }
        let ideal = tiltsim_report::analysis::ideal_tilt(&s, &dir);
        self.entries
            .push(tiltsim_report::table4::entry(s, summary, ideal));
        Ok(&self.entries[self.entries.len() - 1].summary)
    }

    /// Writes the tables, figures and the final `compare.json`; returns the entries and the
    /// text of `table.csv`.
    pub fn finish(mut self) -> Result<(Vec<Entry>, String), CompareError> {
        let out = &self.out;
        let failed = |e: std::io::Error| {
            CompareError::Failed(format!("{}: {e}", out.join("plots").display()))
        };
        self.manifest.trade_off = tiltsim_report::table4::trade_off_points(&self.entries);
        let (md, csv, columns) = tiltsim_report::table4::tables(&self.entries);
        for (name, text) in [
            ("table.md", &md),
            ("table.csv", &csv),
            ("columns.csv", &columns),
        ] {
            tiltsim_rundir::files::write_atomic(&out.join(name), text)
                .map_err(|e| CompareError::Failed(e.to_string()))?;
        }
        let runs: Vec<_> = self
            .entries
            .iter()
            .map(|e| {
                (
                    e.scenario.name.clone(),
                    e.scenario.clone(),
                    out.join(&e.scenario.name),
                )
            })
            .collect();
        tiltsim_report::analysis::write_compare_plots(&runs, out).map_err(failed)?;
        tiltsim_report::table4::write_trade_off_plot(&self.manifest.trade_off, out)
            .map_err(failed)?;
        write_json(&out.join("compare.json"), &self.manifest)?;
        Ok((std::mem::take(&mut self.entries), csv))
    }
}

/// Removes an earlier compare's runs (each claimed first, so a live one is never touched) and
/// tables from `out`.
fn clear_earlier(out: &Path) -> Result<(), CompareError> {
    if let Some(old) = Manifest::read(out) {
        for r in old.runs {
            let dir = out.join(&r.dir);
            if r.dir.contains(['/', '\\']) || r.dir.starts_with('.') || !dir.is_dir() {
                continue;
            }
            drop(outdir::claim_run(&dir, "compare").map_err(invalid)?);
            outdir::remove_if_empty(&dir);
        }
    }
    outdir::clear_compare_results(out).map_err(invalid)?;
    Ok(())
}
