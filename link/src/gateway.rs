//! The gateway's loop: local poses out to Zenoh, remote poses into this
//! host's cells and roster, and a report for `shoal status`.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use shoal_broker::roster::{self, RosterReaders};
use shoal_broker::{
    Bus, BusLimits, BusSection, CellExchange, CellKey, PoseSample, RosterPublisher, SampleCheck,
    cell_at,
};
use shoal_link::interest::Interest;
use shoal_link::keys;
use shoal_link::report::{IdClash, LinkReport, LinkTraffic, RemoteHost, RemoteRobot};
use shoal_link::wire::{HostSummary, RemotePose};
use shoal_runtime::SwarmRuntime;
use shoal_scenario::Scenario;
use zenoh::Wait;
use zenoh::handlers::{FifoChannel, FifoChannelHandler};
use zenoh::pubsub::Subscriber;
use zenoh::sample::{Locality, Sample, SampleKind};

pub struct Options {
    pub swarm: String,
    pub zenoh_config: Option<PathBuf>,
    pub listen: Vec<String>,
    pub connect: Vec<String>,
}

/// How often a host tells the others who runs on it.
const SUMMARY_PERIOD: Duration = Duration::from_secs(1);
/// A host not summarised for this long is taken as gone for `shoal status`.
const SUMMARY_STALE: Duration = Duration::from_secs(3);
/// How long the link listens for the other hosts before it says it is
/// ready: long enough for each to have summarised itself once.
const LISTEN_FIRST: Duration = Duration::from_millis(1500);
/// How long the link waits for a host it found to summarise itself.
const GIVE_UP_WAITING: Duration = Duration::from_secs(5);
/// Zenoh buffers this many received samples per subscriber between polls.
const RECEIVE_BUFFER: usize = 8192;
const POLL: Duration = Duration::from_millis(1);

type Inbox = Subscriber<FifoChannelHandler<Sample>>;

/// A robot of another host, standing in for it in this host's bus.
struct Proxy {
    host: String,
    cells: CellExchange,
    roster: RosterPublisher,
    heard: Instant,
}

struct HostState {
    summary: Option<(HostSummary, Instant)>,
    /// Its liveliness token is present.
    present: bool,
}

struct Gateway {
    swarm: String,
    host: String,
    bus: Bus,
    runtime: SwarmRuntime,
    scenario: Scenario,
    /// The scenario's `[bus]` section: the cells every host publishes in.
    cells: BusSection,
    epoch_unix_ms: u64,
    session: zenoh::Session,
    roster: shoal_broker::RosterReader,
    roster_readers: RosterReaders,
    check: SampleCheck,
    /// This host's robots: their newest pose and when it came.
    local: BTreeMap<u32, (PoseSample, Instant)>,
    proxies: HashMap<u32, Proxy>,
    hosts: BTreeMap<String, HostState>,
    cell_inboxes: BTreeMap<CellKey, Inbox>,
    whole_swarm: Option<Inbox>,
    interest: Interest,
    clashes: BTreeSet<(u32, String)>,
    traffic: LinkTraffic,
    stale_after: Duration,
}

fn zenoh_error(what: &str) -> impl FnOnce(zenoh::Error) -> anyhow::Error + '_ {
    move |e| anyhow!("{what}: {e}")
}

/// Asks the other hosts for what they put on `key`, kept until polled.
fn inbox(session: &zenoh::Session, key: String, buffer: usize) -> Result<Inbox> {
    session
        .declare_subscriber(&key)
        .allowed_origin(Locality::Remote)
        .with(FifoChannel::new(buffer))
        .wait()
        .map_err(|e| anyhow!("listening to {key}: {e}"))
}

fn zenoh_config(options: &Options) -> Result<zenoh::Config> {
    let mut config = match &options.zenoh_config {
        Some(path) => zenoh::Config::from_file(path)
            .map_err(|e| anyhow!("{}: not a usable Zenoh configuration: {e}", path.display()))?,
        None => zenoh::Config::default(),
    };
    let endpoints = |list: &[String]| serde_json::to_string(list).unwrap_or_default();
    if !options.listen.is_empty() {
        config
            .insert_json5("listen/endpoints", &endpoints(&options.listen))
            .map_err(|e| anyhow!("--listen {:?}: {e}", options.listen))?;
    }
    if !options.connect.is_empty() {
        config
            .insert_json5("connect/endpoints", &endpoints(&options.connect))
            .map_err(|e| anyhow!("--connect {:?}: {e}", options.connect))?;
    }
    Ok(config)
}

