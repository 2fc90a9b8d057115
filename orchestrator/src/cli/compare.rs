//! `tiltsim compare SCENARIO...`: several runs laid out like the paper's Table 4, with the
//! ideal-tilt reference and the validity flags.

use std::path::PathBuf;

use super::common::{interrupt_and_exe, load, TransportArg};
use super::error::{CliError, CliResult};
use tiltsim_master::engine::RunOptions;
use tiltsim_runner::compare::{CompareError, Comparison};
use tiltsim_scenario::scenario::Scenario;

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

/// The error of the command for a comparison's error.
fn cli(e: CompareError) -> CliError {
    match e {
        CompareError::Invalid(m) => CliError::Invalid(m),
        CompareError::Failed(m) => CliError::Failed(m),
        CompareError::Interrupted(m) => CliError::Interrupted(m),
    }
}

/// Runs the command.
pub fn exec(a: CompareArgs) -> CliResult {
    let mut loaded = load_all(&a)?;
    for note in tiltsim_runner::compare::distinct(&mut loaded, &a.out) {
        eprintln!("note: {note}");
    }
    // The compare holds its directory; an earlier compare's runs and tables there go first.
    let mut cmp = Comparison::start(&a.out, &loaded).map_err(cli)?;
    let (interrupt, exe) = interrupt_and_exe()?;
    let mut base = RunOptions::new(a.out.clone(), exe);
    base.interrupt = interrupt;
    for (file, s) in loaded {
        let head = format!("{} ({})", s.name, super::report::who(&s));
        let summary = cmp.run(&file, s, &base).map_err(cli)?;
        println!(
            "{head}: {}, P_CT standing (EN 12299) {:.2} %, peak lateral acceleration {:.2} %g",
            summary.status,
            summary.comfort.p_ct_en12299.standing,
            summary.comfort.lat_acc_peak_pct_g
        );
    }
    cmp.finish().map_err(cli)?;
    println!(
        "wrote {0}/table.md, {0}/table.csv (units: {0}/columns.csv) and {0}/plots/compare_*.svg|png",
        a.out.display()
    );
    Ok(())
}

/// The scenarios compared, each with its file, on the transport asked for.
fn load_all(a: &CompareArgs) -> Result<Vec<(PathBuf, Scenario)>, CliError> {
    let mut loaded = Vec::new();
    for f in &a.scenarios {
        let mut s = load(f)?;
        if let Some(t) = a.transport {
            s.run.transport = t.into();
        }
        loaded.push((f.clone(), s));
    }
    Ok(loaded)
}
