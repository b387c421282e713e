//! Pose latency from one robot process to a neighbour process: over the
//! iceoryx2 cell exchange (woken by an iceoryx2 event, or polling), over a
//! plain iceoryx2 service (what iceoryx2 itself costs) and over a Unix
//! datagram socket, in the same run, inside swarms of real robots.

use std::os::unix::net::UnixDatagram;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::ipc;
use serde::{Deserialize, Serialize};
use shoal_broker::{Bus, BusLimits, BusSection, CellExchange, PoseSample, cell_at, names};
use shoal_scenario::Scenario;
use shoal_swarm::RunningSwarm;
use shoal_swarm::process::{ProcessUsage, usage};

/// Samples go out in blocks that alternate between transports, so that
/// drifting background load touches all of them alike.
const BLOCK: usize = 50;
/// Gap between the receiver's acknowledgement and the next send: the
/// receiver is asleep again by then.
const GAP: Duration = Duration::from_micros(200);
/// The shortest window over which the robots' CPU time is measured.
const CPU_WINDOW: Duration = Duration::from_secs(15);
const TRANSPORTS: [Transport; 5] = [
    Transport::IceoryxEvent,
    Transport::IceoryxPoll,
    Transport::RawIceoryxCellPoll,
    Transport::RawIceoryxPoll,
    Transport::UnixSocket,
];

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum Role {
    Send,
    Receive,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum Transport {
    /// Cell publish, then an iceoryx2 event wakes the receiver.
    IceoryxEvent,
    /// Cell publish; the receiver spins on its subscriber.
    IceoryxPoll,
    /// The same 176-byte sample on a plain iceoryx2 service of its own (one
    /// publisher, one subscriber, no checks); the receiver spins on it. What
    /// iceoryx2 itself costs, to tell it from what Shoal adds.
    RawIceoryxPoll,
    /// The same sample on the probe cell's own iceoryx2 service, with plain
    /// iceoryx2 ports (no exchange, no checks); the receiver spins on it.
    /// The cell's robots are connected to it as to the exchange, so this is
    /// what iceoryx2 costs with the cell's fan-out: the method, apart from
    /// what Shoal's code adds.
    RawIceoryxCellPoll,
    /// A datagram on a Unix domain socket; the receiver blocks in recv.
    UnixSocket,
}

/// Which transport carries each sample: blocks of [`BLOCK`], each round of
/// blocks in a new order, the same for sender and receiver (a fixed seed
/// per round). In a fixed order, whichever transport came right after the
/// event-woken one measured about 2 µs slower at p50 whatever it was
/// (BENCHMARKS.md, "Pose latency: Shoal's path against raw iceoryx2 and a Unix socket").
fn schedule(samples: usize) -> impl Iterator<Item = Transport> {
    use rand::SeedableRng;
    use rand::seq::SliceRandom;
    let rounds = samples.div_ceil(BLOCK);
    (0..rounds as u64)
        .flat_map(|round| {
            let mut order = TRANSPORTS;
            order.shuffle(&mut rand::rngs::StdRng::seed_from_u64(round));
            order
        })
        .flat_map(|transport| std::iter::repeat_n(transport, BLOCK))
        .take(samples * TRANSPORTS.len())
}

fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the timespec we own.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The robot id the probe's samples carry, above any robot's.
const PROBE_ID: u32 = u32::MAX - 1;

/// Where both probe ends meet: the middle of the arena, among the robots.
fn probe_sample(sequence: u64, x: f64) -> PoseSample {
    PoseSample::standing(PROBE_ID, std::process::id(), sequence, x, x, 0.0)
}

fn as_bytes(sample: &PoseSample) -> &[u8] {
    // SAFETY: PoseSample is repr(C), plain old data, without padding bytes.
    unsafe {
        std::slice::from_raw_parts(
            (sample as *const PoseSample).cast::<u8>(),
            size_of::<PoseSample>(),
        )
    }
}

#[derive(Debug, Default, Serialize, Deserialize)]
struct ProbeResult {
    /// Nanoseconds, per transport in `TRANSPORTS` order.
    latencies: Vec<Vec<u64>>,
    lost: Vec<usize>,
}

/// Tries `receive` until it yields the probe sample's send time, for at
/// most a second (the sample is then lost).
fn poll_for_a_second(mut receive: impl FnMut() -> Result<Option<u64>>) -> Result<Option<u64>> {
    let deadline = Instant::now() + Duration::from_secs(1);
    while Instant::now() < deadline {
        if let Some(sent) = receive()? {
            return Ok(Some(sent));
        }
    }
    Ok(None)
}

/// The send time `sample` carries if it is probe sample `sequence`.
fn probe_send_time(sample: &PoseSample, sequence: usize) -> Option<u64> {
    (sample.tick == sequence as u64 && sample.agent_id == PROBE_ID)
        .then_some(sample.sim_time.to_bits())
}

/// The send time of probe sample `sequence`, if it waits in the cells.
fn from_cells(cells: &CellExchange, sequence: usize) -> Result<Option<u64>> {
    let mut sent = None;
    cells.receive(|s| sent = sent.or(probe_send_time(&s, sequence)))?;
    Ok(sent)
}

/// The send time of probe sample `sequence`, if it waits at a plain
/// iceoryx2 subscriber (every waiting sample is read, as the exchange does).
fn from_raw(
    subscriber: &Subscriber<ipc::Service, PoseSample, ()>,
    sequence: usize,
) -> Result<Option<u64>> {
    let mut sent = None;
    while let Some(s) = subscriber.receive().map_err(|e| anyhow::anyhow!("{e:?}"))? {
        sent = sent.or(probe_send_time(&s, sequence));
    }
    Ok(sent)
}

/// Where the probe stands: 10 m by default; a value that is not a number
/// is an error, not the default.
fn probe_position() -> Result<f64> {
    match std::env::var("SHOAL_PROBE_AT") {
        Ok(text) => text
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite())
            .with_context(|| format!("SHOAL_PROBE_AT={text:?} is not a position in metres")),
        Err(_) => Ok(10.0),
    }
}

