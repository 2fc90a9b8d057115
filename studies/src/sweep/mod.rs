//! `tiltsim sweep`: many runs of one scenario with something varied, and what the comfort
//! metrics do across them.
//!
//! Two plans:
//! * **Monte Carlo** (Fig. 21 of the paper): every mass, inertia and suspension parameter of
//!   the true vehicle is scaled by its own factor drawn uniformly from `1 ± spread` (default
//!   ±22 %), while the controller keeps the nominal design (`design_vehicle`). Sample `j`
//!   draws from ChaCha8 seeded with the sweep seed on stream `j`, so a sample's parameters do
//!   not depend on which other samples run, where or in which order. The track irregularity
//!   and sensor noise keep the scenario's `run.seed`: samples differ only in the vehicle.
//! * **Grid**: one numeric scenario key (dotted path, e.g. `vehicle.m_v` or
//!   `links.actuator_command.delay_ticks`) set to each listed value in turn.
//!
//! Results: `samples.csv` (one row per sample: parameters, status, every comfort metric),
//! `series.csv` (each sample's lateral acceleration every 10 ms), `table.md`/`table.csv`
//! (Monte Carlo: median, 5th and 95th percentile of each metric; grid: the metrics per
//! value), `plots/` and `sweep.json` (the plan). A shard (`--shard i/n`) runs samples
//! `j ≡ i (mod n)` and writes the same files for its samples; `tiltsim sweep-merge` joins
//! shards into files byte-identical to the unsharded sweep's, because every file is written
//! by one function from the rows alone, and numbers are written in Rust's shortest
//! round-trip form, so reading a shard back loses nothing.

mod exec;
mod figures;
pub mod identity;
mod merge;
mod outputs;
mod plan;
mod resume;

pub use exec::*;
pub use merge::*;
pub use outputs::*;
pub use plan::*;

/// Why a sweep could not be set up or its files read back.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A `--grid`, `--shard` or sweep key as given: the message names it and what is allowed.
    #[error("{0}")]
    Argument(String),
    /// A sweep's files: the message names the file (and line) and what is wrong.
    #[error("{0}")]
    Files(String),
    /// Shards that do not make one sweep together.
    #[error("{0}")]
    Merge(String),
}

/// How one sample ended (written `completed` or `failed: cause`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SampleStatus {
    /// The run completed.
    Completed,
    /// The run failed, or the sample could not be set up.
    Failed(String),
}

impl SampleStatus {
    /// Whether the run completed.
    pub fn completed(&self) -> bool {
        *self == SampleStatus::Completed
    }

    /// Parses the text of `samples.csv`.
    pub fn parse(s: &str) -> Option<Self> {
        if s == "completed" {
            Some(SampleStatus::Completed)
        } else {
            s.strip_prefix("failed: ")
                .map(|why| SampleStatus::Failed(why.to_string()))
        }
    }
}

impl std::fmt::Display for SampleStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SampleStatus::Completed => f.write_str("completed"),
            SampleStatus::Failed(why) => write!(f, "failed: {why}"),
        }
    }
}

/// One sample's result.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Sample index.
    pub sample: usize,
    /// Parameter values ([`Plan::columns`]).
    pub params: Vec<f64>,
    /// How it ended.
    pub status: SampleStatus,
    /// Metrics in [`METRICS`] order (NaN when the run failed).
    pub metrics: Vec<f64>,
    /// The validity flags the run raised (`tiltsim_assessment::validity::Flags::raised`).
    pub flags: Vec<String>,
    /// Lateral acceleration at 0, [`SERIES_DT`], 2·[`SERIES_DT`], ... (m/s²), as far as
    /// recorded.
    pub series: Vec<f64>,
}

#[cfg(test)]
mod tests {
    use tiltsim_scenario::scenario::Scenario;

    use super::*;

    #[test]
    fn grid_specs_parse_to_exact_values_and_bad_ones_are_named() {
        let Plan::Grid { key, values } = parse_grid("run.seed=1:5:2").unwrap() else {
            panic!()
        };
        assert_eq!((key.as_str(), values), ("run.seed", vec![1.0, 3.0, 5.0]));
        let Plan::Grid { values, .. } = parse_grid("x=0:0.3:0.1").unwrap() else {
            panic!()
        };
        assert_eq!(values.len(), 4);
        let Plan::Grid { values, .. } = parse_grid("x=3,1.5").unwrap() else {
            panic!()
        };
        assert_eq!(values, vec![3.0, 1.5]);
        for bad in ["x", "x=1:2", "x=2:1:1", "x=a,b", "=1"] {
            assert!(parse_grid(bad).is_err(), "{bad}");
        }
    }

