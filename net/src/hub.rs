//! The orchestrator's side: the run's session, its offer, the join handshake's judge, and the
//! ports of every remote role, declared before anyone joins so that no reply can be published
//! before the orchestrator listens for it.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;
use zenoh::handlers::{FifoChannel, FifoChannelHandler};
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::query::{Query, Queryable};
use zenoh::sample::{Sample, SampleKind};
use zenoh::Wait;

use cosim::msg::{now_ns, Message, PROTOCOL_VERSION};
use cosim::Role;

use crate::credentials::{self, Holder};
use crate::endpoint::NetEndpoint;
use crate::join::{judge, welcome_proof, Hello, Judge, Offer, Welcome};
use crate::watch::{take_tls_refusals, Attempt, AttemptKind};
use crate::{acl, keys, new_secret, session, zenoh_error, NetError, NetSettings};

/// A remote participant that joined.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Joined {
    /// Its role.
    pub role: Role,
    /// Its host's name.
    pub host: String,
    /// Its process id there.
    pub pid: u32,
    /// The orchestrator's clock minus the participant's (ns), measured at joining.
    pub clock_offset_ns: i64,
    /// The round trip of that measurement (ns): the offset is known to within half of it.
    pub clock_rtt_ns: u64,
}

/// A participant refused at joining.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Refusal {
    /// The role it asked for.
    pub role: Role,
    /// Its host's name.
    pub host: String,
    /// Its process id there.
    pub pid: u32,
    /// Why it was refused.
    pub reason: String,
}

/// Samples a reply subscriber holds: the lock-step has one in flight.
const REPLY_BUFFER: usize = 1024;

pub(crate) fn idx(r: Role) -> usize {
    match r {
        Role::Plant => 0,
        Role::Actuator => 1,
        Role::Controller => 2,
    }
}

/// What the session's callbacks share with the hub and its endpoints.
pub(crate) struct Shared {
    run: String,
    offer_nonce: String,
    secret: String,
    params: [Option<String>; 3],
    joined: Mutex<[Option<Joined>; 3]>,
    refusals: Mutex<Vec<Refusal>>,
    /// Whether each role's liveliness token is present.
    pub(crate) alive: [AtomicBool; 3],
    /// What each role said last outside the exchange.
    pub(crate) notes: Mutex<[Option<String>; 3]>,
    /// The step of the newest request sent: when an attempt is seen, the run was there.
    pub(crate) step: AtomicU64,
    /// The run's authority, named in every common name of its certificates.
    authority_id: String,
    /// Attempts seen so far, in order.
    attempts: Mutex<Vec<Attempt>>,
    /// The links of remote roles open now: the certificate's common name and the peer.
    links: Mutex<Vec<(String, String)>>,
}

impl Shared {
    fn awaited(&self) -> Vec<Role> {
        let joined = self.joined.lock().unwrap_or_else(|e| e.into_inner());
        Role::ALL
            .into_iter()
            .filter(|&r| self.params[idx(r)].is_some() && joined[idx(r)].is_none())
            .collect()
    }

    /// Answers a hello on the join key of `role`.
    fn admit(&self, role: Role, hello: &Hello) -> Welcome {
        let mut joined = self.joined.lock().unwrap_or_else(|e| e.into_inner());
        let remote = |r: Role| self.params[idx(r)].is_some();
        let snapshot = joined.clone();
        let holder = move |r: Role| snapshot[idx(r)].as_ref().map(|j| (j.host.clone(), j.pid));
        let verdict = judge(
            &Judge {
                secret: &self.secret,
                run: &self.run,
                offer_nonce: &self.offer_nonce,
                remote: &remote,
                holder: &holder,
            },
            role,
            hello,
        );
        match verdict {
            Ok(()) => {
                joined[idx(role)] = Some(Joined {
                    role,
                    host: hello.host.clone(),
                    pid: hello.pid,
                    clock_offset_ns: hello.clock_offset_ns,
                    clock_rtt_ns: hello.clock_rtt_ns,
                });
                tracing::info!(
                    "participant {role} joined from host {} (pid {}), clock offset {:.3} ms ± {:.3} ms",
                    hello.host,
                    hello.pid,
                    hello.clock_offset_ns as f64 * 1e-6,
                    hello.clock_rtt_ns as f64 * 0.5e-6
                );
                let params = self.params[idx(role)].clone().unwrap_or_default();
                Welcome {
                    accepted: true,
                    reason: String::new(),
                    proof: welcome_proof(
                        &self.secret,
                        &self.run,
                        role,
                        (&self.offer_nonce, &hello.nonce),
                        &params,
                    ),
                    params,
                }
            }
            Err(reason) => {
                tracing::warn!(
                    "refused a participant for {role} from host {} (pid {}): {reason}",
                    hello.host,
                    hello.pid
                );
                self.refusals
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push(Refusal {
                        role,
                        host: hello.host.clone(),
                        pid: hello.pid,
                        reason: reason.clone(),
                    });
                Welcome {
                    accepted: false,
                    reason,
                    params: String::new(),
                    proof: String::new(),
                }
            }
        }
    }

