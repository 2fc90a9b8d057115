//! Communication points on the FMU's base-tick grid.
//!
//! An instance counts time in whole base ticks (`dt_s` of its `resources/tiltsim.json`); a
//! master's `currentCommunicationPoint` and the end of its step are read as the ticks they lie
//! on. A master that adds its step sizes up in floating point drifts off the grid: 16 800 sums
//! of 0.001 give 16.79999999999755 (2.5e-12 s short, after which OMSimulator asks for a last
//! step of 2.45e-12 s), an hour of them 2.7e-7 s. A point within [`TOLERANCE`] of a tick
//! (a thousandth of the tick, 1 µs on a 1 ms grid) is that tick; anything farther off is not
//! a point of the grid and is refused.

use tiltsim_fmi::layout::Stepping;

/// How far from a grid point (as a fraction of the base tick) a master's time may lie.
pub const TOLERANCE: f64 = 1e-3;

/// The tick that time `t` (s) lies on, on a grid of `dt` s; `None` when `t` is not finite,
/// negative beyond the tolerance, or more than [`TOLERANCE`] · `dt` from every grid point.
pub fn tick_of(t: f64, dt: f64) -> Option<u64> {
    if !t.is_finite() || !dt.is_finite() || dt <= 0.0 {
        return None;
    }
    let n = (t / dt).round();
    if n < 0.0 || n >= u64::MAX as f64 || (t - n * dt).abs() > TOLERANCE * dt {
        return None;
    }
    Some(n as u64)
}

/// A communication step as ticks: from tick `from` up to (not including) tick `to`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Span {
    /// The tick the step starts on.
    pub from: u64,
    /// The tick it ends on (`from` for a step shorter than the tolerance).
    pub to: u64,
}

impl Span {
    /// The ticks in `from..to` on which a participant of period `period` (ticks) computes:
    /// the multiples of its period, as the lock-step master steps it.
    pub fn due(self, period: u64) -> impl Iterator<Item = u64> {
        let p = period.max(1);
        let first = self.from.div_ceil(p) * p;
        (first..self.to).step_by(p as usize)
    }
}

