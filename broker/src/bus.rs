use core::fmt::Debug;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{
    event as event_factory, publish_subscribe as pubsub_factory,
};

pub use crate::error::BusError;
use crate::names;

/// A publish-subscribe service and the limits every process opens it with.
#[derive(Clone, Debug)]
pub(crate) struct Topic {
    pub name: String,
    pub publishers: usize,
    pub subscribers: usize,
    /// Unread samples a subscriber holds per publisher before the oldest
    /// are overwritten.
    pub buffer: usize,
    /// Samples a late subscriber still receives.
    pub history: usize,
}

/// Sizes of the swarm's services. iceoryx2's defaults (2 publishers, 8
/// subscribers, 20 nodes per service) are far too small for a swarm, and every
/// process must open a service with the same limits, so they live in one place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusLimits {
    /// Robots that may publish into one spatial cell.
    pub max_per_cell: usize,
    /// Robots that may listen to one spatial cell. Every send visits every
    /// listener slot, so this bounds what a robot's pose costs to publish.
    pub max_listeners_per_cell: usize,
    /// Robots in the whole swarm.
    pub max_agents: usize,
    /// Observers (status, recorder, SLAM, clock) that read the whole swarm.
    pub max_observers: usize,
}

impl Default for BusLimits {
    fn default() -> Self {
        Self {
            max_per_cell: 24,
            max_listeners_per_cell: 216,
            max_agents: 2048,
            max_observers: 16,
        }
    }
}

impl BusLimits {
    /// The limits a scenario's `[bus]` section sets; every process of a
    /// swarm opens its services with these.
    pub fn of(bus: &BusSection) -> Self {
        Self {
            max_per_cell: bus.max_per_cell,
            max_listeners_per_cell: bus.max_listeners_per_cell,
            ..Self::default()
        }
    }

    pub fn cell_subscribers(&self) -> usize {
        self.max_listeners_per_cell + self.max_observers
    }
}

/// The narrowest cell, metres.
const MIN_CELL_M: f64 = 0.1;
/// Each cell a robot listens to is a service it opens.
const MAX_LISTENED_CELLS: f64 = 1024.0;
const MAX_RING: usize = 16;
const MAX_PER_CELL: usize = 1024;
const MAX_LISTENERS_PER_CELL: usize = 16_384;

/// The scenario's `[bus]` section: the cells robots publish and listen in,
/// and how many may share one.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BusSection {
    /// Side of a spatial cell: a robot publishes into the cell it stands in
    /// and listens to the cells near it, so its cost follows local density,
    /// not swarm size. Smaller cells fit what it listens to closer to what it
    /// senses (fewer robots heard for nothing) but cost more services, and
    /// each service a robot listens to costs more than a robot it hears
    /// (BENCHMARKS.md, build f467245: 1.75 m cells took more CPU and twice the
    /// memory of 3.5 m ones).
    pub cell_size: f64,
    /// How far one ring of listening reaches, metres: a robot listens to
    /// every cell within `ring * listen_step` of it and senses robots up to
    /// a metre short of that.
    pub listen_step: f64,
    /// How many rings a robot widens its listening to when it sees fewer
    /// robots than it tracks.
    pub max_ring: u32,
    /// The most robots that may publish in one cell at once.
    pub max_per_cell: usize,
    /// The most robots that may listen to one cell at once.
    pub max_listeners_per_cell: usize,
}

impl Default for BusSection {
    fn default() -> Self {
        Self {
            cell_size: 3.5,
            listen_step: 3.5,
            max_ring: 3,
            max_per_cell: 24,
            max_listeners_per_cell: 216,
        }
    }
}

impl shoal_scenario::Section for BusSection {
    const NAME: &'static str = "bus";

    /// The cells and their services: no robot may listen to more cells than
    /// the bus can hold.
    fn check(&self, check: &mut shoal_scenario::RangeCheck) {
        let max_arena = shoal_scenario::MAX_ARENA_M;
        check.number("cell_size", self.cell_size, MIN_CELL_M, true, max_arena);
        check.number("listen_step", self.listen_step, MIN_CELL_M, true, max_arena);
        check.count("max_ring", self.max_ring as usize, 0, MAX_RING);
        let widest =
            2.0 * f64::from(self.max_ring.max(1)) * self.listen_step / self.cell_size + 2.0;
        if widest * widest > MAX_LISTENED_CELLS {
            check.fail(
                "cell_size",
                format!(
                    "{} m cells would have a robot listening to up to {:.0} cells at its widest \
                 ({} rings of {} m); at most {MAX_LISTENED_CELLS} are allowed",
                    self.cell_size,
                    widest * widest,
                    self.max_ring,
                    self.listen_step
                ),
            );
        }
        check.count("max_per_cell", self.max_per_cell, 1, MAX_PER_CELL);
        check.count(
            "max_listeners_per_cell",
            self.max_listeners_per_cell,
            self.max_per_cell,
            MAX_LISTENERS_PER_CELL,
        );
    }
}