    pub(crate) fn note(&self, role: Role) -> Option<String> {
        self.notes.lock().unwrap_or_else(|e| e.into_inner())[idx(role)].clone()
    }

    fn attempt(&self, kind: AttemptKind, from: String, common_name: String, detail: String) {
        let a = Attempt {
            kind,
            from,
            common_name,
            step: self.step.load(Ordering::Relaxed),
            detail,
        };
        tracing::warn!(
            "refused {}{}{} at step {}: {}",
            kind.words(),
            if a.from.is_empty() { "" } else { " from " },
            a.from,
            a.step,
            a.detail
        );
        let mut v = self.attempts.lock().unwrap_or_else(|e| e.into_inner());
        if v.len() < MAX_ATTEMPTS {
            v.push(a);
        }
    }

    /// A link opened or closed: a remote role's own, or someone else's, named.
    fn link_event(&self, up: bool, common_name: Option<&str>, from: String) {
        let name = common_name.unwrap_or("").to_string();
        let mut links = self.links.lock().unwrap_or_else(|e| e.into_inner());
        if !up {
            links.retain(|(n, f)| !(n == &name && f == &from));
            return;
        }
        let holder = Holder::of_common_name(&name, &self.authority_id);
        let role = match holder {
            Some(Holder::Role(r)) => Some(r).filter(|&r| self.params[idx(r)].is_some()),
            _ => None,
        };
        match role {
            None if holder.is_none() => {
                drop(links);
                self.attempt(
                    AttemptKind::WrongCredentials,
                    from,
                    name.clone(),
                    format!("certificate `{name}` is not of this run's authority: access control admits it to nothing"),
                );
            }
            None => {
                drop(links);
                self.attempt(
                    AttemptKind::OtherRole,
                    from,
                    name.clone(),
                    format!(
                        "certificate `{name}`: access control admits it to nothing of this run"
                    ),
                );
            }
            Some(r) if links.iter().any(|(n, _)| n == &name) => {
                drop(links);
                self.attempt(
                    AttemptKind::SecondSession,
                    from,
                    name,
                    format!("{r} is connected already; the second session gets no sample of the run's exchange with it"),
                );
            }
            Some(_) => links.push((name, from)),
        }
    }

    /// Moves the TLS refusals logged since the last look into the attempts.
    pub(crate) fn collect_tls_refusals(&self) {
        for (kind, detail) in take_tls_refusals() {
            self.attempt(kind, String::new(), String::new(), format!("TLS: {detail}"));
        }
    }
}

/// At most this many attempts are named one by one (a flood is cut there).
const MAX_ATTEMPTS: usize = 1000;

/// One remote role's ports, declared when the hub opens.
pub(crate) struct Ports {
    pub(crate) request: Publisher<'static>,
    pub(crate) control: Publisher<'static>,
    pub(crate) replies: Subscriber<FifoChannelHandler<Sample>>,
}

/// The orchestrator's side of the network transport for one run.
pub struct NetHub {
    settings: NetSettings,
    session: zenoh::Session,
    shared: Arc<Shared>,
    ports: [Option<Ports>; 3],
    _queryables: Vec<Queryable<()>>,
    _subscribers: Vec<Subscriber<()>>,
    _token: zenoh::liveliness::LivelinessToken,
}

