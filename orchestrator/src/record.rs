//! The run's time series, one typed [`Row`] per plant step, defined once: the recorder streams
//! it to `timeseries.csv` with the `csv` crate as the run goes (one write per 1000 rows, so a
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
    /// The value a field holds, if it holds one of this type.
    fn read(field: &[u8]) -> Option<Self>;
    fn lo(self, other: Self) -> Self;
    fn hi(self, other: Self) -> Self;
}
impl Cell for f64 {
    fn read(field: &[u8]) -> Option<Self> {
        std::str::from_utf8(field).ok()?.parse().ok()
    }
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
///
/// The bytes are those of `std`'s `{x}` and `{x:e}` (test
/// `every_float_is_written_as_std_writes_it`); the shortest digits come from `ryu`, which makes
/// writing a row 1.6-1.8 times faster (`cargo bench -p orchestrator --bench record`).
pub fn put_f64(x: f64, out: &mut String) {
    let a = x.abs();
    if a == 0.0 || !a.is_finite() {
        std_put_f64(x, out);
        return;
    }
    let mut buf = ryu::Buffer::new();
    let text = buf.format_finite(x);
    if halfway_places(x).is_some_and(|k| k == places(text)) {
        // Two shortest forms equally near: `ryu` takes the even last digit, `std` the larger
        // magnitude. Rare (only values with at most 25 binary places or a small odd part).
        std_put_f64(x, out);
        return;
    }
    // `ryu` writes 1e-5 ≤ |x| < 1e16 positionally (integers with `.0`) and the rest as
    // `d.ddde±x`, which is `std`'s `{:e}`; from 1e-5 to 1e-4 the exponent form is ours.
    if a >= 1e-4 {
        out.push_str(text.strip_suffix(".0").unwrap_or(text));
        return;
    }
    if a < 1e-5 {
        out.push_str(text);
        return;
    }
    // `0.0000ddd` → `d.dde-5`.
    let (sign, digits) = match text.strip_prefix('-') {
        Some(rest) => ("-", rest),
        None => ("", text),
    };
    let digits = digits
        .strip_prefix("0.0000")
        .expect("ryu writes 1e-5..1e-4 as 0.0000ddd");
    out.push_str(sign);
    out.push_str(&digits[..1]);
    if digits.len() > 1 {
        out.push('.');
        out.push_str(&digits[1..]);
    }
    out.push_str("e-5");
}

/// [`put_f64`] by `std`'s formatting: the reference its fast path matches byte for byte
/// (test `every_float_is_written_as_std_writes_it`), and its path for the rare values where
/// `ryu` rounds differently.
fn std_put_f64(x: f64, out: &mut String) {
    use std::fmt::Write as _;
    let a = x.abs();
    let _ = if a != 0.0 && a.is_finite() && !(1e-4..1e16).contains(&a) {
        write!(out, "{x:e}")
    } else {
        write!(out, "{x}")
    };
}

/// The one number of decimal places `k` at which `|x|` could lie exactly halfway between two
/// decimals of `k` places (`|x|·10^k = D + ½`), if there is one a shortest form could end at.
///
/// `2·|x|·10^k` must be an odd integer. With `|x| = m·2^e` and `m = m'·2^t` (`m'` odd) it is
/// `m'·5^k·2^(t+e+1+k)`: odd and whole exactly when `k = −1 − (t + e)` and, for `k < 0`,
/// `5^−k` divides `m'`. A shortest form has at most 17 significant digits, so the exact
/// expansion (`m'·5^(k+1)` digits, for `k ≥ 0`) may have at most 18: `k + 1 ≤ 25`.
fn halfway_places(x: f64) -> Option<i32> {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1 << 52) - 1);
    let (m, e) = if biased == 0 {
        (fraction, -1074)
    } else {
        (fraction | 1 << 52, biased - 1075)
    };
    if m == 0 {
        return None;
    }
    let t = m.trailing_zeros() as i32;
    let k = -1 - (t + e);
    // m' < 2^53 < 5^23.
    let whole = k >= 0 || (-k <= 22 && (m >> t).is_multiple_of(5u64.pow((-k) as u32)));
    (k < 25 && whole).then_some(k)
}

