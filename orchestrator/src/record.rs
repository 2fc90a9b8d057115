//! Recording: `timeseries.csv`, one row per plant step, flushed as it goes so that a run that
//! fails keeps what it recorded.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use cosim::msg::{FromActuator, FromController, FromPlant};

/// Column names, SI units and radians (units in README). The `rx_*` columns are the values
/// as the receiving participant got them over each link (after delay, drop, bias, ...).
pub const COLUMNS: &[&str] = &[
    "step",
    "t",
    "s",
    "curvature",
    "cant",
    "y_v",
    "theta_v",
    "y_b",
    "theta_b",
    "dy_v",
    "dtheta_v",
    "dy_b",
    "dtheta_b",
    "theta_r",
    "psi",
    "lat_acc",
    "theta_v_meas",
    "theta_v_hat",
    "theta_ref",
    "delta_a_cmd",
    "delta_a",
    "delta_a_ref",
    "motor_torque",
    "motor_speed",
    "motor_current",
    "dc_power",
    "phase_current_peak",
    "v_dc",
    "chopper_power",
    "actuator_limits",
    "solver_status",
    "rx_actuator_command",
    "rx_bar_angle",
    "rx_measurement",
    "rx_bar_twist",
];

/// Writes the time series.
pub struct Recorder {
    out: BufWriter<File>,
    rows: u64,
    line: String,
}

impl Recorder {
    /// Creates `path` and writes the header.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let mut out = BufWriter::with_capacity(1 << 16, File::create(path)?);
        writeln!(out, "{}", COLUMNS.join(","))?;
        Ok(Recorder {
            out,
            rows: 0,
            line: String::with_capacity(512),
        })
    }

    /// Appends the row of step `k`. Floats are written in Rust's shortest round-trip form, so
    /// identical values give identical bytes.
    pub fn row(
        &mut self,
        k: u64,
        p: &FromPlant,
        a: &FromActuator,
        c: &FromController,
        rx: &[f64; 4],
    ) -> std::io::Result<()> {
        use std::fmt::Write as _;
        self.line.clear();
        let _ = write!(self.line, "{k}");
        let mut put = |v: f64| {
            let _ = write!(self.line, ",{v}");
        };
        for v in [p.t, p.s, p.curvature, p.cant] {
            put(v);
        }
        for v in p.x {
            put(v);
        }
        for v in [
            p.psi,
            p.lat_acc,
            p.theta_v_meas,
            c.theta_v_hat,
            c.theta_ref,
            c.delta_a_cmd,
            a.delta_a,
            a.delta_a_ref,
        ] {
            put(v);
        }
        for v in [
            a.motor_torque,
            a.motor_speed,
            a.motor_current,
            a.dc_power,
            a.phase_current_peak,
            a.v_dc,
            a.chopper_power,
        ] {
            put(v);
        }
        let _ = write!(self.line, ",{},{}", a.limits, c.solver_status);
        for v in rx {
            let _ = write!(self.line, ",{v}");
        }
        self.line.push('\n');
        self.out.write_all(self.line.as_bytes())?;
        self.rows += 1;
        if self.rows.is_multiple_of(1000) {
            self.out.flush()?;
        }
        Ok(())
    }

    /// Rows written.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Flushes to disk.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}