/// Declares host `host` present in swarm `swarm`, unless another machine or
/// domain already is that host. The token goes when this link does.
fn claim_host(
    session: &zenoh::Session,
    swarm: &str,
    host: &str,
) -> Result<zenoh::liveliness::LivelinessToken> {
    let token_key = keys::host_token(swarm, host);
    let others = session
        .liveliness()
        .get(&token_key)
        .timeout(Duration::from_millis(500))
        .wait()
        .map_err(zenoh_error("asking which hosts are present"))?;
    while let Ok(reply) = others.recv() {
        if reply.result().is_ok() {
            bail!(
                "host `{host}` is already part of swarm `{swarm}` on another machine or domain; give this one another --host"
            );
        }
    }
    session
        .liveliness()
        .declare_token(&token_key)
        .wait()
        .map_err(zenoh_error("declaring this host present"))
}

pub fn run(options: &Options) -> Result<()> {
    let host = shoal_runtime::host::current().name.clone();
    let runtime = SwarmRuntime::locate(&options.swarm);
    let meta = runtime.read_meta()?;
    if meta.lockstep {
        bail!(
            "a lockstep swarm cannot span hosts: its clock waits on every robot through this machine's shared memory"
        );
    }
    let scenario = runtime.read_scenario()?;
    let cells: BusSection = scenario.section()?;
    let session = zenoh::open(zenoh_config(options)?)
        .wait()
        .map_err(zenoh_error("opening the Zenoh session"))?;
    let _token = claim_host(&session, &options.swarm, &host)?;
    let bus = Bus::join_tool(&options.swarm, "link", BusLimits::of(&cells))?;
    let hosts_inbox = session
        .liveliness()
        .declare_subscriber(keys::all_hosts(&options.swarm))
        .history(true)
        .with(FifoChannel::new(256))
        .wait()
        .map_err(zenoh_error("watching hosts"))?;
    let summaries = inbox(&session, keys::all_summaries(&options.swarm), 256)?;
    let mut gateway = Gateway {
        swarm: options.swarm.clone(),
        host,
        roster: roster::reader(&bus)?,
        roster_readers: RosterReaders::open(&bus)?,
        bus,
        check: SampleCheck::for_scenario(&scenario),
        interest: Interest::new(
            cells.cell_size,
            f64::from(cells.max_ring) * cells.listen_step,
        ),
        stale_after: Duration::from_secs_f64(scenario.timing.observer_stale_s()),
        scenario,
        cells,
        runtime,
        epoch_unix_ms: meta.epoch_unix_ms,
        session,
        local: BTreeMap::new(),
        proxies: HashMap::new(),
        hosts: BTreeMap::new(),
        cell_inboxes: BTreeMap::new(),
        whole_swarm: None,
        clashes: BTreeSet::new(),
        traffic: LinkTraffic::default(),
    };
    tracing::info!(host = gateway.host, swarm = gateway.swarm, "link up");
    let started = Instant::now();
    let mut last_summary = Instant::now() - SUMMARY_PERIOD;
    while !gateway.bus.termination_requested() && gateway.runtime.is_up() {
        gateway.send_local()?;
        gateway.receive_remote()?;
        while let Ok(Some(sample)) = summaries.try_recv() {
            gateway.heard_summary(&sample);
        }
        while let Ok(Some(sample)) = hosts_inbox.try_recv() {
            gateway.heard_host(&sample);
        }
        if last_summary.elapsed() >= SUMMARY_PERIOD {
            last_summary = Instant::now();
            gateway.expire();
            gateway.summarise()?;
            gateway.update_interest()?;
            gateway.report(started.elapsed())?;
        }
        std::thread::sleep(POLL);
    }
    tracing::info!("link down");
    Ok(())
}

impl Gateway {
    /// This host's robots' poses out to the hosts that want them.
    fn send_local(&mut self) -> Result<()> {
        let me = std::process::id();
        let now = Instant::now();
        let mut out = Vec::new();
        self.roster.receive(|sample| {
            // What this link stood in for another host is not this host's.
            if sample.pid != me {
                out.push(sample);
            }
        })?;
        for sample in out {
            self.local.insert(sample.agent_id, (sample, now));
            let key = keys::pose(
                &self.swarm,
                cell_at(self.cells.cell_size, sample.x, sample.y),
                &self.host,
                sample.agent_id,
            );
            let bytes = RemotePose {
                epoch_unix_ms: self.epoch_unix_ms,
                sample,
            }
            .encode();
            self.traffic.poses_offered += 1;
            self.traffic.bytes_offered += bytes.len() as u64;
            self.session
                .put(&key, bytes)
                .wait()
                .map_err(zenoh_error("sending a pose"))?;
        }
        Ok(())
    }