/// Reads `fmi*DoStep(t, h)` of an instance at tick `at` on a grid of `dt` s whose participant
/// computes every `period` ticks; `stepping` says which steps it takes. The error says what
/// is wrong with `t` or `h` and what is allowed.
pub fn span(
    t: f64,
    h: f64,
    at: u64,
    dt: f64,
    period: u64,
    stepping: Stepping,
) -> Result<Span, String> {
    if tick_of(t, dt) != Some(at) {
        return Err(format!(
            "currentCommunicationPoint {t} s: the FMU is at {} s (tick {at} of {dt} s)",
            cosim::time::tick_time(at, dt)
        ));
    }
    if !h.is_finite() || h < 0.0 {
        return Err(format!(
            "communicationStepSize {h} s: allowed a step of zero or more seconds"
        ));
    }
    // The messages are made only on the way out: a step that is taken costs no formatting.
    let takes = || match stepping {
        Stepping::Tick => format!("its base tick {dt} s"),
        Stepping::Period => format!(
            "its fixed period {} s (exported with --steps period; an FMU exported with \
             --steps tick takes any whole multiple of {dt} s)",
            dt * period as f64
        ),
    };
    let Some(to) = tick_of(t + h, dt) else {
        return Err(format!(
            "communicationStepSize {h} s: the step from {t} s ends between the FMU's ticks; \
             this FMU steps with {} or a whole multiple of it",
            takes()
        ));
    };
    let n = to.saturating_sub(at);
    let p = period.max(1);
    if stepping == Stepping::Period && !(at.is_multiple_of(p) && n.is_multiple_of(p)) {
        return Err(format!(
            "communicationStepSize {h} s at {t} s: this FMU steps with {} or a whole multiple of it, from a multiple of it",
            takes()
        ));
    }
    Ok(Span {
        from: at,
        to: at + n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 1e-3;

    /// The steps of a master that adds 1 ms up in floating point to `end_s`, then takes the
    /// remainder to `end_s` as one last step (OMSimulator's way to reach its stop time).
    fn accumulated(ticks: u64, end_s: f64) -> Vec<(f64, f64)> {
        let mut steps = Vec::new();
        let mut t = 0.0f64;
        for _ in 0..ticks {
            steps.push((t, DT));
            t += DT;
        }
        steps.push((t, end_s - t));
        steps
    }

    #[test]
    fn a_master_summing_one_millisecond_steps_runs_to_its_stop_time() {
        let steps = accumulated(16_800, 16.8);
        // The sum is off the grid by a few ulps, and the last step is that drift.
        let (t_last, h_last) = *steps.last().unwrap();
        assert_eq!(t_last, 16.79999999999755);
        assert!(h_last > 0.0 && h_last < 1e-11, "{h_last}");
        let mut at = 0u64;
        let mut computed = 0u64;
        for (i, &(t, h)) in steps.iter().enumerate() {
            let s = span(t, h, at, DT, 1, Stepping::Tick)
                .unwrap_or_else(|e| panic!("step {i} ({t}, {h}): {e}"));
            computed += s.due(1).count() as u64;
            at = s.to;
        }
        // Exactly 16 800 ticks computed, the tiny step none, and the FMU at 16.8 s.
        assert_eq!(at, 16_800);
        assert_eq!(computed, 16_800);
        assert_eq!(cosim::time::tick_time(at, DT), 16.8);
        // The tiny last step is a zero-tick step.
        assert_eq!(
            span(t_last, h_last, 16_800, DT, 1, Stepping::Tick).unwrap(),
            Span {
                from: 16_800,
                to: 16_800
            }
        );
    }

    #[test]
    fn an_hour_of_summed_steps_stays_on_the_grid() {
        let mut t = 0.0f64;
        for k in 0..3_600_000u64 {
            assert_eq!(tick_of(t, DT), Some(k), "{t}");
            t += DT;
        }
        assert_eq!(tick_of(t, DT), Some(3_600_000));
    }

    #[test]
    fn a_slower_participant_computes_on_its_own_ticks_whatever_the_step() {
        // Period 50: due at 0, 50, 100, … whether stepped by 1, 7 or 50 ticks.
        for step in [1u64, 7, 50, 120] {
            let mut due = Vec::new();
            let mut at = 0;
            while at < 200 {
                let t = cosim::time::tick_time(at, DT);
                let s = span(t, step as f64 * DT, at, DT, 50, Stepping::Tick).unwrap();
                due.extend(s.due(50));
                at = s.to;
            }
            let want: Vec<u64> = (0..at).filter(|k| k % 50 == 0).collect();
            assert_eq!(due, want, "step of {step} ticks");
        }
    }

    #[test]
    fn steps_off_the_grid_and_backwards_are_refused_naming_what_is_allowed() {
        // Half a tick.
        let e = span(0.0, 0.0005, 0, DT, 1, Stepping::Tick).unwrap_err();
        assert!(
            e.contains("0.0005") && e.contains("base tick 0.001 s"),
            "{e}"
        );
        // A point the FMU is not at.
        let e = span(0.002, DT, 1, DT, 1, Stepping::Tick).unwrap_err();
        assert!(e.contains("the FMU is at 0.001 s"), "{e}");
        // Negative and non-finite sizes.
        for h in [-DT, f64::NAN, f64::INFINITY] {
            let e = span(0.0, h, 0, DT, 1, Stepping::Tick).unwrap_err();
            assert!(e.contains("zero or more"), "{h}: {e}");
        }
        assert_eq!(tick_of(-0.5, DT), None);
        assert_eq!(tick_of(f64::NAN, DT), None);
        // Just inside and just outside the tolerance.
        assert_eq!(tick_of(0.005 + 0.9e-6, DT), Some(5));
        assert_eq!(tick_of(0.005 + 1.1e-6, DT), None);
    }

    #[test]
    fn the_exact_period_mode_takes_whole_periods_only() {
        let p = 50;
        assert_eq!(
            span(0.0, 0.05, 0, DT, p, Stepping::Period).unwrap(),
            Span { from: 0, to: 50 }
        );
        assert_eq!(
            span(0.05, 0.1, 50, DT, p, Stepping::Period).unwrap(),
            Span { from: 50, to: 150 }
        );
        // One tick is not a period.
        let e = span(0.0, DT, 0, DT, p, Stepping::Period).unwrap_err();
        assert!(e.contains("fixed period 0.05 s"), "{e}");
        // A zero-length step (a master reaching its stop time) is taken.
        assert_eq!(
            span(0.1, 1e-13, 100, DT, p, Stepping::Period).unwrap(),
            Span { from: 100, to: 100 }
        );
    }
}
