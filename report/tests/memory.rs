//! The analysis and the figures of a run need memory bounded by what they keep, not by the
//! run's length: the same work on ten times the rows and ten times the timing trace must not
//! take ten times the heap. The heap is counted by this test binary's global allocator (its
//! own process, so nothing else allocates through it), and no clock is read.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use cosim::Role;
use tiltsim_formats::table::{Recorder, Row, Rows};
use tiltsim_master::free::trace::{StepTrace, TraceHead, TraceWriter, TIMING_CSV};
use tiltsim_scenario::scenario::Scenario;

/// The system allocator, counting the bytes live and the most ever live.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract is passed on to the system allocator unchanged.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `alloc` above with this `layout`.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// The heap `work` needs above what was live when it started (bytes).
fn peak_heap(work: impl FnOnce()) -> usize {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    work();
    PEAK.load(Ordering::Relaxed) - base
}

/// paper-lqg over `ticks` ticks, its rows in `dir/timeseries.csv` and a free run's timing
/// trace in `dir/timing.csv` (every step on time, each reading its producers' latest).
fn write_run(dir: &Path, ticks: u64) -> Scenario {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/paper-lqg.toml");
    let s = Scenario::load(&file).expect("paper-lqg loads");
    let duration = format!("{}", ticks as f64 * s.run.dt_s);
    let s = s
        .with_setting("run.duration_s", &duration)
        .expect("a duration");
    assert_eq!(s.steps(), ticks);
    std::fs::create_dir_all(dir).expect("a directory");
    let mut rows = Recorder::create(&dir.join("timeseries.csv")).expect("timeseries.csv");
    for k in 0..ticks {
        let t = k as f64 * s.run.dt_s;
        let mut r = Row {
            time: t,
            step: k,
            s: t * s.track.speed(),
            ..Row::default()
        };
        r.theta_v = 0.01 * (0.7 * t).sin();
        r.lat_acc = 0.5 * (1.3 * t).sin();
        r.delta_a = 0.02 * (0.4 * t).cos();
        rows.write(&r).expect("a row");
    }
    rows.finish().expect("timeseries.csv written");
    let period = s.controller_period_ticks();
    let head = TraceHead {
        dt_s: s.run.dt_s,
        steps: ticks,
        controller_period_ticks: period,
        start_ns: 0,
    };
    let mut trace = TraceWriter::create(&dir.join(TIMING_CSV), &head).expect("timing.csv");
    let dt_ns = (s.run.dt_s * 1e9) as u64;
    for k in 0..ticks {
        let at = |role, from| StepTrace {
            role,
            step: k,
            from,
            due_ns: k * dt_ns,
            read_ns: k * dt_ns + 1000 + k % 7 * 100,
            compute_end_ns: k * dt_ns + 20_000,
            publish_ns: k * dt_ns + 30_000,
        };
        let held = (k / period * period) as i64;
        if k.is_multiple_of(period) {
            trace
                .push(&at(Role::Controller, [Some(k as i64 - 1), None, None]))
                .expect("a step");
        }
        let actuator = [Some(k as i64 - 1), None, Some(held)];
        trace.push(&at(Role::Actuator, actuator)).expect("a step");
        let plant = [None, Some(k as i64 - 1), None];
        trace.push(&at(Role::Plant, plant)).expect("a step");
    }
    trace.finish().expect("timing.csv written");
    s
}

/// The heap of the analysis, the run's figures and the timing figures of `dir`.
fn analysis_heap(s: &Scenario, dir: &Path) -> usize {
    peak_heap(|| {
        tiltsim_report::analysis::assess(s, Rows::File(dir)).expect("assessed");
        tiltsim_report::analysis::write_plots(s, dir).expect("figures drawn");
        let timing = tiltsim_report::analysis::write_timing_plots(s, dir).expect("timing");
        assert_eq!(timing.len(), 4, "both timing figures, svg and png");
    })
}

#[test]
fn analysis_and_figures_do_not_grow_with_the_rows() {
    let root: PathBuf = std::env::temp_dir().join(format!("tiltsim-memory-{}", std::process::id()));
    // Both lengths draw envelopes of the same 40 000 points per line (blocks of 3 and of 30
    // ticks), so what may differ is the analysis' own state, which is the same whatever the
    // length but for one value per 5 s ride window (a few kilobytes here), and the digits of
    // the figures' text.
    let short = 60_000;
    let long = 10 * short;
    let s_short = write_run(&root.join("short"), short);
    let s_long = write_run(&root.join("long"), long);
    let small = analysis_heap(&s_short, &root.join("short"));
    let large = analysis_heap(&s_long, &root.join("long"));
    let _ = std::fs::remove_dir_all(&root);
    eprintln!("peak heap: {short} ticks {small} B, {long} ticks {large} B");
    // Anything kept per row or per tick, 8 bytes a value at the least, would add 4.3 MB for
    // one column over the 540 000 more ticks: 1 MiB leaves room for the figures' text and
    // nothing kept per row.
    assert!(
        large <= small + (1 << 20),
        "{long} ticks took {large} B of heap at most, {short} ticks {small} B: the analysis or \
         the figures keep something per row"
    );
    assert!(small > 0);
}