/// The receiving end's ports, one per transport.
struct Receivers {
    listener: Listener<ipc::Service>,
    cells: CellExchange,
    raw: Subscriber<ipc::Service, PoseSample, ()>,
    raw_cell: Subscriber<ipc::Service, PoseSample, ()>,
    datagram: UnixDatagram,
}

impl Receivers {
    /// The send time of probe sample `sequence` over `transport`, or `None`
    /// if it did not come within a second.
    fn sent_time(&self, transport: Transport, sequence: usize) -> Result<Option<u64>> {
        match transport {
            Transport::IceoryxEvent => poll_for_a_second(|| {
                let _ = self.listener.timed_wait(|_| {}, Duration::from_secs(1));
                from_cells(&self.cells, sequence)
            }),
            Transport::IceoryxPoll => poll_for_a_second(|| from_cells(&self.cells, sequence)),
            Transport::RawIceoryxPoll => poll_for_a_second(|| from_raw(&self.raw, sequence)),
            Transport::RawIceoryxCellPoll => {
                poll_for_a_second(|| from_raw(&self.raw_cell, sequence))
            }
            Transport::UnixSocket => {
                let mut buffer = [0u8; 512];
                Ok(match self.datagram.recv(&mut buffer) {
                    Ok(n) if n == size_of::<PoseSample>() => {
                        // SAFETY: n bytes of a PoseSample the sender wrote; read unaligned.
                        let s: PoseSample =
                            unsafe { std::ptr::read_unaligned(buffer.as_ptr().cast()) };
                        probe_send_time(&s, sequence)
                    }
                    _ => None,
                })
            }
        }
    }
}

/// The sending end's ports, one per transport.
struct Senders<'a> {
    bus: &'a Bus,
    cells: &'a mut CellExchange,
    notifier: Notifier<ipc::Service>,
    raw: Publisher<ipc::Service, PoseSample, ()>,
    raw_cell: Publisher<ipc::Service, PoseSample, ()>,
    datagram: UnixDatagram,
}

