//! Whether a run's numbers mean what they say: flags in `summary.json` → `flags`, each with the
//! measured value that raised it or would have (docs/outputs.md, "A run's files", `summary.json`).
//!
//! * `oscillation`: a sustained oscillation of the roll error θ_v − θ_v^d where the reference
//!   is steady (straights and steady curve, from 2 s after the reference last moved: a
//!   transition's own tracking error is not an oscillation). The error is high-passed (itself
//!   minus its 0.3 Hz Butterworth low-pass, which removes a steady offset) and cut into 2 s
//!   windows; a window oscillates when its amplitude √2·RMS exceeds `threshold_deg` (0.1°,
//!   i.e. 0.2° peak to peak). The loop oscillates when more than half of the windows do *and*
//!   the oscillation is self-sustained: every window shows it at about the same amplitude
//!   (smallest/largest ≥ 0.7), or one that never falls below 0.7 of an earlier window's (an
//!   unstable loop's oscillation grows: paper-mpc with its measurement 200 to 300 ms late,
//!   0.74-0.84 Hz, 1.3-6° in its last window), and frequency (spectral peaks within 0.3 Hz). A limit cycle keeps its amplitude and frequency; the forced response to a random cant irregularity
//!   (±0.6°, a broadband input) passes the amplitude threshold too but wanders in both
//!   (measured on the shipped irregular scenarios: ratios 0.50-0.54, peaks 0.3-1.0 Hz apart;
//!   paper-pi: 0.95 and 0.12 Hz). The frequency reported is the spectral peak (0.2-20 Hz) of
//!   the window with the largest amplitude.
//! * `bump_stop`: the secondary lateral deflection reached the bump-stop clearance.
//! * `drive_limit`: time (ms counted from `actuator_limits`) during which the drive was at its
//!   torque, current, speed or stroke limit, on its end stop, or had a protection block its
//!   gates.
//! * `chopper`: energy dumped in the braking chopper; raised above `threshold_j`, the energy
//!   one tilt gives back through the gear: η·max ½M δ_a over the run, M = k_vr(δ_a − ψ) the
//!   bar's moment (docs/model.md D47). Tilting the vehicle to δ_a against the moment M, which
//!   grows with it from zero, takes about ½M δ_a (bar, airsprings and the body's weight
//!   together); tilting back returns it, and the back-driven gear passes η of it to the motor
//!   (less its copper loss, and the capacitor's 125 J between 780 and 850 V and the auxiliary
//!   load take the first of it). A chopper that dumps more burns energy the drive pumped
//!   through the bar more than once per tilt: the controller works the bar, not the curve.
//! * `thermal`: the motor's RMS torque over the run (equivalently its RMS current, T/k_t)
//!   against its continuous rating `bldc.continuous_torque_nm`: the servo sizing rule that a
//!   duty repeated for longer than the motor's thermal time constant must keep the RMS torque
//!   within the continuous torque (docs/model.md D48).
//! * `p_ct_range`: a P_CT above 100 % (the formula gives the percentage of passengers
//!   uncomfortable; past 100 % it is extrapolated and says only "worse than the scale").

use serde::Serialize;

use actuator_proc::bldc::limit;

use crate::comfort::Comfort;

/// Amplitude above which a 2 s window of θ_v − θ_v^d counts as oscillating (deg).
pub const OSCILLATION_THRESHOLD_DEG: f64 = 0.1;
const WINDOW_S: f64 = 2.0;
/// Time after the reference last moved before a window may start (s).
const SETTLE_S: f64 = 2.0;

/// Oscillation of the roll error.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct Oscillation {
    /// Raised.
    pub raised: bool,
    /// Largest window amplitude √2·RMS (deg).
    pub amplitude_deg: f64,
    /// Dominant frequency of the window with the largest amplitude (Hz).
    pub frequency_hz: f64,
    /// Windows above the threshold, of all.
    pub windows_oscillating: usize,
    /// Windows (2 s each, where the reference is steady).
    pub windows: usize,
    /// Smallest over largest window amplitude.
    pub amplitude_ratio: f64,
    /// Smallest amplitude of a window over the largest of the windows before it (1 when no
    /// window is smaller than one before it): a growing oscillation keeps it at 1.
    pub decay_ratio: f64,
    /// Largest minus smallest spectral peak frequency over the windows (Hz).
    pub frequency_spread_hz: f64,
    /// Threshold (deg amplitude).
    pub threshold_deg: f64,
}

