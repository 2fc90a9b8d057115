//! Co-simulation masters tiltsim did not write, running tiltsim's FMUs, against tiltsim's own
//! Jacobi master.
//!
//! * libcosim (the Open Simulation Platform's master, through libcosimpy) loads the SSP system
//!   `tiltsim export-ssp` writes, as it is: three FMI 2.0 FMUs stepped every 1 ms. Every output
//!   of every FMU after every step equals the row of `tiltsim run --master jacobi` bit for bit,
//!   for the LQG and the MPC scenario (the MPC controller computing every 50th step and holding
//!   its outputs between).
//! * FMPy's container FMU does the same with the three FMI 3.0 FMUs.
//! * libcosim with the controller stepped every 50 ms (its own period) equals tiltsim's Jacobi
//!   run with `[links.actuator_command] delay_ticks = 49`: how a decimated participant's
//!   outputs reach the others in an FMI master (docs/architecture.md, "Coupling").
//!
//! The masters come from PyPI in `target/fmi-venv` (scripts/fmi-requirements.txt); one that
//! cannot be imported fails these tests, naming it.

use std::path::{Path, PathBuf};

use tiltsim_suite::{csv_table, fmi_tool, root, run, scenario, temp_dir, Series, Tiltsim};

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Simulated seconds of every comparison: the curve's entry transition starts at 3 s (135 m
/// at 162 km/h), so 4 s has the controllers commanding and the MPC's constraints in play.
const SECONDS: u64 = 4;

/// An FMU output (`ROLE.VARIABLE`) and the `timeseries.csv` column that records it.
const COLUMNS: [(&str, &str); 30] = [
    ("plant.t", "time"),
    ("plant.s", "s"),
    ("plant.curvature", "curvature"),
    ("plant.cant", "cant"),
    ("plant.x[0]", "y_v"),
    ("plant.x[1]", "theta_v"),
    ("plant.x[2]", "y_b"),
    ("plant.x[3]", "theta_b"),
    ("plant.x[4]", "dy_v"),
    ("plant.x[5]", "dtheta_v"),
    ("plant.x[6]", "dy_b"),
    ("plant.x[7]", "dtheta_b"),
    ("plant.x[8]", "theta_r"),
    ("plant.psi", "psi"),
    ("plant.lat_acc", "lat_acc"),
    ("plant.theta_v_meas", "theta_v_meas"),
    ("actuator.delta_a", "delta_a"),
    ("actuator.delta_a_ref", "delta_a_ref"),
    ("actuator.motor_torque", "motor_torque"),
    ("actuator.motor_speed", "motor_speed"),
    ("actuator.motor_current", "motor_current"),
    ("actuator.dc_power", "dc_power"),
    ("actuator.phase_current_peak", "phase_current_peak"),
    ("actuator.v_dc", "v_dc"),
    ("actuator.chopper_power", "chopper_power"),
    ("actuator.limits", "actuator_limits"),
    ("controller.delta_a_cmd", "delta_a_cmd"),
    ("controller.theta_ref", "theta_ref"),
    ("controller.theta_v_hat", "theta_v_hat"),
    ("controller.solver_status", "solver_status"),
];

/// `tiltsim run SCENARIO --master jacobi` for [`SECONDS`], in-process; its time series.
fn jacobi(sc: &Path, out: &Path) -> Series {
    Tiltsim::run(sc)
        .out(out)
        .master("jacobi")
        .transport_in_process()
        .duration(SECONDS)
        .quiet()
        .success();
    Series::read(&out.join("timeseries.csv"))
}

/// Runs a helper of tests/outside/libcosim/ with the check environment's Python; `master` names the outside
/// master in the failure (a master that cannot be imported fails the test).
fn helper(master: &str, script: &str, args: &[&str]) -> serde_json::Value {
    let path = root().join("tests/outside/libcosim").join(script);
    let mut a = vec![s(&path)];
    a.extend_from_slice(args);
    let (code, out, err) = fmi_tool("python", &a);
    assert_eq!(
        code, 0,
        "{master} ({script}) failed; it comes from scripts/fmi-requirements.txt:\n{err}"
    );
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{master}: {e}: {out}"))
}

/// The rows a helper wrote: `step` then `ROLE.VARIABLE` columns.
fn read_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut t = csv_table(&text);
    let header = t.remove(0);
    (header, t)
}

/// Every compared output of the outside master's rows against the run's rows, bit for bit:
/// the master's row `k` (after its `k`-th step) is the run's row `k` (after tick `k − 1`).
/// Returns the number of values compared.
fn same_bits(what: &str, rows: &Path, series: &Series) -> usize {
    same_bits_seen_late(what, rows, series, "", 0)
}

