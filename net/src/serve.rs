//! The participant's side: find the run, prove the secret, take the settings, serve.
//!
//! `tiltsim participant ROLE --connect ENDPOINT [--run KEY] [--secret-file PATH]
//! [--join-timeout-s S] [--lease-ms MS]`; without `--secret-file` the secret is read from
//! `TILTSIM_SECRET`. The participant ends, leaving nothing behind, when the run stops it, when
//! the run's orchestrator leaves (its liveliness token disappears: a closed connection at
//! once, a cut link when the lease runs out), or when a fault the run schedules kills it.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use zenoh::handlers::FifoChannel;
use zenoh::qos::CongestionControl;
use zenoh::sample::{Sample, SampleKind};
use zenoh::Wait;

use cosim::msg::{now_ns, Kind, Message, FLAG_CRASH, FLAG_FREE_START, PROTOCOL_VERSION};
use cosim::participant::Served;
use cosim::{Participant, Role};

use tiltsim_protocol::address::{Address, ADDRESS_FORM};

use crate::credentials::{self, Holder};
use crate::join::{clock_offset, proof, welcome_is_genuine, ClockSample, Hello, Offer, Welcome};
use crate::{acl, host_name, keys, new_secret, session, zenoh_error, NetError};

/// The participant's command line after `participant ROLE`.
#[derive(Debug, Clone, PartialEq)]
pub struct JoinArgs {
    /// The run's address.
    pub connect: Address,
    /// The run's key, when more than one run may answer at that address.
    pub run: Option<String>,
    /// The run's secret.
    pub secret: String,
    /// How long to look for the run.
    pub join_timeout: Duration,
    /// Zenoh's link lease.
    pub lease: Duration,
}

/// The variable that holds the run's secret when no `--secret-file` is given.
pub const SECRET_VAR: &str = "TILTSIM_SECRET";

impl JoinArgs {
    /// Whether a participant's arguments ask for the network (`--connect`).
    pub fn wanted(args: &[String]) -> bool {
        args.iter().any(|a| a == "--connect")
    }

    /// Parses the arguments; `secret_var` is the value of [`SECRET_VAR`], if set.
    pub fn parse(args: &[String], secret_var: Option<String>) -> Result<Self, String> {
        let mut connect = None;
        let mut run = None;
        let mut secret_file = None;
        let mut join_timeout = Duration::from_secs(60);
        let mut lease = Duration::from_millis(1000);
        let mut it = args.iter();
        while let Some(a) = it.next() {
            let mut value = |name: &str| {
                it.next()
                    .cloned()
                    .ok_or_else(|| format!("{name} needs a value"))
            };
            match a.as_str() {
                "--connect" => connect = Some(value("--connect")?),
                "--run" => run = Some(value("--run")?),
                "--secret-file" => secret_file = Some(value("--secret-file")?),
                "--join-timeout-s" => {
                    let v = value("--join-timeout-s")?;
                    let s: f64 = v
                        .parse()
                        .ok()
                        .filter(|s: &f64| s.is_finite() && *s > 0.0 && *s <= 86_400.0)
                        .ok_or_else(|| {
                            format!("--join-timeout-s {v}: expected seconds in (0, 86400]")
                        })?;
                    join_timeout = Duration::from_secs_f64(s);
                }
                "--lease-ms" => {
                    let v = value("--lease-ms")?;
                    let ms: u64 = v
                        .parse()
                        .ok()
                        .filter(|m| (100..=600_000).contains(m))
                        .ok_or_else(|| format!("--lease-ms {v}: expected 100 to 600000"))?;
                    lease = Duration::from_millis(ms);
                }
                other => {
                    return Err(format!(
                        "unknown argument `{other}`; expected --connect, --run, --secret-file, --join-timeout-s, --lease-ms"
                    ))
                }
            }
        }
        let connect: String =
            connect.ok_or("missing --connect ADDRESS (for example 10.0.0.1:7447)")?;
        let connect = Address::parse(&connect)
            .map_err(|why| format!("--connect {connect}: {why}; expected {ADDRESS_FORM}"))?;
        let secret = match secret_file {
            Some(path) => std::fs::read_to_string(&path)
                .map_err(|e| format!("--secret-file {path}: {e}"))?
                .trim()
                .to_string(),
            None => secret_var.map(|s| s.trim().to_string()).unwrap_or_default(),
        };
        if secret.is_empty() {
            return Err(format!(
                "no credentials: give --secret-file PATH or set {SECRET_VAR} to the run's secret"
            ));
        }
        Ok(JoinArgs {
            connect,
            run,
            secret,
            join_timeout,
            lease,
        })
    }
}