/// Bump-stop contact.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct BumpStop {
    /// Raised.
    pub raised: bool,
    /// Largest |secondary lateral deflection| (mm).
    pub deflection_peak_mm: f64,
    /// Clearance (mm).
    pub clearance_mm: f64,
    /// Time at or beyond the clearance (s).
    pub time_in_contact_s: f64,
    /// Largest force of one side's bump stop (kN): how hard the body hit.
    pub force_peak_kn: f64,
    /// Impulse of the bump-stop force over the run, ∫|F| dt of one side (kN·s).
    pub impulse_kn_s: f64,
}

/// Time at the drive's limits (s).
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct DriveLimit {
    /// Raised.
    pub raised: bool,
    /// At any of the limits below (s).
    pub time_at_any_limit_s: f64,
    /// Torque limit (s).
    pub torque_s: f64,
    /// Current limit reached by a measured phase current (s).
    pub current_s: f64,
    /// Speed (DC-link voltage) limit (s).
    pub speed_s: f64,
    /// Command outside the stroke (s).
    pub stroke_command_s: f64,
    /// On the end stop (s).
    pub end_stop_s: f64,
    /// Over-current protection blocked the gates (s).
    pub overcurrent_trip_s: f64,
    /// Over-voltage protection blocked the gates (s).
    pub overvoltage_s: f64,
    /// Largest phase current in any electrical step (A).
    pub phase_current_peak_a: f64,
    /// Largest |electromagnetic torque| of any millisecond (N·m).
    pub torque_peak_nm: f64,
    /// Largest power drawn from the DC link in any millisecond (W).
    pub motoring_power_peak_w: f64,
    /// Largest power returned to the DC link in any millisecond (W).
    pub braking_power_peak_w: f64,
}

/// Energy dumped in the braking chopper.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct Chopper {
    /// Raised.
    pub raised: bool,
    /// Energy dumped (J).
    pub energy_j: f64,
    /// Threshold (J).
    pub threshold_j: f64,
    /// Time the chopper was on (s).
    pub time_on_s: f64,
    /// Largest DC-link voltage recorded (V).
    #[serde(rename = "v_dc_max_v")]
    pub v_dc_max: f64,
}

/// The motor's thermal duty: RMS torque over the run against the continuous rating.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct Thermal {
    /// Raised.
    pub raised: bool,
    /// RMS of the per-millisecond electromagnetic torque over the run (N·m).
    pub torque_rms_nm: f64,
    /// RMS of the torque-producing current over the run, T_rms/k_t (A).
    pub current_rms_a: f64,
    /// The motor's continuous torque (N·m).
    pub continuous_torque_nm: f64,
}

/// The drive's ratings the flags judge a run against (from the scenario).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveRating {
    /// Continuous torque of the motor (N·m).
    pub continuous_torque_nm: f64,
    /// Torque constant k_t (N·m/A).
    pub k_t: f64,
    /// Anti-roll bar stiffness k_vr (N·m/rad).
    pub k_vr: f64,
    /// Gear efficiency η.
    pub gear_efficiency: f64,
}

/// P_CT outside the formula's meaningful range.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct PctRange {
    /// Raised.
    pub raised: bool,
    /// The largest P_CT of the run (whole-run peaks or EN 12299, standing or seated) (%).
    pub largest_pct: f64,
}

/// A free run that did not keep real time: its plant fell behind its own clock, so the ride it
/// recorded is not the one the real-time system would give (the controller saw older
/// measurements than it would have). Raised by the run, not by the series.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct NotRealTime {
    /// Raised.
    pub raised: bool,
    /// The plant's largest start lateness (s).
    pub plant_max_lateness_s: f64,
    /// The lateness above which a run is not real-time (s).
    pub margin_s: f64,
}

/// Every flag of a run.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct Flags {
    /// Roll-error oscillation.
    pub oscillation: Oscillation,
    /// Bump-stop contact.
    pub bump_stop: BumpStop,
    /// Time at a drive limit.
    pub drive_limit: DriveLimit,
    /// Chopper energy.
    pub chopper: Chopper,
    /// Motor RMS torque against its continuous rating.
    pub thermal: Thermal,
    /// P_CT above 100 %.
    pub p_ct_range: PctRange,
    /// A free run's real-time judgement (absent for lock-step runs, whose values do not
    /// depend on time).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_real_time: Option<NotRealTime>,
    /// The whole car's running safety against EN 14363's limits (absent for the half
    /// vehicle, which has no wheelsets).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub running_safety: Option<crate::running_safety::RunningSafetyFlag>,
}