impl NetHub {
    /// Opens the run's session on `settings.listen` for the roles in `remote`, each with its
    /// settings as JSON, and starts answering offers and hellos.
    pub fn open(settings: NetSettings, remote: Vec<(Role, String)>) -> Result<Self, NetError> {
        let urandom = |e: std::io::Error| NetError::Zenoh {
            what: "drawing the run's key".into(),
            why: e.to_string(),
        };
        let run = new_secret().map_err(urandom)?;
        let offer_nonce = new_secret().map_err(urandom)?;
        let mut params: [Option<String>; 3] = Default::default();
        for (r, p) in remote {
            params[idx(r)] = Some(p);
        }
        let roles: Vec<Role> = Role::ALL
            .into_iter()
            .filter(|&r| params[idx(r)].is_some())
            .collect();
        let shared = Arc::new(Shared {
            run: run.clone(),
            offer_nonce,
            secret: settings.secret.clone(),
            params,
            joined: Mutex::default(),
            refusals: Mutex::default(),
            alive: Default::default(),
            notes: Mutex::default(),
            step: AtomicU64::new(0),
            authority_id: credentials::authority_id(&settings.secret)
                .map_err(|e| NetError::Participant(e.to_string()))?,
            attempts: Mutex::default(),
            links: Mutex::default(),
        });
        let credentials = credentials::issue(&settings.secret, Holder::Orchestrator)
            .map_err(|e| NetError::Participant(e.to_string()))?;
        let authority_id = credentials.authority_id.clone();
        // Refusals logged before this run's session opened are not this run's.
        let _ = take_tls_refusals();
        let session = session::open(
            &session::End::Listen(settings.listen.clone()),
            settings.lease,
            &session::Security::Tls {
                credentials,
                acl: acl::orchestrator(&run, &roles, &authority_id),
            },
            session::Tuning::default(),
        )?;
        watch_links(&session, &shared)?;
        let ports = declare_ports(&session, &shared)?;
        let queryables = answer_joins(&session, &shared)?;
        let subscribers = watch_participants(&session, &shared)?;
        let token = session
            .liveliness()
            .declare_token(keys::orchestrator_alive(&run))
            .wait()
            .map_err(zenoh_error("declaring the orchestrator's liveliness"))?;
        Ok(NetHub {
            settings,
            session,
            shared,
            ports,
            _queryables: queryables,
            _subscribers: subscribers,
            _token: token,
        })
    }

    /// Whether `role` joins from another host in this run.
    pub fn is_remote(&self, role: Role) -> bool {
        self.shared.params[idx(role)].is_some()
    }

    /// The run's key (in every key expression of the run).
    pub fn run_key(&self) -> &str {
        &self.shared.run
    }

    /// The run's settings.
    pub fn settings(&self) -> &NetSettings {
        &self.settings
    }

    /// The command that joins `role` to this run from another host (the secret left to
    /// `TILTSIM_SECRET` or a file).
    pub fn join_command(&self, role: Role) -> String {
        format!(
            "tiltsim participant {role} --connect {} --run {}",
            self.settings.listen, self.shared.run
        )
    }

