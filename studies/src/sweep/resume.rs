//! Resumable sweeps: each finished sample's row is kept in `DIR/done/sample-NNNNN.json`
//! (written whole or not at all) as soon as it ends, so a sweep or a shard that is killed
//! (preempted, retried by its scheduler) and started again with the same arguments skips what
//! it finished. Floats are kept as their bits, so a resumed sweep's files equal an
//! uninterrupted one's byte for byte.
//!
//! `DIR/done/plan.json` records the sweep the directory holds: its fingerprint (base scenario,
//! plan and build of the program, [`super::identity`]), the shard and the number of samples.
//! Every kept sample carries the same fingerprint, shard and sample count, its own index and a
//! SHA-256 of all of it, and is checked against them, and its parameters against the plan's,
//! before it is used: one that fails is run again, with a warning naming the file. Samples
//! kept for another scenario, plan or build are removed (with a warning, printed also under
//! `-q`). A directory started as one shard is never resumed as another: that is refused.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::{identity, Plan, Row, SampleStatus, Shard, SweepError};
use tiltsim_assessment::comfort::METRICS;
use tiltsim_scenario::scenario::Scenario;

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

/// A file's contents and the SHA-256 of their JSON.
#[derive(Serialize, Deserialize)]
struct Sealed<T> {
    body: T,
    sha256: String,
}

fn seal<T: Serialize>(body: T) -> String {
    let text = serde_json::to_string(&body).unwrap_or_default();
    let sha256 = identity::sha256(text.as_bytes());
    serde_json::to_string(&Sealed { body, sha256 }).unwrap_or_default() + "\n"
}

/// The body of a sealed file whose checksum matches (the body written again gives the bytes
/// that were hashed: the JSON of these types is canonical, floats being kept as bits).
fn unseal<T: Serialize + DeserializeOwned>(text: &str) -> Result<T, String> {
    let s: Sealed<T> =
        serde_json::from_str(text).map_err(|e| format!("not a file this tiltsim wrote ({e})"))?;
    let again = serde_json::to_string(&s.body).unwrap_or_default();
    if identity::sha256(again.as_bytes()) != s.sha256 {
        return Err("its checksum does not match its contents".into());
    }
    Ok(s.body)
}

/// What a directory's kept samples belong to (`done/plan.json`).
#[derive(Serialize, Deserialize, PartialEq)]
struct Identity {
    fingerprint: String,
    build: String,
    shard: String,
    samples: usize,
    plan: Plan,
    scenario: String,
}

/// One kept sample (`done/sample-NNNNN.json`).
#[derive(Serialize, Deserialize)]
struct KeptSample {
    fingerprint: String,
    shard: String,
    sample: usize,
    samples: usize,
    row: Kept,
}

/// The finished samples of one sweep directory.
pub struct Done {
    dir: PathBuf,
    id: Identity,
    base: Scenario,
}

/// `i/n` of a shard; a whole sweep is shard `0/1`.
pub fn shard_text(shard: Option<Shard>) -> String {
    let s = shard.unwrap_or(Shard { index: 0, count: 1 });
    format!("{}/{}", s.index, s.count)
}

fn remove_samples(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .filter(|e| {
                    let n = e.file_name().to_string_lossy().into_owned();
                    n.starts_with("sample-") && n.ends_with(".json")
                })
                .filter(|e| std::fs::remove_file(e.path()).is_ok())
                .count()
        })
        .unwrap_or(0)
}

/// Removes the kept samples and the plan of `out/done` (all of it the sweep's own files).
pub fn clear(out: &Path) {
    let dir = out.join("done");
    remove_samples(&dir);
    let _ = std::fs::remove_file(dir.join("plan.json"));
    tiltsim_rundir::outdir::remove_if_empty(&dir);
}

