//! The robots a launcher started and how those that ended did: a process
//! that ends unasked is a death, reported with the end of its log.

use std::collections::BTreeMap;
use std::process::Child;

use shoal_runtime::SwarmRuntime;

/// The robots this process started, and how those that ended did.
#[derive(Default)]
pub(crate) struct Children {
    pub(crate) running: BTreeMap<u32, Child>,
    pub(crate) deaths: Vec<Death>,
}

/// A robot or helper that ended without a user or the launcher asking it to.
#[derive(Clone, Debug, PartialEq)]
pub struct Death {
    /// `robot 3`, or the helper's binary.
    pub who: String,
    pub status: String,
    /// The last lines of its log, which say why.
    pub log_tail: Vec<String>,
    /// A crash (an error exit, a panic, a fault), not a kill from outside.
    pub crashed: bool,
}

impl std::fmt::Display for Death {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {}", self.who, self.status)?;
        for line in &self.log_tail {
            write!(f, "\n    | {line}")?;
        }
        Ok(())
    }
}

/// Lines of a dead process's log shown to the user.
const LOG_TAIL_LINES: usize = 6;

/// The log of helper `binary` in the swarm's folder.
pub(crate) fn helper_log_name(binary: &str) -> String {
    format!("{binary}.log")
}

impl Death {
    /// The death of `who`, with the end of its log `log`; none for a clean
    /// exit (status 0), which a process makes only when asked to (SIGTERM,
    /// or the Ctrl-C that reaches the whole terminal's process group).
    pub(crate) fn unless_clean(
        who: String,
        status: std::process::ExitStatus,
        runtime: &SwarmRuntime,
        log: &str,
    ) -> Option<Self> {
        (!status.success()).then(|| Self::of(who, status, runtime.log_tail(log, LOG_TAIL_LINES)))
    }

    fn of(who: String, status: std::process::ExitStatus, log_tail: Vec<String>) -> Self {
        use std::os::unix::process::ExitStatusExt;
        let (status, crashed) = match (status.code(), status.signal()) {
            (Some(code), _) => (format!("exited with status {code}"), code != 0),
            // Killed from outside (kill -9, SIGTERM, a closed terminal, the
            // kernel's OOM killer): said, but not a crash of ours.
            (_, Some(sig))
                if [libc::SIGKILL, libc::SIGTERM, libc::SIGINT, libc::SIGHUP].contains(&sig) =>
            {
                (
                    format!("was killed by signal {sig} ({})", signal_name(sig)),
                    false,
                )
            }
            (_, Some(sig)) => (format!("died of signal {sig} ({})", signal_name(sig)), true),
            _ => (format!("ended: {status}"), true),
        };
        Self {
            who,
            status,
            log_tail,
            crashed,
        }
    }
}

fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        libc::SIGINT => "SIGINT",
        libc::SIGHUP => "SIGHUP",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGABRT => "SIGABRT",
        libc::SIGBUS => "SIGBUS",
        libc::SIGFPE => "SIGFPE",
        libc::SIGILL => "SIGILL",
        _ => "signal",
    }
}

impl Children {
    /// Collects exited robots so they do not linger as zombies, and notes
    /// those that nobody asked to stop.
    /// Returns how many ended.
    pub(crate) fn reap(&mut self, runtime: &SwarmRuntime) -> usize {
        let mut ended = Vec::new();
        self.running.retain(|id, child| match child.try_wait() {
            Ok(None) => true,
            Ok(Some(status)) => {
                ended.push((*id, status));
                false
            }
            Err(_) => false,
        });
        let count = ended.len();
        for (id, status) in ended {
            let asked = runtime.take_stopped_by_user(id);
            if !asked {
                let log = SwarmRuntime::agent_log_name(id);
                self.deaths.extend(Death::unless_clean(
                    format!("robot {id}"),
                    status,
                    runtime,
                    &log,
                ));
            }
        }
        count
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::process::ExitStatusExt;

    /// An error exit or a fault is a crash; a kill from outside is said but
    /// is not a crash of ours.
    #[test]
    fn a_death_says_how_it_ended_and_whether_it_was_a_crash() {
        let exited = Death::of(
            "robot 3".into(),
            std::process::ExitStatus::from_raw(1 << 8),
            vec!["boom".into()],
        );
        assert!(exited.crashed);
        assert_eq!(
            exited.to_string(),
            "robot 3 exited with status 1\n    | boom"
        );
        let killed = Death::of(
            "robot 4".into(),
            std::process::ExitStatus::from_raw(libc::SIGKILL),
            vec![],
        );
        assert!(!killed.crashed);
        assert_eq!(killed.status, "was killed by signal 9 (SIGKILL)");
        let faulted = Death::of(
            "shoal-slam".into(),
            std::process::ExitStatus::from_raw(libc::SIGSEGV),
            vec![],
        );
        assert!(faulted.crashed);
        assert!(faulted.status.contains("SIGSEGV"), "{}", faulted.status);
    }
}
