//! `tiltsim replay RUN_DIR --participant ROLE`: one participant alone against the inputs a
//! recorded run gave it; where its outputs differ from the recording.

use std::path::PathBuf;

use super::common::{load, TransportArg};
use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct ReplayArgs {
    /// Directory of a run recorded with `tiltsim run SCENARIO --record`.
    run_dir: PathBuf,
    /// plant, actuator or controller.
    #[arg(long)]
    participant: String,
    /// Scenario to build the participant from [default: RUN_DIR/scenario.toml, as recorded];
    /// give a changed one to see where the outputs move.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Output directory [default: RUN_DIR/replay-ROLE].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Run the participant in this process (default) or as its own process over iceoryx2.
    #[arg(long, value_enum)]
    transport: Option<TransportArg>,
}

/// Runs the command.
pub fn exec(a: ReplayArgs) -> CliResult {
    let role = cosim::Role::parse(&a.participant).ok_or_else(|| {
        CliError::Invalid(format!(
            "--participant {}: allowed plant, actuator, controller",
            a.participant
        ))
    })?;
    // A run still writing its recording there is not replayed.
    if let Some(h) = tiltsim_rundir::outdir::live_holder(&a.run_dir) {
        return Err(CliError::Invalid(format!(
            "{}: in use by {h}: its recording is not finished",
            a.run_dir.display()
        )));
    }
    let file = a
        .scenario
        .clone()
        .unwrap_or_else(|| a.run_dir.join("scenario.toml"));
    let s = load(&file)?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| a.run_dir.join(format!("replay-{}", role.name())));
    let at = match a.transport.map(tiltsim_scenario::scenario::Transport::from) {
        Some(tiltsim_scenario::scenario::Transport::Ipc) => {
            tiltsim_master::participant_replay::Where::Process(std::env::current_exe().map_err(
                |e| CliError::Failed(format!("cannot find the tiltsim executable: {e}")),
            )?)
        }
        _ => tiltsim_master::participant_replay::Where::InProcess,
    };
    let r = tiltsim_master::participant_replay::replay(&a.run_dir, role, &s, &at, &out).map_err(
        |e| match e {
            tiltsim_master::participant_replay::ReplayError::Recording { .. } => {
                CliError::Invalid(e.to_string())
            }
            _ => CliError::Failed(e.to_string()),
        },
    )?;
    let lost = r
        .lost_at_step
        .map(|k| format!(" (lost at step {k} in the recording; replayed up to it)"))
        .unwrap_or_default();
    if r.identical {
        println!(
            "{}: {} steps replayed, every output identical to the recording{lost}",
            role.name(),
            r.steps
        );
    } else {
        println!(
            "{}: {} steps replayed, {} differ{lost}",
            role.name(),
            r.steps,
            r.differing_steps
        );
        if let Some(d) = &r.first_difference {
            let f = |v: Option<f64>| v.map_or("NaN".into(), |v| v.to_string());
            println!(
                "  first difference at step {}: {} recorded {}, replayed {}",
                d.step,
                d.field,
                f(d.recorded),
                f(d.replayed)
            );
        }
        for (field, d) in &r.max_abs_difference {
            println!("  largest |difference| of {field}: {d}");
        }
    }
    println!(
        "wrote {}/{}-out.jsonl, replay.json",
        out.display(),
        role.name()
    );
    Ok(())
}