/// iceoryx2 warns on stdout that it found no config file; its defaults are
/// what we want, so only its errors are shown (`IOX2_LOG_LEVEL` overrides).
pub fn quiet_iceoryx() {
    set_log_level_from_env_or(LogLevel::Error);
}

/// Set by SIGINT or SIGTERM and never cleared, for the whole process.
///
/// iceoryx2 alone is not enough: it keeps only the last signal, in one
/// slot that reading clears, and it also clears that slot whenever it
/// creates a shared-memory segment (it watches the segment's zeroing for
/// signals). A Ctrl-C or SIGTERM that arrived while a process opened
/// services was lost: robots crossing cells "ignored SIGTERM" and were
/// killed after the grace, and `shoal up` went on starting robots after
/// Ctrl-C.
static TERMINATION: OnceLock<Arc<AtomicBool>> = OnceLock::new();

/// Holds SIGINT and SIGTERM back from this thread while it exists. A
/// process has no handler for them until its first node is made (iceoryx2
/// installs its own then, and Shoal's after it), so one that arrived while
/// iceoryx2 was still making the node ended the process half way: 2 of 100
/// robots sent SIGTERM as they started left a node folder holding only its
/// details file, which iceoryx2 lists as neither alive nor dead and no
/// sweep removes. Held back, the signal arrives once the handlers exist,
/// and the process ends as on any other SIGTERM.
struct TerminationDeferred {
    previous: libc::sigset_t,
}

impl TerminationDeferred {
    fn new() -> Self {
        // SAFETY: the sets are plain data owned here; sigemptyset and
        // sigaddset only fill them, and pthread_sigmask changes this
        // thread's mask alone.
        unsafe {
            let mut termination: libc::sigset_t = core::mem::zeroed();
            let mut previous: libc::sigset_t = core::mem::zeroed();
            libc::sigemptyset(&mut termination);
            libc::sigaddset(&mut termination, libc::SIGINT);
            libc::sigaddset(&mut termination, libc::SIGTERM);
            libc::pthread_sigmask(libc::SIG_BLOCK, &termination, &mut previous);
            Self { previous }
        }
    }
}

impl Drop for TerminationDeferred {
    fn drop(&mut self) {
        // SAFETY: restores the mask this thread had; a signal held back
        // meanwhile is delivered now.
        unsafe {
            libc::pthread_sigmask(libc::SIG_SETMASK, &self.previous, core::ptr::null_mut());
        }
    }
}

/// Whether SIGINT or SIGTERM arrived since this process first joined a
/// swarm: for a thread that holds no bus of its own.
pub fn termination_signalled() -> bool {
    TERMINATION
        .get()
        .is_some_and(|flag| flag.load(Ordering::Relaxed))
}

/// The process's termination flag, registered once. iceoryx2 installs its
/// signal handlers on first use without keeping earlier ones, so it is
/// made to install them first (a wait on `node`); signal-hook's handlers
/// then call iceoryx2's after setting the flag.
fn termination_flag(node: &Node<ipc::Service>) -> Arc<AtomicBool> {
    Arc::clone(TERMINATION.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        if node.wait(core::time::Duration::ZERO).is_err() {
            flag.store(true, Ordering::Relaxed);
        }
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            if let Err(e) = signal_hook::flag::register(signal, Arc::clone(&flag)) {
                tracing::warn!("cannot watch signal {signal}: {e}; relying on iceoryx2's handler");
            }
        }
        flag
    }))
}

/// Room each subscriber keeps for samples of publishers that went away.
/// iceoryx2's default is 128; a subscriber's connection storage (about
/// 3.6 KB a slot) is allocated at once for its service's publishers plus
/// these, so 128 made every cell subscriber 544 KB: most of a robot's
/// private memory. Shoal's subscribers borrow at most 2 samples (iceoryx2's
/// default, which this must not be below) and copy each out at once.
const EXPIRED_CONNECTION_BUFFER: usize = 4;

