//! Who tried to reach the run without the right to: the attempts a run names in
//! `summary.json` → `network.attempts` and in `events.csv`.
//!
//! Three kinds are seen:
//! - a connection whose TLS handshake failed (no certificate, a certificate the run's
//!   authority did not sign, not QUIC at all): Zenoh's QUIC link reports it only in its log, so
//!   [`layer`] takes those log events, out of the user's sight, and [`take_tls_refusals`]
//!   hands them over;
//! - a session with a valid certificate for a role the run does not have on another host, or
//!   a second session for a role: seen in Zenoh's link events, by the certificate's common
//!   name; access control gives it nothing;
//! - a hello that fails the handshake's checks ([`crate::Refusal`]).

use std::sync::Mutex;

use serde::Serialize;
use tracing::field::{Field, Visit};
use tracing::subscriber::Interest;
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::filter::LevelFilter;
use tracing_subscriber::layer::{Context, Filter, Layer};

/// What kind of attempt.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AttemptKind {
    /// A connection without a certificate.
    NoCredentials,
    /// A certificate not signed by the run's authority: another secret.
    WrongCredentials,
    /// Not a TLS client (plain TCP, or another protocol).
    NotTls,
    /// A TLS handshake that failed otherwise or did not finish in time.
    TlsFailed,
    /// A valid certificate for a role the run does not have on another host, or for the
    /// orchestrator itself.
    OtherRole,
    /// A second session with the certificate of a role already connected.
    SecondSession,
}

impl AttemptKind {
    /// In words, for messages and `events.csv`.
    pub fn words(self) -> &'static str {
        match self {
            AttemptKind::NoCredentials => "a connection without credentials",
            AttemptKind::WrongCredentials => {
                "a connection with credentials of another secret (wrong credentials)"
            }
            AttemptKind::NotTls => "a connection that is not TLS",
            AttemptKind::TlsFailed => "a TLS handshake that failed",
            AttemptKind::OtherRole => {
                "a session with valid credentials of a role this run has no remote participant for"
            }
            AttemptKind::SecondSession => {
                "a second session with the credentials of a role already connected"
            }
        }
    }
}

/// One attempt.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Attempt {
    /// What kind.
    pub kind: AttemptKind,
    /// Where it came from, when known (`ADDRESS:PORT`), else empty.
    pub from: String,
    /// The certificate's common name, when it had a valid one.
    pub common_name: String,
    /// The step the run was at when it was seen.
    pub step: u64,
    /// The words of the layer that refused it (TLS's reason, or access control's).
    pub detail: String,
}

/// TLS refusals logged since the last [`take_tls_refusals`]: kind and TLS's reason.
static TLS_REFUSALS: Mutex<Vec<(AttemptKind, String)>> = Mutex::new(Vec::new());

/// At most this many refusals are kept between two takes (a flood is counted, not stored).
const KEPT: usize = 1000;

/// How many refusals wait to be taken: a run looks at it every tick, cheaply.
static PENDING: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Whether TLS refusals wait to be taken.
pub fn tls_refusals_pending() -> bool {
    PENDING.load(std::sync::atomic::Ordering::Relaxed) > 0
}

/// The kind of a TLS failure from its message (rustls's words).
pub fn classify(message: &str) -> AttemptKind {
    let m = message.to_ascii_lowercase();
    if m.contains("no certificates") || m.contains("certificaterequired") {
        AttemptKind::NoCredentials
    } else if m.contains("unknownissuer")
        || m.contains("badsignature")
        || m.contains("decrypterror")
        || m.contains("badcertificate")
        || m.contains("unknown ca")
        || m.contains("unknownca")
        || m.contains("invalid peer certificate")
    {
        AttemptKind::WrongCredentials
    } else if m.contains("corrupt message") || m.contains("invalidcontenttype") {
        AttemptKind::NotTls
    } else {
        AttemptKind::TlsFailed
    }
}

/// The TLS refusals logged since the last call, in order.
pub fn take_tls_refusals() -> Vec<(AttemptKind, String)> {
    let mut v = TLS_REFUSALS.lock().unwrap_or_else(|e| e.into_inner());
    PENDING.store(0, std::sync::atomic::Ordering::Relaxed);
    std::mem::take(&mut *v)
}

