//! The run's time series, one typed [`Row`] per plant step, defined once: the recorder streams
//! it to `timeseries.csv` with the `csv` crate as the run goes (flushed every 1000 rows, so a
//! run that fails keeps what it recorded and memory does not grow with run length), and
//! [`read_rows`] reads the file back into the same type for plots, comfort, flags, `compare`
//! and sweeps.
//!
//! Floats are written in Rust's shortest round-trip form (`Display`), so identical values give
//! identical bytes and every value reads back exactly.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use serde::{Deserialize, Serialize};

use cosim::msg::{FromActuator, FromController, FromPlant};

/// A value of a row as it is written.
trait Cell {
    fn put(&self, out: &mut String);
}
impl Cell for f64 {
    fn put(&self, out: &mut String) {
        use std::fmt::Write as _;
        let _ = write!(out, "{self}");
    }
}
impl Cell for u64 {
    fn put(&self, out: &mut String) {
        use std::fmt::Write as _;
        let _ = write!(out, "{self}");
    }
}
impl Cell for u32 {
    fn put(&self, out: &mut String) {
        use std::fmt::Write as _;
        let _ = write!(out, "{self}");
    }
}

macro_rules! row {
    ($(#[$m:meta])* pub struct $name:ident { $($(#[$fm:meta])* $f:ident : $t:ty),* $(,)? }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
        pub struct $name {
            $($(#[$fm])* pub $f: $t,)*
        }
        /// Column names of `timeseries.csv`, in order: the fields of [`Row`].
        pub const COLUMNS: &[&str] = &[$(stringify!($f)),*];
        impl $name {
            /// Appends every field, formatted, to `record` (using `buf` as scratch).
            fn write_into(&self, record: &mut csv::ByteRecord, buf: &mut String) {
                record.clear();
                $(
                    buf.clear();
                    Cell::put(&self.$f, buf);
                    record.push_field(buf.as_bytes());
                )*
            }
        }
    };
}

row!(
    /// One row of `timeseries.csv`: every participant's latest output after tick `step`, at
    /// `t = (step + 1)·dt`. SI units and radians (README, "Output").
    pub struct Row {
        /// Tick.
        step: u64,
        /// Simulated time (s).
        t: f64,
        /// Position along the track (m).
        s: f64,
        /// Curvature 1/R (1/m).
        curvature: f64,
        /// Cant θ_o with irregularity (rad).
        cant: f64,
        /// Body lateral displacement (m).
        y_v: f64,
        /// Body roll relative to the track (rad).
        theta_v: f64,
        /// Bogie lateral displacement (m).
        y_b: f64,
        /// Bogie roll (rad).
        theta_b: f64,
        /// ẏ_v (m/s).
        dy_v: f64,
        /// θ̇_v (rad/s).
        dtheta_v: f64,
        /// ẏ_b (m/s).
        dy_b: f64,
        /// θ̇_b (rad/s).
        dtheta_b: f64,
        /// Airspring reservoir roll θ_r (rad).
        theta_r: f64,
        /// ψ = θ_v − θ_b (rad).
        psi: f64,
        /// Passenger lateral acceleration, eq 13 (m/s²).
        lat_acc: f64,
        /// Measured roll (rad).
        theta_v_meas: f64,
        /// Estimated roll (rad).
        theta_v_hat: f64,
        /// Reference of eq 18 as the controller computed it (rad).
        theta_ref: f64,
        /// Commanded bar angle (rad).
        delta_a_cmd: f64,
        /// Achieved bar angle (rad).
        delta_a: f64,
        /// Set-point after command shaping (rad).
        delta_a_ref: f64,
        /// Mean electromagnetic torque (N·m).
        motor_torque: f64,
        /// Rotor speed (rad/s).
        motor_speed: f64,
        /// T_e/k_t (A).
        motor_current: f64,
        /// Power drawn from the DC link (W).
        dc_power: f64,
        /// Largest phase current of the millisecond (A).
        phase_current_peak: f64,
        /// DC-link voltage (V).
        v_dc: f64,
        /// Chopper power (W).
        chopper_power: f64,
        /// `actuator_proc::bldc::limit` bits.
        actuator_limits: u32,
        /// 0 no QP, 1 solved, 2 failed (previous command held).
        solver_status: u32,
        /// What the actuator received as its command (rad).
        rx_actuator_command: f64,
        /// What the plant received as the bar angle (rad).
        rx_bar_angle: f64,
        /// What the controller received as the measurement (rad).
        rx_measurement: f64,
        /// What the actuator received as the bar twist (rad).
        rx_bar_twist: f64,
    }
);

impl Row {
    /// The row of tick `k` from the held outputs and what each link delivered
    /// (`rx` = actuator command, bar angle, measurement, bar twist).
    pub fn new(k: u64, p: &FromPlant, a: &FromActuator, c: &FromController, rx: &[f64; 4]) -> Self {
        let x = &p.x;
        Row {
            step: k,
            t: p.t,
            s: p.s,
            curvature: p.curvature,
            cant: p.cant,
            y_v: x[0],
            theta_v: x[1],
            y_b: x[2],
            theta_b: x[3],
            dy_v: x[4],
            dtheta_v: x[5],
            dy_b: x[6],
            dtheta_b: x[7],
            theta_r: x[8],
            psi: p.psi,
            lat_acc: p.lat_acc,
            theta_v_meas: p.theta_v_meas,
            theta_v_hat: c.theta_v_hat,
            theta_ref: c.theta_ref,
            delta_a_cmd: c.delta_a_cmd,
            delta_a: a.delta_a,
            delta_a_ref: a.delta_a_ref,
            motor_torque: a.motor_torque,
            motor_speed: a.motor_speed,
            motor_current: a.motor_current,
            dc_power: a.dc_power,
            phase_current_peak: a.phase_current_peak,
            v_dc: a.v_dc,
            chopper_power: a.chopper_power,
            actuator_limits: a.limits,
            solver_status: c.solver_status,
            rx_actuator_command: rx[0],
            rx_bar_angle: rx[1],
            rx_measurement: rx[2],
            rx_bar_twist: rx[3],
        }
    }
}

/// Streams rows to `timeseries.csv`.
pub struct Recorder {
    out: csv::Writer<BufWriter<File>>,
    rows: u64,
    record: csv::ByteRecord,
    buf: String,
}

impl Recorder {
    /// Creates `path` and writes the header.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let file = BufWriter::with_capacity(1 << 16, File::create(path)?);
        let mut out = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(file);
        out.write_record(COLUMNS).map_err(std::io::Error::other)?;
        Ok(Recorder {
            out,
            rows: 0,
            record: csv::ByteRecord::new(),
            buf: String::with_capacity(32),
        })
    }

    /// Appends one row.
    pub fn write(&mut self, row: &Row) -> std::io::Result<()> {
        row.write_into(&mut self.record, &mut self.buf);
        self.out
            .write_byte_record(&self.record)
            .map_err(std::io::Error::other)?;
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

/// Reads `dir/timeseries.csv` back into rows. A run that was cut short may end in a partial
/// line: reading stops at the first row that is not complete.
pub fn read_rows(dir: &Path) -> std::io::Result<Vec<Row>> {
    let path = dir.join("timeseries.csv");
    let mut rd = csv::Reader::from_path(&path).map_err(std::io::Error::other)?;
    let header = rd.headers().map_err(std::io::Error::other)?.clone();
    if header.iter().ne(COLUMNS.iter().copied()) {
        return Err(std::io::Error::other(format!(
            "{}: the header is not that of this tiltsim version (columns {})",
            path.display(),
            COLUMNS.join(",")
        )));
    }
    Ok(rd.deserialize::<Row>().map_while(Result::ok).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_exactly_and_a_partial_last_line_is_dropped() {
        let dir = std::env::temp_dir().join(format!("tiltsim-record-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = FromPlant {
            t: 0.001,
            x: [
                1e-20,
                -0.1,
                2.5e-7,
                3.0,
                0.0,
                1.0 / 3.0,
                -0.0,
                7e300,
                f64::MIN_POSITIVE,
            ],
            ..Default::default()
        };
        let a = FromActuator {
            limits: 64 | 2,
            v_dc: 849.95,
            ..Default::default()
        };
        let c = FromController {
            solver_status: 1,
            theta_ref: 0.042,
            ..Default::default()
        };
        let rows: Vec<Row> = (0..3)
            .map(|k| Row::new(k, &p, &a, &c, &[0.1, 0.2, f64::NAN, 0.4]))
            .collect();
        let mut rec = Recorder::create(&dir.join("timeseries.csv")).unwrap();
        for r in &rows {
            rec.write(r).unwrap();
        }
        rec.flush().unwrap();
        drop(rec);
        let text = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
        assert_eq!(text.lines().next().unwrap(), COLUMNS.join(","));
        // Display form, as before the csv crate: no exponent, shortest round trip.
        assert!(text.contains(",0.00000000000000000001,"), "{text}");
        let back = read_rows(&dir).unwrap();
        assert_eq!(back.len(), 3);
        for (a, b) in back.iter().zip(&rows) {
            assert_eq!(a.x_bits(), b.x_bits());
        }
        // A killed run's last line stops half-way.
        let cut = &text[..text.len() - 20];
        std::fs::write(dir.join("timeseries.csv"), cut).unwrap();
        assert_eq!(read_rows(&dir).unwrap().len(), 2);
        let _ = std::fs::remove_dir_all(&dir);
    }

    impl Row {
        /// Every float's bits (NaN compares equal to itself).
        fn x_bits(&self) -> Vec<u64> {
            vec![
                self.t.to_bits(),
                self.y_v.to_bits(),
                self.dtheta_v.to_bits(),
                self.dy_b.to_bits(),
                self.dtheta_b.to_bits(),
                self.theta_r.to_bits(),
                self.v_dc.to_bits(),
                self.rx_measurement.to_bits(),
                self.actuator_limits as u64,
                self.solver_status as u64,
            ]
        }
    }
}
