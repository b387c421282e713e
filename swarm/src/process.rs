//! Starting and signalling robot processes.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

use anyhow::{Context, Result, bail};
use shoal_physics::Pose;

/// The helpers' binaries, beside this executable.
pub const RECORDER_BINARY: &str = "shoal-viewer-log";
pub const SLAM_BINARY: &str = "shoal-slam";
pub const LINK_BINARY: &str = "shoal-link";

/// The highest robot id a command accepts: ids index start poses, which
/// are drawn in order, so an id of a million would take minutes to place.
pub const MAX_ROBOT_ID: u32 = 65_535;

/// Refuses `count` robots from id `first` when they would pass the highest
/// id Shoal runs.
pub fn check_id_range(first: u32, count: usize) -> Result<()> {
    if u64::from(first) + count as u64 > u64::from(MAX_ROBOT_ID) + 1 {
        bail!(
            "{count} robots from id {first} would pass the highest id Shoal runs, {MAX_ROBOT_ID}"
        );
    }
    Ok(())
}

/// A workspace binary beside this executable.
pub fn sibling_binary(name: &str) -> Result<PathBuf> {
    let me = std::env::current_exe().context("locating the shoal executable")?;
    let path = me.with_file_name(name);
    if !path.exists() {
        bail!(
            "{} not found: build the whole workspace (cargo build --release --workspace)",
            path.display()
        );
    }
    Ok(path)
}

/// How a started process is tied to the one that starts it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tie {
    /// A session of its own: it outlives the command that started it, and a
    /// Ctrl-C in that terminal does not reach it (`shoal restart`, `spawn`).
    Detached,
    /// A plain child: a real-time swarm goes on without its launcher.
    Child,
    /// SIGTERM when the launcher dies, even by SIGKILL: a lockstep robot or
    /// helper would otherwise wait forever for ticks that never come.
    DiesWithLauncher,
}

impl Tie {
    /// Ties the process `command` will start accordingly.
    pub fn apply(self, command: &mut Command) {
        match self {
            Tie::Detached => {
                use std::os::unix::process::CommandExt;
                // SAFETY: setsid is async-signal-safe and touches no memory of ours.
                unsafe {
                    command.pre_exec(|| {
                        libc::setsid();
                        Ok(())
                    });
                }
            }
            Tie::DiesWithLauncher => die_with_parent(command),
            Tie::Child => {}
        }
    }
}

/// Asks the kernel to send `command`'s process SIGTERM when this process
/// dies (Linux's parent-death signal).
fn die_with_parent(command: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: getpid is taken before the fork; in the child, prctl, getppid
    // and kill are async-signal-safe and touch no memory of ours.
    let parent = unsafe { libc::getpid() };
    unsafe {
        command.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // The parent may have died before the call above took effect.
            if libc::getppid() != parent {
                libc::kill(libc::getpid(), libc::SIGTERM);
            }
            Ok(())
        });
    }
}

/// One process held by a pidfd: a signal sent through it reaches that
/// process or nothing, never a later process that reuses its pid.
pub struct Pinned {
    pid: i32,
    fd: std::os::fd::OwnedFd,
}

impl Pinned {
    /// Pins `pid` if it runs a Shoal binary (`shoal`, `shoal-agent`, ...); a
    /// pid from the bus may by now belong to anyone, and a Python reader on
    /// the bus is the user's, not Shoal's to stop.
    pub fn shoal_process(pid: i32) -> Option<Self> {
        let pinned = Self::open(pid)?;
        // Read after pinning: if the pid was reused in between, the pidfd
        // names the old, dead process, and signalling it does nothing.
        let exe = std::fs::read_link(format!("/proc/{pid}/exe")).ok()?;
        let name = exe.file_name()?.to_str()?;
        (name == "shoal" || name.starts_with("shoal-")).then_some(pinned)
    }

    /// Pins our own child, whose pid cannot be reused before we reap it.
    pub fn child(child: &Child) -> Option<Self> {
        Self::open(child.id() as i32)
    }

    fn open(pid: i32) -> Option<Self> {
        use std::os::fd::FromRawFd;
        if pid <= 0 {
            return None;
        }
        // SAFETY: pidfd_open takes a pid and flags and returns a new fd or -1.
        let fd = unsafe { libc::syscall(libc::SYS_pidfd_open, pid, 0) };
        if fd < 0 {
            return None;
        }
        // SAFETY: the fd was just opened and nothing else owns it.
        let fd = unsafe { std::os::fd::OwnedFd::from_raw_fd(fd as i32) };
        Some(Self { pid, fd })
    }

    pub fn pid(&self) -> i32 {
        self.pid
    }

    pub fn signal(&self, signal: i32) -> Result<()> {
        use std::os::fd::AsRawFd;
        // SAFETY: pidfd_send_signal with a null siginfo behaves like kill(2).
        let sent = unsafe {
            libc::syscall(
                libc::SYS_pidfd_send_signal,
                self.fd.as_raw_fd(),
                signal,
                std::ptr::null::<libc::siginfo_t>(),
                0,
            )
        };
        if sent != 0 {
            bail!(
                "cannot signal pid {}: {}",
                self.pid,
                std::io::Error::last_os_error()
            );
        }
        Ok(())
    }

