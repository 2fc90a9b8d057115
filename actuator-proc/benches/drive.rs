//! Wall time per simulated millisecond of the actuator, switched (1 µs) and averaged (20 µs):
//! a tilt profile like the paper's curve (ramp to 2.4°, hold, ramp back) against the bar.
//!
//! `cargo bench -p actuator-proc --bench drive`

use std::time::Instant;

use actuator_proc::{Bldc, BldcParams, DcLinkParams, Electrics};

fn main() {
    let p = BldcParams::default();
    for kind in [Electrics::Switched, Electrics::Averaged] {
        let mut per_ms = Vec::new();
        let mut total = 0.0;
        for _ in 0..3 {
            let mut m = Bldc::new(&p, &DcLinkParams::default(), kind, 2.0e6);
            let started = Instant::now();
            for k in 0..16_800u32 {
                let t = k as f64 * 1e-3;
                let ramp = ((t - 3.0) / 2.4).clamp(0.0, 1.0) - ((t - 11.4) / 2.4).clamp(0.0, 1.0);
                let cmd = 2.4f64.to_radians() * ramp;
                let t0 = Instant::now();
                m.advance(cmd, 0.4 * cmd, 1e-3);
                per_ms.push(t0.elapsed().as_secs_f64() * 1e6);
            }
            total += started.elapsed().as_secs_f64();
        }
        per_ms.sort_by(f64::total_cmp);
        let q = |f: f64| per_ms[((per_ms.len() - 1) as f64 * f) as usize];
        println!(
            "{kind:?} (step {} us): {:.1} us wall per simulated ms (p50), p99 {:.1} us; a 16.8 s run takes {:.3} s",
            Bldc::new(&p, &DcLinkParams::default(), kind, 2.0e6).dt() * 1e6,
            q(0.5),
            q(0.99),
            total / 3.0
        );
    }
}
