//! `tiltsim linearize SCENARIO`: the design model and the controller's gains. A summary for
//! a person (with `--design-pi` the designed gains first, as a scenario file writes them,
//! then the scenario's own loop and the model's modes); the whole report (matrices,
//! eigenvalues, modes, gains) as JSON with `--json` on standard output or `--out FILE`.

use std::path::PathBuf;

use serde_json::Value;

use super::bounds::{self, End};
use super::common::load;
use super::error::{CliError, CliResult};
use tiltsim_report::linearize::PiTargets;
use tiltsim_scenario::scenario::Scenario;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct LinearizeArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Print the whole report as JSON on standard output instead of the summary.
    #[arg(long, conflicts_with = "out")]
    json: bool,
    /// Write the whole report as JSON to this file (the summary is printed as well).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also design a PI for this scenario's vehicle and actuator: the largest K_p with
    /// integral time --ti whose margins reach --phase-margin and --gain-margin.
    #[arg(long)]
    design_pi: bool,
    /// Phase-margin target of --design-pi (deg).
    #[arg(long, default_value_t = 60.0,
          value_parser = bounds::real((0.0, End::Closed), (89.0, End::Closed), " deg"))]
    phase_margin: f64,
    /// Gain-margin target of --design-pi (dB).
    #[arg(long, default_value_t = 6.0,
          value_parser = bounds::real((0.0, End::Closed), (40.0, End::Closed), " dB"))]
    gain_margin: f64,
    /// Integral time K_p/K_i of --design-pi (s).
    #[arg(long, default_value_t = 0.25,
          value_parser = bounds::real((1e-3, End::Closed), (100.0, End::Closed), " s"))]
    ti: f64,
}

/// Runs the command.
pub fn exec(a: LinearizeArgs) -> CliResult {
    let design = a.design_pi.then_some(PiTargets {
        phase_margin_deg: a.phase_margin,
        gain_margin_db: a.gain_margin,
        ti_s: a.ti,
    });
    for (flag, v, lo, hi) in [
        ("--phase-margin", a.phase_margin, 0.0, 89.0),
        ("--gain-margin", a.gain_margin, 0.0, 40.0),
        ("--ti", a.ti, 1e-3, 100.0),
    ] {
        if design.is_some() && !(lo..=hi).contains(&v) {
            return Err(CliError::Invalid(format!(
                "{flag} = {v}: allowed {lo} to {hi}"
            )));
        }
    }
    let s = load(&a.scenario)?;
    let report = tiltsim_report::linearize::report(&s, design).map_err(|e| {
        CliError::Invalid(format!("{}: controller design: {e}", a.scenario.display()))
    })?;
    let text = serde_json::to_string_pretty(&report).unwrap_or_default() + "\n";
    if a.json {
        print!("{text}");
        return Ok(());
    }
    for line in summary(&s, &report) {
        println!("{line}");
    }
    match a.out {
        Some(p) => {
            tiltsim_rundir::files::write_atomic(&p, text)
                .map_err(|e| CliError::Failed(e.to_string()))?;
            println!(
                "wrote {} (matrices, eigenvalues, modes and gains as JSON)",
                p.display()
            );
        }
        None => {
            println!("the matrices, eigenvalues, modes and gains as JSON: --json, or --out FILE")
        }
    }
    Ok(())
}

/// A number of the report as written in a scenario file (`60`, `0.25`).
fn num(v: &Value) -> String {
    v.as_f64()
        .map_or_else(|| "?".to_string(), |x| format!("{x}"))
}

/// `x` with `n` significant digits, without an exponent.
fn sig(x: f64, n: i32) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let decimals = (n - 1 - x.abs().log10().floor() as i32).max(0) as usize;
    format!("{x:.decimals$}")
}

/// The margins of a PI loop (`controller_proc::pi_loop::Margins` as JSON) in words, and
/// whether a margin is negative (the loop unstable).
fn margins(m: &Value) -> (String, bool) {
    let pm = m["phase_margin_deg"].as_f64();
    let gm = m["gain_margin_db"].as_f64();
    let phase = match (m["crossover_hz"].as_f64(), pm) {
        (Some(f), Some(p)) => format!("crossover {} Hz, phase margin {p:.1}°", sig(f, 3)),
        _ => "no gain crossover between 0.01 and 100 Hz".to_string(),
    };
    let gain = match (gm, m["phase_crossover_hz"].as_f64()) {
        (Some(g), Some(f)) => format!("gain margin {g:.1} dB at {} Hz", sig(f, 3)),
        _ => "no phase crossover (no gain limit)".to_string(),
    };
    let unstable = pm.is_some_and(|p| p < 0.0) || gm.is_some_and(|g| g < 0.0);
    (format!("{phase}; {gain}"), unstable)
}