/// One row's inputs to the flags.
#[derive(Debug, Clone, Copy, Default)]
pub struct FlagSample {
    /// θ_v − θ_v^d (rad).
    pub roll_error: f64,
    /// θ_v^d (rad), to find where the reference is steady.
    pub reference: f64,
    /// Secondary lateral deflection (m).
    pub deflection: f64,
    /// Force of one side's bump stop at that deflection (N), 0 inside the clearance.
    pub bump_force: f64,
    /// `actuator_limits` bits.
    pub limits: u32,
    /// Largest phase current of the row (A).
    pub phase_current_peak: f64,
    /// Mean electromagnetic torque (N·m).
    pub torque: f64,
    /// Power drawn from the DC link (W).
    pub dc_power: f64,
    /// Chopper power (W).
    pub chopper_power: f64,
    /// DC-link voltage (V).
    pub v_dc: f64,
    /// Bar twist at the actuator, δ_a − ψ (rad).
    pub bar_twist: f64,
    /// Bar angle δ_a (rad).
    pub delta_a: f64,
}

/// Any limit of the drive (the chopper is not one: it is the link doing its job).
const ANY_LIMIT: u32 = limit::TORQUE
    | limit::CURRENT
    | limit::SPEED
    | limit::STROKE_COMMAND
    | limit::END_STOP
    | limit::OVERCURRENT_TRIP
    | limit::OVERVOLTAGE;

/// The drive bits whose time is reported, in the order of [`DriveLimit`]'s fields, then the
/// chopper.
const TIMED_BITS: [u32; 9] = [
    ANY_LIMIT,
    limit::TORQUE,
    limit::CURRENT,
    limit::SPEED,
    limit::STROKE_COMMAND,
    limit::END_STOP,
    limit::OVERCURRENT_TRIP,
    limit::OVERVOLTAGE,
    limit::CHOPPER,
];

/// The validity flags of a run, one row at a time in constant memory (a 2 s window of the
/// roll error is the most it holds).
pub struct Flagger {
    dt: f64,
    clearance: f64,
    rows_at: [u64; 9],
    phase_current_peak: f64,
    torque_peak: f64,
    motoring: f64,
    braking: f64,
    chopper_sum: f64,
    v_dc_max: f64,
    deflection_peak: f64,
    contact_rows: u64,
    bump_force_peak: f64,
    bump_impulse: f64,
    oscillation: Oscillator,
    rating: DriveRating,
    torque_sq: f64,
    rows: u64,
    tilt_work_peak: f64,
}

impl Flagger {
    /// Flags at row period `dt` (s) with bump-stop `clearance` (m), the drive judged against
    /// `rating`.
    pub fn new(dt: f64, clearance: f64, rating: DriveRating) -> Self {
        Flagger {
            dt,
            clearance,
            rating,
            torque_sq: 0.0,
            rows: 0,
            tilt_work_peak: 0.0,
            rows_at: [0; 9],
            phase_current_peak: 0.0,
            torque_peak: 0.0,
            motoring: 0.0,
            braking: 0.0,
            chopper_sum: 0.0,
            v_dc_max: 0.0,
            deflection_peak: 0.0,
            contact_rows: 0,
            bump_force_peak: 0.0,
            bump_impulse: 0.0,
            oscillation: Oscillator::new(dt),
        }
    }

    /// Takes the next row.
    pub fn push(&mut self, x: &FlagSample) {
        for (n, bits) in self.rows_at.iter_mut().zip(TIMED_BITS) {
            *n += u64::from(x.limits & bits != 0);
        }
        self.phase_current_peak = self.phase_current_peak.max(x.phase_current_peak);
        self.torque_peak = self.torque_peak.max(x.torque.abs());
        self.motoring = self.motoring.max(x.dc_power);
        self.braking = self.braking.max(-x.dc_power);
        self.chopper_sum += x.chopper_power;
        self.v_dc_max = self.v_dc_max.max(x.v_dc);
        self.deflection_peak = self.deflection_peak.max(x.deflection.abs());
        self.contact_rows += u64::from(x.deflection.abs() >= self.clearance);
        self.bump_force_peak = self.bump_force_peak.max(x.bump_force.abs());
        self.bump_impulse += x.bump_force.abs() * self.dt;
        self.oscillation.push(x.roll_error, x.reference);
        self.torque_sq += x.torque * x.torque;
        self.rows += 1;
        let work = 0.5 * self.rating.k_vr * x.bar_twist * x.delta_a;
        self.tilt_work_peak = self.tilt_work_peak.max(work);
    }