    /// Whether the process has ended (a pidfd turns readable when it does).
    pub fn ended(&self) -> bool {
        use std::os::fd::AsRawFd;
        let mut poll = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one valid pollfd, no wait.
        unsafe { libc::poll(&mut poll, 1, 0) > 0 }
    }
}

/// Asks `processes` to stop (SIGTERM), waits up to `grace` for them, then
/// kills those left (SIGKILL). Returns how many had to be killed.
pub fn stop_processes(processes: &[Pinned], grace: std::time::Duration) -> usize {
    for process in processes {
        let _ = process.signal(libc::SIGTERM);
    }
    let deadline = std::time::Instant::now() + grace;
    while std::time::Instant::now() < deadline && processes.iter().any(|p| !p.ended()) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let stubborn: Vec<&Pinned> = processes.iter().filter(|p| !p.ended()).collect();
    for process in &stubborn {
        tracing::warn!(pid = process.pid, "process ignored SIGTERM; killing it");
        let _ = process.signal(libc::SIGKILL);
    }
    stubborn.len()
}

/// Starts robot `id` at `pose`, its log going to the swarm's folder.
pub fn start_agent(
    swarm: &str,
    id: u32,
    pose: Pose,
    runtime: &shoal_runtime::SwarmRuntime,
    tie: Tie,
) -> Result<Child> {
    let log_file = runtime.create_log(&shoal_runtime::SwarmRuntime::agent_log_name(id))?;
    let mut command = Command::new(sibling_binary("shoal-agent")?);
    command
        .args([
            "--swarm",
            swarm,
            "--id",
            &id.to_string(),
            "--at",
            &format!("{},{},{}", pose.x, pose.y, pose.theta),
        ])
        .stdin(Stdio::null())
        .stdout(log_file.try_clone()?)
        .stderr(log_file);
    shoal_runtime::host::pass_to(&mut command);
    tie.apply(&mut command);
    command
        .spawn()
        .with_context(|| format!("starting robot {id}"))
}

pub fn signal(pid: i32, signal: i32) -> Result<()> {
    // SAFETY: kill has no memory-safety preconditions.
    if unsafe { libc::kill(pid, signal) } != 0 {
        bail!(
            "cannot signal pid {pid}: {}",
            std::io::Error::last_os_error()
        );
    }
    Ok(())
}

/// CPU time and memory of one process, from `/proc`.
#[derive(Clone, Copy, Debug, Default)]
pub struct ProcessUsage {
    pub cpu_s: f64,
    pub rss_mb: f64,
    pub private_mb: f64,
}

impl std::iter::Sum for ProcessUsage {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::default(), |a, b| Self {
            cpu_s: a.cpu_s + b.cpu_s,
            rss_mb: a.rss_mb + b.rss_mb,
            private_mb: a.private_mb + b.private_mb,
        })
    }
}

pub fn usage(pid: i32) -> Option<ProcessUsage> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name: state is 3rd, utime 14th, stime 15th.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    // SAFETY: sysconf has no preconditions.
    let per_second = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kb = |key: &str| {
        status
            .lines()
            .find(|l| l.starts_with(key))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    Some(ProcessUsage {
        cpu_s: ticks / per_second,
        rss_mb: kb("VmRSS:") / 1024.0,
        private_mb: kb("RssAnon:") / 1024.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pinned_process_is_signalled_until_it_ends_and_never_after() {
        let mut child = Command::new("sleep")
            .arg("30")
            .spawn()
            .expect("start sleep");
        let pid = child.id() as i32;
        // `sleep` is not a Shoal binary, so a pid from the bus naming it is left alone.
        assert!(Pinned::shoal_process(pid).is_none());
        let pinned = Pinned::child(&child).expect("pin our child");
        assert!(!pinned.ended());
        assert_eq!(
            stop_processes(
                std::slice::from_ref(&pinned),
                std::time::Duration::from_secs(5)
            ),
            0
        );
        assert!(pinned.ended());
        child.wait().expect("reap");
        // Reaped, its pid may now be anyone's; the pidfd still names the
        // dead process, so the signal goes nowhere.
        assert!(pinned.signal(libc::SIGKILL).is_err());
    }
}

#[cfg(test)]
mod id_tests {
    use super::*;

    #[test]
    fn robots_past_the_highest_id_are_refused() {
        assert!(check_id_range(0, MAX_ROBOT_ID as usize + 1).is_ok());
        assert!(check_id_range(1, MAX_ROBOT_ID as usize + 1).is_err());
        assert!(check_id_range(MAX_ROBOT_ID, 1).is_ok());
        let error = check_id_range(MAX_ROBOT_ID, 2).unwrap_err().to_string();
        assert!(error.contains("65535"), "{error}");
    }
}
