//! A manipulator written outside tiltsim: the body-roll measurement reaches the controller
//! quantised to the resolution of a digital inclinometer, as a link of the scenario would
//! carry it if the sensor were coarser than the model's.
//!
//! ```sh
//! cargo run --release -p tiltsim-suite --example quantised_sensor -- scenarios/paper-lqg.toml out/quantised 0.001
//! ```
//!
//! The run's rows go to `OUT/timeseries.csv` (its `rx_measurement` column holds what the
//! controller got) and its events to `OUT/events.csv`; it prints how many samples it
//! quantised as JSON.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use tiltsim_formats::events::{EventKind, EventLog};
use tiltsim_master::engine::manipulate::{Control, Manipulator};
use tiltsim_master::engine::outputs::Rows;
use tiltsim_master::engine::{Run, RunOptions};
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::scenario::{Scenario, Transport};

/// Rounds every measurement to the nearest multiple of `step` (rad).
struct Quantiser {
    step: f64,
    count: Arc<AtomicU64>,
}

impl Manipulator for Quantiser {
    fn name(&self) -> &str {
        "quantised_sensor"
    }

    fn tick_commencing(&mut self, k: u64, ctl: &mut Control<'_>) {
        if k == 0 {
            let detail = format!("measurement quantised to {} rad", self.step);
            ctl.events
                .push(0, "measurement", EventKind::Manipulated, self.step, detail);
        }
    }

    fn carry(&mut self, link: LinkId, _k: u64, _t: f64, v: f64, _ev: &mut EventLog) -> f64 {
        if link != LinkId::Measurement {
            return v;
        }
        self.count.fetch_add(1, Ordering::Relaxed);
        (v / self.step).round() * self.step
    }
}

fn fail(what: impl std::fmt::Display, code: i32) -> ! {
    eprintln!("{what}");
    std::process::exit(code)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [scenario, out, step] = args.as_slice() else {
        fail("usage: quantised_sensor SCENARIO.toml OUT_DIR STEP_RAD", 2);
    };
    let step: f64 = match step.parse() {
        Ok(q) if q > 0.0 && f64::is_finite(q) => q,
        _ => fail(format!("STEP_RAD: `{step}` is not a positive number"), 2),
    };
    let mut s = Scenario::load(&PathBuf::from(scenario)).unwrap_or_else(|e| fail(e, 2));
    s.run.transport = Transport::InProcess;
    let opts = RunOptions::new(PathBuf::from(out), PathBuf::from("tiltsim"));
    let csv = std::fs::create_dir_all(out)
        .and_then(|()| Rows::to_file(&opts.out_dir.join("timeseries.csv"), s.run.dt_s))
        .unwrap_or_else(|e| fail(format!("{out}: {e}"), 1));
    let count = Arc::new(AtomicU64::new(0));
    let ran = Run::new(&s, scenario, &opts)
        .add_observer(Box::new(csv))
        .add_manipulator(Box::new(Quantiser {
            step,
            count: count.clone(),
        }))
        .simulate()
        .unwrap_or_else(|e| fail(e, 1));
    println!(
        "{}",
        serde_json::json!({
            "status": ran.summary.status.to_string(),
            "quantised": count.load(Ordering::Relaxed),
            "step_rad": step,
        })
    );
}