/// Entry point of a participant on another host: joins the run, builds the model from the
/// settings the run sends with `make`, and serves until stopped.
pub fn participant_main<S, P>(
    role: Role,
    args: &[String],
    make: impl FnOnce(S) -> Result<P, String>,
) -> Result<(), NetError>
where
    S: serde::de::DeserializeOwned,
    P: Participant,
{
    let a = JoinArgs::parse(args, std::env::var(SECRET_VAR).ok())
        .map_err(|e| NetError::Participant(format!("{}: {e}", role.process_name())))?;
    if role != P::ROLE {
        return Err(NetError::Participant(format!(
            "{role}: the model serves {}",
            P::ROLE
        )));
    }
    let credentials = credentials::issue(&a.secret, Holder::Role(role))
        .map_err(|e| NetError::Participant(format!("{}: {e}", role.process_name())))?;
    let acl = acl::participant(&credentials.authority_id);
    let session = session::open(
        &session::End::Connect(a.connect.clone()),
        a.lease,
        &session::Security::Tls { credentials, acl },
        session::Tuning::default(),
    )?;
    let result = join_and_serve(&session, role, &a, make);
    let _ = session.close().wait();
    result
}

fn fail(role: Role, what: impl std::fmt::Display) -> NetError {
    NetError::Participant(format!("{}: {what}", role.process_name()))
}