/// Modes (`controller_proc::design::Mode` as JSON) as "0.665 Hz ζ 0.165, 3.69 Hz real, ...":
/// each complex pair once.
fn modes(list: &Value) -> String {
    let Some(list) = list.as_array() else {
        return String::new();
    };
    list.iter()
        .filter(|m| m["im"].as_f64().unwrap_or(0.0) >= 0.0)
        .map(|m| {
            let f = sig(m["f_n_hz"].as_f64().unwrap_or(f64::NAN), 3);
            if m["im"].as_f64() == Some(0.0) {
                format!("{f} Hz real")
            } else {
                let zeta = m["zeta"].as_f64().unwrap_or(f64::NAN);
                format!("{f} Hz ζ {zeta:.3}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The summary's lines: the designed PI first, then what the scenario is, its controller's
/// loop and the design model.
fn summary(s: &Scenario, r: &Value) -> Vec<String> {
    let mut lines = Vec::new();
    let d = &r["pi_design"];
    if d.is_object() {
        let (m, _) = margins(&d["margins"]);
        lines.extend([
            format!(
                "PI designed for {} behind the {} at {} km/h: the largest K_p with integral time {} s \
                 that keeps a phase margin of {}° and a gain margin of {} dB",
                s.name,
                s.actuator.model.label(),
                s.track.speed_kmh,
                num(&d["ti_s"]),
                num(&d["phase_margin_target_deg"]),
                num(&d["gain_margin_target_db"])
            ),
            "  [controller.pi]".to_string(),
            format!("  kp = {}", sig(d["kp"].as_f64().unwrap_or(f64::NAN), 5)),
            format!("  ki = {}", sig(d["ki"].as_f64().unwrap_or(f64::NAN), 5)),
            format!("  {m}"),
        ]);
    }
    lines.push(format!(
        "{} ({}) at {} km/h, controller period {} ms",
        s.name,
        super::report::who(s),
        s.track.speed_kmh,
        s.controller.period_s * 1e3
    ));
    lines.extend(controller(r));
    let states = r["states"].as_array().map_or(0, Vec::len);
    lines.push(format!(
        "  design model: {states} states, input delta_a, output theta_v; open-loop modes {}",
        modes(&r["continuous"]["modes"])
    ));
    lines
}

/// The lines of the scenario's controller: the PI's loop margins, the LQG's gains and modes,
/// the MPC's estimator; none for the passive vehicle.
fn controller(r: &Value) -> Vec<String> {
    let row = |v: &Value| -> String {
        let cells: Vec<String> = v
            .as_array()
            .into_iter()
            .flatten()
            .flat_map(|r| r.as_array().cloned().unwrap_or_else(|| vec![r.clone()]))
            .map(|x| sig(x.as_f64().unwrap_or(f64::NAN), 4))
            .collect();
        format!("[{}]", cells.join(", "))
    };
    let mut lines = Vec::new();
    let pi = &r["pi_loop"];
    if pi.is_object() {
        let (m, unstable) = margins(&pi["margins"]);
        lines.push(format!(
            "  PI kp = {}, ki = {} with {} ms of sampling delay: {m}{}",
            num(&pi["kp"]),
            num(&pi["ki"]),
            sig(pi["delay_s"].as_f64().unwrap_or(f64::NAN) * 1e3, 3),
            if unstable {
                "; a negative margin: the loop is unstable"
            } else {
                ""
            }
        ));
        lines.push("  (a linear loop: the drive's rate limit is not in it)".to_string());
    }
    let lqg = &r["lqg"];
    if lqg.is_object() {
        lines.push(format!(
            "  LQG servo K_op = {} (the last is the integrator's); discrete loop spectral radius {}",
            row(&lqg["K_op"]),
            sig(
                lqg["discrete_loop_spectral_radius"]
                    .as_f64()
                    .unwrap_or(f64::NAN),
                5
            )
        ));
        lines.push(format!(
            "  closed-loop modes {}",
            modes(&lqg["closed_loop_modes"])
        ));
        lines.push(format!("  Kalman filter K_est = {}", row(&lqg["K_est"])));
    }
    let mpc = &r["mpc"];
    if mpc.is_object() {
        lines.push(format!(
            "  MPC predicting a {} input between updates; Kalman filter L_est = {}",
            mpc["prediction_input_shape"].as_str().unwrap_or("?"),
            row(&mpc["L_est"])
        ));
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_keep_their_significant_digits() {
        assert_eq!(sig(0.5707742361919452, 5), "0.57077");
        assert_eq!(sig(2.283096944767781, 5), "2.2831");
        assert_eq!(sig(38.24, 4), "38.24");
        assert_eq!(sig(-31.622776601683768, 4), "-31.62");
        assert_eq!(sig(1234.4, 3), "1234");
    }

    #[test]
    fn margins_say_when_the_loop_is_unstable() {
        let m = serde_json::json!({"crossover_hz": 5.6187, "phase_margin_deg": -18.76,
                                   "phase_crossover_hz": 2.3739, "gain_margin_db": -20.48});
        let (text, unstable) = margins(&m);
        assert_eq!(
            text,
            "crossover 5.62 Hz, phase margin -18.8°; gain margin -20.5 dB at 2.37 Hz"
        );
        assert!(unstable);
        let m = serde_json::json!({"crossover_hz": null, "phase_margin_deg": null,
                                   "phase_crossover_hz": null, "gain_margin_db": null});
        assert!(!margins(&m).1);
    }
}
