//! `tiltsim bench`'s report as a Markdown table, with the ratios, the load and the floors
//! under it.

use cosim::ipc::placement::Reason;

use crate::bench::{ExchangeFloors, Report};

/// The report as a Markdown table.
pub fn table(r: &Report) -> String {
    use std::fmt::Write as _;
    let mut s = format!(
        "tiltsim bench: {} for {} s simulated per configuration on {} CPUs{}\n\
         machine: {}, {} logical CPUs, Linux {}\n\n\
         | transport | master | wait | realtime | placement | ticks | overhead p50 (µs) | p99 (µs) | iceoryx2 floor per tick, best–worst set (µs) | overhead / floor, median of rounds | plant round trip − compute p50 (µs) | round trip p99 (µs) | wall (s) | CPU (s) |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        r.scenario,
        r.duration_s,
        r.cpus,
        if r.hogs > 0 {
            format!(", beside {} CPU hog(s)", r.hogs)
        } else {
            String::new()
        },
        r.machine.cpu_model, r.machine.logical_cpus, r.machine.kernel
    );
    for c in &r.configs {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {:.2} | {:.2} | {} | {} | {:.2} | {:.2} | {:.3} | {:.2} |",
            c.transport,
            c.master,
            c.wait,
            if c.realtime { "yes" } else { "-" },
            c.placement.map_or("-", Reason::name),
            c.ticks,
            c.overhead_p50_us,
            c.overhead_p99_us,
            c.exchange_floor_us
                .zip(c.exchange_floor_worst_us)
                .map_or("-".into(), |(f, w)| format!("{f:.2}–{w:.2}")),
            c.overhead_over_floor
                .map_or("-".into(), |f| format!("{f:.2}")),
            c.plant_round_trip_p50_us,
            c.plant_round_trip_p99_us,
            c.wall_s,
            c.cpu_s
        );
    }
    footer(&mut s, r);
    s
}

/// The lines under the table: the ratios, the load, the floors.
fn footer(s: &mut String, r: &Report) {
    use std::fmt::Write as _;
    let ratio = |x: Option<f64>| x.map_or("withheld".into(), |x| format!("{x:.2}"));
    let load = |x: Option<f64>| x.map_or("unknown".into(), |x| format!("{x:.2}"));
    let _ = writeln!(
        s,
        "\nplant round trip (best p50 over the IPC configurations): {:.2} µs\n\
         load average (1 min): {} before, {} after, on {} CPUs\n\
         wall time, median of {} round(s): in-process {:.3} s, IPC (gauss-seidel, adaptive) {:.3} s, ratio {}; \
         IPC (jacobi, adaptive) {:.3} s, ratio {}",
        r.ipc_round_trip_floor_us,
        load(r.load_average.before),
        load(r.load_average.after),
        r.cpus,
        r.wall_rounds.in_process_s.len(),
        r.wall_in_process_s,
        r.wall_ipc_s,
        ratio(r.ipc_over_in_process),
        r.wall_ipc_jacobi_s,
        ratio(r.jacobi_ipc_over_in_process)
    );
    if let Some(rt) = &r.realtime {
        let _ = writeln!(
            s,
            "under SCHED_FIFO (--realtime), median of {} round(s): IPC (gauss-seidel, adaptive) \
             {:.3} s, ratio {}; IPC (jacobi, adaptive) {:.3} s, ratio {} (to the in-process run \
             under the ordinary policy)",
            r.wall_rounds.ipc_gauss_seidel_realtime_s.len(),
            rt.wall_ipc_s,
            ratio(rt.ipc_over_in_process),
            rt.wall_ipc_jacobi_s,
            ratio(rt.jacobi_ipc_over_in_process)
        );
    }
    if let Some(why) = &r.ratio_withheld {
        let _ = writeln!(
            s,
            "ratios withheld: {why}; a ratio from these runs would measure the machine, not \
             tiltsim (rerun on a quieter machine, or with more --repeat)"
        );
    }
    if let Some(f) = &r.machine_floors {
        let _ = writeln!(
            s,
            "machine floors (iceoryx2 ping-pong, {} B, one way p50): {:.2} µs between processes \
             busy-waiting on their own CPUs, {:.2} µs handing one CPU from one process to another",
            f.payload_bytes, f.one_way_cross_cpu_us, f.one_way_same_cpu_us
        );
    }
    if let Some(f) = &r.exchange_floors {
        let every: Vec<String> = f.every.iter().map(u64::to_string).collect();
        let ((a, b), (c, d)) = (f.in_turn_us(), f.all_at_once_us());
        let _ = writeln!(
            s,
            "iceoryx2 floor per tick (an echo per participant, asked every {} ticks, placed and \
             waiting as an adaptive run; {} sets of fresh processes after each of {} round(s), \
             {} ticks each): p50 {a:.2}-{b:.2} µs one exchange after the other (gauss-seidel), \
             {c:.2}-{d:.2} µs all at once (jacobi)",
            every.join("/"),
            f.sets_per_round,
            f.rounds(),
            f.ticks,
        );
        round_ratios(s, r, f);
    }
}

/// Each round's overhead over the best floor set measured right after it, per row set beside
/// a floor.
fn round_ratios(s: &mut String, r: &Report, f: &ExchangeFloors) {
    use std::fmt::Write as _;
    for c in r.configs.iter().filter(|c| c.overhead_over_floor.is_some()) {
        let each: Vec<String> = c
            .rounds
            .iter()
            .enumerate()
            .map(|(i, round)| {
                let floor = f
                    .round_best_us(c.master, i)
                    .map_or("-".into(), |x| format!("{x:.2}"));
                let ratio = round
                    .overhead_over_floor
                    .map_or("-".into(), |x| format!("{x:.2}"));
                format!("{:.2} / {floor} µs = {ratio}", round.overhead_p50_us)
            })
            .collect();
        let _ = writeln!(
            s,
            "overhead over the floor measured right after it, {} {}{}, each round: {}",
            c.transport,
            c.master,
            if c.realtime { " realtime" } else { "" },
            each.join("; ")
        );
    }
}
