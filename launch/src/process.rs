//! Starting and signalling robot processes.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

use anyhow::{Context, Result, bail};
use shoal_physics::Pose;

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

/// Asks `pids` to stop (SIGTERM), waits up to `grace` for them, then kills
/// those left (SIGKILL). Returns how many had to be killed.
pub fn stop_processes(pids: &[i32], grace: std::time::Duration) -> usize {
    for pid in pids {
        let _ = signal(*pid, libc::SIGTERM);
    }
    let deadline = std::time::Instant::now() + grace;
    while std::time::Instant::now() < deadline && pids.iter().any(|p| pid_alive(*p)) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let stubborn: Vec<i32> = pids.iter().copied().filter(|p| pid_alive(*p)).collect();
    for pid in &stubborn {
        tracing::warn!(pid, "process ignored SIGTERM; killing it");
        let _ = signal(*pid, libc::SIGKILL);
    }
    stubborn.len()
}

/// Starts robot `id` at `pose`, its log going to the swarm's folder.
pub fn start_agent(
    swarm: &str,
    id: u32,
    pose: Pose,
    runtime: &shoal_broker::SwarmRuntime,
    tie: Tie,
) -> Result<Child> {
    let log_file = runtime.create_log(&shoal_broker::SwarmRuntime::agent_log_name(id))?;
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
    tie.apply(&mut command);
    command
        .spawn()
        .with_context(|| format!("starting robot {id}"))
}

/// Whether `pid` is a running (not zombie) process.
pub fn pid_alive(pid: i32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        // The state letter follows the parenthesised command name.
        Ok(stat) => stat
            .rsplit_once(')')
            .and_then(|(_, rest)| rest.trim_start().chars().next())
            .is_some_and(|s| s != 'Z' && s != 'X'),
        Err(_) => false,
    }
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