    /// Every flag of the rows taken, with the run's comfort for the P_CT range.
    pub fn finish(&self, comfort: &Comfort) -> Flags {
        let dt = self.dt;
        let time = |i: usize| self.rows_at[i] as f64 * dt;
        let drive = DriveLimit {
            raised: self.rows_at[0] > 0,
            time_at_any_limit_s: time(0),
            torque_s: time(1),
            current_s: time(2),
            speed_s: time(3),
            stroke_command_s: time(4),
            end_stop_s: time(5),
            overcurrent_trip_s: time(6),
            overvoltage_s: time(7),
            phase_current_peak_a: self.phase_current_peak,
            torque_peak_nm: self.torque_peak,
            motoring_power_peak_w: self.motoring,
            braking_power_peak_w: self.braking,
        };
        let energy = self.chopper_sum * dt;
        let r = self.rating;
        let threshold = r.gear_efficiency * self.tilt_work_peak;
        let chopper = Chopper {
            raised: energy > threshold,
            energy_j: energy,
            threshold_j: threshold,
            time_on_s: time(8),
            v_dc_max: self.v_dc_max,
        };
        let rms = (self.torque_sq / self.rows.max(1) as f64).sqrt();
        let thermal = Thermal {
            raised: rms > r.continuous_torque_nm,
            torque_rms_nm: rms,
            current_rms_a: rms / r.k_t,
            continuous_torque_nm: r.continuous_torque_nm,
        };
        let peak = self.deflection_peak;
        let bump = BumpStop {
            raised: peak >= self.clearance,
            deflection_peak_mm: peak * 1e3,
            clearance_mm: self.clearance * 1e3,
            time_in_contact_s: self.contact_rows as f64 * dt,
            force_peak_kn: self.bump_force_peak * 1e-3,
            impulse_kn_s: self.bump_impulse * 1e-3,
        };
        let largest = [
            comfort.p_ct_paper.standing,
            comfort.p_ct_paper.seated,
            comfort.p_ct_en12299.standing,
            comfort.p_ct_en12299.seated,
        ]
        .into_iter()
        .fold(0.0, f64::max);
        Flags {
            oscillation: self.oscillation.finish(),
            bump_stop: bump,
            drive_limit: drive,
            chopper,
            thermal,
            p_ct_range: PctRange {
                raised: largest > 100.0,
                largest_pct: largest,
            },
            not_real_time: None,
            running_safety: None,
        }
    }
}