impl Done {
    /// Opens `out/done` for `base`, `plan` and `shard` as computed by `build`: `Ok((done,
    /// true))` when it resumes samples kept there for the same sweep, `Ok((done, false))` when
    /// it starts afresh (samples of another scenario, plan or build removed, with a warning).
    /// A directory kept for another shard is refused.
    pub fn open(
        out: &Path,
        base: &Scenario,
        plan: &Plan,
        shard: Option<Shard>,
        build: &str,
    ) -> Result<(Done, bool), SweepError> {
        let dir = out.join("done");
        let scenario = toml::to_string(base).unwrap_or_default();
        let id = Identity {
            fingerprint: identity::fingerprint(&scenario, plan, build),
            build: build.to_string(),
            shard: shard_text(shard),
            samples: plan.len(),
            plan: plan.clone(),
            scenario,
        };
        let id_path = dir.join("plan.json");
        let old = match std::fs::read_to_string(&id_path) {
            Ok(t) => Some(unseal::<Identity>(&t)),
            Err(_) => None,
        };
        let resumed = match &old {
            Some(Ok(old)) if old.shard != id.shard => {
                return Err(SweepError::Argument(format!(
                    "{}: this directory holds shard {} of its sweep ({}), and is never resumed as shard {}: give `--shard {}` (a resubmitted array task: in place of `--shard auto`), or another --out",
                    out.display(),
                    old.shard,
                    id_path.display(),
                    id.shard,
                    old.shard
                )))
            }
            Some(Ok(old)) => *old == id,
            _ => false,
        };
        if !resumed {
            let stale = remove_samples(&dir);
            if stale > 0 {
                let why = match &old {
                    Some(Ok(o)) if o.plan == id.plan && o.scenario == id.scenario => format!(
                        "were computed by another build of tiltsim ({}; this is {}): they are run again",
                        o.build, id.build
                    ),
                    Some(Ok(_)) => "belong to another scenario or plan: removed".to_string(),
                    Some(Err(e)) => format!("{}: {e}: they are run again", id_path.display()),
                    None => format!("{} is missing: they are run again", id_path.display()),
                };
                // Said even under -q: results are being recomputed.
                eprintln!(
                    "warning: {}: the {stale} samples kept there {why}",
                    dir.display()
                );
            }
            std::fs::create_dir_all(&dir)
                .and_then(|_| tiltsim_rundir::files::write_atomic(&id_path, seal(&id)))
                .map_err(|e| SweepError::Files(format!("{}: {e}", dir.display())))?;
        }
        Ok((
            Done {
                dir,
                id,
                base: base.clone(),
            },
            resumed,
        ))
    }

    fn path(&self, j: usize) -> PathBuf {
        self.dir.join(format!("sample-{j:05}.json"))
    }

    /// The kept row of sample `j`: `Ok(None)` if it has not finished before, `Err(why)` if its
    /// file is damaged or not of this sweep (the file is then removed; the sample runs again).
    pub fn get(&self, j: usize, plan: &Plan) -> Result<Option<Row>, String> {
        let p = self.path(j);
        let text = match std::fs::read_to_string(&p) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(format!("{}: {e}", p.display())),
        };
        let checked = self.check(j, plan, &text);
        if checked.is_err() {
            let _ = std::fs::remove_file(&p);
        }
        checked
            .map(Some)
            .map_err(|e| format!("{}: {e}", p.display()))
    }

    fn check(&self, j: usize, plan: &Plan, text: &str) -> Result<Row, String> {
        let k: KeptSample = unseal(text)?;
        if k.fingerprint != self.id.fingerprint {
            return Err("kept for another sweep (fingerprint differs)".into());
        }
        if k.shard != self.id.shard {
            return Err(format!("kept for shard {}, not {}", k.shard, self.id.shard));
        }
        if k.sample != j || k.row.sample != j {
            return Err(format!("holds sample {}, not {j}", k.sample));
        }
        if k.samples != self.id.samples {
            return Err(format!(
                "kept for a plan of {} samples, not {}",
                k.samples, self.id.samples
            ));
        }
        let status = SampleStatus::parse(&k.row.status)
            .ok_or_else(|| format!("status `{}` is neither completed nor failed", k.row.status))?;
        if k.row.metrics.len() != METRICS.len() {
            return Err(format!(
                "{} metrics, expected {}",
                k.row.metrics.len(),
                METRICS.len()
            ));
        }
        let row = Row {
            sample: j,
            params: floats(&k.row.params),
            status,
            metrics: floats(&k.row.metrics),
            flags: k.row.flags,
            series: floats(&k.row.series),
        };
        super::check_params(&self.base, plan, &row)?;
        Ok(row)
    }

    /// Keeps a finished sample's row.
    pub fn put(&self, r: &Row) -> std::io::Result<()> {
        let k = KeptSample {
            fingerprint: self.id.fingerprint.clone(),
            shard: self.id.shard.clone(),
            sample: r.sample,
            samples: self.id.samples,
            row: Kept {
                sample: r.sample,
                params: bits(&r.params),
                status: r.status.to_string(),
                metrics: bits(&r.metrics),
                flags: r.flags.clone(),
                series: bits(&r.series),
            },
        };
        tiltsim_rundir::files::write_atomic(&self.path(r.sample), seal(&k))
    }
}
