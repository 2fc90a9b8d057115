//! The run's time series, one typed [`Row`] per plant step, defined once: the recorder streams
//! it to `timeseries.csv` with the `csv` crate as the run goes (flushed every 1000 rows, so a
//! run that fails keeps what it recorded and memory does not grow with run length), and
//! [`read_rows`] reads the file back into the same type for plots, comfort, flags, `compare`
//! and sweeps.
//!
//! Floats are written in shortest round-trip form ([`put_f64`]), so identical values give
//! identical bytes and every value reads back exactly.

use std::fs::File;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use cosim::msg::{FromActuator, FromController, FromPlant};

/// A value of a row as it is written.
trait Cell: Copy {
    fn put(&self, out: &mut String);
    fn lo(self, other: Self) -> Self;
    fn hi(self, other: Self) -> Self;
}
impl Cell for f64 {
    fn put(&self, out: &mut String) {
        put_f64(*self, out);
    }
    fn lo(self, other: Self) -> Self {
        self.min(other)
    }
    fn hi(self, other: Self) -> Self {
        self.max(other)
    }
}

/// `x` as [`put_f64`] writes it.
pub fn fmt_f64(x: f64) -> String {
    let mut s = String::new();
    put_f64(x, &mut s);
    s
}

/// Writes `x` in shortest round-trip form: positional (`0.0123`) where that is as short as the
/// exponent form, and with an exponent (`1.5e-7`, `2e22`) below 1e-4 and from 1e16 in
/// magnitude, where the positional form would grow with the exponent (a decayed transient of
/// 1e-300 would take 300 characters). Every value is at most 24 characters, so a row's width
/// stays within a constant of its start over any run length.
pub fn put_f64(x: f64, out: &mut String) {
    use std::fmt::Write as _;
    let a = x.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e16).contains(&a) {
        let _ = write!(out, "{x:e}");
    } else {
        let _ = write!(out, "{x}");
    }
}
impl Cell for u64 {
    fn put(&self, out: &mut String) {
        use std::fmt::Write as _;
        let _ = write!(out, "{self}");
    }
    fn lo(self, other: Self) -> Self {
        self.min(other)
    }
    fn hi(self, other: Self) -> Self {
        self.max(other)
    }
}
impl Cell for u32 {
    fn put(&self, out: &mut String) {
        use std::fmt::Write as _;
        let _ = write!(out, "{self}");
    }
    fn lo(self, other: Self) -> Self {
        self.min(other)
    }
    fn hi(self, other: Self) -> Self {
        self.max(other)
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
            /// Widens the field-wise envelope `lo`..`hi` to take in this row.
            pub fn widen(&self, lo: &mut Self, hi: &mut Self) {
                $(
                    lo.$f = Cell::lo(lo.$f, self.$f);
                    hi.$f = Cell::hi(hi.$f, self.$f);
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

/// The file under the csv writer: counts the bytes the system accepted and, after its first
/// error, refuses every later write (so nothing lands after the recorder has cut the file
/// back to its last complete row, not even from the csv writer's flush on drop).
struct Sink {
    file: File,
    written: u64,
    broken: bool,
}

impl std::io::Write for Sink {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        if self.broken {
            return Err(std::io::Error::other("closed after an earlier error"));
        }
        match self.file.write(b) {
            Ok(n) => {
                self.written += n as u64;
                Ok(n)
            }
            Err(e) => {
                self.broken = true;
                Err(e)
            }
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Streams rows to `timeseries.csv`: the header at once, then rows in batches of 1000 (and at
/// [`Recorder::finish`]). The file only ever holds the header and complete rows, and
/// [`Recorder::rows_on_disk`] counts exactly those: a write that fails (a full disk, a file-size
/// limit) cuts the file back to the end of the last batch that was written whole, and every
/// error names the file and what the system said.
pub struct Recorder {
    out: csv::Writer<Sink>,
    path: PathBuf,
    rows: u64,
    on_disk_rows: u64,
    on_disk_bytes: u64,
    failed: Option<(std::io::ErrorKind, String)>,
    record: csv::ByteRecord,
    buf: String,
}

impl Recorder {
    /// Creates `path` and writes the header (flushed at once: a run killed at any point
    /// leaves a valid header).
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let named =
            |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
        let file = File::create(path).map_err(named)?;
        let out = csv::WriterBuilder::new()
            .has_headers(false)
            .buffer_capacity(1 << 16)
            .from_writer(Sink {
                file,
                written: 0,
                broken: false,
            });
        let mut r = Recorder {
            out,
            path: path.to_path_buf(),
            rows: 0,
            on_disk_rows: 0,
            on_disk_bytes: 0,
            failed: None,
            record: csv::ByteRecord::new(),
            buf: String::with_capacity(32),
        };
        let header = r.out.write_record(COLUMNS).map_err(std::io::Error::other);
        header.and_then(|_| r.commit()).map_err(|e| r.fail(e))?;
        Ok(r)
    }

    /// Appends one row.
    pub fn write(&mut self, row: &Row) -> std::io::Result<()> {
        if let Some((kind, msg)) = &self.failed {
            return Err(std::io::Error::new(*kind, msg.clone()));
        }
        row.write_into(&mut self.record, &mut self.buf);
        if let Err(e) = self.out.write_byte_record(&self.record) {
            return Err(self.fail(csv_io(e)));
        }
        self.rows += 1;
        if self.rows.is_multiple_of(1000) {
            self.commit().map_err(|e| self.fail(e))?;
        }
        Ok(())
    }

    /// Writes what is buffered; the file then ends with the last row.
    fn commit(&mut self) -> std::io::Result<()> {
        self.out.flush()?;
        self.on_disk_rows = self.rows;
        self.on_disk_bytes = self.out.get_ref().written;
        Ok(())
    }

    /// After a failed write: cuts the file back to its last complete row, refuses every later
    /// write and returns the error, naming the file.
    fn fail(&mut self, e: std::io::Error) -> std::io::Error {
        if self.failed.is_none() {
            // Swap in a writer whose sink refuses everything; the old writer's flush on drop
            // may still land, so the file is cut afterwards.
            if let Ok(file) = self.out.get_ref().file.try_clone() {
                self.out = csv::WriterBuilder::new()
                    .has_headers(false)
                    .from_writer(Sink {
                        file,
                        written: self.on_disk_bytes,
                        broken: true,
                    });
            }
            let _ = self.out.get_ref().file.set_len(self.on_disk_bytes);
            self.failed = Some((e.kind(), format!("{}: {e}", self.path.display())));
        }
        let (kind, msg) = self.failed.clone().unwrap_or((e.kind(), e.to_string()));
        std::io::Error::new(kind, msg)
    }

    /// Complete rows in the file (all of them after a successful [`Recorder::finish`]).
    pub fn rows_on_disk(&self) -> u64 {
        self.on_disk_rows
    }

    /// Writes the rows still buffered. On error the file keeps its header and every complete
    /// row of the batches written before, and the error names the file.
    pub fn finish(&mut self) -> std::io::Result<()> {
        if let Some((kind, msg)) = &self.failed {
            return Err(std::io::Error::new(*kind, msg.clone()));
        }
        self.commit().map_err(|e| self.fail(e))
    }
}

/// The I/O error inside a csv error (the csv writer's errors on writing are I/O errors).
fn csv_io(e: csv::Error) -> std::io::Error {
    match e.into_kind() {
        csv::ErrorKind::Io(e) => e,
        other => std::io::Error::other(format!("{other:?}")),
    }
}

/// Where a run's rows are: its directory's `timeseries.csv`, or kept in memory (a sweep's
/// samples, [`crate::engine::RunOptions::keep_rows`]).
#[derive(Debug, Clone, Copy)]
pub enum Rows<'a> {
    /// `timeseries.csv` of this directory.
    File(&'a Path),
    /// The rows themselves.
    Kept(&'a [Row]),
}

impl Rows<'_> {
    /// Hands each row to `visit` in order until it returns false; returns the rows visited
    /// ([`each_row`] for a file).
    pub fn each(&self, mut visit: impl FnMut(&Row) -> bool) -> std::io::Result<u64> {
        match self {
            Rows::File(dir) => each_row(dir, visit),
            Rows::Kept(rows) => {
                let mut n = 0;
                for r in rows.iter() {
                    n += 1;
                    if !visit(r) {
                        break;
                    }
                }
                Ok(n)
            }
        }
    }
}

/// Reads `dir/timeseries.csv` back, handing each row to `visit` in order, one row in memory
/// at a time, until `visit` returns false; returns the number of rows read. A run that was
/// cut short may end in a partial line: reading stops at the first row that is not complete.
pub fn each_row(dir: &Path, mut visit: impl FnMut(&Row) -> bool) -> std::io::Result<u64> {
    let path = dir.join("timeseries.csv");
    let named = |e: csv::Error| std::io::Error::other(format!("{}: {e}", path.display()));
    let mut rd = csv::Reader::from_path(&path).map_err(named)?;
    let header = rd.byte_headers().map_err(named)?;
    if header.iter().ne(COLUMNS.iter().map(|c| c.as_bytes())) {
        return Err(std::io::Error::other(format!(
            "{}: the header is not that of this tiltsim version (columns {})",
            path.display(),
            COLUMNS.join(",")
        )));
    }
    let mut record = csv::ByteRecord::new();
    let mut n = 0;
    while rd.read_byte_record(&mut record).unwrap_or(false) {
        let Ok(row) = record.deserialize::<Row>(None) else {
            break;
        };
        n += 1;
        if !visit(&row) {
            break;
        }
    }
    Ok(n)
}

/// The rows of `dir/timeseries.csv` to draw, at most about `points` of them: every row when
/// there are few enough, otherwise the field-wise minimum and maximum of each of `points / 2`
/// consecutive blocks (a min/max envelope, so a peak is never lost to the decimation). Memory
/// stays bounded for runs of any length.
pub fn rows_to_plot(dir: &Path, points: usize) -> std::io::Result<Vec<Row>> {
    let n = each_row(dir, |_| !crate::signals::received())? as usize;
    if n <= points {
        return read_rows(dir);
    }
    let block = n.div_ceil((points / 2).max(1));
    let mut out = Vec::with_capacity(2 * n.div_ceil(block));
    let mut k = 0usize;
    let (mut lo, mut hi) = (Row::default(), Row::default());
    each_row(dir, |r| {
        if k.is_multiple_of(block) {
            (lo, hi) = (*r, *r);
        }
        r.widen(&mut lo, &mut hi);
        k += 1;
        if k.is_multiple_of(block) || k == n {
            // Each pair keeps its block's time span in order.
            out.push(lo);
            out.push(hi);
        }
        !crate::signals::received()
    })?;
    Ok(out)
}

/// Reads `dir/timeseries.csv` back into rows (for short runs; [`each_row`] for any length).
pub fn read_rows(dir: &Path) -> std::io::Result<Vec<Row>> {
    let mut rows = Vec::new();
    each_row(dir, |r| {
        rows.push(*r);
        true
    })?;
    Ok(rows)
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
        rec.finish().unwrap();
        assert_eq!(rec.rows_on_disk(), 3);
        drop(rec);
        let text = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
        assert_eq!(text.lines().next().unwrap(), COLUMNS.join(","));
        // Shortest round trip, with an exponent where the positional form would be long.
        assert!(text.contains(",1e-20,"), "{text}");
        assert!(text.contains(",2.5e-7,"), "{text}");
        assert!(text.contains(",7e300,"), "{text}");
        assert!(text.contains(",849.95,"), "{text}");
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

    #[test]
    fn every_float_is_short_and_reads_back_exactly() {
        // Powers of ten and awkward mantissas over the whole exponent range, subnormals too.
        let mut x = f64::MIN_POSITIVE / 1e10;
        let mut longest = 0;
        while x < f64::MAX / 10.0 {
            for v in [x, -x, x * 1.2345678901234567, x * 9.999999999999998] {
                let mut s = String::new();
                put_f64(v, &mut s);
                assert_eq!(s.parse::<f64>().unwrap().to_bits(), v.to_bits(), "{s}");
                longest = longest.max(s.len());
            }
            x *= 10.0;
        }
        // Sign, 17 significant digits, point, `e-` and three exponent digits.
        assert!(longest <= 24, "longest {longest}");
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
