//! The run's time series, one typed [`Row`] per plant step, defined once: the recorder streams
//! it to `timeseries.csv` with the `csv` crate as the run goes (one write per 1000 rows, so a
//! run that fails keeps what it recorded and memory does not grow with run length), and
//! [`read_rows`] reads the file back into the same type for plots, comfort, flags, `compare`
//! and sweeps.
//!
//! Floats are written in shortest round-trip form ([`put_f64`]), so identical values give
//! identical bytes and every value reads back exactly.

use serde::{Deserialize, Serialize};

use tiltsim_protocol::msg::{FromActuator, FromController, FromPlant};
use tiltsim_scenario::links::LinkId;

mod cells;
mod reader;
mod writer;

pub use crate::float_text::{fmt_f64, put_f64};
use cells::Cell;
pub use reader::{each_row, read_rows, rows_to_plot, whole_lines, Rows};
pub use writer::Recorder;

macro_rules! row {
    ($(#[$m:meta])* pub struct $name:ident {
        $(#[doc = $doc:literal] $f:ident : $t:ty => $unit:literal),* $(,)?
    }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
        pub struct $name {
            $(#[doc = $doc] pub $f: $t,)*
        }
        /// Column names of `timeseries.csv`, in order: the fields of [`Row`].
        pub const COLUMNS: &[&str] = &[$(stringify!($f)),*];
        /// The unit of each column of [`COLUMNS`] (UCUM codes: `1` a pure number, empty for a
        /// code or a set of bits).
        pub const UNITS: &[&str] = &[$($unit),*];
        /// What each column of [`COLUMNS`] holds.
        pub const DESCRIPTIONS: &[&str] = &[$($doc),*];
        /// The Rust type of each column of [`COLUMNS`] (`f64`, `u64`, `u32`, `i32`).
        pub const TYPES: &[&str] = &[$(stringify!($t)),*];
        /// Where each column of [`COLUMNS`] lies in a [`Row`] (bytes from its start): rows
        /// kept in memory are read column-wise in place, a column being every
        /// `size_of::<Row>()` bytes from its offset.
        pub const OFFSETS: &[usize] = &[$(std::mem::offset_of!($name, $f)),*];
        /// Each column of [`COLUMNS`] of a row, as a float (the signals of a requirement).
        pub const GETTERS: &[fn(&$name) -> f64] = &[$(|r: &$name| Cell::number(r.$f)),*];
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
    /// One row of `timeseries.csv`: every participant's latest output at `time = step·dt`;
    /// row 0 holds the outputs at the start time, row `k + 1` those after tick `k`. SI units
    /// and radians (`columns.csv` beside the file gives each unit; docs/outputs.md).
    pub struct Row {
        /// Simulated time (s).
        time: f64 => "s",
        /// Ticks since the start time.
        step: u64 => "1",
        /// Position along the track (m).
        s: f64 => "m",
        /// Curvature 1/R (1/m).
        curvature: f64 => "/m",
        /// Cant θ_o with irregularity (rad).
        cant: f64 => "rad",
        /// Body lateral displacement (m).
        y_v: f64 => "m",
        /// Body roll relative to the track (rad).
        theta_v: f64 => "rad",
        /// Bogie lateral displacement (m).
        y_b: f64 => "m",
        /// Bogie roll (rad).
        theta_b: f64 => "rad",
        /// ẏ_v (m/s).
        dy_v: f64 => "m/s",
        /// θ̇_v (rad/s).
        dtheta_v: f64 => "rad/s",
        /// ẏ_b (m/s).
        dy_b: f64 => "m/s",
        /// θ̇_b (rad/s).
        dtheta_b: f64 => "rad/s",
        /// Airspring reservoir roll θ_r (rad).
        theta_r: f64 => "rad",
        /// ψ = θ_v − θ_b (rad).
        psi: f64 => "rad",
        /// Passenger lateral acceleration, eq 13 (m/s²).
        lat_acc: f64 => "m/s2",
        /// Measured roll (rad).
        theta_v_meas: f64 => "rad",
        /// Estimated roll (rad).
        theta_v_hat: f64 => "rad",
        /// Reference of eq 18 as the controller computed it (rad).
        theta_ref: f64 => "rad",
        /// Commanded bar angle (rad).
        delta_a_cmd: f64 => "rad",
        /// Achieved bar angle (rad).
        delta_a: f64 => "rad",
        /// Set-point after command shaping (rad).
        delta_a_ref: f64 => "rad",
        /// Mean electromagnetic torque (N·m).
        motor_torque: f64 => "N.m",
        /// Rotor speed (rad/s).
        motor_speed: f64 => "rad/s",
        /// T_e/k_t (A).
        motor_current: f64 => "A",
        /// Power drawn from the DC link (W).
        dc_power: f64 => "W",
        /// Largest phase current of the millisecond (A).
        phase_current_peak: f64 => "A",
        /// DC-link voltage (V).
        v_dc: f64 => "V",
        /// Chopper power (W).
        chopper_power: f64 => "W",
        /// `actuator_proc::bldc::limit` bits.
        actuator_limits: u32 => "",
        /// 0 no QP, 1 solved, 2 failed (previous command held).
        solver_status: u32 => "",
        /// What the actuator received as its command (rad).
        rx_actuator_command: f64 => "rad",
        /// What the plant received as the bar angle (rad).
        rx_bar_angle: f64 => "rad",
        /// What the controller received as the measurement (rad).
        rx_measurement: f64 => "rad",
        /// What the actuator received as the bar twist (rad).
        rx_bar_twist: f64 => "rad",
    }
);

pub use tiltsim_protocol::time::tick_time;

impl Row {
    /// The row after tick `k` (step `k + 1`) from the held outputs and what each link
    /// delivered (`rx` = actuator command, bar angle, measurement, bar twist).
    pub fn after_tick(
        k: u64,
        dt: f64,
        p: &FromPlant,
        a: &FromActuator,
        c: &FromController,
        rx: &[f64; 4],
    ) -> Self {
        Self::of(k + 1, dt, p, a, c, rx)
    }

    /// Row 0: the outputs at the start time. Nothing has travelled a link yet, so each
    /// `rx_*` column holds what its sender holds.
    pub fn at_start(dt: f64, p: &FromPlant, a: &FromActuator, c: &FromController) -> Self {
        Self::of(0, dt, p, a, c, &LinkId::carried(p, a, c))
    }

    fn of(
        step: u64,
        dt: f64,
        p: &FromPlant,
        a: &FromActuator,
        c: &FromController,
        rx: &[f64; 4],
    ) -> Self {
        let x = &p.x;
        Row {
            time: tick_time(step, dt),
            step,
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

#[cfg(test)]
mod tests {
    use super::*;
    #[allow(unused_imports)]
    use super::{reader::*, writer::*};
    use crate::float_text::{halfway_places, places, std_put_f64};

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
            .map(|k| Row::of(k, 1e-3, &p, &a, &c, &[0.1, 0.2, f64::NAN, 0.4]))
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
                Row::of(k, 1e-3, &p, &a, &c, &[0.0; 4])
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

    #[test]
    fn whole_floats_keep_their_point_so_readers_infer_floats() {
        let cases = [
            (0.0, "0.0"),
            (-0.0, "-0.0"),
            (1.0, "1.0"),
            (-3.0, "-3.0"),
            (1200.0, "1200.0"),
            (9999999999999998.0, "9999999999999998.0"),
            (1e16, "1e16"),
            (0.25, "0.25"),
            (1.5e-7, "1.5e-7"),
            (f64::NAN, "NaN"),
            (f64::INFINITY, "inf"),
        ];
        for (v, want) in cases {
            assert_eq!(fmt_f64(v), want);
            let back: f64 = want.parse().unwrap();
            assert!(back.to_bits() == v.to_bits() || v.is_nan(), "{want}");
        }
    }

    impl Row {
        /// Every float's bits (NaN compares equal to itself).
        fn x_bits(&self) -> Vec<u64> {
            vec![
                self.time.to_bits(),
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