impl Senders<'_> {
    fn send(&mut self, transport: Transport, sample: PoseSample) -> Result<()> {
        match transport {
            Transport::IceoryxEvent => {
                self.cells.publish(self.bus, &sample)?;
                self.notifier
                    .notify()
                    .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            }
            Transport::IceoryxPoll => self.cells.publish(self.bus, &sample)?,
            Transport::RawIceoryxPoll => {
                self.raw
                    .send_copy(sample)
                    .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            }
            Transport::RawIceoryxCellPoll => {
                self.raw_cell
                    .send_copy(sample)
                    .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            }
            Transport::UnixSocket => {
                self.datagram.send(as_bytes(&sample))?;
            }
        }
        Ok(())
    }
}

pub fn probe(
    role: Role,
    swarm: &str,
    samples: usize,
    socket: &Path,
    listeners_per_cell: usize,
) -> Result<()> {
    let limits = BusLimits {
        max_listeners_per_cell: listeners_per_cell,
        ..BusLimits::default()
    };
    let bus = Bus::join_tool(swarm, &format!("probe-{role:?}"), limits)?;
    let centre = probe_position()?;
    let event_name = format!("{}probe-event", names::prefix(swarm));
    let event = bus
        .node
        .service_builder(&Bus::service_name(&event_name)?)
        .event()
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("probe event: {e:?}"))?;
    let raw_name = format!("{}probe-raw", names::prefix(swarm));
    let raw = bus
        .node
        .service_builder(&Bus::service_name(&raw_name)?)
        .publish_subscribe::<PoseSample>()
        .max_publishers(1)
        .max_subscribers(1)
        .subscriber_max_buffer_size(2)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("probe raw service: {e:?}"))?;
    let cell_size = BusSection::default().cell_size;
    let raw_cell = CellExchange::cell_service(&bus, cell_at(cell_size, centre, centre))?;
    let mut cells = CellExchange::new(cell_size);
    let failed = |e: &dyn std::fmt::Debug| anyhow::anyhow!("probe port: {e:?}");
    match role {
        Role::Receive => {
            // Only the cell the probe stands in.
            cells.listen(&bus, (centre, centre), 0.0)?;
            let datagram = UnixDatagram::bind(socket)
                .with_context(|| format!("binding {}", socket.display()))?;
            datagram.set_read_timeout(Some(Duration::from_secs(1)))?;
            let receivers = Receivers {
                listener: event.listener_builder().create().map_err(|e| failed(&e))?,
                cells,
                raw: raw.subscriber_builder().create().map_err(|e| failed(&e))?,
                raw_cell: raw_cell
                    .subscriber_builder()
                    .create()
                    .map_err(|e| failed(&e))?,
                datagram,
            };
            receive(&receivers, samples, socket)
        }
        Role::Send => {
            let deadline = Instant::now() + Duration::from_secs(10);
            while !socket.exists() && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(10));
            }
            let datagram = UnixDatagram::unbound()?;
            datagram
                .connect(socket)
                .with_context(|| format!("connecting {}", socket.display()))?;
            let mut senders = Senders {
                bus: &bus,
                cells: &mut cells,
                notifier: event.notifier_builder().create().map_err(|e| failed(&e))?,
                raw: raw.publisher_builder().create().map_err(|e| failed(&e))?,
                raw_cell: raw_cell
                    .publisher_builder()
                    .create()
                    .map_err(|e| failed(&e))?,
                datagram,
            };
            send(&mut senders, samples, socket, centre)
        }
    }
}

/// Receives every probe sample and prints the latencies as JSON.
fn receive(receivers: &Receivers, samples: usize, socket: &Path) -> Result<()> {
    // The sender waits for this acknowledgement before its next sample,
    // so a slow receiver never finds a queue of stale samples.
    let acks = UnixDatagram::unbound()?;
    let ack_path = socket.with_extension("ack");
    let mut result = ProbeResult {
        latencies: vec![Vec::new(); TRANSPORTS.len()],
        lost: vec![0; TRANSPORTS.len()],
    };
    for (sequence, transport) in schedule(samples).enumerate() {
        let index = TRANSPORTS.iter().position(|t| *t == transport).unwrap_or(0);
        let sent = receivers.sent_time(transport, sequence)?;
        let now = monotonic_ns();
        match sent {
            Some(sent) => result.latencies[index].push(now.saturating_sub(sent)),
            None => result.lost[index] += 1,
        }
        let _ = acks.send_to(&(sequence as u64).to_le_bytes(), &ack_path);
    }
    println!("{}", serde_json::to_string(&result)?);
    Ok(())
}

