//! Which host's part of a swarm a process belongs to.
//!
//! A swarm may span machines (`shoal up --link zenoh`); each machine's part
//! is a *host*, named by `--host` (default: the machine's name). On one
//! machine, two hosts are kept apart exactly as two machines would be: each
//! has its own iceoryx2 domain (shared-memory files under its own prefix)
//! and its own runtime folder. The machine's own name keeps iceoryx2's
//! default domain and the usual folder, so a swarm on one machine, and every
//! client that reads it with iceoryx2's defaults, is unchanged.
//!
//! The host travels to every process of it in [`HOST_ENV`]: the launcher
//! sets it on each child ([`pass_to`]), and `SHOAL_HOST=b shoal status`
//! works as `shoal status --host b` does.

use std::sync::OnceLock;

pub const HOST_ENV: &str = "SHOAL_HOST";

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Host {
    pub name: String,
    /// Not this machine's own name: the host has a domain and folder of its own.
    pub separate: bool,
}

#[derive(Debug, thiserror::Error)]
#[error(
    "invalid host name `{0}`: use letters, digits, `-` and `_` (at most 32), e.g. --host lab-a"
)]
pub struct InvalidHost(pub String);

static CURRENT: OnceLock<Host> = OnceLock::new();

/// Whether `name` is 1-32 letters, digits, `-` and `_`: what a swarm or
/// host name may be, since it becomes part of file, service and Zenoh key
/// names.
pub fn is_plain_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 32
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

/// Checks a host name (see [`is_plain_name`]).
pub fn validate(name: &str) -> Result<(), InvalidHost> {
    if is_plain_name(name) {
        Ok(())
    } else {
        Err(InvalidHost(name.to_owned()))
    }
}

/// This machine's name as a host name: the hostname's first label, with
/// anything a host name may not hold replaced by `-`.
pub fn machine_name() -> String {
    let raw = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    let label: String = raw
        .trim()
        .split('.')
        .next()
        .unwrap_or_default()
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .take(32)
        .collect();
    if label.is_empty() {
        "localhost".to_owned()
    } else {
        label
    }
}

/// The host called `name` (already validated).
pub fn host_named(name: String) -> Host {
    let separate = name != machine_name();
    Host { name, separate }
}

/// Sets this process's host (the command line's `--host`); without one,
/// [`HOST_ENV`] or the machine's name. Call it before anything joins a
/// swarm: the first answer is kept for the life of the process.
pub fn choose(name: Option<&str>) -> Result<&'static Host, InvalidHost> {
    let name = match name {
        Some(name) => name.to_owned(),
        None => match std::env::var(HOST_ENV) {
            Ok(name) if !name.is_empty() => name,
            _ => machine_name(),
        },
    };
    validate(&name)?;
    let chosen = CURRENT.get_or_init(|| host_named(name.clone()));
    if chosen.name != name {
        // Only a bug can ask twice with different names; keep the first.
        tracing::error!("host already chosen as `{}`, not `{name}`", chosen.name);
    }
    Ok(chosen)
}

/// This process's host: as chosen, else from [`HOST_ENV`], else this
/// machine. An invalid [`HOST_ENV`] falls back to the machine, with a
/// warning: every binary checks it at start through [`choose`].
pub fn current() -> &'static Host {
    CURRENT.get_or_init(|| match std::env::var(HOST_ENV) {
        Ok(name) if validate(&name).is_ok() => host_named(name),
        Ok(name) if !name.is_empty() => {
            tracing::warn!("{}; using this machine's name", InvalidHost(name));
            host_named(machine_name())
        }
        _ => host_named(machine_name()),
    })
}

/// Makes a child process belong to this process's host.
pub fn pass_to(command: &mut std::process::Command) {
    command.env(HOST_ENV, &current().name);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn host_names_are_restricted_and_the_machine_name_is_one() {
        assert!(validate("lab-a_2").is_ok());
        assert!(validate("").is_err());
        assert!(validate("a.b").is_err());
        assert!(validate(&"x".repeat(33)).is_err());
        assert!(validate(&machine_name()).is_ok());
        assert!(!host_named(machine_name()).separate);
        assert!(host_named(format!("{}-other", machine_name())).separate);
    }
}