/// [`same_bits`] where the outputs of the FMUs whose column starts with `late` are seen `lag`
/// rows later by the outside master: its row `k` of them is the run's row `k − lag` (row 0,
/// the outputs at t₀, before that).
fn same_bits_seen_late(what: &str, rows: &Path, series: &Series, late: &str, lag: usize) -> usize {
    let (header, body) = read_rows(rows);
    let steps = (SECONDS * 1000) as usize;
    assert_eq!(body.len(), steps, "{what}: steps taken");
    assert_eq!(series.rows.len(), steps + 1, "{what}: tiltsim's rows");
    let mut compared = 0;
    for (fmu, col) in COLUMNS {
        let i = header
            .iter()
            .position(|h| h == fmu)
            .unwrap_or_else(|| panic!("{what}: no column {fmu} in {header:?}"));
        let ours = series.col(col);
        let lag = if !late.is_empty() && fmu.starts_with(late) {
            lag
        } else {
            0
        };
        for (k, row) in body.iter().enumerate() {
            assert_eq!(row[0], (k + 1).to_string(), "{what}: step of row {k}");
            let theirs: f64 = row[i]
                .parse()
                .unwrap_or_else(|e| panic!("{what}: {fmu} `{}`: {e}", row[i]));
            let r = (k + 1).saturating_sub(lag);
            assert_eq!(
                theirs.to_bits(),
                ours[r].to_bits(),
                "{what}: {fmu} after step {}: {theirs} there, {} in tiltsim's row {r} ({col})",
                k + 1,
                ours[r]
            );
            compared += 1;
        }
    }
    compared
}

/// `tiltsim export-ssp SCENARIO --out DIR`.
fn export_ssp(sc: &Path, dir: &Path) -> PathBuf {
    let (code, out, err) = run(&["export-ssp", s(sc), "--out", s(dir)]);
    assert_eq!(code, 0, "export-ssp {}: {err}", sc.display());
    assert!(out.contains("SystemStructure.ssd"), "{out}");
    dir.join("SystemStructure.ssd")
}

/// The controller's command changes, and (for a 50-tick controller) only after a step that
/// starts on a multiple of 50 ticks: the comparison is not of a silent controller.
fn the_controller_acts(what: &str, series: &Series, period: usize) {
    let cmd = series.col("delta_a_cmd");
    let moves: Vec<usize> = (1..cmd.len()).filter(|&k| cmd[k] != cmd[k - 1]).collect();
    assert!(
        moves.len() > 10,
        "{what}: the command moved {} times",
        moves.len()
    );
    // Row k holds the outputs after tick k − 1: a controller computing on tick 50j changes
    // row 50j + 1.
    assert!(
        moves.iter().all(|k| (k - 1) % period == 0),
        "{what}: the command moved off the controller's ticks: {:?}",
        &moves[..moves.len().min(10)]
    );
}

#[test]
fn libcosim_runs_the_exported_ssp_systems_as_tiltsims_jacobi_master_bit_for_bit() {
    let dir = temp_dir("fmi-libcosim");
    for (file, period) in [("paper-lqg.toml", 1), ("paper-mpc.toml", 50)] {
        let sc = scenario(file);
        let ssp = dir.join(file.trim_end_matches(".toml"));
        let ssd = export_ssp(&sc, &ssp);
        let rows = ssp.join("libcosim.csv");
        let steps = (SECONDS * 1000).to_string();
        let r = helper("libcosim", "libcosim_run.py", &[s(&ssd), &steps, s(&rows)]);
        assert_eq!(
            r["components"],
            serde_json::json!(["actuator", "controller", "plant"]),
            "{file}"
        );
        let series = jacobi(&sc, &ssp.join("jacobi"));
        the_controller_acts(file, &series, period);
        let n = same_bits(&format!("libcosim, {file}"), &rows, &series);
        assert_eq!(n, COLUMNS.len() * SECONDS as usize * 1000);
    }
}

