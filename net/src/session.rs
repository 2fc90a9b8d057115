//! Zenoh configuration of both sides: peers that talk only to the endpoints they are given
//! (no multicast or gossip scouting, so a run never meets a session it was not pointed at),
//! over QUIC with mutual TLS 1.3 and the run's credentials ([`crate::credentials`]) and with
//! access control denying everything the role does not need ([`crate::acl`]), with the run's
//! lease.
//!
//! Why QUIC and not Zenoh's TLS-over-TCP link: that link reads and writes one rustls stream
//! from two tasks at once through an `UnsafeCell`, which rustls does not support (Zenoh issue
//! 2557); here a free run's two-way traffic crashed a participant with a corrupted allocation
//! within a second. QUIC's library (quinn) owns its TLS state behind its own lock.

use std::time::Duration;

use serde_json::Value;
use zenoh::Wait;

use tiltsim_protocol::address::Address;

use crate::credentials::Credentials;
use crate::{zenoh_error, NetError};

/// Which end of the run's link this session is.
#[derive(Debug, Clone)]
pub enum End {
    /// The orchestrator: listens on this address.
    Listen(Address),
    /// A participant: connects to this address.
    Connect(Address),
}

/// What a session proves and admits.
#[derive(Debug, Clone)]
pub enum Security {
    /// QUIC, mutual TLS 1.3 with these credentials, and this access control (Zenoh's
    /// `access_control` section). Every run's session.
    Tls {
        /// This end's credentials.
        credentials: Credentials,
        /// The access control.
        acl: Value,
    },
    /// Plain TCP, no authentication: only `tiltsim bench --network`, to measure what the
    /// security costs against the same exchange without it.
    PlainForMeasurement,
}

/// How Zenoh's transport is set up (the same at both ends: some settings are negotiated).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tuning {
    /// Zenoh's low-latency transport (no queues, no batching, no QoS priorities).
    pub lowlatency: bool,
    /// Zenoh's adaptive batching of small messages under back-pressure.
    pub batching: bool,
}

impl Default for Tuning {
    /// What a run uses: the low-latency transport, whose median and tail are lower than the
    /// queued transport's in every pair measured (docs/performance.md, "Participants on other
    /// hosts"); every sample and welcome of a run is far below its largest message (a batch).
    fn default() -> Self {
        Tuning {
            lowlatency: true,
            batching: true,
        }
    }
}

/// The configuration of one session.
pub fn config(
    end: &End,
    lease: Duration,
    security: &Security,
    tuning: Tuning,
) -> Result<zenoh::Config, NetError> {
    let mut c = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, k: &str, v: String| {
        c.insert_json5(k, &v).map_err(|e| NetError::Zenoh {
            what: format!("setting {k}"),
            why: crate::clean(&e.to_string()),
        })
    };
    set(&mut c, "mode", "\"peer\"".into())?;
    set(&mut c, "scouting/multicast/enabled", "false".into())?;
    set(&mut c, "scouting/gossip/enabled", "false".into())?;
    let endpoint = |a: &Address| match security {
        Security::Tls { .. } => a.quic_endpoint(),
        Security::PlainForMeasurement => a.tcp_endpoint(),
    };
    match end {
        End::Listen(a) => {
            set(&mut c, "listen/endpoints", json_list(&endpoint(a)))?;
            set(&mut c, "connect/endpoints", "[]".into())?;
        }
        End::Connect(a) => {
            set(&mut c, "listen/endpoints", "[]".into())?;
            set(&mut c, "connect/endpoints", json_list(&endpoint(a)))?;
        }
    }
    let lease_ms = lease.as_millis().max(100) as u64;
    set(&mut c, "transport/link/tx/lease", lease_ms.to_string())?;
    if tuning.lowlatency {
        set(&mut c, "transport/unicast/qos/enabled", "false".into())?;
        set(&mut c, "transport/unicast/lowlatency", "true".into())?;
    }
    set(
        &mut c,
        "transport/link/tx/queue/batching/enabled",
        tuning.batching.to_string(),
    )?;
    if let Security::Tls { credentials, acl } = security {
        use base64::Engine;
        let b64 = |pem: &str| {
            serde_json::to_string(&base64::engine::general_purpose::STANDARD.encode(pem))
                .unwrap_or_default()
        };
        let tls = "transport/link/tls";
        set(
            &mut c,
            &format!("{tls}/root_ca_certificate_base64"),
            b64(&credentials.authority_pem),
        )?;
        let side = match end {
            End::Listen(_) => "listen",
            End::Connect(_) => "connect",
        };
        set(
            &mut c,
            &format!("{tls}/{side}_certificate_base64"),
            b64(&credentials.certificate_pem),
        )?;
        set(
            &mut c,
            &format!("{tls}/{side}_private_key_base64"),
            b64(&credentials.key_pem),
        )?;
        set(&mut c, &format!("{tls}/enable_mtls"), "true".into())?;
        // The peer is known by its certificate's authority and common name, not by the name
        // of the host it was reached at.
        set(
            &mut c,
            &format!("{tls}/verify_name_on_connect"),
            "false".into(),
        )?;
        set(&mut c, "access_control", acl.to_string())?;
    }
    Ok(c)
}

fn json_list(endpoint: &str) -> String {
    serde_json::to_string(&[endpoint]).unwrap_or_else(|_| "[]".into())
}

/// Opens a session.
pub fn open(
    end: &End,
    lease: Duration,
    security: &Security,
    tuning: Tuning,
) -> Result<zenoh::Session, NetError> {
    let what = match end {
        End::Listen(a) => format!("listening on {a}"),
        End::Connect(a) => format!("connecting to {a}"),
    };
    zenoh::open(config(end, lease, security, tuning)?)
        .wait()
        .map_err(zenoh_error(&what))
}

/// Checks that this host can listen on `a` (a UDP port, QUIC's) before Zenoh tries, so that
/// a wrong address or a port in use is said in words.
pub fn check_listen(a: &Address) -> Result<(), String> {
    use std::net::ToSocketAddrs;
    let addrs: Vec<std::net::SocketAddr> = match a.socket_addr() {
        Some(sa) => vec![sa],
        None => (a.to_string().as_str())
            .to_socket_addrs()
            .map_err(|e| format!("cannot resolve {}: {e}", a))?
            .collect(),
    };
    let Some(sa) = addrs.first() else {
        return Err(format!("{a} resolves to no address"));
    };
    match std::net::UdpSocket::bind(sa) {
        Ok(_) => Ok(()),
        Err(e) => Err(match e.kind() {
            std::io::ErrorKind::AddrInUse => format!(
                "UDP port {} is in use on {} (another run, or another program, listens there)",
                a.port,
                sa.ip()
            ),
            std::io::ErrorKind::AddrNotAvailable => {
                format!("this host has no address {} (see `ip address`)", sa.ip())
            }
            std::io::ErrorKind::PermissionDenied => format!(
                "not allowed to listen on port {} (ports below 1024 need privileges)",
                a.port
            ),
            _ => format!("cannot listen on {a}: {e}"),
        }),
    }
}
