//! The tilt controllers in closed loop: tracking on the steady curve, the MPC's
//! constraints at ρ = 0.50 against the LQG clamped and unclamped, solver reporting, the `linearize`
//! export, and byte-identical MPC runs over both transports.

use std::path::{Path, PathBuf};

use tiltsim_suite::{leftovers, prefix, run, scenario, summary, temp_dir, Series, Tiltsim};

/// Runs a scenario file with the values `set` (`--set KEY=VALUE`); returns its output
/// directory.
fn run_file(name: &str, file: &Path, transport: &str, set: &[(&str, &str)]) -> PathBuf {
    let dir = temp_dir(name);
    let pfx = prefix(name);
    set.iter()
        .fold(Tiltsim::run(file), |cmd, (k, v)| cmd.set(k, v))
        .out(&dir)
        .transport(transport)
        .ipc_prefix(&pfx)
        .quiet()
        .success();
    assert!(leftovers(&pfx).is_empty());
    dir
}

/// Mean, RMS and largest |θ_v − θ_v^d| (rad) from 3 s into the steady curve to its end
/// (t = 8.4 … 11.4 s on the paper's track at 162 km/h).
fn steady_tracking(dir: &Path) -> (f64, f64, f64) {
    let s = Series::read(&dir.join("timeseries.csv"));
    let (t, th, r) = (s.col("time"), s.col("theta_v"), s.col("theta_ref"));
    let e: Vec<f64> = (0..t.len())
        .filter(|&i| (8.4..=11.4).contains(&t[i]))
        .map(|i| th[i] - r[i])
        .collect();
    let n = e.len() as f64;
    let mean = e.iter().sum::<f64>() / n;
    let rms = (e.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    (mean, rms, e.iter().fold(0.0f64, |m, v| m.max(v.abs())))
}

#[test]
fn every_controller_tracks_the_tilt_command_on_the_steady_curve() {
    // Tolerances: 1 mrad of roll is 0.1 %g of lateral acceleration; the paper quotes a
    // tracking error of about 0.01 m/s² (1 mrad) for its MPC. The measurement noise (σ =
    // 1 mrad, each sample held 0.1 s) enters every loop: a controller that followed the
    // measurement exactly would show an RMS error of 1 mrad. We allow a mean within 1.5 mrad,
    // an RMS within 2.5 mrad (loop amplification of the held noise) and every sample within
    // 10 mrad (0.57°), on a reference of 18.5 mrad.
    // Controllers are judged here with the ideal actuator (the BLDC drive has its own tests);
    // the LQG and the MPC also with the BLDC drive their scenarios ship with. The paper's PI
    // gains drive the rate-limited BLDC actuator into a limit cycle (docs/model.md D24), so
    // the PI is checked with the ideal actuator only.
    let cases = [
        ("paper-pi.toml", true),
        ("paper-lqg.toml", true),
        ("paper-lqg.toml", false),
        ("paper-mpc.toml", true),
        ("paper-mpc.toml", false),
        ("paper-mpc-preview.toml", false),
    ];
    for (file, ideal) in cases {
        let kind = if ideal { "ideal" } else { "bldc" };
        let name = format!("{}-{kind}", file.trim_end_matches(".toml"));
        let set: &[_] = if ideal {
            &[("actuator.model", "ideal")]
        } else {
            &[]
        };
        let dir = run_file(&name, &scenario(file), "in-process", set);
        let (mean, rms, max) = steady_tracking(&dir);
        assert!(rms < 2.5e-3, "{name}: RMS tracking error {rms} rad");
        assert!(
            mean.abs() < 1.5e-3,
            "{name}: mean tracking error {mean} rad"
        );
        assert!(max < 10e-3, "{name}: largest tracking error {max} rad");
        let s = Series::read(&dir.join("timeseries.csv"));
        let r = s.col("theta_ref");
        let mid = r[r.len() / 2];
        assert!(
            (mid.to_degrees() - 1.06).abs() < 0.02,
            "θ_v^d mid-curve {mid}"
        );
    }
}

#[test]
fn at_rho_half_the_mpc_respects_its_limits_and_only_the_papers_unlimited_lqg_exceeds_them() {
    let mpc = run_file(
        "mpc-rho50",
        &scenario("paper-mpc-rho50.toml"),
        "in-process",
        &[],
    );
    let s = Series::read(&mpc.join("timeseries.csv"));
    let u = s.col("delta_a_cmd");
    let lim = 3.5f64.to_radians();
    let rate = 0.5f64.to_radians();
    // Within the QP's feasibility tolerance (1e-8 rad), plus the final clamp.
    assert!(u.iter().all(|v| v.abs() <= lim + 1e-9), "MPC left ±3.5°");
    // The command changes only every 50 ms (50 rows); every change at most 0.5°.
    let largest_move = u
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    assert!(
        largest_move <= rate + 1e-9,
        "MPC moved {largest_move} rad in one step"
    );
    // The limit is actually active: the command sits on 3.5° on the steady curve.
    let at_limit = u.iter().filter(|v| (v.abs() - lim).abs() < 1e-6).count();
    assert!(at_limit > 2000, "only {at_limit} samples at the limit");
    let sum = summary(&mpc);
    assert_eq!(sum["controller_solver"]["failures"], 0);
    assert_eq!(sum["controller_solver"]["solves"], 336);
    let ctrl = &sum["participants"][2];
    assert_eq!(ctrl["compute_us"]["n"], 336);

    // The paper's LQI has no saturation and asks for more than the actuator's range (Fig. 17);
    // by default ours is clamped there with its integrator held (docs/model.md D14).
    let lqg_file = scenario("paper-lqg.toml");
    let rho50 = ("controller.rho", "0.50");
    let lqg = run_file("lqg-rho50", &lqg_file, "in-process", &[rho50]);
    let u = Series::read(&lqg.join("timeseries.csv")).col("delta_a_cmd");
    let peak = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        peak <= lim,
        "limited LQG peak command {} deg",
        peak.to_degrees()
    );
    assert!(
        summary(&lqg)["results"]["command_at_limit_s"]
            .as_f64()
            .unwrap()
            > 0.1
    );
    let paper = run_file(
        "lqg-rho50-paper",
        &lqg_file,
        "in-process",
        &[rho50, ("controller.lqg.limit_command", "false")],
    );
    let u = Series::read(&paper.join("timeseries.csv")).col("delta_a_cmd");
    let peak = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        peak > lim,
        "the paper's LQG peak command {} deg",
        peak.to_degrees()
    );
}

