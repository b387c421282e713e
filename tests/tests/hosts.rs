//! One swarm on two hosts linked over Zenoh: hosts `a` and `b` are separate
//! iceoryx2 domains and runtime folders, started as a user would on two
//! machines, on loopback and (where `ip netns` works, as root) in two
//! network namespaces joined by a veth pair, so the poses cross a real
//! network interface.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use serde_json::Value;
use shoal_e2e::{bin, inspect_recording, scratch, serial, status_metrics, wait_until};

/// The formation spread of `scenarios/two-hosts-*.toml`.
const SPREAD: f64 = 1.0;

/// Host `a`'s or `b`'s scenario: the left or right half of a 20 x 13 m
/// arena (`scenarios/two-hosts-*.toml`).
fn scenario(host: &str) -> PathBuf {
    shoal_e2e::package_dir()
        .join("../scenarios")
        .join(format!("two-hosts-{host}.toml"))
}

/// One host's `shoal up --link zenoh`, optionally inside a network namespace.
struct Host {
    name: String,
    child: Option<Child>,
    log: PathBuf,
}

impl Host {
    fn start(
        swarm: &str,
        name: &str,
        first_id: u32,
        scenario: &Path,
        zenoh: &[&str],
        netns: Option<&str>,
    ) -> Self {
        let log = std::env::temp_dir().join(format!("shoal-e2e-{swarm}-{name}.log"));
        let out = std::fs::File::create(&log).expect("create the host's log");
        let mut command = match netns {
            Some(ns) => {
                let mut command = Command::new("ip");
                command.args(["netns", "exec", ns]).arg(bin("shoal"));
                command
            }
            None => Command::new(bin("shoal")),
        };
        command
            .args(["up", "--swarm", swarm, "--host", name, "--link", "zenoh"])
            .args(["--first-id", &first_id.to_string()])
            .arg("--scenario")
            .arg(scenario)
            .args(zenoh)
            .stdin(Stdio::null())
            .stdout(out.try_clone().expect("clone the log handle"))
            .stderr(out);
        Self {
            name: name.to_owned(),
            child: Some(command.spawn().expect("start shoal up")),
            log,
        }
    }

    fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// SIGKILL of every process of the host, as a machine that loses power.
    fn kill_all(&mut self) {
        let Some(mut child) = self.child.take() else {
            return;
        };
        for pid in descendants(child.id() as i32)
            .into_iter()
            .chain([child.id() as i32])
        {
            // SAFETY: kill(2) of processes this test started.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
        let _ = child.wait();
    }

    /// Ctrl-C, as a user stops it; what it printed.
    fn stop(&mut self) -> String {
        if let Some(mut child) = self.child.take() {
            // SAFETY: kill(2) of a child this test started.
            unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
            let _ = child.wait();
        }
        self.log()
    }
}

impl Drop for Host {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Every process below `pid`, children first found first.
fn descendants(pid: i32) -> Vec<i32> {
    let mut found = Vec::new();
    let mut queue = vec![pid];
    while let Some(parent) = queue.pop() {
        let children = std::fs::read_to_string(format!("/proc/{parent}/task/{parent}/children"))
            .unwrap_or_default();
        for child in children.split_whitespace().filter_map(|c| c.parse().ok()) {
            found.push(child);
            queue.push(child);
        }
    }
    found
}

fn status(swarm: &str, host: &str) -> Value {
    let output = Command::new(bin("shoal"))
        .args(["status", "--swarm", swarm, "--host", host, "--json"])
        .output()
        .expect("run shoal status");
    assert!(
        output.status.success(),
        "status failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("status prints JSON")
}

/// Alive robots by host, in one status.
fn alive_on(status: &Value, host: &str) -> Vec<u64> {
    status["agents"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|a| a["state"] == "alive" && a["host"] == host)
        .filter_map(|a| a["id"].as_u64())
        .collect()
}

/// Whether a robot of host `a` lists a robot of host `b` as a neighbour.
fn linked_across(status: &Value) -> bool {
    status["agents"].as_array().into_iter().flatten().any(|a| {
        a["host"] == "a"
            && a["neighbours"]
                .as_array()
                .into_iter()
                .flatten()
                .any(|n| n.as_u64().is_some_and(|n| n >= 100))
    })
}

fn groups(status: &Value) -> usize {
    status_metrics(status, SPREAD).components
}

/// What both hosts said, for a failure.
fn logs(hosts: &[&Host]) -> String {
    hosts
        .iter()
        .map(|h| format!("--- host {}:\n{}", h.name, h.log()))
        .collect()
}

/// The scenario of the issue, for hosts joined by `a_zenoh` and `b_zenoh`
/// arguments, each optionally in a network namespace. With `cut_network`,
/// first the network between them is cut (`cut_network(true)`) and mended.
fn two_hosts_form_drop_and_rejoin(
    swarm: &str,
    a_zenoh: &[&str],
    b_zenoh: &[&str],
    netns: Option<(&str, &str)>,
    cut_network: Option<&dyn Fn(bool)>,
) {
    let dir = scratch(swarm);
    let (a_scenario, b_scenario) = (scenario("a"), scenario("b"));
    // Host a records: the recording is to hold both hosts' robots, each
    // tagged with its host.
    let recording = dir.join("a.rrd");
    let recording_arg = recording.to_str().expect("utf-8 path");
    let a_args: Vec<&str> = a_zenoh
        .iter()
        .copied()
        .chain(["--record", recording_arg])
        .collect();
    let mut a = Host::start(swarm, "a", 0, &a_scenario, &a_args, netns.map(|n| n.0));
    let b_start = || Host::start(swarm, "b", 100, &b_scenario, b_zenoh, netns.map(|n| n.1));
    let mut b = b_start();

    let mut last = Value::Null;
    let phase = std::time::Instant::now();
    let formed = wait_until(Duration::from_secs(30), || {
        last = status(swarm, "a");
        alive_on(&last, "a").len() == 10
            && alive_on(&last, "b").len() == 10
            && groups(&last) == 1
            && linked_across(&last)
    });
    assert!(
        formed,
        "20 robots in one group linked across hosts within 30 s\nstatus: {last}\n{}",
        logs(&[&a, &b])
    );
    assert_eq!(last["stale_nodes"], 0, "{last}");
    eprintln!(
        "{swarm}: one group of 20 across hosts after {:?}",
        phase.elapsed()
    );

    if let Some(cut) = cut_network {
        cut(true);
        let phase = std::time::Instant::now();
        let apart = wait_until(Duration::from_secs(10), || {
            last = status(swarm, "a");
            alive_on(&last, "a").len() == 10
                && alive_on(&last, "b").is_empty()
                && groups(&last) == 1
        });
        assert!(
            apart,
            "host a alone within 10 s of the network's cut\nstatus: {last}\n{}",
            logs(&[&a, &b])
        );
        eprintln!("{swarm}: host a alone {:?} after the cut", phase.elapsed());
        // Cut for longer than Zenoh's lease (10 s), so the session is lost
        // and the hosts must find each other again, not only resend.
        std::thread::sleep(Duration::from_secs(12).saturating_sub(phase.elapsed()));
        cut(false);
        let phase = std::time::Instant::now();
        // Host b's link connects to --connect's endpoint again.
        let mended = wait_until(Duration::from_secs(40), || {
            last = status(swarm, "a");
            alive_on(&last, "b").len() == 10 && groups(&last) == 1
        });
        assert!(
            mended,
            "host b's robots back in one group within 40 s of the network's mending\nstatus: {last}\n{}",
            logs(&[&a, &b])
        );
        eprintln!(
            "{swarm}: together again {:?} after the mending",
            phase.elapsed()
        );
    }

    b.kill_all();
    let phase = std::time::Instant::now();
    let dropped = wait_until(Duration::from_secs(10), || {
        last = status(swarm, "a");
        alive_on(&last, "a").len() == 10
            && alive_on(&last, "b").is_empty()
            && last["stale_nodes"] == 0
            && groups(&last) == 1
    });
    assert!(
        dropped,
        "host a alone: 10 alive, 0 stale nodes, one group within 10 s of host b's death\nstatus: {last}\n{}",
        logs(&[&a, &b])
    );

    eprintln!(
        "{swarm}: host a alone {:?} after host b's SIGKILL",
        phase.elapsed()
    );
    let b = b_start();
    let phase = std::time::Instant::now();
    let rejoined = wait_until(Duration::from_secs(30), || {
        last = status(swarm, "a");
        alive_on(&last, "a").len() == 10 && alive_on(&last, "b").len() == 10
    });
    assert!(
        rejoined,
        "host b's robots rejoin within 30 s\nstatus: {last}\n{}",
        logs(&[&a, &b])
    );
    eprintln!(
        "{swarm}: 20 again {:?} after host b's restart",
        phase.elapsed()
    );
    drop(b);
    let said = a.stop();
    assert!(said.contains("linked host `a`"), "{said}");
    let found = inspect_recording(&recording);
    let robots: Vec<u64> = found["robots"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(Value::as_u64)
        .collect();
    assert!(
        (0..10).chain(100..110).all(|id| robots.contains(&id)),
        "host a's recording holds both hosts' robots: {robots:?}"
    );
    assert_eq!(found["hosts"]["3"], "a", "{}\n{said}", found["hosts"]);
    assert_eq!(found["hosts"]["105"], "b", "{}\n{said}", found["hosts"]);
    let _ = std::fs::remove_dir_all(dir);
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

#[test]
fn two_hosts_on_loopback_form_one_swarm_drop_a_dead_host_and_take_it_back() {
    let _serial = serial();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    two_hosts_form_drop_and_rejoin(
        "e2e-hosts",
        &["--listen", &endpoint],
        &["--connect", &endpoint],
        None,
        None,
    );
}

#[test]
fn a_robot_id_another_host_runs_and_a_lockstep_across_hosts_are_refused() {
    let _serial = serial();
    let swarm = "e2e-hosts-refuse";
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let mut a = Host::start(
        swarm,
        "a",
        0,
        &scenario("a"),
        &["--listen", &endpoint],
        None,
    );
    let up = wait_until(Duration::from_secs(30), || {
        alive_on(&status(swarm, "a"), "a").len() == 10
    });
    assert!(up, "host a up\n{}", a.log());
    let clash = Command::new(bin("shoal"))
        .args(["up", "--swarm", swarm, "--host", "b", "--link", "zenoh"])
        .args(["--first-id", "5", "--agents", "3", "--connect", &endpoint])
        .output()
        .expect("run shoal up");
    let said = String::from_utf8_lossy(&clash.stderr);
    assert!(!clash.status.success(), "{said}");
    assert!(
        said.contains("host `a` runs robots 5, 6, 7") && said.contains("this host `b`"),
        "{said}"
    );
    // Host a goes on untouched: still its 10 robots, none of b's.
    let after = status(swarm, "a");
    assert_eq!(alive_on(&after, "a").len(), 10, "{after}");
    assert!(alive_on(&after, "b").is_empty(), "{after}");

    let lockstep = Command::new(bin("shoal"))
        .args([
            "up",
            "--swarm",
            swarm,
            "--host",
            "c",
            "--link",
            "zenoh",
            "--lockstep",
        ])
        .output()
        .expect("run shoal up");
    assert!(!lockstep.status.success());
    assert!(
        String::from_utf8_lossy(&lockstep.stderr).contains("--lockstep cannot span hosts"),
        "{}",
        String::from_utf8_lossy(&lockstep.stderr)
    );
    a.stop();
}

/// Two network namespaces joined by a veth pair; removed when dropped.
struct Namespaces {
    names: [String; 2],
    /// The veth pair's ends, in the first and the second namespace.
    veth: [String; 2],
}

impl Namespaces {
    /// None where `ip` cannot make them.
    fn create(tag: &str) -> Option<Self> {
        let names = [format!("shoal-{tag}-a"), format!("shoal-{tag}-b")];
        let veth = [format!("sv{tag}a"), format!("sv{tag}b")];
        let ip = |args: &[&str]| {
            Command::new("ip")
                .args(args)
                .stderr(Stdio::null())
                .status()
                .is_ok_and(|s| s.success())
        };
        let spaces = Self { names, veth };
        let [na, nb] = &spaces.names;
        let [va, vb] = &spaces.veth;
        let made = ip(&["netns", "add", na])
            && ip(&["netns", "add", nb])
            && ip(&["link", "add", va, "type", "veth", "peer", "name", vb])
            && ip(&["link", "set", va, "netns", na])
            && ip(&["link", "set", vb, "netns", nb])
            && ip(&["-n", na, "addr", "add", "10.213.0.1/24", "dev", va])
            && ip(&["-n", nb, "addr", "add", "10.213.0.2/24", "dev", vb])
            && ip(&["-n", na, "link", "set", va, "up"])
            && ip(&["-n", nb, "link", "set", vb, "up"])
            && ip(&["-n", na, "link", "set", "lo", "up"])
            && ip(&["-n", nb, "link", "set", "lo", "up"]);
        made.then_some(spaces)
    }
}

impl Drop for Namespaces {
    fn drop(&mut self) {
        for name in &self.names {
            // Deleting a namespace deletes its end of the veth pair, and the pair with it.
            let _ = Command::new("ip")
                .args(["netns", "delete", name])
                .stderr(Stdio::null())
                .status();
        }
    }
}

#[test]
fn two_hosts_in_separate_network_namespaces_link_over_a_veth_pair() {
    let _serial = serial();
    let tag = (std::process::id() % 100_000).to_string();
    // SAFETY: geteuid has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        // CI runs as root (and scripts/test installs iproute2), so there it runs.
        eprintln!("skipped: network namespaces need root");
        return;
    }
    let spaces = Namespaces::create(&tag).expect(
        "as root, `ip netns` makes two namespaces joined by a veth pair (iproute2 installed?)",
    );
    let [na, nb] = &spaces.names;
    let cut = |down: bool| {
        let done = Command::new("ip")
            .args(["-n", nb, "link", "set", &spaces.veth[1]])
            .arg(if down { "down" } else { "up" })
            .status()
            .is_ok_and(|s| s.success());
        assert!(
            done,
            "set host b's network {}",
            if down { "down" } else { "up" }
        );
    };
    two_hosts_form_drop_and_rejoin(
        "e2e-hosts-netns",
        &["--listen", "tcp/10.213.0.1:7447"],
        &["--connect", "tcp/10.213.0.1:7447"],
        Some((na, nb)),
        Some(&cut),
    );
}

/// Runs `openssl` with `args` in `dir`; the test needs it (Debian's openssl).
fn openssl(dir: &Path, args: &[&str]) {
    let ok = Command::new("openssl")
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "openssl {} (is openssl installed?)", args.join(" "));
}

/// A certificate authority `name` in `dir`: `name.key`, `name.pem`.
fn certificate_authority(dir: &Path, name: &str) {
    let (key, pem, subject) = (
        format!("{name}.key"),
        format!("{name}.pem"),
        format!("/CN={name}"),
    );
    openssl(
        dir,
        &[
            "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-keyout", &key, "-out",
            &pem, "-subj", &subject,
        ],
    );
}

#[test]
fn hosts_link_over_tls_and_a_host_without_the_swarms_authority_stays_out() {
    let _serial = serial();
    let swarm = "e2e-hosts-tls";
    let dir = scratch(swarm);
    // The swarm's authority signs host a's certificate; a stranger has another.
    certificate_authority(&dir, "swarm-ca");
    certificate_authority(&dir, "stranger-ca");
    openssl(
        &dir,
        &[
            "req",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-keyout",
            "a.key",
            "-out",
            "a.csr",
            "-subj",
            "/CN=localhost",
        ],
    );
    std::fs::write(
        dir.join("san.cnf"),
        "subjectAltName=DNS:localhost,IP:127.0.0.1\n",
    )
    .expect("write san.cnf");
    openssl(
        &dir,
        &[
            "x509",
            "-req",
            "-in",
            "a.csr",
            "-CA",
            "swarm-ca.pem",
            "-CAkey",
            "swarm-ca.key",
            "-CAcreateserial",
            "-out",
            "a.pem",
            "-days",
            "2",
            "-extfile",
            "san.cnf",
        ],
    );
    let endpoint = format!("tls/localhost:{}", free_port());
    let config = |name: &str, body: String| {
        let path = dir.join(name);
        std::fs::write(&path, body).expect("write a Zenoh configuration");
        path
    };
    let d = dir.display();
    let a_config = config(
        "a.json5",
        format!(
            "{{ listen: {{ endpoints: [\"{endpoint}\"] }}, scouting: {{ multicast: {{ enabled: false }} }},\n\
             transport: {{ link: {{ tls: {{ listen_private_key: \"{d}/a.key\", listen_certificate: \"{d}/a.pem\",\n\
             root_ca_certificate: \"{d}/swarm-ca.pem\" }} }} }} }}\n"
        ),
    );
    let b_config = |ca: &str| {
        config(
            &format!("b-{ca}.json5"),
            format!(
                "{{ connect: {{ endpoints: [\"{endpoint}\"] }}, scouting: {{ multicast: {{ enabled: false }} }},\n\
                 transport: {{ link: {{ tls: {{ root_ca_certificate: \"{d}/{ca}.pem\" }} }} }} }}\n"
            ),
        )
    };
    let a_args = ["--zenoh-config", a_config.to_str().expect("utf-8")];
    let mut a = Host::start(swarm, "a", 0, &scenario("a"), &a_args, None);

    // Host b, started trusting authority `ca`.
    let b_start = |ca: &str| {
        let config = b_config(ca);
        Host::start(
            swarm,
            "b",
            100,
            &scenario("b"),
            &["--zenoh-config", config.to_str().expect("utf-8")],
            None,
        )
    };
    // Host b trusting another authority cannot verify host a: it never joins.
    let mut b = b_start("stranger-ca");
    let mut last = Value::Null;
    let alone = wait_until(Duration::from_secs(30), || {
        last = status(swarm, "a");
        alive_on(&last, "a").len() == 10
    });
    assert!(alone, "host a up\nstatus: {last}\n{}", logs(&[&a, &b]));
    // Host b runs (its robots are up on its own side), only apart: what
    // keeps it out is the certificate, not a failed start.
    let b_alone = wait_until(Duration::from_secs(30), || {
        alive_on(&status(swarm, "b"), "b").len() == 10
    });
    assert!(b_alone, "host b up on its own\n{}", logs(&[&a, &b]));
    std::thread::sleep(Duration::from_secs(5));
    last = status(swarm, "a");
    assert!(
        alive_on(&last, "b").is_empty(),
        "a host without the swarm's authority joined\nstatus: {last}\n{}",
        logs(&[&a, &b])
    );
    b.stop();

    // With the swarm's authority it joins, over TLS.
    let b = b_start("swarm-ca");
    let joined = wait_until(Duration::from_secs(30), || {
        last = status(swarm, "a");
        alive_on(&last, "b").len() == 10 && linked_across(&last)
    });
    assert!(
        joined,
        "host b joins over TLS\nstatus: {last}\n{}",
        logs(&[&a, &b])
    );
    drop(b);
    a.stop();
    let _ = std::fs::remove_dir_all(dir);
}
