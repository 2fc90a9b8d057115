//! A peer on the run's network that has no business in the run, for the network tests: it
//! connects to the run's address as an attacker would and tries everything a Zenoh peer can.
//!
//! `rogue-peer --connect HOST:PORT --run KEY --as plain|wrong|ROLE [--secret S]`
//! - `plain`: Zenoh over plain TCP, no credentials;
//! - `wrong`: TLS with credentials of another secret;
//! - `ROLE` (plant, actuator, controller): TLS with a valid certificate of that role, made
//!   from the run's secret `S` (what a stolen certificate of that role gives).
//!
//! While its standard input stays open it reads everything under `tiltsim/**` and stops
//! reading at the first sample (a stalled reader holds its link's queue), floods forged
//! replies, notes, liveliness tokens and requests on every role's keys of run `KEY`, asks for
//! offers and joins, and declares the run's queryables to answer them itself. When standard
//! input closes it prints what it got as JSON on one line and exits.

use std::io::Read;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use zenoh::handlers::FifoChannel;
use zenoh::qos::CongestionControl;
use zenoh::sample::Locality;
use zenoh::Wait;

use cosim::Role;
use tiltsim_net::credentials::{self, Holder};
use tiltsim_net::session::{self, Security, Tuning};
use tiltsim_protocol::address::Address;

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// What `--as` says the peer holds.
fn security_of(args: &[String], mode: &str) -> Security {
    let none = || serde_json::json!({ "enabled": false });
    match mode {
        "plain" => Security::PlainForMeasurement,
        "wrong" => Security::Tls {
            credentials: credentials::issue("not-the-run's-secret", Holder::Role(Role::Plant))
                .expect("credentials"),
            acl: none(),
        },
        role => {
            let r = Role::parse(role).expect("--as plain|wrong|ROLE");
            let secret = arg(args, "--secret").expect("--secret");
            Security::Tls {
                credentials: credentials::issue(&secret, Holder::Role(r)).expect("credentials"),
                acl: none(),
            }
        }
    }
}

/// Everything the peer holds open while it attacks.
struct Held {
    _subscribers: Vec<zenoh::pubsub::Subscriber<()>>,
    _queryables: Vec<zenoh::query::Queryable<()>>,
    _tokens: Vec<zenoh::liveliness::LivelinessToken>,
    publishers: Vec<zenoh::pubsub::Publisher<'static>>,
}

/// Subscribes to everything (stopping at the first sample from others), watches every
/// liveliness token, answers the run's offer and joins, shows itself alive as every role and
/// declares a publisher on every role's keys of run `run`.
fn declare(s: &zenoh::Session, run: &str, got: &Arc<AtomicU64>) -> Held {
    let mut subscribers = Vec::new();
    let seen = got.clone();
    // Only what comes from others counts (its own samples and queries stay out of its sight).
    subscribers.extend(
        s.declare_subscriber("tiltsim/**")
            .allowed_origin(Locality::Remote)
            .callback(move |_| {
                seen.fetch_add(1, Ordering::SeqCst);
                loop {
                    std::thread::sleep(Duration::from_secs(3600));
                }
            })
            .wait(),
    );
    // Its own tokens (declared below) are not news.
    let own_token = format!("tiltsim/run/{run}/");
    let seen = got.clone();
    subscribers.extend(
        s.liveliness()
            .declare_subscriber("tiltsim/**")
            .callback(move |sample: zenoh::sample::Sample| {
                let k = sample.key_expr().as_str();
                let own = k.starts_with(&own_token)
                    && Role::ALL
                        .iter()
                        .any(|r| k.ends_with(&format!("/{}/alive", r.name())));
                if !own {
                    seen.fetch_add(1, Ordering::SeqCst);
                }
            })
            .wait(),
    );
    let mut queryables = Vec::new();
    for key in [
        format!("tiltsim/run/{run}/offer"),
        format!("tiltsim/run/{run}/join/*"),
    ] {
        queryables.extend(
            s.declare_queryable(key)
                .allowed_origin(Locality::Remote)
                .callback(|q| {
                    let _ = q.reply(q.key_expr().clone(), b"{}".to_vec()).wait();
                })
                .wait(),
        );
    }
    let mut tokens = Vec::new();
    let mut publishers = Vec::new();
    for r in Role::ALL {
        let n = r.name();
        tokens.extend(
            s.liveliness()
                .declare_token(format!("tiltsim/run/{run}/{n}/alive"))
                .wait(),
        );
        for what in ["reply", "note", "request", "control"] {
            publishers.extend(
                s.declare_publisher(format!("tiltsim/run/{run}/{n}/{what}"))
                    .allowed_destination(Locality::Remote)
                    .congestion_control(CongestionControl::Drop)
                    .wait(),
            );
        }
    }
    Held {
        _subscribers: subscribers,
        _queryables: queryables,
        _tokens: tokens,
        publishers,
    }
}

/// Floods forged samples and asks for offers and joins until `stop` says so; the puts sent.
fn flood(
    s: &zenoh::Session,
    run: &str,
    held: &Held,
    answered: &AtomicU64,
    stop: &std::sync::mpsc::Receiver<()>,
) -> u64 {
    let forged = vec![0xA5u8; 400];
    let mut sent = 0u64;
    loop {
        for p in &held.publishers {
            if p.put(forged.clone()).wait().is_ok() {
                sent += 1;
            }
        }
        for key in [
            "tiltsim/run/*/offer".to_string(),
            format!("tiltsim/run/{run}/join/controller"),
        ] {
            if let Ok(replies) = s
                .get(key)
                .allowed_destination(Locality::Remote)
                .with(FifoChannel::new(16))
                .timeout(Duration::from_millis(20))
                .wait()
            {
                while let Ok(r) = replies.recv() {
                    if r.result().is_ok() {
                        answered.fetch_add(1, Ordering::SeqCst);
                    }
                }
            }
        }
        if stop.recv_timeout(Duration::from_millis(1)).is_ok() {
            return sent;
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let connect = Address::parse(&arg(&args, "--connect").expect("--connect")).expect("address");
    let run = arg(&args, "--run").expect("--run");
    let mode = arg(&args, "--as").expect("--as");
    let s = session::open(
        &session::End::Connect(connect),
        Duration::from_secs(10),
        &security_of(&args, &mode),
        Tuning::default(),
    )
    .expect("a Zenoh session (the link may still fail; the session retries)");
    let got = Arc::new(AtomicU64::new(0));
    let held = declare(&s, &run, &got);
    let answered = AtomicU64::new(0);
    // Standard input closing ends the attack.
    let (tx, rx) = std::sync::mpsc::channel::<()>();
    std::thread::spawn(move || {
        let mut sink = Vec::new();
        let _ = std::io::stdin().read_to_end(&mut sink);
        let _ = tx.send(());
    });
    let sent = flood(&s, &run, &held, &answered, &rx);
    println!(
        "{}",
        serde_json::json!({
            "mode": mode,
            "samples_received": got.load(Ordering::SeqCst),
            "query_answers": answered.load(Ordering::SeqCst),
            "puts_sent": sent,
        })
    );
    // The subscriber's callback may be parked forever: leave without closing the session.
    std::process::exit(0);
}