/// Sends every probe sample, each after the receiver acknowledged the last.
fn send(senders: &mut Senders, samples: usize, socket: &Path, centre: f64) -> Result<()> {
    let acks = UnixDatagram::bind(socket.with_extension("ack"))?;
    acks.set_read_timeout(Some(Duration::from_secs(2)))?;
    let mut ack = [0u8; 8];
    // Let the receiver's subscriber settle before the first sample.
    senders
        .cells
        .publish(senders.bus, &probe_sample(u64::MAX, centre))?;
    std::thread::sleep(Duration::from_millis(300));
    for (sequence, transport) in schedule(samples).enumerate() {
        std::thread::sleep(GAP);
        let mut sample = probe_sample(sequence as u64, centre);
        sample.sim_time = f64::from_bits(monotonic_ns());
        senders.send(transport, sample)?;
        // Wait for the receiver (a lost sample times out there first).
        while let Ok(8) = acks.recv(&mut ack) {
            if u64::from_le_bytes(ack) >= sequence as u64 {
                break;
            }
        }
    }
    Ok(())
}

#[derive(Debug, Serialize)]
struct Row {
    agents: usize,
    /// Listener slots of each cell's service.
    listeners_per_cell: usize,
    transport: Transport,
    p50_us: f64,
    p99_us: f64,
    max_us: f64,
    lost: usize,
    /// This transport's p50 divided by the Unix socket's p50 in the same run.
    p50_vs_unix_socket: f64,
    p99_vs_unix_socket: f64,
    /// This transport's p50 divided by raw iceoryx2's (polled) in the same run.
    p50_vs_raw_iceoryx2: f64,
    p99_vs_raw_iceoryx2: f64,
    /// This transport's p50 divided by raw iceoryx2's on the probe's cell
    /// service (same fan-out) in the same run: what Shoal's code adds.
    p50_vs_raw_iceoryx2_cell: f64,
    p99_vs_raw_iceoryx2_cell: f64,
    /// CPU time of the swarm's robot processes per robot per control period.
    robot_cpu_ms_per_period: Option<f64>,
}