    /// Other hosts' poses into this host's cells and roster.
    fn receive_remote(&mut self) -> Result<()> {
        let mut received = Vec::new();
        // Zenoh delivers a pose once to each matching subscriber: while
        // every pose comes, the cells' copies are left unread.
        for inbox in self.cell_inboxes.values() {
            while let Ok(Some(sample)) = inbox.try_recv() {
                if self.whole_swarm.is_none() {
                    received.push(sample);
                }
            }
        }
        if let Some(inbox) = &self.whole_swarm {
            while let Ok(Some(sample)) = inbox.try_recv() {
                received.push(sample);
            }
        }
        for sample in received {
            self.stand_in(&sample)?;
        }
        Ok(())
    }

    fn stand_in(&mut self, message: &Sample) -> Result<()> {
        let bytes = message.payload().to_bytes();
        self.traffic.poses_received += 1;
        self.traffic.bytes_received += bytes.len() as u64;
        let Some((host, id)) = keys::pose_origin(&self.swarm, message.key_expr().as_str()) else {
            self.traffic.rejected += 1;
            return Ok(());
        };
        if host == self.host {
            return Ok(());
        }
        let pose = match RemotePose::decode(&bytes) {
            Ok(pose) if pose.sample.agent_id == id => pose,
            Ok(_) => {
                self.reject(&host, "its key and its robot id differ");
                return Ok(());
            }
            Err(e) => {
                self.reject(&host, &e.to_string());
                return Ok(());
            }
        };
        if self.local.contains_key(&id) {
            if self.clashes.insert((id, host.clone())) {
                tracing::error!(
                    "robot id {id} runs on host `{host}` and on this host `{}`: ids must be unique across the swarm (--first-id); host `{host}`'s robot {id} is not shown here",
                    self.host
                );
            }
            return Ok(());
        }
        let Some(mut sample) =
            pose.in_local_time(self.epoch_unix_ms, self.scenario.timing.period_s)
        else {
            return Ok(());
        };
        if !self.check.accept(&sample) {
            self.traffic.rejected += 1;
            return Ok(());
        }
        // Here the stand-in is this process: robots that check whether a
        // neighbour's process lives find this one, which lives as long as
        // the link carries the robot.
        sample.pid = std::process::id();
        let wanted_here =
            self.cell_inboxes
                .contains_key(&cell_at(self.cells.cell_size, sample.x, sample.y));
        let proxy = match self.proxies.entry(id) {
            std::collections::hash_map::Entry::Occupied(entry) => entry.into_mut(),
            std::collections::hash_map::Entry::Vacant(entry) => entry.insert(Proxy {
                host: host.clone(),
                cells: CellExchange::new(self.cells.cell_size),
                roster: roster::publisher(&self.bus)?,
                heard: Instant::now(),
            }),
        };
        proxy.heard = Instant::now();
        proxy.host = host;
        // Robots here hear it only where one of them listens: a far robot
        // goes to the roster alone, and opens no cell nobody needs.
        if wanted_here && let Err(e) = proxy.cells.publish(&self.bus, &sample) {
            tracing::warn!(
                "cannot stand in for robot {id}: {:#}",
                anyhow::Error::from(e)
            );
        }
        proxy.roster.publish(&sample)?;
        Ok(())
    }

    fn reject(&mut self, host: &str, why: &str) {
        self.traffic.rejected += 1;
        tracing::warn!("rejected a pose message from host `{host}`: {why}");
    }

    fn heard_summary(&mut self, message: &Sample) {
        let bytes = message.payload().to_bytes();
        match serde_json::from_slice::<HostSummary>(&bytes) {
            Ok(summary) if summary.host == keys::last_chunk(message.key_expr().as_str()) => {
                let state = self.hosts.entry(summary.host.clone()).or_insert(HostState {
                    summary: None,
                    present: true,
                });
                state.summary = Some((summary, Instant::now()));
            }
            Ok(_) => {
                self.traffic.rejected += 1;
                tracing::warn!("rejected a host summary whose key names another host");
            }
            Err(e) => {
                self.traffic.rejected += 1;
                tracing::warn!("rejected a malformed host summary: {e}");
            }
        }
    }

