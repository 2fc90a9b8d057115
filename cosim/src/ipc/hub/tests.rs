//! The hub and its endpoints against participants in threads of this process.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use super::*;
use crate::endpoint::Endpoint;
use crate::msg::{FromController, Header, Kind, ToController};
use crate::participant::Participant;
use crate::wait::WaitStrategy;

/// Doubles the measurement, counts its steps and takes `pause` over each.
struct Doubler {
    steps: Arc<AtomicU64>,
    pause: Duration,
}
impl Participant for Doubler {
    type Input = ToController;
    type Output = FromController;
    const ROLE: Role = Role::Controller;
    fn initial_output(&mut self) -> FromController {
        FromController::default()
    }
    fn step(&mut self, i: &ToController) -> FromController {
        self.steps.fetch_add(1, Ordering::Relaxed);
        std::thread::sleep(self.pause);
        FromController {
            theta_v_hat: 2.0 * i.theta_v_meas,
            ..Default::default()
        }
    }
}

type ControllerEndpoint = IpcEndpoint<ToController, FromController>;

/// A hub under a prefix of its own and its endpoint to the controller, served by `model` in a
/// thread with the participant's side losing what `drops` says; returns the hub, the endpoint,
/// connected, and the serving thread.
fn served(
    model: Doubler,
    drops: DropPlan,
) -> (
    IpcHub,
    ControllerEndpoint,
    std::thread::JoinHandle<Result<(), IpcError>>,
) {
    let prefix = super::super::unique_prefix();
    let hub = IpcHub::new(IpcSettings {
        prefix: prefix.clone(),
        wait: WaitStrategy::Adaptive,
        deadline: Duration::from_millis(500),
        ceiling: Duration::from_secs(600),
        participant_cpu: None,
    })
    .unwrap();
    let mut ep = hub
        .attach::<ToController, FromController>(Role::Controller)
        .unwrap();
    let serving = std::thread::spawn(move || {
        super::super::serve::serve_dropping(
            model,
            &prefix,
            WaitStrategy::Adaptive,
            crate::wait::SPIN_POLLS,
            super::super::IDLE_LIMIT,
            |_| {},
            drops,
        )
    });
    assert!(ep.await_connection(Duration::from_secs(600), None).unwrap());
    (hub, ep, serving)
}

/// Stops the participant, waits for its thread and checks that no file of the run is left.
fn stop(
    hub: IpcHub,
    ep: ControllerEndpoint,
    serving: std::thread::JoinHandle<Result<(), IpcError>>,
) {
    let prefix = hub.settings.prefix.clone();
    let _ = super::super::publish(
        &ep.publisher,
        ToController {
            header: Header::new(u64::MAX, Kind::Stop),
            ..Default::default()
        },
    );
    serving.join().unwrap().unwrap();
    drop(ep);
    drop(hub);
    super::super::remove_run_files(&prefix);
    assert!(super::super::leftover_files(&prefix).is_empty());
}

/// Step `k`'s request, measuring `k`.
fn request(k: u64) -> ToController {
    ToController {
        header: Header::new(k, Kind::Step),
        theta_v_meas: k as f64,
        ..Default::default()
    }
}

#[test]
fn a_lost_request_and_a_lost_reply_are_resent_and_the_model_steps_once_each() {
    let steps = Arc::new(AtomicU64::new(0));
    let model = Doubler {
        steps: steps.clone(),
        pause: Duration::ZERO,
    };
    // The orchestrator loses its first sending of step 3's request, the participant its
    // first sending of step 5's reply.
    let (hub, mut ep, serving) = served(model, DropPlan::new(vec![(Role::Controller, false, 5)]));
    ep.drops = DropPlan::new(vec![(Role::Controller, true, 3)]);
    for k in 0..8u64 {
        ep.send(&request(k)).unwrap();
        let reply = ep.receive(k, Kind::Step).unwrap();
        assert_eq!(reply.theta_v_hat, 2.0 * k as f64, "step {k}");
    }
    // Every step computed once: the repeat of step 5 was answered from the last reply.
    assert_eq!(steps.load(Ordering::Relaxed), 8);
    let c = ep.counts().lost_samples;
    assert_eq!((c.lost_requests, c.lost_replies), (1, 1), "{c:?}");
    // One re-send per loss; more only if a slow answer met a look under heavy load.
    assert!(c.resends >= 2 && c.repeats_answered >= 1, "{c:?}");
    stop(hub, ep, serving);
}

#[test]
fn a_request_sent_ahead_is_answered_after_the_pending_one_and_each_reply_goes_to_its_receive() {
    // Each step lasts long enough for the next request to wait behind it.
    let model = Doubler {
        steps: Arc::default(),
        pause: Duration::from_millis(2),
    };
    let (hub, mut ep, serving) = served(model, DropPlan::default());
    ep.send(&request(0)).unwrap();
    for k in 0..6u64 {
        // Step k + 1 goes while k is pending; only one may wait ahead.
        assert!(ep.send_ahead(&request(k + 1)).unwrap(), "step {}", k + 1);
        assert!(!ep.send_ahead(&request(k + 2)).unwrap());
        if k % 2 == 1 {
            // Both replies are in before k's is taken: k + 1's is kept for its own receive.
            while ep.status.words().answered.load(Ordering::Acquire) < 2 * (k + 1) + 2 {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
        let reply = ep.receive(k, Kind::Step).unwrap();
        assert_eq!(reply.theta_v_hat, 2.0 * k as f64, "step {k}");
    }
    let reply = ep.receive(6, Kind::Step).unwrap();
    assert_eq!(reply.theta_v_hat, 12.0);
    let c = ep.counts().lost_samples;
    assert_eq!(
        (c.lost_requests, c.lost_replies, c.resends),
        (0, 0, 0),
        "{c:?}"
    );
    stop(hub, ep, serving);
}

#[test]
fn a_participant_cues_the_one_named_next_once_it_has_answered() {
    let model = Doubler {
        steps: Arc::new(AtomicU64::new(0)),
        pause: Duration::ZERO,
    };
    let (hub, mut ep, serving) = served(model, DropPlan::default());
    let plant = Status::create(&hub.settings.prefix, Role::Plant).unwrap();
    for k in 0..4u64 {
        // The plant asked after the controller, for the same tick, on even ticks only; the
        // name goes with the request, so the one of the next request cannot be taken for it.
        ep.set_cue_next((k % 2 == 0).then_some((Role::Plant, k)));
        ep.send(&request(k)).unwrap();
        ep.receive(k, Kind::Step).unwrap();
    }
    // Step 2's cue was written before step 3 was taken, so before its reply came.
    assert_eq!(plant.words().cue.cue.load(Ordering::Acquire), 3);
    let c = ep.counts().cue;
    assert_eq!((c.given, c.steps_aside), (2, 0), "{c:?}");
    drop(plant);
    stop(hub, ep, serving);
}
