//! The link's report in the swarm's folder: what this host's link knows of
//! the swarm's other hosts, for the launcher, `shoal status`, `kill`,
//! `spawn` and the recorder.

use shoal_runtime::folder::HelperReport;

/// What this host's link (`shoal-link`) knows of the swarm's other hosts,
/// for `shoal status`, `kill` and `spawn` here.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LinkReport {
    pub pid: u32,
    pub host: String,
    /// Set once the link has listened long enough to have heard every host
    /// it found: only then does an id it does not list belong to no one.
    pub ready: bool,
    pub hosts: Vec<RemoteHost>,
    /// Remote robots refused because a robot of this host has their id.
    pub clashes: Vec<IdClash>,
    pub traffic: LinkTraffic,
}

impl LinkReport {
    /// Every robot of the other hosts, with its host's name.
    pub fn robots(&self) -> impl Iterator<Item = (&str, &RemoteRobot)> {
        self.hosts
            .iter()
            .flat_map(|h| h.robots.iter().map(move |r| (h.name.as_str(), r)))
    }

    /// The other host that runs robot `id`.
    pub fn host_of(&self, id: u32) -> Option<&str> {
        self.robots()
            .find(|(_, r)| r.id == id)
            .map(|(host, _)| host)
    }
}

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RemoteHost {
    pub name: String,
    pub robots: Vec<RemoteRobot>,
}

/// A robot of another host, as that host last summarised it.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RemoteRobot {
    pub id: u32,
    /// Its process on its own host.
    pub pid: u32,
    pub x: f64,
    pub y: f64,
    pub theta: f64,
    pub tick: u64,
    pub neighbours: Vec<u32>,
    pub missed_periods: u32,
    pub neighbour_age_ms: u32,
}

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IdClash {
    pub id: u32,
    /// The other host that runs a robot with this id.
    pub host: String,
}

/// What the link handed to Zenoh and took from it since it started.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LinkTraffic {
    /// Poses handed to Zenoh, which sends each only to hosts that asked
    /// for its cell (none, when no other host's robots are near).
    pub poses_offered: u64,
    pub poses_received: u64,
    pub bytes_offered: u64,
    pub bytes_received: u64,
    /// Messages that failed to decode or their plausibility check.
    pub rejected: u64,
    /// Remote robots standing in this host's cells for its robots now.
    pub proxies: usize,
    /// Cells whose remote poses this host asks for now.
    pub cells_wanted: usize,
    /// Whether it asks for every remote pose (a recorder or status listens here).
    pub whole_swarm: bool,
}

impl HelperReport for LinkReport {
    const FILE: &'static str = "link.toml";
    fn writer_pid(&self) -> u32 {
        self.pid
    }
}