/// Finds the run's offer at the address: the one run named, or the only one awaiting `role`.
fn find_offer(session: &zenoh::Session, role: Role, a: &JoinArgs) -> Result<Offer, NetError> {
    let key = match &a.run {
        Some(run) => keys::offer(run),
        None => keys::ANY_OFFER.to_string(),
    };
    let start = Instant::now();
    loop {
        let replies = session
            .get(&key)
            .timeout(Duration::from_millis(500))
            .wait()
            .map_err(zenoh_error("asking for the run's offer"))?;
        let mut offers = Vec::new();
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                if let Ok(o) = serde_json::from_slice::<Offer>(&sample.payload().to_bytes()) {
                    offers.push(o);
                }
            }
        }
        let awaiting: Vec<Offer> = offers
            .iter()
            .filter(|o| o.awaited.contains(&role))
            .cloned()
            .collect();
        match awaiting.len() {
            1 => return Ok(awaiting[0].clone()),
            // The only run there, or the one named, awaits no such role (it has joined
            // already, or the run has none on another host): its answer to the hello says
            // which, by name.
            0 if offers.len() == 1 => return Ok(offers.remove(0)),
            0 => {}
            many => {
                let runs: Vec<&str> = awaiting.iter().map(|o| o.run.as_str()).collect();
                return Err(fail(
                    role,
                    format!(
                        "{many} runs at {} await a {role}: name one with --run ({})",
                        a.connect,
                        runs.join(", ")
                    ),
                ));
            }
        }
        if start.elapsed() >= a.join_timeout {
            let seen = if offers.is_empty() {
                why_no_answer(&a.connect)
            } else {
                format!(
                    "the run{} at {} await{} no {role}",
                    if offers.len() > 1 { "s" } else { "" },
                    a.connect,
                    if offers.len() > 1 { "" } else { "s" }
                )
            };
            return Err(fail(
                role,
                format!(
                    "found no run to join within {:.0} s: {seen}",
                    a.join_timeout.as_secs_f64()
                ),
            ));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Why no run answered at `at`: nothing listens there (the host answers a datagram to the
/// port with "port unreachable"), or something does but no QUIC session with this secret's
/// credentials opened (TLS does not say which end refused, or why).
fn why_no_answer(at: &Address) -> String {
    use std::net::{ToSocketAddrs, UdpSocket};
    let closed = at
        .to_string()
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .and_then(|sa| {
            let any = if sa.is_ipv4() { "0.0.0.0:0" } else { "[::]:0" };
            let s = UdpSocket::bind(any).ok()?;
            s.connect(sa).ok()?;
            s.set_read_timeout(Some(Duration::from_millis(500))).ok()?;
            s.send(&[0u8]).ok()?;
            let mut b = [0u8; 1];
            Some(matches!(s.recv(&mut b), Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused))
        })
        .unwrap_or(false);
    if closed {
        format!("no run answered at {at}: nothing listens there (check the address, the port, and that the run has started)")
    } else {
        format!(
            "no run answered at {at}: nothing there opened a session with this secret's credentials (the run's secret does not match, the run has not started, or a firewall drops UDP to the port)"
        )
    }
}

/// Measures the offset of the orchestrator's clock from this host's.
fn measure_clock(session: &zenoh::Session, run: &str) -> (i64, u64) {
    let mut samples = Vec::new();
    for _ in 0..16 {
        let t0 = now_ns();
        let Ok(replies) = session
            .get(keys::clock(run))
            .timeout(Duration::from_millis(500))
            .wait()
        else {
            continue;
        };
        if let Ok(reply) = replies.recv() {
            let t3 = now_ns();
            if let Ok(sample) = reply.result() {
                let b = sample.payload().to_bytes();
                if let Ok(a) = <[u8; 8]>::try_from(&b[..]) {
                    samples.push(ClockSample {
                        t0,
                        t: u64::from_le_bytes(a),
                        t3,
                    });
                }
            }
        }
    }
    clock_offset(&samples).unwrap_or((0, 0))
}

/// What a joined participant holds of the run: its ports, the process faults ordered, the
/// orchestrator's presence.
struct Ports {
    requests: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<Sample>>,
    replies: zenoh::pubsub::Publisher<'static>,
    stall_ns: Arc<AtomicU64>,
    orchestrator_gone: Arc<AtomicBool>,
    _control: zenoh::pubsub::Subscriber<()>,
    _watch: zenoh::pubsub::Subscriber<()>,
    _token: zenoh::liveliness::LivelinessToken,
}

/// Declares everything the run will send to, or watch of, this participant, before the
/// hello: the run's first request cannot overtake the subscription it is meant for.
fn declare(session: &zenoh::Session, run: &str, role: Role) -> Result<Ports, NetError> {
    let stall_ns = Arc::new(AtomicU64::new(0));
    let stall = stall_ns.clone();
    let orchestrator_gone = Arc::new(AtomicBool::new(false));
    let gone = orchestrator_gone.clone();
    Ok(Ports {
        requests: session
            .declare_subscriber(keys::request(run, role))
            .with(FifoChannel::new(1024))
            .wait()
            .map_err(zenoh_error("declaring the request subscriber"))?,
        _control: session
            .declare_subscriber(keys::control(run, role))
            .callback(move |s: Sample| {
                let order = String::from_utf8_lossy(&s.payload().to_bytes()).into_owned();
                if order == "kill" {
                    // A scheduled `kill` fault: end as SIGKILL ends a process on one host.
                    // SAFETY: kill with this process's own pid has no preconditions.
                    unsafe { libc::kill(libc::getpid(), libc::SIGKILL) };
                } else if let Some(ns) = order.strip_prefix("stall ").and_then(|n| n.parse().ok()) {
                    stall.store(ns, Ordering::Release);
                }
            })
            .wait()
            .map_err(zenoh_error("declaring the control subscriber"))?,
        replies: session
            .declare_publisher(keys::reply(run, role))
            .congestion_control(CongestionControl::Block)
            .express(true)
            .wait()
            .map_err(zenoh_error("declaring the reply publisher"))?,
        _watch: session
            .liveliness()
            .declare_subscriber(keys::orchestrator_alive(run))
            .callback(move |s: Sample| {
                if s.kind() == SampleKind::Delete {
                    gone.store(true, Ordering::Release);
                }
            })
            .wait()
            .map_err(zenoh_error("watching the run's orchestrator"))?,
        _token: session
            .liveliness()
            .declare_token(keys::alive(run, role))
            .wait()
            .map_err(zenoh_error("declaring this participant's liveliness"))?,
        stall_ns,
        orchestrator_gone,
    })
}

/// Sends the hello to the run of `offer` and returns the settings it answers with, or why it
/// refused.
fn hello(
    session: &zenoh::Session,
    role: Role,
    a: &JoinArgs,
    offer: &Offer,
    clock: (i64, u64),
) -> Result<String, NetError> {
    let run = &offer.run;
    let nonce = new_secret().map_err(|e| fail(role, format!("drawing a nonce: {e}")))?;
    let hello = Hello {
        role,
        protocol_version: PROTOCOL_VERSION,
        host: host_name(),
        pid: std::process::id(),
        proof: proof(&a.secret, run, role, &offer.nonce, &nonce),
        nonce: nonce.clone(),
        clock_offset_ns: clock.0,
        clock_rtt_ns: clock.1,
    };
    // The run's answer may be slow on a loaded host (its queryable shares Zenoh's threads with
    // whatever else reaches it), and a hello is not repeated: the run admits a role once. So
    // the answer is awaited as long as the run is looked for.
    let answer = session
        .get(keys::join(run, role))
        .payload(serde_json::to_vec(&hello).unwrap_or_default())
        .timeout(a.join_timeout.max(Duration::from_secs(5)))
        .wait()
        .map_err(zenoh_error("asking to join"))?
        .recv()
        .map_err(|_| {
            fail(
                role,
                format!(
                    "the run at {} did not answer the hello within {:.0} s",
                    a.connect,
                    a.join_timeout.max(Duration::from_secs(5)).as_secs_f64()
                ),
            )
        })?;
    let welcome: Welcome = answer
        .result()
        .ok()
        .and_then(|s| serde_json::from_slice(&s.payload().to_bytes()).ok())
        .ok_or_else(|| fail(role, "the run's answer to the hello is not a welcome"))?;
    if !welcome.accepted {
        return Err(fail(
            role,
            format!("refused by the run: {}", welcome.reason),
        ));
    }
    if !welcome_is_genuine(&a.secret, run, role, (&offer.nonce, &nonce), &welcome) {
        return Err(fail(
            role,
            format!(
                "the answer from {} does not prove the run's secret: not the run's orchestrator",
                a.connect
            ),
        ));
    }
    Ok(welcome.params)
}

fn join_and_serve<S, P>(
    session: &zenoh::Session,
    role: Role,
    a: &JoinArgs,
    make: impl FnOnce(S) -> Result<P, String>,
) -> Result<(), NetError>
where
    S: serde::de::DeserializeOwned,
    P: Participant,
{
    let offer = find_offer(session, role, a)?;
    let run = offer.run.clone();
    let clock = measure_clock(session, &run);
    let ports = declare(session, &run, role)?;
    let params = hello(session, role, a, &offer, clock)?;
    let note = |text: String| {
        let _ = session
            .put(keys::note(&run, role), text.into_bytes())
            .wait();
    };
    let settings: S = serde_json::from_str(&params).map_err(|e| {
        note(format!("its settings do not parse: {e}"));
        fail(role, format!("bad settings from the run: {e}"))
    })?;
    let model = make(settings).map_err(|e| {
        note(e.clone());
        fail(role, e)
    })?;
    serve_lockstep(Served::new(model), &ports, clock.0, &note).map_err(|why| fail(role, why))
}

/// Serves requests in lock-step until the run stops this participant; a free run's start
/// hands over to [`Free`]. What ends it otherwise is noted to the run and returned.
fn serve_lockstep<P: Participant>(
    mut served: Served<P>,
    ports: &Ports,
    clock_offset_ns: i64,
    note: &dyn Fn(String),
) -> Result<(), String> {
    let failed = |why: String| {
        note(why.clone());
        why
    };
    let mut last_step: Option<u64> = None;
    let cpu0 = cpu_s();
    loop {
        if ports.orchestrator_gone.load(Ordering::Acquire) {
            return Err("the run's orchestrator left".into());
        }
        let sample = match ports.requests.recv_timeout(Duration::from_millis(100)) {
            Ok(Some(s)) => s,
            Ok(None) => continue,
            Err(e) => return Err(format!("receiving: {e}")),
        };
        let req = P::Input::from_wire(&sample.payload().to_bytes())
            .map_err(|e| failed(format!("a request it cannot read: {e}")))?;
        let h = *req.header();
        match Kind::from_raw(h.kind) {
            Some(Kind::Stop) => {
                note(format!("stopped cpu_s={:.6}", cpu_s() - cpu0));
                return Ok(());
            }
            Some(Kind::Init) => last_step = None,
            Some(Kind::Step) if h.flags & FLAG_FREE_START != 0 => {
                // The start of a free run: from here the participant keeps its own clock.
                let free = Free {
                    requests: &ports.requests,
                    replies: &ports.replies,
                    stall_ns: &ports.stall_ns,
                    orchestrator_gone: &ports.orchestrator_gone,
                    clock_offset_ns,
                };
                return free.serve(&mut served, req).map_err(failed);
            }
            Some(Kind::Step) => {
                if let Some(l) = last_step.filter(|&l| h.step <= l) {
                    return Err(failed(format!("step {} after step {l}", h.step)));
                }
                last_step = Some(h.step);
            }
            None => return Err(failed(format!("a request of kind {}", h.kind))),
        }
        if h.flags & FLAG_CRASH != 0 {
            // A scheduled `crash` fault: die as a crashing process does.
            std::process::abort();
        }
        let stall = ports.stall_ns.swap(0, Ordering::AcqRel);
        if stall > 0 {
            std::thread::sleep(Duration::from_nanos(stall));
        }
        let mut reply = served.answer(&req);
        if let Some(why) = served.model.failure() {
            return Err(failed(format!("failed: {why}")));
        }
        reply.header_mut().attempt = h.attempt;
        ports
            .replies
            .put(reply.to_wire())
            .wait()
            .map_err(|e| format!("sending step {}: {e}", h.step))?;
    }
}

/// A participant running free over the network: step `j` is due at `start + j·period` on the
/// orchestrator's clock, which is this host's plus the offset measured at joining; otherwise
/// as on one host (`cosim::ipc`'s free running): sleep until due, drain the requests and keep
/// the newest, step, publish at once. The reply's instants are this host's; the orchestrator
/// moves them onto its clock with the same offset.
struct Free<'a> {
    requests: &'a zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<Sample>>,
    replies: &'a zenoh::pubsub::Publisher<'static>,
    stall_ns: &'a AtomicU64,
    orchestrator_gone: &'a AtomicBool,
    clock_offset_ns: i64,
}

impl Free<'_> {
    fn serve<P: Participant>(&self, served: &mut Served<P>, first: P::Input) -> Result<(), String> {
        let c = first.header().clock;
        let start = (c.start_ns as i128 - self.clock_offset_ns as i128).max(0) as u64;
        let period = c.period_ns.max(1);
        let ticks = u64::from(c.period_ticks).max(1);
        let busy_ns = u64::from(c.busy_us) * 1000;
        let mut input = first;
        let mut relay = 0u64;
        for j in 0u64.. {
            let due = start + j * period;
            while now_ns() < due {
                cosim::wait::sleep_until_ns(due);
            }
            loop {
                let sample = match self.requests.try_recv() {
                    Ok(Some(s)) => s,
                    Ok(None) => break,
                    Err(e) => return Err(format!("receiving: {e}")),
                };
                let got =
                    P::Input::from_wire(&sample.payload().to_bytes()).map_err(|e| e.to_string())?;
                match Kind::from_raw(got.header().kind) {
                    Some(Kind::Stop) => return Ok(()),
                    Some(Kind::Step) => {
                        if got.header().flags & FLAG_CRASH != 0 {
                            std::process::abort();
                        }
                        input = got;
                        relay = got.header().relay;
                    }
                    _ => {}
                }
            }
            if self.orchestrator_gone.load(Ordering::Acquire) {
                return Err("the run's orchestrator left".into());
            }
            let stall = self.stall_ns.swap(0, Ordering::AcqRel);
            if stall > 0 {
                std::thread::sleep(Duration::from_nanos(stall));
            }
            let reply = served.answer_free(&input, j * ticks, relay, busy_ns);
            if let Some(why) = served.model.failure() {
                return Err(format!("failed: {why}"));
            }
            self.replies
                .put(reply.to_wire())
                .wait()
                .map_err(|e| format!("sending step {}: {e}", j * ticks))?;
        }
        Ok(())
    }
}

