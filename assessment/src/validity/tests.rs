//! Unit tests of the validity flags.

use super::*;

/// Amplitude of the sinusoid at `f` Hz in `x` (step `dt`).
fn amplitude_at(x: &[f64], dt: f64, f: f64) -> f64 {
    amplitudes_at(x, dt, [f])[0]
}

const RATING: DriveRating = DriveRating {
    continuous_torque_nm: 200.0,
    k_t: 7.15,
    k_vr: 2.0e6,
    gear_efficiency: 0.7,
};

#[test]
fn the_thermal_flag_compares_the_rms_torque_with_the_continuous_rating() {
    // A torque of amplitude A in whole cycles has the RMS A/√2 (closed form): 270 N·m
    // gives 190.9 N·m, clear against 200; 290 N·m gives 205.1 N·m, raised. The current is
    // the torque over k_t.
    for (amplitude, raised) in [(270.0, false), (290.0, true)] {
        let mut f = Flagger::new(1e-3, 0.06, RATING);
        for k in 0..4000 {
            let t = amplitude * (std::f64::consts::TAU * k as f64 * 1e-3).sin();
            f.push(&FlagSample {
                torque: t,
                ..Default::default()
            });
        }
        let th = f.finish(&Comfort::default()).thermal;
        let rms = amplitude / 2f64.sqrt();
        assert!((th.torque_rms_nm - rms).abs() < 1e-9 * rms, "{th:?}");
        assert!((th.current_rms_a - rms / 7.15).abs() < 1e-9 * rms);
        assert_eq!(th.raised, raised, "{th:?}");
    }
}

#[test]
fn the_chopper_threshold_is_what_one_tilt_returns_through_the_gear() {
    // A bar held at δ_a = 2.4° twisted by 1.0° against the body: M = k_vr·1.0°, one tilt
    // stores ½·M·δ_a = 731 J, the gear passes η = 0.7 of it, 512 J. 0.5 kJ in the chopper
    // is clear, 0.55 kJ raises the flag.
    let (d, tw) = (2.4f64.to_radians(), 1.0f64.to_radians());
    let want = 0.7 * 0.5 * 2.0e6 * tw * d;
    for (p_chop, raised) in [(500.0, false), (550.0, true)] {
        let mut f = Flagger::new(1e-3, 0.06, RATING);
        for _ in 0..1000 {
            f.push(&FlagSample {
                delta_a: d,
                bar_twist: tw,
                chopper_power: p_chop,
                ..Default::default()
            });
        }
        let c = f.finish(&Comfort::default()).chopper;
        assert!((c.threshold_j - want).abs() < 1e-9 * want, "{c:?}");
        assert!((c.energy_j - p_chop).abs() < 1e-6, "{c:?}");
        assert_eq!(c.raised, raised);
    }
}

#[test]
fn the_goertzel_amplitude_is_that_of_a_whole_number_of_cycles() {
    // 0.7·cos(2π·2t + 0.3) over 2 s: four whole cycles, so the correlation at 2 Hz is
    // exactly the amplitude and at 3 Hz (orthogonal over the window) exactly zero.
    let dt = 1e-3;
    let x: Vec<f64> = (0..2000)
        .map(|k| 0.7 * (std::f64::consts::TAU * 2.0 * k as f64 * dt + 0.3).cos())
        .collect();
    assert!((amplitude_at(&x, dt, 2.0) - 0.7).abs() < 1e-9);
    assert!(amplitude_at(&x, dt, 3.0) < 1e-9);
    // On the 0.02 Hz grid the image at −2 Hz tilts the main lobe: the peak is found
    // within a tenth of a hertz (the window resolves 0.5 Hz).
    assert!((spectral_peak(&x, dt) - 2.0).abs() <= 0.1);
}