    /// An environment of the variables `vars`.
    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + Copy + 'a {
        move |k: &str| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn the_shard_of_a_slurm_array_task_is_read_from_its_variables() {
        let slurm = env(&[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "8"),
        ]);
        assert_eq!(
            Shard::auto(None, slurm).unwrap(),
            Shard { index: 4, count: 8 }
        );
        // `--array=0-6:2`: tasks 0, 2, 4, 6 are shards 0..3 of 4.
        for (id, index) in [("0", 0), ("2", 1), ("4", 2), ("6", 3)] {
            let vars: Vec<(&str, &str)> = vec![
                ("SLURM_ARRAY_TASK_ID", id),
                ("SLURM_ARRAY_TASK_MIN", "0"),
                ("SLURM_ARRAY_TASK_MAX", "6"),
                ("SLURM_ARRAY_TASK_STEP", "2"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ];
            assert_eq!(
                Shard::auto(None, env(&vars)).unwrap(),
                Shard { index, count: 4 }
            );
        }
        // `sbatch --array=2`, task 2 of a larger array submitted again: refused, saying how.
        let single = env(&[
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_MIN", "2"),
            ("SLURM_ARRAY_TASK_MAX", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "1"),
        ]);
        let e = Shard::auto(None, single).unwrap_err().to_string();
        assert!(e.contains("--shard 2/8") && e.contains("--array=2"), "{e}");
        // An array of one task numbered 0 is a sweep of one shard.
        let one = env(&[
            ("SLURM_ARRAY_TASK_ID", "0"),
            ("SLURM_ARRAY_TASK_COUNT", "1"),
        ]);
        assert_eq!(
            Shard::auto(None, one).unwrap(),
            Shard { index: 0, count: 1 }
        );
        // `--array=1,2,5`: not evenly spaced, refused.
        let uneven = env(&[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ]);
        let e = Shard::auto(None, uneven).unwrap_err().to_string();
        assert!(
            e.contains("evenly spaced") && e.contains("--shard I/N"),
            "{e}"
        );
    }

    #[test]
    fn the_shard_of_an_aws_or_kubernetes_array_task_is_read_and_none_is_an_error() {
        let aws = env(&[
            ("AWS_BATCH_JOB_ARRAY_INDEX", "2"),
            ("AWS_BATCH_JOB_ARRAY_SIZE", "3"),
        ]);
        assert_eq!(
            Shard::auto(None, aws).unwrap(),
            Shard { index: 2, count: 3 }
        );
        let k8s = env(&[("JOB_COMPLETION_INDEX", "1")]);
        assert_eq!(
            Shard::auto(Some(4), k8s).unwrap(),
            Shard { index: 1, count: 4 }
        );
        let e = Shard::auto(None, k8s).unwrap_err().to_string();
        assert!(e.contains("--shards N"), "{e}");
        let e = Shard::auto(None, env(&[])).unwrap_err().to_string();
        assert!(
            e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"),
            "{e}"
        );
        let bad = env(&[
            ("AWS_BATCH_JOB_ARRAY_INDEX", "3"),
            ("AWS_BATCH_JOB_ARRAY_SIZE", "3"),
        ]);
        assert!(Shard::auto(None, bad).is_err());
    }

    #[test]
    fn monte_carlo_factors_are_within_the_spread_and_fixed_per_sample() {
        let base = Scenario::default();
        let plan = Plan::MonteCarlo {
            samples: 50,
            spread: 0.22,
            seed: 7,
        };
        let (s3, f3) = sample(&base, &plan, 3).unwrap();
        assert_eq!(
            sample(&base, &plan, 3).unwrap().1,
            f3,
            "a sample is reproducible"
        );
        assert_ne!(sample(&base, &plan, 4).unwrap().1, f3, "samples differ");
        assert!((s3.vehicle.m_v / base.vehicle.m_v - f3[0]).abs() < 1e-12);
        assert_eq!(s3.design_vehicle.as_ref(), Some(&base.vehicle));
        let mut lo: f64 = 1.0;
        let mut hi: f64 = 1.0;
        for j in 0..50 {
            for f in sample(&base, &plan, j).unwrap().1 {
                lo = lo.min(f);
                hi = hi.max(f);
            }
        }
        // 750 uniform draws: all inside ±22 %, and reaching near both ends.
        assert!(lo >= 0.78 && hi <= 1.22, "{lo} {hi}");
        assert!(lo < 0.80 && hi > 1.20, "{lo} {hi}");
    }

    #[test]
    fn keys_are_set_with_their_type_and_checked() {
        let base = Scenario::default();
        let s = with_key(&base, "vehicle.m_v", 21000.0).unwrap();
        assert_eq!(s.vehicle.m_v, 21000.0);
        let s = with_key(&base, "run.seed", 9.0).unwrap();
        assert_eq!(s.run.seed, 9);
        let e = with_key(&base, "run.seed", 1.5).unwrap_err().to_string();
        assert!(e.contains("run.seed") && e.contains("whole number"), "{e}");
        let e = with_key(&base, "vehicle.m_vv", 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("m_vv"), "{e}");
        // An unknown section is named as the user wrote it, with no line of an internal
        // document.
        let e = with_key(&base, "foo.bar", 1.0).unwrap_err().to_string();
        assert!(
            e.contains("key `foo.bar`") && e.contains("unknown field `foo`"),
            "{e}"
        );
        assert!(!e.contains("line "), "{e}");
        let e = with_key(&base, "vehicle.m_v", -1.0).unwrap_err();
        assert!(matches!(e, SweepError::Argument(_)));
        assert!(e.to_string().contains("vehicle.m_v"), "{e}");
    }

    #[test]
    fn percentiles_interpolate_between_order_statistics() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(percentile(&v, 0.5), 3.0);
        assert_eq!(percentile(&v, 0.05), 1.2);
        assert_eq!(percentile(&v, 1.0), 5.0);
        assert!(percentile(&[], 0.5).is_nan());
    }
}
