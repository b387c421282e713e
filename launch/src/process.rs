//! Starting and signalling robot processes.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

use anyhow::{Context, Result, bail};
use shoal_physics::Pose;

/// The `shoal-agent` binary beside this executable.
pub fn agent_binary() -> Result<PathBuf> {
    let me = std::env::current_exe().context("locating the shoal executable")?;
    let agent = me.with_file_name("shoal-agent");
    if !agent.exists() {
        bail!("{} not found: build the whole workspace (cargo build --release)", agent.display());
    }
    Ok(agent)
}

/// Starts robot `id` at `pose`, its log going to `log`. A `detached` robot
/// gets a session of its own, so it outlives the command that started it and
/// a Ctrl-C in that terminal does not reach it.
pub fn start_agent(swarm: &str, id: u32, pose: Pose, log: &std::path::Path, detached: bool) -> Result<Child> {
    let log_file = std::fs::File::create(log).with_context(|| format!("creating {}", log.display()))?;
    let mut command = Command::new(agent_binary()?);
    command
        .args(["--swarm", swarm, "--id", &id.to_string(), "--at", &format!("{},{},{}", pose.x, pose.y, pose.theta)])
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
    command.spawn().with_context(|| format!("starting robot {id}"))
}

/// Whether `pid` is a running (not zombie) process.
pub fn pid_alive(pid: i32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        // The state letter follows the parenthesised command name.
        Ok(stat) => stat.rsplit_once(')').and_then(|(_, rest)| rest.trim_start().chars().next()).is_some_and(|s| s != 'Z' && s != 'X'),
        Err(_) => false,
    }
}

pub fn signal(pid: i32, signal: i32) -> Result<()> {
    // SAFETY: kill has no memory-safety preconditions.
    if unsafe { libc::kill(pid, signal) } != 0 {
        bail!("cannot signal pid {pid}: {}", std::io::Error::last_os_error());
    }
    Ok(())
}