#[test]
fn a_sinusoid_is_found_with_its_amplitude_and_frequency() {
    let dt = 1e-3;
    // 0.5° at 1.3 Hz on top of a slow ramp (a transition's quasi-static error).
    let e: Vec<f64> = (0..16_000)
        .map(|k| {
            let t = k as f64 * dt;
            0.5f64.to_radians() * (std::f64::consts::TAU * 1.3 * t).sin() + 1e-3 * t
        })
        .collect();
    // A reference that is steady except for a ramp from 6 to 8 s: windows at 0, 2, 4 s and
    // from just after 10 s (2 s after the ramp): 10-12 and 12-14 s (the next would end
    // after 16 s).
    let r: Vec<f64> = (0..16_000)
        .map(|k| (k as f64 * dt - 6.0).clamp(0.0, 2.0))
        .collect();
    let o = oscillation(&e, &r, dt);
    assert!(o.raised);
    assert_eq!(o.windows, 5, "{o:?}");
    // x − LP(x) at 1.3 Hz: the 0.3 Hz low-pass still passes 5 % at about −160°, so the
    // high-pass shows up to 1.05 times the amplitude, plus what is left of the ramp's
    // filter transient: within 10 %.
    assert!((o.amplitude_deg - 0.5).abs() < 0.05, "{o:?}");
    assert!((o.frequency_hz - 1.3).abs() < 0.05, "{o:?}");
    // Below the threshold: clear, amplitude still reported.
    let small: Vec<f64> = e.iter().map(|v| v * 0.1).collect();
    let o = oscillation(&small, &r, dt);
    assert!(!o.raised && o.amplitude_deg > 0.04, "{o:?}");
    // Above the threshold but not sustained: the amplitude halves in the later windows.
    let fading: Vec<f64> = e
        .iter()
        .enumerate()
        .map(|(k, v)| if k >= 10_000 { 0.4 * v } else { *v })
        .collect();
    let o = oscillation(&fading, &r, dt);
    assert!(!o.raised && o.amplitude_ratio < 0.7, "{o:?}");
}

/// An oscillation that grows (an unstable loop's, 0.6 Hz from 1° to 8° over 14 s) is raised,
/// though its windows' amplitudes differ by far more than a limit cycle's; one that decays as
/// fast is not.
#[test]
fn a_growing_oscillation_is_raised_and_a_decaying_one_is_not() {
    let dt = 1e-3;
    let n = 14_000;
    let r = vec![0.0; n];
    let wave = |k: usize, amp_deg: f64| {
        amp_deg.to_radians() * (std::f64::consts::TAU * 0.6 * k as f64 * dt).sin()
    };
    let growing: Vec<f64> = (0..n)
        .map(|k| wave(k, 1.0 + 7.0 * k as f64 / n as f64))
        .collect();
    let o = oscillation(&growing, &r, dt);
    assert!(o.raised, "{o:?}");
    assert!(o.amplitude_ratio < 0.7 && o.decay_ratio >= 0.7, "{o:?}");
    // The flag reads the error high-passed (the error less its 0.3 Hz second-order
    // Butterworth low-pass), whose gain at 0.6 Hz is |1 − H(jΩ)| at Ω = f/fc = 2:
    // |−Ω² + j√2·Ω| / |1 − Ω² + j√2·Ω| = 1.188. The largest window is the last, 2 s ending at
    // 14 s, where the wave's amplitude goes from 7° to 8°; the √2·RMS of a sine over ωT rad
    // lies within √(1 ± 1/(ωT)) of its amplitude.
    let w2 = 4.0f64;
    let gain = ((w2 * w2 + 2.0 * w2) / ((1.0 - w2).powi(2) + 2.0 * w2)).sqrt();
    let wt = std::f64::consts::TAU * 0.6 * 2.0;
    let (lo, hi) = (
        7.0 * gain * (1.0 - 1.0 / wt).sqrt(),
        8.0 * gain * (1.0 + 1.0 / wt).sqrt(),
    );
    assert!(
        o.amplitude_deg > lo && o.amplitude_deg < hi,
        "{lo} {hi} {o:?}"
    );
    assert!((o.frequency_hz - 0.6).abs() < 0.3, "{o:?}");
    let decaying: Vec<f64> = (0..n)
        .map(|k| wave(k, 8.0 - 7.0 * k as f64 / n as f64))
        .collect();
    let o = oscillation(&decaying, &r, dt);
    assert!(!o.raised && o.decay_ratio < 0.7, "{o:?}");
}