    /// A host's link came or went (its process ended, or Zenoh's lease ran
    /// out on a cut network): its robots go at once.
    fn heard_host(&mut self, message: &Sample) {
        let name = keys::last_chunk(message.key_expr().as_str()).to_owned();
        if name == self.host {
            return;
        }
        let present = message.kind() == SampleKind::Put;
        tracing::info!(
            host = name,
            present,
            "host {}",
            if present { "joined" } else { "left" }
        );
        if !present {
            self.proxies.retain(|_, proxy| proxy.host != name);
            self.clashes.retain(|(_, host)| *host != name);
        }
        let state = self.hosts.entry(name).or_insert(HostState {
            summary: None,
            present,
        });
        state.present = present;
        if !present {
            state.summary = None;
        }
    }

    /// Forgets robots silent for an observer's stale period.
    fn expire(&mut self) {
        let stale_after = self.stale_after;
        self.local
            .retain(|_, (_, heard)| heard.elapsed() <= stale_after);
        self.proxies
            .retain(|_, proxy| proxy.heard.elapsed() <= stale_after);
        let local = &self.local;
        self.clashes.retain(|(id, _)| local.contains_key(id));
    }

    fn summarise(&self) -> Result<()> {
        let summary = HostSummary {
            host: self.host.clone(),
            epoch_unix_ms: self.epoch_unix_ms,
            robots: self
                .local
                .values()
                .map(|(s, _)| RemoteRobot {
                    id: s.agent_id,
                    pid: s.pid,
                    x: s.x,
                    y: s.y,
                    theta: s.theta,
                    tick: s.tick,
                    neighbours: s.neighbour_ids().to_vec(),
                    missed_periods: s.missed_periods,
                    neighbour_age_ms: s.neighbour_age_ms,
                })
                .collect(),
        };
        self.session
            .put(
                keys::summary(&self.swarm, &self.host),
                serde_json::to_vec(&summary)?,
            )
            .wait()
            .map_err(zenoh_error("sending this host's summary"))
    }

    /// Asks for the cells this host's robots listen to, or for every pose
    /// while an observer here reads the whole swarm.
    fn update_interest(&mut self) -> Result<()> {
        let robots: Vec<(f64, f64)> = self.local.values().map(|(s, _)| (s.x, s.y)).collect();
        let wanted: BTreeSet<CellKey> = self.cell_inboxes.keys().copied().collect();
        let change = self.interest.update(&wanted, &robots);
        for cell in change.drop {
            self.cell_inboxes.remove(&cell);
        }
        for cell in change.add {
            let cell_inbox = inbox(
                &self.session,
                keys::cell_poses(&self.swarm, cell),
                RECEIVE_BUFFER,
            )?;
            self.cell_inboxes.insert(cell, cell_inbox);
        }
        // The launcher and this link always read the roster; anyone else
        // (a recorder, `shoal status`) wants every robot of the swarm.
        let observers = self.roster_readers.count().saturating_sub(2);
        match (observers > 0, self.whole_swarm.is_some()) {
            (true, false) => {
                self.whole_swarm = Some(inbox(
                    &self.session,
                    keys::all_poses(&self.swarm),
                    RECEIVE_BUFFER,
                )?);
            }
            (false, true) => self.whole_swarm = None,
            _ => {}
        }
        Ok(())
    }

    fn report(&mut self, up_for: Duration) -> Result<()> {
        self.traffic.proxies = self.proxies.len();
        self.traffic.cells_wanted = self.cell_inboxes.len();
        self.traffic.whole_swarm = self.whole_swarm.is_some();
        let hosts = self
            .hosts
            .iter()
            .filter(|(_, state)| state.present)
            .filter_map(|(name, state)| {
                let (summary, heard) = state.summary.as_ref()?;
                (heard.elapsed() <= SUMMARY_STALE).then(|| RemoteHost {
                    name: name.clone(),
                    robots: summary.robots.clone(),
                })
            })
            .collect::<Vec<_>>();
        // Ready once every host present has been heard from, or after a
        // while whatever answered (a host that never summarises is broken).
        let every_host_heard = self
            .hosts
            .values()
            .all(|state| !state.present || state.summary.is_some());
        let ready = up_for >= LISTEN_FIRST && (every_host_heard || up_for >= GIVE_UP_WAITING);
        let report = LinkReport {
            pid: std::process::id(),
            host: self.host.clone(),
            ready,
            hosts,
            clashes: self
                .clashes
                .iter()
                .map(|(id, host)| IdClash {
                    id: *id,
                    host: host.clone(),
                })
                .collect(),
            traffic: self.traffic.clone(),
        };
        self.runtime.write_report(&report).with_context(|| {
            format!(
                "writing the link's report in {}",
                self.runtime.dir.display()
            )
        })
    }
}