/// CPU time of this process, user + system (s).
fn cpu_s() -> f64 {
    // SAFETY: an all-zero rusage is valid; getrusage only writes into it.
    let mut u: libc::rusage = unsafe { core::mem::zeroed() };
    // SAFETY: RUSAGE_SELF with a valid pointer.
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    (u.ru_utime.tv_sec + u.ru_stime.tv_sec) as f64
        + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) as f64 * 1e-6
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn the_join_arguments_need_an_address_and_credentials() {
        let a =
            JoinArgs::parse(&args(&["--connect", "tcp/10.0.0.1:7447"]), Some("s".into())).unwrap();
        assert_eq!(a.connect.to_string(), "10.0.0.1:7447");
        let e =
            JoinArgs::parse(&args(&["--connect", "10.0.0.1:99999"]), Some("s".into())).unwrap_err();
        assert!(
            e.starts_with("--connect 10.0.0.1:99999: port 99999 is outside 1-65535"),
            "{e}"
        );
        assert_eq!(a.secret, "s");
        assert_eq!(a.run, None);
        let e = JoinArgs::parse(&args(&["--connect", "tcp/10.0.0.1:7447"]), None).unwrap_err();
        assert!(e.starts_with("no credentials"), "{e}");
        let e = JoinArgs::parse(&args(&[]), Some("s".into())).unwrap_err();
        assert!(e.starts_with("missing --connect"), "{e}");
        let e = JoinArgs::parse(
            &args(&["--connect", "x:1", "--lease-ms", "5"]),
            Some("s".into()),
        )
        .unwrap_err();
        assert_eq!(e, "--lease-ms 5: expected 100 to 600000");
        let e = JoinArgs::parse(
            &args(&["--connect", "x:1", "--secret-file", "/nonexistent/s"]),
            None,
        )
        .unwrap_err();
        assert!(e.starts_with("--secret-file /nonexistent/s:"), "{e}");
        assert!(JoinArgs::wanted(&args(&["--connect", "x"])));
        assert!(!JoinArgs::wanted(&args(&["--params", "{}"])));
    }
}
