//! The frame of every Shoal binary: logs to stderr (`RUST_LOG` overrides the
//! default level), and an error ends the process with its context and a
//! non-zero exit.

use std::process::ExitCode;

pub fn run_main(
    name: &str,
    default_level: &str,
    body: impl FnOnce() -> anyhow::Result<()>,
) -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| default_level.into()),
        )
        .with_writer(std::io::stderr)
        // Logs that go to a file (a robot's log) stay readable text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    // Every process of a host belongs to its domain: a host name that
    // cannot be one is an error here, not a silent fall back to another.
    if let Ok(host) = std::env::var(crate::host::HOST_ENV)
        && !host.is_empty()
        && let Err(e) = crate::host::validate(&host)
    {
        eprintln!("{name}: error: {} {e}", crate::host::HOST_ENV);
        return ExitCode::FAILURE;
    }
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{name}: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