/// Gives the memory of dropped ports back to the system. A subscriber's
/// connection storage (about 100 KB, sized for its cell's publishers and
/// touched whole when made) comes from the heap, and glibc keeps what is
/// freed in the middle of the heap resident: a robot that had crossed cells
/// or listened wider while the swarm gathered kept the storage of every
/// subscriber it had dropped. `malloc_trim` hands those pages back; it is
/// called only when a robot has dropped a port.
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free pages of glibc's heap to the
    // system; it takes the allocator's lock like any allocation.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// The iceoryx2 domain of this process's host
/// ([`shoal_runtime::host`]): iceoryx2's global configuration, with files
/// under a prefix of the host's own when the host is not this machine's
/// (iceoryx2's way to keep groups of processes apart on one machine).
pub fn domain_config() -> Config {
    let mut config = Config::global_config().clone();
    let host = shoal_runtime::host::current();
    if host.separate {
        // A host name is letters, digits, `-` and `_`: a valid file name.
        match FileName::new(format!("shoal_{}_", host.name).as_bytes()) {
            Ok(prefix) => config.global.prefix = prefix,
            Err(e) => tracing::error!("host `{}` cannot name iceoryx2 files: {e:?}", host.name),
        }
    }
    config
}

/// The folder where iceoryx2 keeps this host's node and service files:
/// its `global.root-path`, which iceoryx2 reads from its configuration
/// files (`config/iceoryx2.toml`, `~/.config/iceoryx2/iceoryx2.toml`,
/// `/etc/iceoryx2/iceoryx2.toml`) for every iceoryx2 program alike.
pub fn iceoryx_root() -> std::path::PathBuf {
    domain_config().global.root_path().to_string().into()
}

/// Whether `path`, or the nearest folder above it that exists, is on a
/// file system in memory (tmpfs, ramfs); `None` if that cannot be told.
pub fn in_memory(path: &std::path::Path) -> Option<bool> {
    use std::os::unix::ffi::OsStrExt;
    const RAMFS_MAGIC: i64 = 0x8584_58f6;
    let existing = path.ancestors().find(|p| p.exists())?;
    let name = std::ffi::CString::new(existing.as_os_str().as_bytes()).ok()?;
    // SAFETY: statfs writes into the zeroed struct we own; `name` is a
    // valid C string for the call's duration.
    let mut fs: libc::statfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statfs(name.as_ptr(), &mut fs) } != 0 {
        return None;
    }
    // f_type and the constants are of different widths on other targets.
    #[allow(clippy::unnecessary_cast)]
    let (kind, tmpfs) = (fs.f_type as i64, libc::TMPFS_MAGIC as i64);
    Some(kind == tmpfs || kind == RAMFS_MAGIC)
}

/// iceoryx2's configuration for this host's domain, with Shoal's changes.
fn node_config() -> Config {
    let mut config = domain_config();
    config
        .defaults
        .publish_subscribe
        .subscriber_expired_connection_buffer = EXPIRED_CONNECTION_BUFFER;
    // By default every node, when created and when dropped, lists every node
    // on the machine to clean up the dead ones: reading each one's details
    // file. A thousand robots starting made that a million reads, and the
    // machine spent its start-up on it (BENCHMARKS.md, "1000 robots in real time"). Dead
    // nodes are still cleaned where it matters: iceoryx2 cleans those of a
    // service whenever a robot opens it, the launcher sweeps when a robot of
    // its own ends, a robot sweeps when a neighbour's process is gone, and
    // `shoal down` sweeps what a killed swarm left.
    config.global.node.cleanup_dead_nodes_on_creation = false;
    config.global.node.cleanup_dead_nodes_on_destruction = false;
    config.global.service.cleanup_dead_nodes_on_open = false;
    config
}

/// One process's connection to one swarm.
pub struct Bus {
    pub node: Node<ipc::Service>,
    pub swarm: String,
    pub limits: BusLimits,
    terminating: Arc<AtomicBool>,
}

impl Bus {
    /// Joins swarm `swarm` as a node called `node_name`.
    pub fn join(swarm: &str, node_name: &str, limits: BusLimits) -> Result<Self, BusError> {
        names::validate_swarm(swarm)?;
        quiet_iceoryx();
        let name = NodeName::new(node_name)
            .map_err(|e| BusError::iceoryx(format!("node name {node_name}"), e))?;
        let deferred = TerminationDeferred::new();
        let node = NodeBuilder::new()
            .name(&name)
            .config(&node_config())
            .create::<ipc::Service>()
            .map_err(|e| BusError::iceoryx(format!("create node {node_name}"), e))?;
        let terminating = termination_flag(&node);
        drop(deferred);
        Ok(Self {
            terminating,
            node,
            swarm: swarm.to_owned(),
            limits,
        })
    }

