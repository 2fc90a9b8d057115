//! The `Endpoint` contract, written once and run against both implementations: the plant in
//! this process (`InProcess`) and the plant as its own process over iceoryx2 (`IpcEndpoint`).
//! Every reply echoes its request's step and kind; a reply for another step is refused as
//! stale or out of order; a non-finite request is rejected naming the field, or held when the
//! request says so; a killed participant and a stalled one are named at the step they failed;
//! nothing is left in shared memory.

use std::time::{Duration, Instant};

use cosim::endpoint::{Endpoint, ProcessFault};
use cosim::ipc::{IpcHub, IpcSettings, Launch};
use cosim::msg::{FromPlant, Header, Message, ToPlant, FLAG_HELD, FLAG_HOLD_BAD_INPUT};
use cosim::wait::WaitStrategy;
use cosim::{InProcess, Kind, LinkError, Role};
use plant_proc::{Plant, PlantSettings};
use tiltsim_suite::{leftovers, prefix, tiltsim};

type Ep = Box<dyn Endpoint<ToPlant, FromPlant>>;

const DEADLINE: Duration = Duration::from_millis(300);

fn settings() -> PlantSettings {
    PlantSettings {
        vehicle: Default::default(),
        track: Default::default(),
        sensor: Default::default(),
        dt_s: 1e-3,
        seed: 1,
    }
}

/// A plant endpoint of each transport; the IPC one lives as long as its hub.
enum Transport {
    InProcess,
    Ipc(String),
}

fn endpoint(t: &Transport) -> (Ep, Option<IpcHub>) {
    match t {
        Transport::InProcess => (
            Box::new(InProcess::new(Plant::new(&settings())).with_deadline(DEADLINE)),
            None,
        ),
        Transport::Ipc(pfx) => {
            let hub = IpcHub::new(IpcSettings {
                prefix: pfx.clone(),
                wait: WaitStrategy::Adaptive,
                deadline: DEADLINE,
                ceiling: Duration::from_secs(60),
                participant_cpu: None,
            })
            .expect("hub");
            let launch = Launch {
                program: tiltsim(),
                args: vec![
                    "participant".into(),
                    "plant".into(),
                    "--params".into(),
                    serde_json::to_string(&settings()).unwrap().into(),
                ],
            };
            let ep = hub
                .spawn::<ToPlant, FromPlant>(Role::Plant, &launch, Duration::from_secs(10))
                .expect("spawn plant");
            (Box::new(ep), Some(hub))
        }
    }
}

fn req(step: u64, kind: Kind, delta_a: f64, flags: u32) -> ToPlant {
    let mut header = Header::new(step, kind);
    header.flags = flags;
    ToPlant { header, delta_a }
}

fn exchange(ep: &mut Ep, r: ToPlant) -> Result<FromPlant, LinkError> {
    ep.send(&r)?;
    ep.receive(r.header.step, Kind::from_raw(r.header.kind).unwrap())
}

/// The contract, for one transport.
fn contract(t: Transport) {
    let name = match &t {
        Transport::InProcess => "in-process",
        Transport::Ipc(_) => "ipc",
    };
    // Replies echo step and kind, in order.
    let (mut ep, hub) = endpoint(&t);
    let init = exchange(&mut ep, req(0, Kind::Init, 0.0, 0)).unwrap();
    assert_eq!(init.header().kind, Kind::Init as u32, "{name}");
    for k in 0..5 {
        let r = exchange(&mut ep, req(k, Kind::Step, 0.01, 0)).unwrap();
        assert_eq!(r.header().step, k, "{name}");
        assert_eq!(r.header().kind, Kind::Step as u32, "{name}");
        assert!(
            (r.t - (k + 1) as f64 * 1e-3).abs() < 1e-12,
            "{name}: t = {}",
            r.t
        );
    }
    // Waiting for another step than the reply carries: refused, never reused.
    ep.send(&req(5, Kind::Step, 0.01, 0)).unwrap();
    let e = ep.receive(6, Kind::Step).unwrap_err();
    assert!(
        matches!(e, LinkError::Stale { .. } | LinkError::OutOfOrder { .. }),
        "{name}: {e}"
    );
    assert_eq!(e.role(), Role::Plant);
    ep.shutdown();
    drop(ep);
    drop(hub);

    // A non-finite input: rejected naming the field, or held when asked.
    let (mut ep, hub) = endpoint(&t);
    exchange(&mut ep, req(0, Kind::Init, 0.0, 0)).unwrap();
    let e = exchange(&mut ep, req(0, Kind::Step, f64::NAN, 0)).unwrap_err();
    assert!(matches!(e, LinkError::BadInput { .. }), "{name}: {e}");
    assert!(e.to_string().contains("delta_a"), "{name}: {e}");
    ep.shutdown();
    drop(ep);
    drop(hub);
    let (mut ep, hub) = endpoint(&t);
    exchange(&mut ep, req(0, Kind::Init, 0.0, 0)).unwrap();
    exchange(&mut ep, req(0, Kind::Step, 0.01, FLAG_HOLD_BAD_INPUT)).unwrap();
    let held = exchange(&mut ep, req(1, Kind::Step, f64::NAN, FLAG_HOLD_BAD_INPUT)).unwrap();
    assert!(held.header().flags & FLAG_HELD != 0, "{name}");
    assert!(held.x.iter().all(|v| v.is_finite()), "{name}");
    ep.shutdown();
    drop(ep);
    drop(hub);

    // Killed: named as gone at the next exchange.
    let (mut ep, hub) = endpoint(&t);
    exchange(&mut ep, req(0, Kind::Init, 0.0, 0)).unwrap();
    ep.inject(ProcessFault::Kill);
    let e = exchange(&mut ep, req(0, Kind::Step, 0.0, 0)).unwrap_err();
    assert!(matches!(e, LinkError::Exited { .. }), "{name}: {e}");
    assert_eq!(e.role(), Role::Plant);
    ep.shutdown();
    drop(ep);
    drop(hub);

    // Stalled past the deadline: a timeout naming the participant, within a bounded wait.
    let (mut ep, hub) = endpoint(&t);
    exchange(&mut ep, req(0, Kind::Init, 0.0, 0)).unwrap();
    ep.inject(ProcessFault::Stall(Duration::from_secs(2)));
    let started = Instant::now();
    let e = exchange(&mut ep, req(0, Kind::Step, 0.0, 0)).unwrap_err();
    assert!(matches!(e, LinkError::Timeout { .. }), "{name}: {e}");
    assert!(e.to_string().contains("plant"), "{name}: {e}");
    assert!(started.elapsed() < Duration::from_secs(10), "{name}");
    ep.shutdown();
    drop(ep);
    drop(hub);
}

#[test]
fn in_process_endpoint_keeps_the_contract() {
    contract(Transport::InProcess);
}

#[test]
fn ipc_endpoint_keeps_the_contract() {
    let pfx = prefix("contract");
    contract(Transport::Ipc(pfx.clone()));
    cosim::ipc::remove_run_files(&pfx);
    assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
}
