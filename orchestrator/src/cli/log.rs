//! The log on standard error. A person reads what the libraries report while a command runs
//! as the command's own messages (`warning: ...`, `error: ...`, with `-v` `info: ...`); with
//! `-vv`, and in the participant processes (whose standard error goes to `logs/ROLE.log`),
//! each line also has its time and the module that wrote it. `RUST_LOG` overrides the level.

use tracing::{Event, Level, Subscriber};
use tracing_subscriber::fmt::format::Writer;
use tracing_subscriber::fmt::{FmtContext, FormatEvent, FormatFields};
use tracing_subscriber::registry::LookupSpan;

/// How much a command logs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Verbosity {
    /// `-v` repeated.
    pub verbose: u8,
    /// `-q`: errors only.
    pub quiet: bool,
    /// Times and module paths on every line (a participant process's log).
    pub detailed: bool,
}

impl Verbosity {
    /// The level filter without `RUST_LOG`.
    fn level(self) -> &'static str {
        match (self.quiet, self.verbose) {
            (true, _) => "error",
            (false, 0) => "warn",
            (false, 1) => "info",
            (false, _) => "debug",
        }
    }
}

/// The word a message of `level` starts with.
fn word(level: Level) -> &'static str {
    match level {
        Level::ERROR => "error",
        Level::WARN => "warning",
        Level::INFO => "info",
        Level::DEBUG => "debug",
        Level::TRACE => "trace",
    }
}

/// `warning: MESSAGE`: the level as a word, the message and its fields, nothing else.
struct Plain;

impl<S, N> FormatEvent<S, N> for Plain
where
    S: Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
{
    fn format_event(
        &self,
        ctx: &FmtContext<'_, S, N>,
        mut w: Writer<'_>,
        event: &Event<'_>,
    ) -> std::fmt::Result {
        write!(w, "{}: ", word(*event.metadata().level()))?;
        ctx.field_format().format_fields(w.by_ref(), event)?;
        writeln!(w)
    }
}

/// Starts the log for this process.
pub fn init(v: Verbosity) {
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    use tracing_subscriber::Layer;
    // Zenoh's own notes on how its sessions are configured (no gossip, no multicast, by
    // design here) are not the user's business below -vv; its errors are. Its QUIC link's
    // refusals of other connections go to the run, which names them in its own words
    // (`tiltsim_net::watch`), and to the log only with -vv.
    let filter = tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
        let level = v.level();
        let zenoh = if v.verbose >= 2 { level } else { "error" };
        let tls = if v.verbose >= 2 { level } else { "off" };
        tracing_subscriber::EnvFilter::new(format!(
            "{level},zenoh={zenoh},zenoh_transport={zenoh},zenoh_link_quic={tls},zenoh_link_commons={tls}"
        ))
    });
    let fmt = tracing_subscriber::fmt::layer().with_writer(std::io::stderr);
    let fmt = if v.detailed || v.verbose >= 2 {
        // Colours only where a person reads them.
        fmt.with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
            .with_filter(filter)
            .boxed()
    } else {
        fmt.with_ansi(false)
            .event_format(Plain)
            .with_filter(filter)
            .boxed()
    };
    let refusals = tiltsim_net::watch::TlsRefusals.with_filter(tiltsim_net::watch::OnlyTlsRefusals);
    let _ = tracing_subscriber::registry()
        .with(fmt)
        .with(refusals)
        .try_init();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What `Plain` writes for the events `f` logs, at `level`.
    fn logged(level: &str, f: impl FnOnce()) -> String {
        #[derive(Clone, Default)]
        struct Buf(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);
        impl std::io::Write for Buf {
            fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
                self.0.lock().unwrap().extend_from_slice(b);
                Ok(b.len())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let buf = Buf::default();
        let writer = buf.clone();
        let sub = tracing_subscriber::fmt()
            .with_env_filter(level)
            .with_writer(move || writer.clone())
            .with_ansi(false)
            .event_format(Plain)
            .finish();
        tracing::subscriber::with_default(sub, f);
        let bytes = buf.0.lock().unwrap().clone();
        String::from_utf8(bytes).unwrap()
    }

    #[test]
    fn warnings_read_as_the_commands_own_messages() {
        let text = logged("warn", || {
            tracing::warn!("participant controller exited; continuing degraded");
            tracing::info!("not shown");
        });
        assert_eq!(
            text,
            "warning: participant controller exited; continuing degraded\n"
        );
    }

    #[test]
    fn quiet_keeps_errors_only_and_verbose_adds_information() {
        let q = Verbosity {
            verbose: 0,
            quiet: true,
            detailed: false,
        };
        let text = logged(q.level(), || {
            tracing::warn!("a warning");
            tracing::error!("an error");
        });
        assert_eq!(text, "error: an error\n");
        let v = Verbosity {
            verbose: 1,
            quiet: false,
            detailed: false,
        };
        assert_eq!(logged(v.level(), || tracing::info!("x")), "info: x\n");
    }
}
