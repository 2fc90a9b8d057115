//! CPU time of 100 000 ticks of 1 ms: the whole car (36 states, RK4 on x' = A x + B u, the
//! track sampled under each wheelset at the stage times) against the half vehicle (9 states,
//! RK4 on its right-hand side, as the plant integrates it). Each figure is the mean of 20
//! runs of 100 000 ticks (the process CPU clock counts in 10 ms). Prints, asserts nothing.
//!
//! `cargo run --release -p vehicle-model --example full_car_cost`

use std::hint::black_box;
use std::time::Instant;

use vehicle_model::full_car::inputs::{inputs_from_track, uniform};
use vehicle_model::full_car::{FullCar, FullCarParams, FullCarSim, WheelsetInput};
use vehicle_model::vehicle::State;
use vehicle_model::{Track, TrackInput, TrackParams, Vehicle, VehicleParams};

/// Process CPU time (user + system) in seconds from /proc/self/stat (Linux; 0 elsewhere).
fn cpu_seconds() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let after = &s[s.rfind(')').map_or(0, |i| i + 2)..];
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks: f64 = f[11].parse::<f64>().unwrap_or(0.0) + f[12].parse::<f64>().unwrap_or(0.0);
    ticks / 100.0 // USER_HZ
}

const REPS: usize = 20;

fn measure(name: &str, n: usize, mut tick: impl FnMut(usize)) {
    let (c0, w0) = (cpu_seconds(), Instant::now());
    for _ in 0..REPS {
        for k in 0..n {
            tick(k);
        }
    }
    let r = REPS as f64;
    let (c, w) = ((cpu_seconds() - c0) / r, w0.elapsed().as_secs_f64() / r);
    println!(
        "{name}: {n} ticks, CPU {c:.3} s ({:.2} µs/tick), wall {w:.3} s",
        1e6 * c / n as f64
    );
}

fn main() {
    const N: usize = 100_000;
    let h = 1e-3;
    let tp = TrackParams {
        curve_m: 4000.0,
        ..TrackParams::default()
    };
    let track = Track::new(&tp, 1);
    let v = tp.speed();

    let veh = Vehicle::new(VehicleParams::default(), v);
    let input_at = |t: f64| {
        let p = track.at(v * t);
        TrackInput {
            curvature: p.curvature,
            cant: p.cant,
            cant_rate: v * p.dcant_ds,
            cant_acc: v * v * p.d2cant_ds2,
            y_o: p.y_o,
            dy_o: v * p.dy_o_ds,
        }
    };
    let mut x = State::zeros();
    measure("half vehicle, RK4 on its right-hand side", N, |k| {
        let t = k as f64 * h;
        let f = |x: &State, t: f64| veh.deriv(x, 0.0, &input_at(t));
        let k1 = f(&x, t);
        let k2 = f(&(x + k1 * (h / 2.0)), t + h / 2.0);
        let k3 = f(&(x + k2 * (h / 2.0)), t + h / 2.0);
        let k4 = f(&(x + k3 * h), t + h);
        x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
    });
    black_box(x);

    let p = FullCarParams::default();
    let mut sim = FullCarSim::new(FullCar::new(p.clone()), v);
    measure(
        "whole car, RK4 on A x + B u, track under each wheelset",
        N,
        |k| {
            let t0 = k as f64 * h;
            sim.step(h, [0.0; 2], |tau| {
                inputs_from_track(&p, &track, v * (t0 + tau), v)
            });
        },
    );
    black_box(sim.state());

    let mut sim = FullCarSim::new(FullCar::new(p), v);
    let w = uniform(WheelsetInput {
        curvature: 1e-3,
        cant: 0.1,
        ..Default::default()
    });
    measure("whole car, RK4 on A x + B u, inputs given", N, |_| {
        sim.step(h, [0.0; 2], |_| w);
    });
    black_box(sim.state());
}