/// The decimal places of the last digit of `ryu`'s text (`-1.25` → 2, `1200.0` → −2,
/// `1.5e-7` → 8, `1e22` → −22).
fn places(text: &str) -> i32 {
    let (mantissa, exp) = match text.split_once('e') {
        Some((m, e)) => (m, e.parse::<i32>().expect("ryu writes an integer exponent")),
        None => (text, 0),
    };
    let whole = |int: &str| -((int.len() - int.trim_end_matches('0').len()) as i32);
    let frac = match mantissa.split_once('.') {
        Some((int, "0")) => whole(int),
        Some((_, frac)) => frac.len() as i32,
        None => whole(mantissa),
    };
    frac - exp
}

impl Cell for u64 {
    fn read(field: &[u8]) -> Option<Self> {
        std::str::from_utf8(field).ok()?.parse().ok()
    }
    fn put(&self, out: &mut String) {
        out.push_str(itoa::Buffer::new().format(*self));
    }
    fn lo(self, other: Self) -> Self {
        self.min(other)
    }
    fn hi(self, other: Self) -> Self {
        self.max(other)
    }
}
impl Cell for u32 {
    fn read(field: &[u8]) -> Option<Self> {
        std::str::from_utf8(field).ok()?.parse().ok()
    }
    fn put(&self, out: &mut String) {
        out.push_str(itoa::Buffer::new().format(*self));
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
            /// The row a record holds: one field per column, each of its column's type.
            fn read_from(record: &csv::ByteRecord) -> Option<Self> {
                if record.len() != COLUMNS.len() {
                    return None;
                }
                let mut fields = record.iter();
                Some($name {
                    $($f: Cell::read(fields.next()?)?,)*
                })
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

/// Rows per batch: each batch is one `write` of whole rows ending on a newline.
const BATCH_ROWS: u64 = 1000;

/// The batch being formatted, in memory under the csv writer (which hands it over in pieces as
/// its own buffer fills; the file gets it whole at [`Recorder::commit`]).
struct Batch(std::cell::RefCell<Vec<u8>>);

impl std::io::Write for Batch {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.get_mut().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Streams rows to `timeseries.csv`: the header at once, then rows in batches of
/// [`BATCH_ROWS`] (and at [`Recorder::finish`]), each batch formatted in memory and handed to
/// the system in one write that ends on a newline. The file only ever holds the header and
/// complete rows (a process killed in the middle of that one write may leave part of it: a
/// last line without its newline, which the readers drop with a warning), and
/// [`Recorder::rows_on_disk`] counts exactly those: a write that fails (a full disk, a
/// file-size limit) cuts the file back to the end of the last batch that was written whole,
/// and every error names the file and what the system said.
pub struct Recorder {
    out: csv::Writer<Batch>,
    file: File,
    path: PathBuf,
    rows: u64,
    on_disk_rows: u64,
    on_disk_bytes: u64,
    failed: Option<(std::io::ErrorKind, String)>,
    record: csv::ByteRecord,
    buf: String,
}

impl Recorder {
    /// Creates `path` and writes the header (written at once: a run killed at any point
    /// leaves a valid header).
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let named =
            |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
        let file = File::create(path).map_err(named)?;
        let out = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Batch(std::cell::RefCell::new(Vec::with_capacity(1 << 20))));
        let mut r = Recorder {
            out,
            file,
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
        if self.rows.is_multiple_of(BATCH_ROWS) {
            self.commit().map_err(|e| self.fail(e))?;
        }
        Ok(())
    }

    /// Writes the batch held in memory in one write; the file then ends with the last row.
    fn commit(&mut self) -> std::io::Result<()> {
        use std::io::Write as _;
        // Into the batch buffer (memory: cannot fail short), then to the file at once.
        self.out.flush()?;
        let mut batch = self.out.get_ref().0.borrow_mut();
        self.file.write_all(&batch)?;
        self.on_disk_bytes += batch.len() as u64;
        batch.clear();
        drop(batch);
        self.on_disk_rows = self.rows;
        Ok(())
    }

    /// After a failed write: cuts the file back to its last complete row, refuses every later
    /// write and returns the error, naming the file.
    fn fail(&mut self, e: std::io::Error) -> std::io::Error {
        if self.failed.is_none() {
            self.out.get_ref().0.borrow_mut().clear();
            let _ = self.file.set_len(self.on_disk_bytes);
            self.failed = Some((e.kind(), format!("{}: {e}", self.path.display())));
        }
        let (kind, msg) = self.failed.clone().unwrap_or((e.kind(), e.to_string()));
        std::io::Error::new(kind, msg)
    }

    /// Complete rows in the file (all of them after a successful [`Recorder::finish`]).
    pub fn rows_on_disk(&self) -> u64 {
        self.on_disk_rows
    }

    /// Writes the rows still held. On error the file keeps its header and every complete
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

/// The length of the file's whole lines: the offset just past its last newline. What follows
/// it is a partial row (a run killed in the middle of a write), never read as a row.
fn whole_lines_len(file: &mut File) -> std::io::Result<u64> {
    use std::io::{Read as _, Seek as _, SeekFrom};
    let len = file.metadata()?.len();
    let mut end = len;
    let mut buf = vec![0u8; 1 << 16];
    while end > 0 {
        let from = end.saturating_sub(buf.len() as u64);
        file.seek(SeekFrom::Start(from))?;
        let chunk = &mut buf[..(end - from) as usize];
        file.read_exact(chunk)?;
        if let Some(i) = chunk.iter().rposition(|&b| b == b'\n') {
            file.seek(SeekFrom::Start(0))?;
            return Ok(from + i as u64 + 1);
        }
        end = from;
    }
    file.seek(SeekFrom::Start(0))?;
    Ok(0)
}

/// Files whose partial last row was already reported (the analysis reads a file several
/// times: once is enough to say so).
static PARTIAL_TOLD: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// A csv reader over the whole lines of the file at `path`: a last line without its newline
/// (a partial row, as a process killed while writing leaves it) is dropped with a warning
/// that gives its size, once per file. Errors name the file.
pub fn whole_lines(path: &Path) -> std::io::Result<csv::Reader<std::io::Take<File>>> {
    use std::io::Read as _;
    let named =
        |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let mut file = File::open(path).map_err(named)?;
    let whole = whole_lines_len(&mut file).map_err(named)?;
    let len = file.metadata().map_err(named)?.len();
    if len > whole {
        let mut told = PARTIAL_TOLD.lock().unwrap_or_else(|p| p.into_inner());
        if !told.iter().any(|p| p == path) {
            told.push(path.to_path_buf());
            tracing::warn!(
                "{}: the last line ({} bytes) has no newline: a partial row, as a run killed while writing leaves it; dropped",
                path.display(),
                len - whole
            );
        }
    }
    Ok(csv::ReaderBuilder::new().from_reader(file.take(whole)))
}

/// Reads `dir/timeseries.csv` back, handing each row to `visit` in order, one row in memory
/// at a time, until `visit` returns false; returns the number of rows read.
///
/// A damaged file is an error naming the file and the line: a row that is not one of this
/// version's (wrong field count, a field that is not a number), or whose step does not follow
/// the one before (rows lost or repeated). The one thing read past is a last line without its
/// newline, as a run killed in the middle of a write leaves it: it is dropped, with a warning
/// that gives its size, since the row it began cannot be known whole.
pub fn each_row(dir: &Path, mut visit: impl FnMut(&Row) -> bool) -> std::io::Result<u64> {
    let path = dir.join("timeseries.csv");
    let named = |what: String| std::io::Error::other(format!("{}: {what}", path.display()));
    let mut rd = whole_lines(&path)?;
    let header = rd.byte_headers().map_err(|e| named(e.to_string()))?;
    if header.iter().ne(COLUMNS.iter().map(|c| c.as_bytes())) {
        return Err(named(format!(
            "the header is not that of this tiltsim version (columns {})",
            COLUMNS.join(",")
        )));
    }
    let mut record = csv::ByteRecord::new();
    let mut n = 0u64;
    let mut previous: Option<u64> = None;
    loop {
        match rd.read_byte_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => {
                let line = e.position().map_or(n + 2, |p| p.line());
                return Err(named(format!("line {line}: {e}")));
            }
        }
        let line = record.position().map_or(n + 2, |p| p.line());
        let Some(row) = Row::read_from(&record) else {
            let what = if record.len() != COLUMNS.len() {
                format!(
                    "{} fields, not the {} of this version",
                    record.len(),
                    COLUMNS.len()
                )
            } else {
                let bad = record
                    .iter()
                    .position(|f| {
                        std::str::from_utf8(f)
                            .ok()
                            .and_then(|t| t.parse::<f64>().ok())
                            .is_none()
                    })
                    .map_or("a field", |i| COLUMNS[i]);
                format!("`{bad}` does not hold a number of its column's type")
            };
            return Err(named(format!("line {line}: {what}")));
        };
        if let Some(p) = previous {
            if p.checked_add(1) != Some(row.step) {
                return Err(named(format!(
                    "line {line}: step {} follows step {p} (rows lost, repeated or out of order)",
                    row.step
                )));
            }
        }
        previous = Some(row.step);
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
    // The block size comes from the complete lines (a partial last line has no newline), so
    // the rows are parsed once; a file cut short by a bad row still gets its last block.
    let n = complete_lines(&dir.join("timeseries.csv"))?.saturating_sub(1) as usize;
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
        if k.is_multiple_of(block) {
            // Each pair keeps its block's time span in order.
            out.push(lo);
            out.push(hi);
        }
        !crate::signals::received()
    })?;
    if !k.is_multiple_of(block) {
        out.push(lo);
        out.push(hi);
    }
    Ok(out)
}

/// The newlines in the file at `path`: its complete lines, counted without parsing them.
fn complete_lines(path: &Path) -> std::io::Result<u64> {
    use std::io::Read as _;
    let named =
        |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let mut file = File::open(path).map_err(named)?;
    let mut buf = vec![0u8; 1 << 16];
    let mut lines = 0u64;
    loop {
        match file.read(&mut buf) {
            Ok(0) => return Ok(lines),
            Ok(got) => lines += buf[..got].iter().filter(|&&b| b == b'\n').count() as u64,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(named(e)),
        }
    }
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
        // A damaged row inside the file is an error naming the file and its line, whether
        // it is cut short, holds a word, or its step does not follow (a row lost); none is
        // read as the end of the run.
        let lines: Vec<&str> = text.lines().collect();
        let damaged = [
            format!("{}\n{}\n1,2,3\n{}\n", lines[0], lines[1], lines[3]),
            format!(
                "{}\n{}\n{}\n{}\n",
                lines[0],
                lines[1],
                lines[2].replacen(",0.2,", ",x,", 1),
                lines[3]
            ),
            format!("{}\n{}\n{}\n", lines[0], lines[1], lines[3]),
        ];
        for (bad, want) in
            damaged
                .iter()
                .zip(["line 3:", "line 3:", "line 3: step 2 follows step 0"])
        {
            std::fs::write(dir.join("timeseries.csv"), bad).unwrap();
            let e = read_rows(&dir).unwrap_err().to_string();
            assert!(e.contains("timeseries.csv: ") && e.contains(want), "{e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn plot_rows_are_every_row_or_each_blocks_min_and_max_read_in_one_pass() {
        let dir = std::env::temp_dir().join(format!("tiltsim-plot-rows-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // 1001 rows: a slow ramp with one spike at row 500.
        let value = |k: u64| {
            if k == 500 {
                9.0
            } else {
                (k as f64 * 0.01).sin()
            }
        };
        let rows: Vec<Row> = (0..1001)
            .map(|k| {
                let p = FromPlant {
                    t: (k + 1) as f64 * 1e-3,
                    lat_acc: value(k),
                    ..Default::default()
                };
                let (a, c) = (FromActuator::default(), FromController::default());
                Row::new(k, &p, &a, &c, &[0.0; 4])
            })
            .collect();
        let mut rec = Recorder::create(&dir.join("timeseries.csv")).unwrap();
        for r in &rows {
            rec.write(r).unwrap();
        }
        rec.finish().unwrap();
        drop(rec);
        // Few enough: every row.
        assert_eq!(rows_to_plot(&dir, 2000).unwrap(), rows);
        // 100 points: blocks of ceil(1001 / 50) = 21 rows, 47 whole and a last one of 14,
        // each as its minimum and maximum row.
        let expect: Vec<Row> = rows
            .chunks(21)
            .flat_map(|b| {
                let pick = |better: fn(f64, f64) -> bool| {
                    let mut m = b[0];
                    for r in b {
                        if better(r.lat_acc, m.lat_acc) {
                            m.lat_acc = r.lat_acc;
                        }
                    }
                    m.lat_acc
                };
                let (lo, hi) = (pick(|a, b| a < b), pick(|a, b| a > b));
                [(b[0].step, lo), (b[b.len() - 1].step, hi)]
            })
            .collect::<Vec<_>>()
            .into_iter()
            .map(|(step, v)| Row {
                step,
                lat_acc: v,
                ..Row::default()
            })
            .collect();
        let got = rows_to_plot(&dir, 100).unwrap();
        assert_eq!(got.len(), 2 * 48);
        for (g, e) in got.iter().zip(&expect) {
            // lo carries the block's first step, hi its last.
            assert_eq!((g.step, g.lat_acc), (e.step, e.lat_acc));
        }
        assert_eq!(got.iter().map(|r| r.lat_acc).fold(f64::MIN, f64::max), 9.0);
        // A killed run's partial last line neither counts nor moves a block.
        let text = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
        std::fs::write(dir.join("timeseries.csv"), format!("{text}1001,1.002,0.5")).unwrap();
        assert_eq!(rows_to_plot(&dir, 100).unwrap(), got);
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

    #[test]
    fn every_float_is_written_as_std_writes_it() {
        use rand::{Rng, SeedableRng};
        let check = |v: f64| {
            let mut s = String::new();
            put_f64(v, &mut s);
            let mut reference = String::new();
            std_put_f64(v, &mut reference);
            assert_eq!(s, reference, "bits {:#x}", v.to_bits());
        };
        // Uniform bit patterns (every exponent, subnormals, NaNs and infinities included) and
        // values of a simulation's magnitudes with few digits, where trailing zeros and the
        // point's place are easiest to get wrong.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
        for _ in 0..1_000_000 {
            check(f64::from_bits(rng.random()));
            let digits = rng.random_range(0..10_000_000_u64) as f64;
            check(digits * 10f64.powi(rng.random_range(-25..25)));
            check(-(rng.random_range(0..1000_u64) as f64) / 1000.0);
        }
        // Exact binary fractions of 17-18 digits: some lie halfway between two shortest forms,
        // where `ryu` and `std` round differently (0xc26b324eeb72d100 is -934465198998.53125).
        let mut ties = 0;
        for _ in 0..200_000 {
            let v = rng.random_range(1_u64 << 40..1 << 53) as f64
                / (1 << rng.random_range(1..9)) as f64;
            let mut buf = ryu::Buffer::new();
            let k = places(buf.format_finite(v));
            ties += usize::from(halfway_places(v) == Some(k));
            check(v);
        }
        assert!(ties > 100, "ties {ties}");
        // Large integers (exponents 2^1 to 2^21 times a 41-53 bit mantissa). A halfway case
        // left of the point (k < 0) needs 5^−k in an odd part that still spans the mantissa,
        // so none is met; `halfway_places` keeps the case for completeness.
        for _ in 0..200_000 {
            let m = rng.random_range(1_u64 << 40..1 << 53) as f64;
            check(m * (1 << rng.random_range(1..22)) as f64);
        }
        check(f64::from_bits(0xc26b324eeb72d100));
        // Both sides of both switches between positional and exponent form, and the extremes.
        for b in [1e-4_f64, 1e16] {
            for v in [b, b.next_up(), b.next_down()] {
                check(v);
                check(-v);
            }
        }
        for v in [
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            f64::MAX,
            f64::MIN,
            f64::EPSILON,
            5e-324,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.1 + 0.2,
            1.0,
            100.0,
            123456789012345.6,
            9999999999999998.0,
        ] {
            check(v);
        }
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