fn percentile(sorted: &[u64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let index = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[index] as f64 / 1000.0
}

pub fn run(
    sizes: &[usize],
    samples: usize,
    listeners_per_cell: Option<usize>,
    json: bool,
) -> Result<()> {
    let listeners_per_cell =
        listeners_per_cell.unwrap_or(BusSection::default().max_listeners_per_cell);
    let mut rows = Vec::new();
    for &agents in sizes {
        if agents < 2 {
            bail!("a swarm for the probe needs at least 2 robots");
        }
        let swarm_name = format!("bench{}-{agents}", std::process::id());
        let robots = agents - 2;
        let arena = |robots: usize| {
            let mut scenario = Scenario::open_arena(robots);
            let bus = BusSection {
                max_listeners_per_cell: listeners_per_cell,
                ..BusSection::default()
            };
            scenario.set_section(&bus)?;
            Ok::<_, anyhow::Error>(scenario)
        };
        let scenario = arena(robots.max(1))?;
        let centre = scenario.arena.width / 2.0;
        let swarm = if robots > 0 {
            Some(RunningSwarm::launch(&swarm_name, arena(robots)?, false)?)
        } else {
            None
        };
        if swarm.is_some() {
            std::thread::sleep(Duration::from_secs(3));
        }
        let pids = swarm.as_ref().map(|s| s.agent_pids()).unwrap_or_default();
        let cpu_before: ProcessUsage = pids.iter().filter_map(|p| usage(*p)).sum();
        let started = Instant::now();
        let socket =
            std::env::temp_dir().join(format!("shoal-bench-{}-{agents}.sock", std::process::id()));
        let probes = run_probes(&swarm_name, samples, &socket, listeners_per_cell, centre);
        // CPU time is counted in 10 ms steps per process: measure long enough.
        if let Some(rest) = CPU_WINDOW.checked_sub(started.elapsed()) {
            std::thread::sleep(rest);
        }
        let elapsed = started.elapsed().as_secs_f64();
        let cpu_after: ProcessUsage = pids.iter().filter_map(|p| usage(*p)).sum();
        drop(swarm);
        let result = probes.with_context(|| format!("the probe failed for {agents} robots"))?;
        let period = scenario.timing.period_s;
        let robot_cpu = (robots > 0).then(|| {
            (cpu_after.cpu_s - cpu_before.cpu_s) * 1000.0 / (robots as f64 * elapsed / period)
        });
        rows.extend(rows_of(agents, listeners_per_cell, &result, robot_cpu));
    }
    shoal_runtime::report::print(&serde_json::json!({ "rows": rows }), json)?;
    Ok(())
}

/// The table's rows for one swarm size: each transport's percentiles and
/// their ratios to the baselines measured in the same run.
fn rows_of(
    agents: usize,
    listeners_per_cell: usize,
    result: &ProbeResult,
    robot_cpu: Option<f64>,
) -> Vec<Row> {
    let mut rows = Vec::new();
    let mut sorted: Vec<Vec<u64>> = result.latencies.clone();
    sorted.iter_mut().for_each(|l| l.sort_unstable());
    let baseline = |transport: Transport| {
        let index = TRANSPORTS.iter().position(|t| *t == transport).unwrap_or(0);
        (
            percentile(&sorted[index], 0.5),
            percentile(&sorted[index], 0.99),
        )
    };
    let (base50, base99) = baseline(Transport::UnixSocket);
    let (raw50, raw99) = baseline(Transport::RawIceoryxPoll);
    let (cell50, cell99) = baseline(Transport::RawIceoryxCellPoll);
    for (index, transport) in TRANSPORTS.iter().enumerate() {
        let (p50, p99) = (
            percentile(&sorted[index], 0.5),
            percentile(&sorted[index], 0.99),
        );
        rows.push(Row {
            agents,
            listeners_per_cell,
            transport: *transport,
            p50_us: p50,
            p99_us: p99,
            max_us: sorted[index]
                .last()
                .map_or(f64::NAN, |v| *v as f64 / 1000.0),
            lost: result.lost[index],
            p50_vs_unix_socket: p50 / base50,
            p99_vs_unix_socket: p99 / base99,
            p50_vs_raw_iceoryx2: p50 / raw50,
            p99_vs_raw_iceoryx2: p99 / raw99,
            p50_vs_raw_iceoryx2_cell: p50 / cell50,
            p99_vs_raw_iceoryx2_cell: p99 / cell99,
            robot_cpu_ms_per_period: robot_cpu,
        });
    }
    rows
}

/// Runs the probe's receiver and sender against swarm `swarm_name` and
/// reads the receiver's latencies.
fn run_probes(
    swarm_name: &str,
    samples: usize,
    socket: &Path,
    listeners_per_cell: usize,
    centre: f64,
) -> Result<ProbeResult> {
    let me = std::env::current_exe()?;
    let _ = std::fs::remove_file(socket);
    let _ = std::fs::remove_file(socket.with_extension("ack"));
    let spawn = |role: &str| {
        Command::new(&me)
            .args([
                "probe",
                "--role",
                role,
                "--swarm",
                swarm_name,
                "--samples",
                &samples.to_string(),
            ])
            .arg("--socket")
            .arg(socket)
            .arg("--listeners-per-cell")
            .arg(listeners_per_cell.to_string())
            .env("SHOAL_PROBE_AT", centre.to_string())
            .stdout(Stdio::piped())
            .spawn()
    };
    let receiver = spawn("receive")?;
    let sender = spawn("send")?;
    let sent = sender.wait_with_output()?;
    let received = receiver.wait_with_output()?;
    let _ = std::fs::remove_file(socket);
    let _ = std::fs::remove_file(socket.with_extension("ack"));
    if !sent.status.success() || !received.status.success() {
        bail!(
            "a probe process failed ({}, {})",
            sent.status,
            received.status
        );
    }
    serde_json::from_slice(&received.stdout).context("probe output")
}
