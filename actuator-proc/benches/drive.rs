//! Wall time per simulated millisecond of the actuator and the accuracy of its switched
//! electrics: a tilt profile like the paper's curve (ramp to 2.4°, hold, ramp back) against
//! the bar, run with
//! * the switched model integrated event by event (the default),
//! * the switched model at its 1 µs fixed step,
//! * the averaged model at 20 µs,
//!
//! and, for accuracy, the switched model at a 0.05 µs fixed step as the reference: bar angle
//! and mean torque at every millisecond, the phase-current peak of every millisecond and the
//! energy drawn from the link, each model's largest and RMS difference from the reference.
//!
//! `cargo bench -p actuator-proc --bench drive` (`-- --quick`: the first 4.8 s of the profile);
//! `DRIVE_WINDOW=FROM:TO` also prints each millisecond FROM..TO of the reference and the two
//! switched models (torque, phase-current peak, speed, commutations so far).

use std::time::Instant;

use actuator_proc::{Bldc, BldcParams, DcLinkParams, Electrics, SwitchedIntegration};

/// Per-millisecond record of one run.
struct Run {
    delta: Vec<f64>,
    torque: Vec<f64>,
    peak: Vec<f64>,
    speed: Vec<f64>,
    comm: Vec<u64>,
    energy_in: f64,
    wall_s: f64,
    per_ms_us: Vec<f64>,
    bldc: Bldc,
}

fn profile(ms: u32) -> impl Iterator<Item = f64> {
    (0..ms).map(|k| {
        let t = k as f64 * 1e-3;
        let ramp = ((t - 3.0) / 2.4).clamp(0.0, 1.0) - ((t - 11.4) / 2.4).clamp(0.0, 1.0);
        2.4f64.to_radians() * ramp
    })
}

fn run(p: &BldcParams, kind: Electrics, ms: u32) -> Run {
    let mut m = Bldc::new(p, &DcLinkParams::default(), kind, 2.0e6);
    let mut r = Run {
        delta: Vec::new(),
        torque: Vec::new(),
        peak: Vec::new(),
        speed: Vec::new(),
        comm: Vec::new(),
        energy_in: 0.0,
        wall_s: 0.0,
        per_ms_us: Vec::new(),
        bldc: m.clone(),
    };
    let started = Instant::now();
    for cmd in profile(ms) {
        let t0 = Instant::now();
        let tel = m.advance(cmd, 0.4 * cmd, 1e-3);
        r.per_ms_us.push(t0.elapsed().as_secs_f64() * 1e6);
        r.delta.push(tel.delta_a);
        r.torque.push(tel.torque);
        r.peak.push(tel.phase_current_peak);
        r.speed.push(tel.speed);
        r.comm.push(m.event_stats().commutations);
    }
    r.wall_s = started.elapsed().as_secs_f64();
    r.energy_in = m.energy.electrical_in;
    r.bldc = m;
    r
}

fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q) as usize]
}

/// Largest and RMS difference of two series, and the millisecond of the largest.
fn diff(a: &[f64], b: &[f64]) -> (f64, f64, usize) {
    let (mut max, mut sq, mut at) = (0.0f64, 0.0, 0);
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        let d = (x - y).abs();
        if d > max {
            max = d;
            at = k;
        }
        sq += d * d;
    }
    (max, (sq / a.len() as f64).sqrt(), at)
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let ms = if quick { 4_800 } else { 16_800 };
    let event = BldcParams::default();
    let fixed = BldcParams {
        switched_integration: SwitchedIntegration::FixedStep,
        ..BldcParams::default()
    };
    let reference = BldcParams {
        dt_switched_s: 5e-8,
        ..fixed.clone()
    };
    let models = [
        ("switched, event-driven", &event, Electrics::Switched),
        ("switched, fixed 1 us", &fixed, Electrics::Switched),
        ("averaged, fixed 20 us", &event, Electrics::Averaged),
    ];
    let mut runs = Vec::new();
    for (name, p, kind) in models {
        // Three runs each; the timing of the fastest, the records of the last (all identical).
        let mut best = f64::MAX;
        let mut per_ms = Vec::new();
        let mut last = None;
        for _ in 0..3 {
            let r = run(p, kind, ms);
            best = best.min(r.wall_s);
            per_ms.extend_from_slice(&r.per_ms_us);
            last = Some(r);
        }
        let r = last.unwrap();
        println!(
            "{name}: {:.2} us wall per simulated ms (p50), p99 {:.2} us; a {:.1} s run takes {:.3} s",
            quantile(&per_ms, 0.5),
            quantile(&per_ms, 0.99),
            ms as f64 * 1e-3,
            best
        );
        let st = r.bldc.event_stats();
        if st.segments > 0 {
            let per = 1.0 / ms as f64;
            println!(
                "  per simulated ms: {:.1} segments, {:.1} switchings, {:.3} commutations, {:.1} DC-link events, {:.1} fixed steps",
                st.segments as f64 * per,
                st.switchings as f64 * per,
                st.commutations as f64 * per,
                st.link_events as f64 * per,
                st.fixed_steps as f64 * per
            );
        }
        runs.push((name, r));
    }
    let t0 = Instant::now();
    let refr = run(&reference, Electrics::Switched, ms);
    println!(
        "reference: switched at a 0.05 us fixed step, {:.1} s wall",
        t0.elapsed().as_secs_f64()
    );
    if let Ok(w) = std::env::var("DRIVE_WINDOW") {
        let (a, b) = w.split_once(':').unwrap();
        for k in a.parse::<usize>().unwrap()..b.parse::<usize>().unwrap() {
            println!("{k} ref {:.3} ev {:.3} fx {:.3}  peak {:.3} {:.3} {:.3} w {:.5} {:.5} {:.5} comm {}", refr.torque[k], runs[0].1.torque[k], runs[1].1.torque[k], refr.peak[k], runs[0].1.peak[k], runs[1].1.peak[k], refr.speed[k], runs[0].1.speed[k], runs[1].1.speed[k], runs[0].1.comm[k]);
        }
    }
    println!("error against the reference (largest / RMS over every ms):");
    for (name, r) in &runs {
        let (dm, dr, da) = diff(&r.delta, &refr.delta);
        let (tm, tr, ta) = diff(&r.torque, &refr.torque);
        let (pm, pr, pa) = diff(&r.peak, &refr.peak);
        println!(
            "  {name}: bar angle {:.3e} (ms {da}) / {:.3e} rad, torque {:.3} (ms {ta}) / {:.3} N·m, phase-current peak {:.3} (ms {pa}) / {:.3} A, energy drawn {:+.4} % ({:.1} J of {:.1} J)",
            dm,
            dr,
            tm,
            tr,
            pm,
            pr,
            100.0 * (r.energy_in / refr.energy_in - 1.0),
            r.energy_in - refr.energy_in,
            refr.energy_in
        );
    }
}
