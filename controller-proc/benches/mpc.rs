//! MPC solve time: the full controller update (Kalman filter, free response, Clarabel QP) in
//! closed loop with the discretised vehicle through the paper's ρ = 0.50 case, where the input
//! constraint is active, so both inactive and active QPs are timed.
//!
//! `cargo bench -p controller-proc --bench mpc`

use std::time::Instant;

use controller_proc::mpc::MpcInput;
use controller_proc::{
    ControllerInit, ControllerSettings, KalmanSettings, LinearModel, Mode, Mpc, MpcSettings,
};
use vehicle_model::{TrackParams, VehicleParams};

fn main() {
    let track = TrackParams::default();
    let v = track.speed();
    let model = LinearModel::new(&VehicleParams::default(), v);
    let period = 0.05;
    let mut times = Vec::new();
    let mut iters = Vec::new();
    let repeats = 30;
    for preview in [false, true] {
        for rep in 0..repeats {
            let s = MpcSettings {
                preview,
                ..Default::default()
            };
            let mut mpc = Mpc::new(
                &model,
                &s,
                &KalmanSettings::default(),
                period,
                3.5,
                controller_proc::InputShape::Hold,
            )
            .unwrap();
            // The tilt command of the paper's track at ρ = 0.50, from the controller's own
            // reference generator.
            let ctrl = controller_proc::Controller::new(&ControllerInit {
                controller: ControllerSettings {
                    mode: Mode::Passive,
                    rho: 0.5,
                    ..Default::default()
                },
                track: track.clone(),
                vehicle: VehicleParams::default(),
                input_shape: controller_proc::InputShape::Hold,
            })
            .unwrap();
            let d = model.discretise(period);
            let mut x = nalgebra::DMatrix::zeros(9, 1);
            let n = (track.length() / v / period) as usize;
            for k in 0..n {
                let pos = v * period * k as f64;
                let r: Vec<f64> = (1..=5)
                    .map(|i| {
                        ctrl.reference_at(if preview {
                            pos + v * period * i as f64
                        } else {
                            pos
                        })
                    })
                    .collect();
                let w = vec![ctrl.track_input_at(pos); 5];
                let xi = x[(1, 0)] + 1e-3 * ((k * 7 + rep) as f64).sin();
                let t0 = Instant::now();
                let u = mpc.step(&MpcInput { xi, r: &r, w: &w });
                times.push(t0.elapsed().as_secs_f64() * 1e6);
                iters.push(u.iterations as f64);
                let wk = nalgebra::DMatrix::from_column_slice(6, 1, &w[0]);
                x = &d.a * &x + &d.b * u.u + &d.g * wk;
            }
        }
    }
    let pct = |v: &mut Vec<f64>, p: f64| {
        v.sort_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * p).round() as usize]
    };
    println!(
        "MPC update (filter + QP), {} solves: p50 {:.1} us, p99 {:.1} us, max {:.1} us; Clarabel iterations p50 {:.0}, max {:.0}",
        times.len(),
        pct(&mut times, 0.5),
        pct(&mut times, 0.99),
        pct(&mut times, 1.0),
        pct(&mut iters, 0.5),
        pct(&mut iters, 1.0)
    );
}