    /// Waits until `role` has joined, then hands over its endpoint. Ends with an error naming
    /// the role, the address and the participants refused meanwhile when the join timeout
    /// passes, or when `interrupt` is set.
    pub fn await_join<I: Message, O: Message>(
        &mut self,
        role: Role,
        interrupt: Option<&AtomicBool>,
    ) -> Result<NetEndpoint<I, O>, NetError> {
        let start = Instant::now();
        loop {
            let joined =
                self.shared.joined.lock().unwrap_or_else(|e| e.into_inner())[idx(role)].clone();
            if let Some(j) = joined {
                let ports = self.ports[idx(role)].take().ok_or_else(|| {
                    NetError::Participant(format!("{role} has no ports in this run"))
                })?;
                return Ok(NetEndpoint::new(
                    j,
                    ports,
                    self.shared.clone(),
                    self.session.clone(),
                    self.settings.deadline,
                ));
            }
            if crate::watch::tls_refusals_pending() {
                self.shared.collect_tls_refusals();
            }
            if interrupt.is_some_and(|f| f.load(Ordering::Relaxed)) {
                return Err(NetError::Interrupted { role });
            }
            if start.elapsed() >= self.settings.join_timeout {
                let refused: Vec<String> = self
                    .refusals()
                    .into_iter()
                    .filter(|r| r.role == role)
                    .map(|r| format!("host {} (pid {}): {}", r.host, r.pid, r.reason))
                    .collect();
                return Err(NetError::NeverJoined {
                    role,
                    listen: self.settings.listen.to_string(),
                    waited_s: start.elapsed().as_secs_f64(),
                    refused: if refused.is_empty() {
                        String::new()
                    } else {
                        format!("; refused: {}", refused.join("; "))
                    },
                });
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// The participants that joined, in role order.
    pub fn joined(&self) -> Vec<Joined> {
        self.shared
            .joined
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .flatten()
            .cloned()
            .collect()
    }

    /// The attempts by others seen so far, in order: connections refused by TLS, sessions
    /// with another role's credentials, second sessions of a role.
    pub fn attempts(&self) -> Vec<Attempt> {
        self.shared.collect_tls_refusals();
        self.shared
            .attempts
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The participants refused so far, in arrival order.
    pub fn refusals(&self) -> Vec<Refusal> {
        self.shared
            .refusals
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// Every remote role's ports: its requests and process faults out, its replies in, declared
/// before anyone joins.
fn declare_ports(
    session: &zenoh::Session,
    shared: &Shared,
) -> Result<[Option<Ports>; 3], NetError> {
    let mut ports: [Option<Ports>; 3] = Default::default();
    for r in Role::ALL {
        if shared.params[idx(r)].is_none() {
            continue;
        }
        let publisher = |key: String| {
            session
                .declare_publisher(key)
                .congestion_control(CongestionControl::Block)
                .express(true)
                .wait()
                .map_err(zenoh_error("declaring a publisher"))
        };
        ports[idx(r)] = Some(Ports {
            request: publisher(keys::request(&shared.run, r))?,
            control: publisher(keys::control(&shared.run, r))?,
            replies: session
                .declare_subscriber(keys::reply(&shared.run, r))
                .with(FifoChannel::new(REPLY_BUFFER))
                .wait()
                .map_err(zenoh_error("declaring a subscriber"))?,
        });
    }
    Ok(ports)
}

/// The run's offer, its clock and the judge of hellos.
fn answer_joins(
    session: &zenoh::Session,
    shared: &Arc<Shared>,
) -> Result<Vec<Queryable<()>>, NetError> {
    let mut queryables = Vec::new();
    let s = shared.clone();
    queryables.push(
        session
            .declare_queryable(keys::offer(&shared.run))
            .callback(move |q: Query| {
                let offer = Offer {
                    run: s.run.clone(),
                    nonce: s.offer_nonce.clone(),
                    protocol_version: PROTOCOL_VERSION,
                    awaited: s.awaited(),
                };
                let body = serde_json::to_vec(&offer).unwrap_or_default();
                let _ = q.reply(q.key_expr().clone(), body).wait();
            })
            .wait()
            .map_err(zenoh_error("declaring the run's offer"))?,
    );
    queryables.push(
        session
            .declare_queryable(keys::clock(&shared.run))
            .callback(move |q: Query| {
                let _ = q
                    .reply(q.key_expr().clone(), now_ns().to_le_bytes().to_vec())
                    .wait();
            })
            .wait()
            .map_err(zenoh_error("declaring the run's clock"))?,
    );
    let s = shared.clone();
    queryables.push(
        session
            .declare_queryable(keys::join_any(&shared.run))
            .callback(move |q: Query| {
                let role = q
                    .key_expr()
                    .as_str()
                    .split('/')
                    .nth(4)
                    .and_then(Role::parse);
                let hello: Option<Hello> = q
                    .payload()
                    .and_then(|p| serde_json::from_slice(&p.to_bytes()).ok());
                let welcome = match (role, hello) {
                    (Some(role), Some(hello)) => s.admit(role, &hello),
                    _ => Welcome {
                        accepted: false,
                        reason: "not a hello of this protocol".into(),
                        params: String::new(),
                        proof: String::new(),
                    },
                };
                let body = serde_json::to_vec(&welcome).unwrap_or_default();
                let _ = q.reply(q.key_expr().clone(), body).wait();
            })
            .wait()
            .map_err(zenoh_error("declaring the run's join"))?,
    );
    Ok(queryables)
}

/// The remote roles' liveliness tokens and notes, into `shared` (each role's own keys only:
/// nothing another role's holder says reaches them).
fn watch_participants(
    session: &zenoh::Session,
    shared: &Arc<Shared>,
) -> Result<Vec<Subscriber<()>>, NetError> {
    let mut subscribers = Vec::new();
    for r in Role::ALL {
        if shared.params[idx(r)].is_none() {
            continue;
        }
        let s = shared.clone();
        subscribers.push(
            session
                .liveliness()
                .declare_subscriber(keys::alive(&shared.run, r))
                .history(true)
                .callback(move |sample: Sample| {
                    let up = sample.kind() == SampleKind::Put;
                    s.alive[idx(r)].store(up, Ordering::Release);
                })
                .wait()
                .map_err(zenoh_error("watching the participants' liveliness"))?,
        );
        let s = shared.clone();
        subscribers.push(
            session
                .declare_subscriber(keys::note(&shared.run, r))
                .callback(move |sample: Sample| {
                    let text = String::from_utf8_lossy(&sample.payload().to_bytes()).into_owned();
                    s.notes.lock().unwrap_or_else(|e| e.into_inner())[idx(r)] = Some(text);
                })
                .wait()
                .map_err(zenoh_error("listening to the participants' notes"))?,
        );
    }
    Ok(subscribers)
}

/// Zenoh's link events: every link that opens is a remote role's, or an attempt named.
fn watch_links(session: &zenoh::Session, shared: &Arc<Shared>) -> Result<(), NetError> {
    let s = shared.clone();
    session
        .info()
        .link_events_listener()
        .history(true)
        .callback(move |e: zenoh::session::LinkEvent| {
            let up = e.kind() == SampleKind::Put;
            let link = e.link();
            let dst = link.dst().to_string();
            let from = dst
                .split_once('/')
                .map_or(dst.as_str(), |(_, a)| a)
                .to_string();
            s.link_event(up, link.auth_identifier(), from);
        })
        .background()
        .wait()
        .map_err(zenoh_error("watching the run's links"))
}

impl Drop for NetHub {
    fn drop(&mut self) {
        let _ = self.session.close().wait();
    }
}