    /// Joins swarm `swarm` as a tool that serves it (a recorder, SLAM,
    /// `shoal status`, a test's observer), not as a robot: its node is
    /// `shoal/<swarm>/<role>`, which liveness and the launcher tell apart
    /// from robots by name.
    pub fn join_tool(swarm: &str, role: &str, limits: BusLimits) -> Result<Self, BusError> {
        Self::join(swarm, &names::tool_node(swarm, role), limits)
    }

    pub fn service_name(name: &str) -> Result<ServiceName, BusError> {
        ServiceName::new(name).map_err(|e| BusError::iceoryx(format!("service name {name}"), e))
    }

    pub(crate) fn publish_subscribe<T: Debug + ZeroCopySend + 'static>(
        &self,
        topic: &Topic,
    ) -> Result<pubsub_factory::PortFactory<ipc::Service, T, ()>, BusError> {
        self.node
            .service_builder(&Self::service_name(&topic.name)?)
            .publish_subscribe::<T>()
            .max_publishers(topic.publishers)
            .max_subscribers(topic.subscribers)
            .max_nodes(topic.publishers + topic.subscribers)
            .subscriber_max_buffer_size(topic.buffer)
            .history_size(topic.history)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| BusError::iceoryx(format!("open {}", topic.name), e))
    }

    pub(crate) fn event(
        &self,
        name: &str,
        notifiers: usize,
        listeners: usize,
    ) -> Result<event_factory::PortFactory<ipc::Service>, BusError> {
        self.node
            .service_builder(&Self::service_name(name)?)
            .event()
            .max_notifiers(notifiers)
            .max_listeners(listeners)
            .max_nodes(notifiers + listeners)
            .open_or_create()
            .map_err(|e| BusError::iceoryx(format!("open {name}"), e))
    }

    /// Whether a termination signal (SIGTERM, SIGINT) arrived, at any time
    /// since the process joined a swarm.
    pub fn termination_requested(&self) -> bool {
        if self.terminating.load(Ordering::Relaxed) {
            return true;
        }
        let requested = self.node.wait(core::time::Duration::ZERO).is_err();
        if requested {
            self.terminating.store(true, Ordering::Relaxed);
        }
        requested
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dev_shm_is_in_memory_and_a_missing_folder_is_judged_by_its_parent() {
        assert_eq!(in_memory(std::path::Path::new("/dev/shm")), Some(true));
        assert_eq!(
            in_memory(std::path::Path::new("/dev/shm/no/such/folder")),
            Some(true)
        );
        assert_eq!(in_memory(std::path::Path::new("/proc")), Some(false));
    }
}

#[cfg(test)]
mod section_tests {
    use super::*;
    use shoal_scenario::Scenario;

    const BASE: &str = "[arena]\nwidth = 10.0\nheight = 10.0\n[agents]\ncount = 3\nstart_region = [1.0, 1.0, 9.0, 9.0]\n";

    #[test]
    fn the_bus_section_is_range_checked_naming_file_line_and_field() {
        let cases = [
            ("[bus]\ncell_size = 1e-9\n", "bus.cell_size", 8),
            ("[bus]\nmax_per_cell = 0\n", "bus.max_per_cell", 8),
            ("[bus]\nmax_ring = \"three\"\n", "bus.max_ring", 8),
            ("[bus]\nlisten_distance = 3.0\n", "bus.listen_distance", 8),
        ];
        for (extra, field, line) in cases {
            let text = format!("{BASE}{extra}");
            let scenario =
                Scenario::from_toml(&text, "s.toml").expect("the scenario's own sections are fine");
            let error = scenario.section::<BusSection>().unwrap_err();
            assert_eq!(error.file, "s.toml", "{error}");
            assert_eq!(error.field.as_deref(), Some(field), "{error}");
            assert_eq!(error.line, Some(line), "{error}");
        }
    }

    #[test]
    fn a_scenario_without_a_bus_section_has_the_default_one_and_a_set_one_round_trips() {
        let mut scenario = Scenario::from_toml(BASE, "s.toml").expect("valid");
        assert_eq!(scenario.section::<BusSection>(), Ok(BusSection::default()));
        let bus = BusSection {
            max_listeners_per_cell: 300,
            ..BusSection::default()
        };
        scenario
            .set_section(&bus)
            .expect("a bus section is a scenario's");
        let text = scenario.to_toml().expect("writes");
        let read = Scenario::from_toml(&text, "again.toml").expect("reads back");
        assert_eq!(read.section::<BusSection>(), Ok(bus));
    }
}