impl Flags {
    /// The flags' names that are raised.
    pub fn raised(&self) -> Vec<&'static str> {
        [
            (self.oscillation.raised, "oscillation"),
            (self.bump_stop.raised, "bump stop"),
            (self.drive_limit.raised, "drive limit"),
            (self.chopper.raised, "chopper"),
            (self.thermal.raised, "thermal"),
            (self.p_ct_range.raised, "P_CT > 100 %"),
            (
                self.not_real_time.as_ref().is_some_and(|n| n.raised),
                "not real-time",
            ),
            (
                self.running_safety.as_ref().is_some_and(|r| r.raised),
                "running safety",
            ),
        ]
        .into_iter()
        .filter_map(|(r, n)| r.then_some(n))
        .collect()
    }

    /// The flags that make comfort numbers meaningless: an oscillating loop (the ride is not
    /// the controller's intended one) or a P_CT outside the formula's 0-100 % range.
    /// Bump-stop contact is not one: the stops are a force of the model (docs/model.md D49),
    /// so a ride on them is physics, and the flag says how long and how hard.
    pub fn ride_invalid(&self) -> bool {
        self.oscillation.raised || self.p_ct_range.raised
    }

    /// A free run that fell behind real time: its comfort numbers do not answer the
    /// real-time question (what the passengers of the real system would feel).
    pub fn not_real_time(&self) -> bool {
        self.not_real_time.as_ref().is_some_and(|n| n.raised)
    }

    /// Whether the comfort numbers are to be shown as not valid (never as plain results).
    pub fn comfort_not_valid(&self) -> bool {
        self.ride_invalid() || self.not_real_time()
    }

    /// One line per raised flag, with its value.
    pub fn describe(&self) -> Vec<String> {
        let mut v = Vec::new();
        if let Some(n) = self.not_real_time.as_ref().filter(|n| n.raised) {
            v.push(format!(
                "not real-time: a plant step started {:.1} ms after it was due (more than {:.1} ms): the ride is not the real-time system's",
                n.plant_max_lateness_s * 1e3,
                n.margin_s * 1e3
            ));
        }
        let o = &self.oscillation;
        if o.raised {
            v.push(format!(
                "oscillation: θ_v − θ_ref oscillates ±{:.2}° at {:.2} Hz ({} of {} windows of 2 s)",
                o.amplitude_deg, o.frequency_hz, o.windows_oscillating, o.windows
            ));
        }
        let b = &self.bump_stop;
        if b.raised {
            v.push(format!(
                "bump stop: secondary deflection {:.1} mm against a {:.0} mm clearance, {:.3} s in contact, force up to {:.1} kN a side ({:.2} kN·s)",
                b.deflection_peak_mm, b.clearance_mm, b.time_in_contact_s, b.force_peak_kn, b.impulse_kn_s
            ));
        }
        let d = &self.drive_limit;
        if d.raised {
            v.push(format!(
                "drive limit: {:.3} s at a limit (torque {:.3} s, current {:.3} s, speed {:.3} s, stroke {:.3} s, end stop {:.3} s, over-current trip {:.3} s, over-voltage {:.3} s)",
                d.time_at_any_limit_s, d.torque_s, d.current_s, d.speed_s, d.stroke_command_s,
                d.end_stop_s, d.overcurrent_trip_s, d.overvoltage_s
            ));
        }
        let c = &self.chopper;
        if c.raised {
            v.push(format!(
                "chopper: {:.2} kJ of braking energy dumped, more than one tilt returns through the gear ({:.2} kJ; {:.3} s on, link up to {:.0} V)",
                c.energy_j / 1e3,
                c.threshold_j / 1e3,
                c.time_on_s,
                c.v_dc_max
            ));
        }
        let t = &self.thermal;
        if t.raised {
            v.push(format!(
                "thermal: RMS torque {:.0} N·m ({:.1} A) above the motor's continuous {:.0} N·m",
                t.torque_rms_nm, t.current_rms_a, t.continuous_torque_nm
            ));
        }
        if self.p_ct_range.raised {
            v.push(format!(
                "P_CT {:.1} % is outside the formula's range (0-100 %)",
                self.p_ct_range.largest_pct
            ));
        }
        v
    }
}

/// The oscillation flag, one sample at a time: the roll error is high-passed (the error less
/// its 0.3 Hz low-pass, which removes a transition's quasi-static error) and cut into 2 s
/// windows that lie where the reference has not moved for `SETTLE_S` (or since the start of
/// the run, where the vehicle starts at rest on a steady reference). Each window gives an
/// amplitude (√2·RMS) and a spectral peak; the flag is raised when most windows exceed the
/// threshold with consistent amplitude and frequency.
struct Oscillator {
    dt: f64,
    n: usize,
    settle: usize,
    k: usize,
    previous: Option<f64>,
    still: usize,
    lp: crate::comfort::LowPass,
    window: Vec<f64>,
    windows: usize,
    oscillating: usize,
    per: Vec<(f64, f64)>,
}

impl Oscillator {
    fn new(dt: f64) -> Self {
        let n = (WINDOW_S / dt).round() as usize;
        Oscillator {
            dt,
            n,
            settle: (SETTLE_S / dt).round() as usize,
            k: 0,
            previous: None,
            still: 0,
            lp: crate::comfort::LowPass::new(dt, 0.3),
            window: Vec::with_capacity(n.min(1 << 20)),
            windows: 0,
            oscillating: 0,
            per: Vec::new(),
        }
    }

    fn push(&mut self, e: f64, reference: f64) {
        let k = self.k;
        self.k += 1;
        // A roll error below 1e-150 rad is zero for this purpose: a transient that has decayed
        // for an hour reaches subnormal numbers, whose arithmetic is a hundred times slower.
        let e = if e.abs() < 1e-150 { 0.0 } else { e };
        let hp = e - self.lp.step(e);
        let hp = if hp.abs() < 1e-150 { 0.0 } else { hp };
        let moved = self.previous.is_some_and(|p| p != reference);
        self.previous = Some(reference);
        self.still = if moved { 0 } else { self.still + 1 };
        // A window may begin once the reference has been still for `settle` samples, or at
        // the start of the run.
        let steady = !moved && (self.still > self.settle || self.still == k + 1);
        if !steady {
            self.window.clear();
            return;
        }
        self.window.push(hp);
        if self.n >= 2 && self.window.len() == self.n {
            let n = self.n as f64;
            let rms = (self.window.iter().map(|x| x * x).sum::<f64>() / n).sqrt();
            let amp = (std::f64::consts::SQRT_2 * rms).to_degrees();
            self.windows += 1;
            if amp > OSCILLATION_THRESHOLD_DEG {
                self.oscillating += 1;
            }
            self.per.push((amp, spectral_peak(&self.window, self.dt)));
            self.window.clear();
        }
    }

