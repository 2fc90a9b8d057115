//! An MPC update allocates no buffer of its own once the controller runs: the filter, the
//! prediction, the horizon's references and the moves are written into buffers set up with
//! the controller. Three allocations per update remain, inside `DefaultSolver::solve`: by
//! Clarabel 0.11's source, each solve resets its timers and inserts their nested timers
//! again, which its settings cannot turn off. The test holds an update to those three, so that
//! no allocation of ours comes back unnoticed.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use controller_proc::{Controller, ControllerInit, ControllerSettings, InputShape, Mode};
use tiltsim_protocol::msg::ToController;
use tiltsim_protocol::Participant;
use vehicle_model::{TrackParams, VehicleParams};

/// Counts the allocations of the thread that asks for it.
struct Counting;

thread_local! {
    static COUNT: Cell<Option<u64>> = const { Cell::new(None) };
}

// SAFETY: every call is passed on to the system allocator unchanged; only a thread-local
// counter is touched besides.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = COUNT.try_with(|c| c.set(c.get().map(|n| n + 1)));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = COUNT.try_with(|c| c.set(c.get().map(|n| n + 1)));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations per update inside Clarabel's `solve` (its timers).
const CLARABEL_PER_SOLVE: u64 = 3;

#[global_allocator]
static ALLOC: Counting = Counting;

/// The allocations `f` makes on this thread.
fn allocations(f: impl FnOnce()) -> u64 {
    COUNT.with(|c| c.set(Some(0)));
    f();
    COUNT.with(|c| c.replace(None)).unwrap_or(0)
}

fn mpc(preview: bool) -> Controller {
    let mut settings = ControllerSettings {
        mode: Mode::Mpc,
        ..Default::default()
    };
    settings.mpc.preview = preview;
    Controller::new(&ControllerInit {
        controller: settings,
        track: TrackParams::default(),
        vehicle: VehicleParams::default(),
        input_shape: InputShape::Hold,
        seed: 1,
    })
    .expect("the paper's MPC")
}

#[test]
fn an_mpc_update_allocates_no_more_than_the_solvers_timers() {
    for preview in [false, true] {
        let mut c = mpc(preview);
        let period = 0.05;
        let v = TrackParams::default().speed();
        let mut counts = Vec::new();
        for k in 0..400u64 {
            let input = ToController {
                t: period * k as f64,
                s: v * period * k as f64,
                theta_v_meas: 0.01 * (k as f64 * 0.1).sin(),
                ..Default::default()
            };
            let n = allocations(|| {
                c.step(&input);
            });
            counts.push(n);
        }
        // The first updates may size what Clarabel keeps for the QP forms it meets first.
        let most = counts[50..].iter().copied().max().unwrap_or(0);
        assert!(
            most <= CLARABEL_PER_SOLVE,
            "preview {preview}: allocations per update {counts:?}"
        );
    }
}
