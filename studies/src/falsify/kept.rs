//! What a search keeps as it goes, so an interrupted one resumes exactly: every evaluation
//! appended to `OUT/done/evals.csv` as it ends, under the search's fingerprint.

use std::collections::HashMap;
use std::io::Write as _;
use std::sync::Mutex;

use tiltsim_scenario::scenario::Scenario;

use super::search::{Eval, Method, Spec, EVAL_COLUMNS};
use super::FalsifyError;

/// The evaluations kept by earlier invocations of the same search.
pub(super) struct Kept {
    pub(super) values: HashMap<(Method, usize), Eval>,
    file: Mutex<std::fs::File>,
}

fn files_error(what: &str, e: impl std::fmt::Display) -> FalsifyError {
    FalsifyError::Files(format!("{what}: {e}"))
}

impl Kept {
    /// Opens `out/done`: its evaluations when `fingerprint` is the one it was kept for, else
    /// emptied for this search.
    pub(super) fn open(out: &std::path::Path, fingerprint: &str) -> Result<Kept, FalsifyError> {
        let dir = out.join("done");
        let id = dir.join("fingerprint");
        let csv = dir.join("evals.csv");
        let same = std::fs::read_to_string(&id).is_ok_and(|f| f.trim() == fingerprint);
        let mut values = HashMap::new();
        if same {
            if let Ok(mut r) = csv::ReaderBuilder::new().from_path(&csv) {
                // A line cut short by a kill does not parse: that evaluation is run again.
                for e in r.deserialize::<Eval>().flatten() {
                    values.insert((e.method, e.evaluation), e);
                }
            }
        } else {
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir)
                .map_err(|e| files_error(&dir.display().to_string(), e))?;
            std::fs::write(&id, format!("{fingerprint}\n"))
                .map_err(|e| files_error(&id.display().to_string(), e))?;
        }
        let fresh = !csv.exists();
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&csv)
            .map_err(|e| files_error(&csv.display().to_string(), e))?;
        if fresh {
            writeln!(file, "{}", EVAL_COLUMNS.join(","))
                .map_err(|e| files_error(&csv.display().to_string(), e))?;
        }
        Ok(Kept {
            values,
            file: Mutex::new(file),
        })
    }

    pub(super) fn put(&self, e: &Eval) {
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Vec::new());
        if w.serialize(e).is_ok() {
            if let (Ok(line), Ok(mut f)) = (w.into_inner(), self.file.lock()) {
                let _ = f.write_all(&line);
            }
        }
    }
}

/// What the search's files are checked against: scenario, bounds, objective, budget, seed
/// and the program's build.
pub fn fingerprint(s: &Scenario, spec: &Spec) -> String {
    let text = format!(
        "tiltsim falsify 3\n{}\n{:?}\n{}\n{} {}\n{}",
        crate::sweep::identity::build(),
        spec.bounds,
        spec.objective.describe(),
        spec.budget,
        spec.seed,
        toml::to_string(s).unwrap_or_default()
    );
    crate::sweep::identity::sha256(text.as_bytes())
}