    fn finish(&self) -> Oscillation {
        let mut o = Oscillation {
            threshold_deg: OSCILLATION_THRESHOLD_DEG,
            windows: self.windows,
            windows_oscillating: self.oscillating,
            ..Default::default()
        };
        let per = &self.per;
        let Some(&(amp, f)) = per.iter().max_by(|a, b| a.0.total_cmp(&b.0)) else {
            return o;
        };
        o.amplitude_deg = amp;
        o.frequency_hz = f;
        let a_min = per.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        let (f_min, f_max) = per.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
            (lo.min(p.1), hi.max(p.1))
        });
        o.amplitude_ratio = if amp > 0.0 { a_min / amp } else { 0.0 };
        o.frequency_spread_hz = f_max - f_min;
        o.decay_ratio = decay_ratio(per.iter().map(|p| p.0));
        // Self-sustained: the same amplitude in every window, or one that never falls by
        // more than the same 30 % from an earlier window (an unstable loop's oscillation
        // grows until the drive's limits hold it).
        o.raised = 2 * o.windows_oscillating > o.windows
            && (o.amplitude_ratio >= 0.7 || o.decay_ratio >= 0.7)
            && o.frequency_spread_hz <= 0.3;
        o
    }
}

/// The smallest amplitude of a window over the largest of the windows before it, windows
/// in time order (1 when none is smaller than one before it, or with fewer than two).
fn decay_ratio(amps: impl Iterator<Item = f64>) -> f64 {
    let mut largest = 0.0f64;
    let mut ratio = 1.0f64;
    for a in amps {
        if largest > 0.0 {
            ratio = ratio.min(a / largest);
        }
        largest = largest.max(a);
    }
    ratio
}

/// The oscillation flag of a roll-error series `e` against its `reference` (step `dt`).
pub fn oscillation(e: &[f64], reference: &[f64], dt: f64) -> Oscillation {
    let mut o = Oscillator::new(dt);
    e.iter().zip(reference).for_each(|(e, r)| o.push(*e, *r));
    o.finish()
}

/// Amplitudes of the sinusoids at `L` frequencies `f` (Hz) in `x` (step `dt`):
/// 2·|Σ x_k e^(−iωk)|/n each, by the Goertzel recurrence, `L` frequencies per pass over `x` so
/// that their independent recurrences run side by side (one multiplication per sample and
/// frequency instead of a sine and a cosine: the spectral peaks of an hour-long run's windows
/// take about a second instead of minutes).
fn amplitudes_at<const L: usize>(x: &[f64], dt: f64, f: [f64; L]) -> [f64; L] {
    let coeff = f.map(|f| 2.0 * (std::f64::consts::TAU * f * dt).cos());
    let (mut s1, mut s2) = ([0.0; L], [0.0; L]);
    for v in x {
        for j in 0..L {
            let s0 = v + coeff[j] * s1[j] - s2[j];
            s2[j] = s1[j];
            s1[j] = s0;
        }
    }
    std::array::from_fn(|j| {
        let power = (s1[j] * s1[j] + s2[j] * s2[j] - coeff[j] * s1[j] * s2[j]).max(0.0);
        2.0 * power.sqrt() / x.len() as f64
    })
}

/// Frequency of the largest spectral amplitude of `x` in 0.2-20 Hz, in steps of 0.02 Hz (a
/// 2 s window resolves 0.5 Hz; the fine grid places the peak within that); the lowest such
/// frequency on a tie.
fn spectral_peak(x: &[f64], dt: f64) -> f64 {
    const LANES: usize = 8;
    let mut peak = (0.0, 0.0);
    let mut k = 10;
    while k <= 1000 {
        let f: [f64; LANES] = std::array::from_fn(|j| 0.02 * (k + j) as f64);
        let a = amplitudes_at(x, dt, f);
        for j in 0..LANES {
            if k + j <= 1000 && a[j] > peak.0 {
                peak = (a[j], f[j]);
            }
        }
        k += LANES;
    }
    peak.1
}

#[cfg(test)]
mod tests;
