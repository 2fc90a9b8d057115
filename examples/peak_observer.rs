//! An observer written outside tiltsim: it watches a lock-step run tick by tick and reports
//! the largest passenger lateral acceleration and when it happened, as its part of the
//! summary.
//!
//! ```sh
//! cargo run --release -p tiltsim-suite --example peak_observer -- scenarios/paper-lqg.toml out/peak
//! ```
//!
//! It prints the observer's part of the summary as JSON; `out/peak/timeseries.csv` holds the
//! rows it watched, written by the built-in rows observer added before it.

use std::path::PathBuf;

use tiltsim_master::engine::observe::{Observer, Start, Tick};
use tiltsim_master::engine::outputs::Rows;
use tiltsim_master::engine::{Run, RunOptions, Summary};
use tiltsim_scenario::scenario::{Scenario, Transport};

/// The largest |ÿ| seen (eq 13, m/s²) and its time.
#[derive(Default)]
struct PeakLateral {
    peak: f64,
    at_s: f64,
    ticks: u64,
}

impl Observer for PeakLateral {
    fn name(&self) -> &str {
        "peak_lateral"
    }

    fn start(&mut self, start: &Start<'_>) -> std::io::Result<()> {
        self.peak = start.plant.lat_acc.abs();
        self.at_s = 0.0;
        Ok(())
    }

    fn tick(&mut self, tick: &Tick<'_>) -> std::io::Result<()> {
        self.ticks += 1;
        let a = tick.plant.lat_acc.abs();
        if a > self.peak {
            self.peak = a;
            self.at_s = tick.time;
        }
        Ok(())
    }

    fn finish(&mut self, summary: &Summary) -> Option<serde_json::Value> {
        Some(serde_json::json!({
            "peak_lat_acc_m_s2": self.peak,
            "at_s": self.at_s,
            "ticks": self.ticks,
            "status": summary.status.to_string(),
        }))
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [scenario, out] = args.as_slice() else {
        eprintln!("usage: peak_observer SCENARIO.toml OUT_DIR");
        std::process::exit(2);
    };
    let mut s = match Scenario::load(&PathBuf::from(scenario)) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    s.run.transport = Transport::InProcess;
    let opts = RunOptions::new(PathBuf::from(out), PathBuf::from("tiltsim"));
    let csv = std::fs::create_dir_all(out)
        .and_then(|()| Rows::to_file(&opts.out_dir.join("timeseries.csv"), s.run.dt_s));
    let csv = match csv {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{out}: {e}");
            std::process::exit(1);
        }
    };
    let ran = Run::new(&s, scenario, &opts)
        .add_observer(Box::new(csv))
        .add_observer(Box::new(PeakLateral::default()))
        .simulate();
    match ran {
        Ok(ran) => println!("{}", ran.summary.observers["peak_lateral"]),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
