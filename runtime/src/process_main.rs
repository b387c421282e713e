//! The frame of every Shoal binary: logs to stderr (`RUST_LOG` overrides the
//! default level), and an error ends the process with its context and a
//! non-zero exit.

use std::io::Write;
use std::process::ExitCode;

/// What a command printed could not be written because the reader of its
/// standard output has gone (`shoal status | head`): the command did its
/// work, so it ends quietly and successfully, as `ls | head` does.
#[derive(Debug, thiserror::Error)]
#[error("standard output closed by its reader")]
pub struct StdoutClosed;

/// Runs `print` on the locked, buffered standard output and flushes it; a
/// reader that has gone becomes [`StdoutClosed`], any other failure an
/// error. Rust's `println!` panics on both.
pub fn print_out(print: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    print(&mut out)
        .and_then(|()| out.flush())
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::BrokenPipe => anyhow::Error::new(StdoutClosed),
            _ => anyhow::Error::new(e).context("writing to standard output"),
        })
}

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
        Err(e) if e.is::<StdoutClosed>() => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{name}: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
