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

/// Starts robot `id` at `pose`, its log going to `log`. A `detached` robot
/// gets a session of its own, so it outlives the command that started it and
/// a Ctrl-C in that terminal does not reach it.
pub fn start_agent(
    swarm: &str,
    id: u32,
    pose: Pose,
    log: &std::path::Path,
    detached: bool,
) -> Result<Child> {
    let log_file =
        std::fs::File::create(log).with_context(|| format!("creating {}", log.display()))?;
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
    if detached {
        use std::os::unix::process::CommandExt;
        // SAFETY: setsid is async-signal-safe and touches no memory of ours.
        unsafe {
            command.pre_exec(|| {
                libc::setsid();
                Ok(())
            });
        }
    }
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
