//! Resumable sweeps: each finished sample's row is kept in `DIR/done/sample-NNNN.json`
//! (written whole or not at all) as soon as it ends, so a sweep or a shard that is killed
//! (preempted, retried by its scheduler) and started again with the same arguments skips what
//! it finished. Floats are kept as their bits, so a resumed sweep's files equal an
//! uninterrupted one's byte for byte. `DIR/done/plan.json` names the base scenario and the
//! plan; samples kept for another plan are never reused.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{Plan, Row, SampleStatus};
use crate::scenario::Scenario;

/// A row as kept on disk: every float by its bits (NaN included).
#[derive(Serialize, Deserialize)]
struct Kept {
    sample: usize,
    params: Vec<u64>,
    status: String,
    metrics: Vec<u64>,
    flags: Vec<String>,
    series: Vec<u64>,
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn floats(v: &[u64]) -> Vec<f64> {
    v.iter().map(|b| f64::from_bits(*b)).collect()
}

/// What a kept sample belongs to.
#[derive(Serialize, Deserialize, PartialEq)]
struct Identity {
    scenario: String,
    plan: Plan,
}

/// The finished samples of one sweep directory.
pub struct Done {
    dir: PathBuf,
}

impl Done {
    /// Opens `out/done` for `base` and `plan`: samples kept there for another scenario or plan
    /// are removed (with a warning), so they cannot be mixed in.
    pub fn open(out: &Path, base: &Scenario, plan: &Plan) -> std::io::Result<Done> {
        let dir = out.join("done");
        std::fs::create_dir_all(&dir)?;
        let id = Identity {
            scenario: toml::to_string(base).unwrap_or_default(),
            plan: plan.clone(),
        };
        let id_path = dir.join("plan.json");
        let same = std::fs::read_to_string(&id_path)
            .ok()
            .and_then(|t| serde_json::from_str::<Identity>(&t).ok())
            .is_some_and(|old| old == id);
        if !same {
            let stale = std::fs::read_dir(&dir)?
                .flatten()
                .filter(|e| e.file_name().to_string_lossy().starts_with("sample-"))
                .filter(|e| std::fs::remove_file(e.path()).is_ok())
                .count();
            if stale > 0 {
                tracing::warn!(
                    "{}: {stale} finished samples of another scenario or plan removed",
                    dir.display()
                );
            }
            crate::files::write_atomic(
                &id_path,
                serde_json::to_string_pretty(&id).unwrap_or_default() + "\n",
            )?;
        }
        Ok(Done { dir })
    }

    fn path(&self, j: usize) -> PathBuf {
        self.dir.join(format!("sample-{j:05}.json"))
    }

    /// The kept row of sample `j`, if it finished before.
    pub fn get(&self, j: usize) -> Option<Row> {
        let k: Kept = serde_json::from_str(&std::fs::read_to_string(self.path(j)).ok()?).ok()?;
        if k.sample != j {
            return None;
        }
        Some(Row {
            sample: k.sample,
            params: floats(&k.params),
            status: SampleStatus::parse(&k.status)?,
            metrics: floats(&k.metrics),
            flags: k.flags,
            series: floats(&k.series),
        })
    }

    /// Keeps a finished sample's row.
    pub fn put(&self, r: &Row) -> std::io::Result<()> {
        let k = Kept {
            sample: r.sample,
            params: bits(&r.params),
            status: r.status.to_string(),
            metrics: bits(&r.metrics),
            flags: r.flags.clone(),
            series: bits(&r.series),
        };
        crate::files::write_atomic(
            &self.path(r.sample),
            serde_json::to_string(&k).unwrap_or_default(),
        )
    }
}
