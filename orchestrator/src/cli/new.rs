//! `tiltsim new NAME`: a commented scenario file to start from, valid as written.

use std::path::PathBuf;

use super::error::{CliError, CliResult};

/// The controller a new scenario starts with.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Controller {
    /// No tilt control: the bar stays at neutral.
    Passive,
    /// The PI loop designed for the drive (pi-drive).
    Pi,
    /// The LQG servo (paper-lqg).
    Lqg,
    /// The MPC with a Kalman filter (paper-mpc).
    Mpc,
}

impl Controller {
    /// The scenario's `controller.mode`.
    fn mode(self) -> controller_proc::Mode {
        match self {
            Controller::Passive => controller_proc::Mode::Passive,
            Controller::Pi => controller_proc::Mode::Pi,
            Controller::Lqg => controller_proc::Mode::Lqg,
            Controller::Mpc => controller_proc::Mode::Mpc,
        }
    }
}

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct NewArgs {
    /// The scenario's name (its default output directory is out/NAME).
    name: String,
    /// The controller to start from.
    #[arg(long, value_enum, default_value = "mpc")]
    controller: Controller,
    /// The file to write [default: NAME.toml]; an existing file is never overwritten.
    #[arg(long)]
    out: Option<PathBuf>,
}

const HEAD: &str = r#"# A tiltsim scenario. Every key is optional: what is left out takes the paper's value
# (docs/scenarios.md, docs/model.md). `tiltsim run` writes the resolved scenario, every
# default filled in, to out/<name>/scenario.toml; `tiltsim validate FILE` checks a file;
# `tiltsim run FILE --set KEY=VALUE` changes one value for one run.
name = "{name}"
description = "{description}"

[run]
dt_s = 0.001                  # base tick (s): the plant and the actuator exchange every tick
# duration_s = 16.8           # default: the track's length at its speed
seed = 1                      # sensor noise, track irregularity, link effects
master = "gauss-seidel"       # or "jacobi": every participant from the previous tick's outputs
transport = "ipc"             # "in-process": the same participants in one process
execution = "lock-step"       # "free": every process on its own clock (docs/free-running.md)

[track]                       # the paper's curve (section 2.3)
speed_kmh = 162.0
radius_m = 1000.0
cant_deg = 6.0
straight_before_m = 135.0
transition_m = 108.0
curve_m = 270.0
straight_after_m = 135.0

[track.irregularity]
model = "knots"               # the paper's random cant; "spectrum": ERRI B176 (needs level)
amplitude_deg = 0.0           # 0.6 is the paper's stochastic case (Figs 19-20)

[sensor]
theta_v_noise_std_rad = 0.001 # roll sensor noise (1 mrad)
noise_hold_s = 0.1            # each noise sample held 0.1 s, as in the paper

[actuator]
model = "bldc"                # switched BLDC drive; "bldc-averaged"; "ideal" (the bar follows)
"#;

const PASSIVE: &str = r#"
[controller]
mode = "passive"              # or "pi", "lqg", "mpc"
"#;

const PI: &str = r#"command_shaping = "hold"      # a new set-point applies at once

[controller]
mode = "pi"                   # or "passive", "lqg", "mpc"
rho = 0.30                    # share of the curve's lateral acceleration the tilt removes
period_s = 0.001
u_max_deg = 3.5               # bar angle limit

[controller.pi]               # designed for 60° phase margin on the drive (pi-drive)
kp = 0.5708
ki = 2.2831
"#;

const LQG: &str = r#"command_shaping = "hold"

[controller]
mode = "lqg"                  # or "passive", "pi", "mpc"
rho = 0.30
period_s = 0.001

[controller.lqg]              # eq 24
q_diag = [0.1, 1000.0, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 1000.0]
r_w = 1.0

[controller.kalman]
w_n = [2.1e-7, 2.23e-3, 5.4e-4, 0.0, 0.0, 0.0]
v_n = 0.10
"#;

const MPC: &str = r#"command_shaping = "ramp"      # each 50 ms set-point reached linearly (the MPC predicts it)

[controller]
mode = "mpc"                  # or "passive", "pi", "lqg"
rho = 0.30
period_s = 0.05
u_max_deg = 3.5

[controller.mpc]              # section 3.3
horizon_p = 5
horizon_m = 2
output_weight = 3.60
rate_weight = 0.028
du_max_deg = 0.5              # hard limit on each move
theta_v_max_deg = 6.0         # soft limit on the body roll

[controller.kalman]
w_n = [2.1e-7, 2.23e-3, 5.4e-4, 0.0, 0.0, 0.0]
v_n = 0.10
"#;

const TAIL: &str = r#"
[vehicle]
bump_stop_m = 0.06            # secondary lateral free play; past it the bump stop pushes back
                              # (k_bump, k3_bump) and the run is flagged

# Link effects between the processes (docs/scenarios.md, "Links"), for example a delayed command:
# [links.actuator_command]
# delay_ticks = 20

# Process faults (docs/scenarios.md, "Faults"), for example a stalled controller:
# [[faults.schedule]]
# participant = "controller"
# action = "stall"
# at_s = 5.0
# stall_s = 0.2
"#;

/// The template for `name` with `controller`.
pub fn template(name: &str, controller: Controller) -> String {
    let (body, description) = match controller {
        Controller::Passive => (PASSIVE, "Passive vehicle on the paper's curve"),
        Controller::Pi => (PI, "PI tilt control on the paper's curve"),
        Controller::Lqg => (LQG, "LQG servo tilt control on the paper's curve"),
        Controller::Mpc => (MPC, "MPC with Kalman filter on the paper's curve"),
    };
    let head = HEAD
        .replace("{name}", name)
        .replace("{description}", description);
    // The passive vehicle has no drive to command: its bar is the ideal one.
    let head = if controller == Controller::Passive {
        head.replace(
            "model = \"bldc\"                # switched BLDC drive; \"bldc-averaged\"; \"ideal\" (the bar follows)",
            "model = \"ideal\"               # no drive: the bar stays at neutral",
        )
    } else {
        head
    };
    format!("{head}{body}{TAIL}")
}

/// Runs the command.
pub fn exec(a: NewArgs) -> CliResult {
    let path = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{}.toml", a.name)));
    let text = template(&a.name, a.controller);
    // The name must be one a scenario may have; checked as the file will be read.
    tiltsim_scenario::scenario::Scenario::parse(&text, &path)
        .map_err(|e| CliError::Invalid(format!("command line: NAME: {e}")))?;
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&path)
        .map_err(|e| {
            CliError::Invalid(format!(
                "{}: {e} (an existing file is never overwritten)",
                path.display()
            ))
        })?;
    std::io::Write::write_all(&mut f, text.as_bytes())
        .map_err(|e| CliError::Failed(format!("{}: {e}", path.display())))?;
    println!(
        "wrote {} ({}); run it with `tiltsim run {}`",
        path.display(),
        a.controller.mode().label(),
        path.display()
    );
    Ok(())
}