/// The TLS reason inside a QUIC accept error (`... reason: b"invalid peer certificate: ..."`),
/// or the message without Zenoh's source location.
fn reason(text: &str) -> String {
    text.split_once("reason: b\"")
        .and_then(|(_, r)| r.split_once('"'))
        .map(|(r, _)| r.to_string())
        .unwrap_or_else(|| crate::clean(text))
}

/// Whether a log event is Zenoh's QUIC link refusing a connection (its accept loop, in
/// `zenoh_link_commons::quic`, or the link itself).
fn is_tls_refusal(meta: &tracing::Metadata<'_>) -> bool {
    let t = meta.target();
    (t.starts_with("zenoh_link_quic") || t.starts_with("zenoh_link_commons::quic"))
        && *meta.level() <= Level::WARN
}

struct Message(String);

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}");
        }
    }
    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.0 = value.to_string();
        }
    }
}

/// The log layer that takes Zenoh's TLS refusals (add it to the process's subscriber; its
/// own filter lets only those events through).
pub struct TlsRefusals;

impl<S: Subscriber> Layer<S> for TlsRefusals {
    fn on_event(&self, event: &Event<'_>, _: Context<'_, S>) {
        let mut m = Message(String::new());
        event.record(&mut m);
        // Zenoh adds a hint about open files to every failed accept; it is not the reason.
        let text =
            m.0.split(". Hint:")
                .next()
                .unwrap_or_default()
                .trim()
                .to_string();
        // What a connecting end notes of its own settings is no refusal.
        if text.starts_with("Skipping name verification") {
            return;
        }
        let text = reason(&text);
        let mut v = TLS_REFUSALS.lock().unwrap_or_else(|e| e.into_inner());
        if v.len() < KEPT {
            v.push((classify(&text), text));
            PENDING.store(v.len(), std::sync::atomic::Ordering::Relaxed);
        }
    }
}

/// The filter of [`TlsRefusals`]. It decides once per call site, from the call site's target
/// and level alone, and says it wants nothing below warnings: without that, every `debug!` and
/// `trace!` of a run's loop would ask it again on each call (a few per cent of an in-process
/// run's wall time, measured).
pub struct OnlyTlsRefusals;

impl<S> Filter<S> for OnlyTlsRefusals {
    fn enabled(&self, meta: &tracing::Metadata<'_>, _: &Context<'_, S>) -> bool {
        is_tls_refusal(meta)
    }

    fn callsite_enabled(&self, meta: &'static tracing::Metadata<'static>) -> Interest {
        if is_tls_refusal(meta) {
            Interest::always()
        } else {
            Interest::never()
        }
    }

    fn max_level_hint(&self) -> Option<LevelFilter> {
        Some(LevelFilter::WARN)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quic_accept_error_is_told_by_its_tls_reason() {
        let raw = "QUIC acceptor failed: ConnectionClosed(ConnectionClose { error_code: Code::crypto(33), frame_type: None, reason: b\"invalid peer certificate: BadSignature\" }) at /x/zenoh-link-commons-1.10.2/src/quic/unicast.rs:686";
        assert_eq!(reason(raw), "invalid peer certificate: BadSignature");
        assert_eq!(classify(&reason(raw)), AttemptKind::WrongCredentials);
        assert_eq!(
            reason("QUIC acceptor failed: TimedOut at /x/y.rs:1"),
            "QUIC acceptor failed: TimedOut"
        );
    }

    #[test]
    fn tls_failures_are_told_apart_by_rustls_words() {
        assert_eq!(
            classify("peer sent no certificates"),
            AttemptKind::NoCredentials
        );
        assert_eq!(
            classify("invalid peer certificate: UnknownIssuer"),
            AttemptKind::WrongCredentials
        );
        // A certificate of another secret's authority (same name, other key) fails its
        // signature, which the other end reports as a decrypt error.
        assert_eq!(
            classify("received fatal alert: DecryptError"),
            AttemptKind::WrongCredentials
        );
        assert_eq!(
            classify("received corrupt message of type InvalidContentType"),
            AttemptKind::NotTls
        );
        assert_eq!(
            classify("Timeout during TLS handshake"),
            AttemptKind::TlsFailed
        );
    }
}