#[test]
fn mpc_runs_are_byte_identical_over_both_transports() {
    let a = run_file("mpc-ipc", &scenario("paper-mpc.toml"), "ipc", &[]);
    let b = run_file("mpc-inproc", &scenario("paper-mpc.toml"), "in-process", &[]);
    let read = |d: &Path| std::fs::read(d.join("timeseries.csv")).unwrap();
    assert!(read(&a) == read(&b), "MPC: ipc and in-process differ");
    // The estimate is the Kalman filter's, not the measurement.
    let s = Series::read(&a.join("timeseries.csv"));
    let (m, h) = (s.col("theta_v_meas"), s.col("theta_v_hat"));
    assert!(m.iter().zip(&h).filter(|(a, b)| a != b).count() > m.len() / 2);
}

#[test]
fn linearize_exports_the_design_model_and_gains() {
    let (code, out, err) = run(&[
        "linearize",
        scenario("paper-lqg.toml").to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(j["continuous"]["A"].as_array().unwrap().len(), 9);
    let modes = j["continuous"]["modes"].as_array().unwrap();
    assert_eq!(modes.len(), 9);
    // The passive vehicle is stable and every mode has positive damping.
    assert!(modes.iter().all(|m| m["zeta"].as_f64().unwrap() > 0.0));
    // Discrete eigenvalues are e^{λT} of the continuous ones: compare the moduli.
    let t = j["discrete"]["period_s"].as_f64().unwrap();
    let mut zc: Vec<f64> = modes
        .iter()
        .map(|m| (m["re"].as_f64().unwrap() * t).exp())
        .collect();
    let mut zd: Vec<f64> = j["discrete"]["eigenvalues"]
        .as_array()
        .unwrap()
        .iter()
        .map(|z| z["modulus"].as_f64().unwrap())
        .collect();
    zc.sort_by(f64::total_cmp);
    zd.sort_by(f64::total_cmp);
    for (a, b) in zc.iter().zip(&zd) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }
    assert_eq!(j["lqg"]["K_op"][0].as_array().unwrap().len(), 10);
    assert!(j["lqg"]["care_residual_control"].as_f64().unwrap() < 1e-9);
    assert!(j["lqg"]["discrete_loop_spectral_radius"].as_f64().unwrap() < 1.0);
    // A scenario error gives exit 2 and names the field.
    let bad = temp_dir("linearize-bad").join("bad.toml");
    std::fs::write(
        &bad,
        "name = \"x\"\n[controller]\nmode = \"lqg\"\n[controller.lqg]\nq_diag = [1.0]\n",
    )
    .unwrap();
    let (code, _, err) = run(&["linearize", bad.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(err.contains("controller.lqg.q_diag"), "{err}");
}