#[test]
fn fmpy_s_container_runs_the_fmi_3_fmus_as_tiltsims_jacobi_master_bit_for_bit() {
    let dir = temp_dir("fmi-container");
    for file in ["paper-lqg.toml", "paper-mpc.toml"] {
        let sc = scenario(file);
        let work = dir.join(file.trim_end_matches(".toml"));
        let mut fmus = Vec::new();
        for role in ["plant", "actuator", "controller"] {
            let fmu = work.join(format!("{role}.fmu"));
            let (code, _, err) = run(&["export-fmu", role, s(&sc), "--out", s(&fmu)]);
            assert_eq!(code, 0, "export-fmu {role}: {err}");
            fmus.push(format!("{role}={}", s(&fmu)));
        }
        let rows = work.join("container.csv");
        let steps = (SECONDS * 1000).to_string();
        let mut args = vec![s(&work), "0.001", &steps, s(&rows)];
        args.extend(fmus.iter().map(String::as_str));
        let r = helper("FMPy's container FMU", "fmpy_container.py", &args);
        assert_eq!(r["steps"], SECONDS * 1000, "{file}");
        let series = jacobi(&sc, &work.join("jacobi"));
        let n = same_bits(&format!("FMPy container, {file}"), &rows, &series);
        assert_eq!(n, COLUMNS.len() * SECONDS as usize * 1000);
    }
}

#[test]
fn export_ssp_refuses_what_an_ssp_system_cannot_carry_naming_the_field() {
    let dir = temp_dir("fmi-ssp-refused");
    let text = std::fs::read_to_string(scenario("paper-mpc.toml")).expect("scenario");
    for (extra, says) in [
        (
            "\n[links.actuator_command]\ndelay_ticks = 49\n",
            "links.actuator_command.delay_ticks = 49",
        ),
        (
            "\n[links.measurement]\nnoise_std = 0.001\n",
            "links.measurement.noise_std",
        ),
    ] {
        let sc = dir.join("refused.toml");
        // `export-ssp` reads a scenario file and takes no `--set`.
        std::fs::write(&sc, format!("{text}{extra}")).expect("write");
        let out = dir.join("out");
        let (code, _, err) = run(&["export-ssp", s(&sc), "--out", s(&out)]);
        assert_eq!(code, 2, "{err}");
        assert!(err.contains(says) && err.contains("refused.toml"), "{err}");
        assert!(err.contains("link effects"), "{err}");
        assert!(!out.join("SystemStructure.ssd").exists());
    }
}

#[test]
fn libcosim_with_the_controller_at_its_own_period_is_tiltsim_with_the_command_49_ticks_late() {
    let dir = temp_dir("fmi-decimated");
    let base = scenario("paper-mpc.toml");
    let ssd = export_ssp(&base, &dir.join("ssp"));
    // The same system with the controller stepped every 50 ms (libcosim's decimation).
    let text = std::fs::read_to_string(&ssd).expect("ssd");
    let at = text
        .find("<ssd:Component name=\"controller\"")
        .expect("the controller's component");
    let hint = "<osp:StepSizeHint value=\"1e-3\"/>";
    let h = at + text[at..].find(hint).expect("the controller's step");
    let decimated = format!(
        "{}<osp:StepSizeHint value=\"5e-2\"/>{}",
        &text[..h],
        &text[h + hint.len()..]
    );
    let ssd50 = ssd.with_file_name("SystemStructure-controller-50ms.ssd");
    std::fs::write(&ssd50, decimated).expect("write");
    let rows = dir.join("libcosim-50ms.csv");
    let steps = (SECONDS * 1000).to_string();
    helper(
        "libcosim",
        "libcosim_run.py",
        &[s(&ssd50), &steps, s(&rows)],
    );
    // tiltsim's Jacobi run with the command 49 ticks late on its link.
    let text = std::fs::read_to_string(&base).expect("scenario");
    let delayed = dir.join("paper-mpc-delayed.toml");
    std::fs::write(
        &delayed,
        format!("{text}\n[links.actuator_command]\ndelay_ticks = 49\n"),
    )
    .expect("write");
    let series = jacobi(&delayed, &dir.join("jacobi-delayed"));
    // libcosim's observer, too, sees a decimated FMU's outputs at the end of its step: the
    // controller's columns 49 rows after tiltsim's. The plant's and the actuator's are equal
    // row for row: the command reached the actuator 49 ticks late in both.
    let n = same_bits_seen_late(
        "libcosim, controller at 50 ms",
        &rows,
        &series,
        "controller.",
        49,
    );
    assert_eq!(n, COLUMNS.len() * SECONDS as usize * 1000);
    // And the delay matters: without it the actuator's rows differ from libcosim's.
    let undelayed = jacobi(&base, &dir.join("jacobi"));
    let (header, body) = read_rows(&rows);
    let i = header
        .iter()
        .position(|h| h == "actuator.delta_a")
        .expect("column");
    let ours = undelayed.col("delta_a");
    let differ = body
        .iter()
        .enumerate()
        .filter(|(k, r)| r[i].parse::<f64>().expect("number").to_bits() != ours[k + 1].to_bits())
        .count();
    assert!(
        differ > 1000,
        "the 50 ms controller left the bar angle as tiltsim's undelayed run ({differ} rows differ)"
    );
}
