//! Neighbour discovery by spatial cells: a robot publishes its pose into the
//! service of the grid cell it stands in and listens to the cells within a
//! radius of it. What it costs depends on how many robots stand nearby, not
//! on swarm size: every robot it listens to is one iceoryx2 connection each
//! way, so the cells it listens to should cover little beyond that radius.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::PortFactory as _;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory;

use crate::bus::{Bus, BusError, Topic};
use crate::check::Rejected;
use crate::names;
use crate::ports::{Sender, receive_checked, subscribe};
use crate::wire::PoseSample;

pub type CellKey = (i32, i32);

/// Subscribers hold at most this many unread samples per publisher; the
/// exchange only needs the newest one or two.
const CELL_BUFFER: usize = 2;
const RETRY_AFTER: Duration = Duration::from_secs(1);

/// How far outside its cell a robot still publishes into it. A robot on a
/// border would otherwise cross back and forth, opening a publisher (one
/// connection per listener) each time; and a publisher kept for each cell it
/// stood in would add those connections for nothing. Listeners hear it all
/// the same: robots sense a metre short of what they listen to.
const PUBLISH_SLACK_M: f64 = 0.4;

/// How far beyond its listening radius a robot keeps a cell it listens to,
/// so that one standing still near the edge does not open and drop the
/// cell's service period after period. Every cell kept costs a subscriber
/// (about 100 KB of connection storage, sized for the cell's publishers),
/// so the margin is what a robot's jitter needs, not more: half a cell kept
/// about 14 cells per robot where 8 to 10 are needed, a third of its memory
/// (BENCHMARKS.md, "Where a robot's time and memory go").
const LISTEN_SLACK_M: f64 = 0.5;

pub struct CellExchange {
    cell_size: f64,
    /// The cell the robot publishes into, within [`PUBLISH_SLACK_M`] of it.
    publisher: Option<(CellKey, Sender<PoseSample>)>,
    subscribers: HashMap<CellKey, Subscriber<ipc::Service, PoseSample, ()>>,
    /// Cells whose subscription failed (full), and when: they are retried
    /// only after [`RETRY_AFTER`], since opening a service is costly.
    failed: HashMap<CellKey, Instant>,
    /// Cells this robot could not join (full, or the bus refused); retried next period.
    pub failures: u64,
    rejected: Rejected,
}

impl CellExchange {
    pub fn new(cell_size: f64) -> Self {
        Self {
            cell_size,
            publisher: None,
            subscribers: HashMap::new(),
            failed: HashMap::new(),
            failures: 0,
            rejected: Rejected::default(),
        }
    }

    pub fn cell_of(&self, x: f64, y: f64) -> CellKey {
        cell_at(self.cell_size, x, y)
    }

    fn topic(bus: &Bus, key: CellKey) -> Topic {
        Topic {
            name: names::cell(&bus.swarm, key.0, key.1),
            publishers: bus.limits.max_per_cell,
            subscribers: bus.limits.cell_subscribers(),
            buffer: CELL_BUFFER,
            history: 0,
        }
    }

    /// The iceoryx2 service of cell `key` itself, for tools that measure
    /// what iceoryx2 costs on it apart from what the exchange adds.
    pub fn cell_service(
        bus: &Bus,
        key: CellKey,
    ) -> Result<PortFactory<ipc::Service, PoseSample, ()>, BusError> {
        bus.publish_subscribe::<PoseSample>(&Self::topic(bus, key))
    }

    /// Publishes into the cell under the sample's pose, moving to a new cell's
    /// service once the robot is clearly out of the old one.
    pub fn publish(&mut self, bus: &Bus, sample: &PoseSample) -> Result<(), BusError> {
        let slack = PUBLISH_SLACK_M.min(self.cell_size / 4.0);
        let (key, publisher) = match self.publisher.take() {
            Some((key, publisher))
                if cell_distance(self.cell_size, key, sample.x, sample.y) <= slack =>
            {
                (key, publisher)
            }
            stale => {
                // The old publisher is dropped first: its connections are
                // released before the new one's are made.
                if stale.is_some() {
                    drop(stale);
                    crate::bus::release_freed_memory();
                }
                let key = self.cell_of(sample.x, sample.y);
                let publisher = Sender::open(bus, &Self::topic(bus, key))
                    .inspect_err(|_| self.failures += 1)?;
                (key, publisher)
            }
        };
        let sent = publisher.publish(sample);
        self.publisher = Some((key, publisher));
        sent
    }

    /// Every cell that comes within `radius` of `(x, y)`.
    pub fn cells_within(&self, x: f64, y: f64, radius: f64) -> Vec<CellKey> {
        let (low, high) = (
            self.cell_of(x - radius, y - radius),
            self.cell_of(x + radius, y + radius),
        );
        (low.0..=high.0)
            .flat_map(|cx| (low.1..=high.1).map(move |cy| (cx, cy)))
            .filter(|key| cell_distance(self.cell_size, *key, x, y) <= radius)
            .collect()
    }

    /// Listens to every cell that comes within `radius` of `(x, y)`; a cell
    /// is let go only once it is [`LISTEN_SLACK_M`] further than that.
    pub fn listen(&mut self, bus: &Bus, (x, y): (f64, f64), radius: f64) -> Result<(), BusError> {
        let keep_within = radius + LISTEN_SLACK_M.min(self.cell_size / 2.0);
        let cell_size = self.cell_size;
        let listened = self.subscribers.len();
        self.subscribers
            .retain(|k, _| cell_distance(cell_size, *k, x, y) <= keep_within);
        if self.subscribers.len() < listened {
            crate::bus::release_freed_memory();
        }
        let mut first_error = None;
        for key in self.cells_within(x, y, radius) {
            if self.subscribers.contains_key(&key) {
                continue;
            }
            if self
                .failed
                .get(&key)
                .is_some_and(|at| at.elapsed() < RETRY_AFTER)
            {
                continue;
            }
            match subscribe(bus, &Self::topic(bus, key)) {
                Ok(subscriber) => {
                    self.failed.remove(&key);
                    self.subscribers.insert(key, subscriber);
                }
                Err(e) => {
                    self.failed.insert(key, Instant::now());
                    self.failures += 1;
                    first_error.get_or_insert(e);
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    }

    /// Hands every sample waiting in the listened cells that passes its
    /// check to `on_sample`.
    pub fn receive(&self, mut on_sample: impl FnMut(PoseSample)) -> Result<(), BusError> {
        for subscriber in self.subscribers.values() {
            receive_checked(subscriber, &self.rejected, "neighbour pose", &mut on_sample)?;
        }
        Ok(())
    }

    /// Poses that failed their check since this exchange was made.
    pub fn rejected(&self) -> u64 {
        self.rejected.count()
    }
}

/// How full one cell's service is. iceoryx2 gives every service a fixed
/// number of publisher and subscriber slots when it is made, and a send
/// visits every subscriber slot, used or not; `shoal status --cells` shows
/// these so a swarm's `[bus]` limits can be sized to what its cells hold.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct CellOccupancy {
    pub cell: CellKey,
    /// Robots publishing into the cell now.
    pub publishers: usize,
    pub max_publishers: usize,
    /// Robots and observers listening to the cell now.
    pub listeners: usize,
    pub max_listeners: usize,
}

/// Every cell service of `bus`'s swarm on this host, and how full it is.
/// Lists every service on the host and opens each of the swarm's cells.
pub fn occupancy(bus: &Bus) -> Result<Vec<CellOccupancy>, BusError> {
    let prefix = names::cell_prefix(&bus.swarm);
    let mut cells = Vec::new();
    ipc::Service::list(&crate::bus::domain_config(), |service| {
        let name = service.static_details.name().as_str();
        if let Some(key) = name.strip_prefix(&prefix).and_then(parse_cell_key) {
            cells.push((key, name.to_owned()));
        }
        CallbackProgression::Continue
    })
    .map_err(|e| BusError::iceoryx("list services", e))?;
    let mut occupancy = Vec::new();
    for (cell, name) in cells {
        // A cell whose last robot left since the listing is gone: skipped.
        let Ok(service) = bus
            .node
            .service_builder(&Bus::service_name(&name)?)
            .publish_subscribe::<PoseSample>()
            .open()
        else {
            continue;
        };
        let (now, limits) = (service.dynamic_config(), service.static_config());
        occupancy.push(CellOccupancy {
            cell,
            publishers: now.number_of_publishers(),
            max_publishers: limits.max_publishers(),
            listeners: now.number_of_subscribers(),
            max_listeners: limits.max_subscribers(),
        });
    }
    occupancy.sort_by_key(|c| c.cell);
    Ok(occupancy)
}

/// `cx_cy`, the end of a cell service's name ([`names::cell`]).
fn parse_cell_key(text: &str) -> Option<CellKey> {
    let (x, y) = text.split_once('_')?;
    Some((x.parse().ok()?, y.parse().ok()?))
}

/// The cell of side `cell_size` that `(x, y)` stands in.
pub fn cell_at(cell_size: f64, x: f64, y: f64) -> CellKey {
    (
        (x / cell_size).floor() as i32,
        (y / cell_size).floor() as i32,
    )
}

/// How far the nearest point of cell `key`, of side `cell_size`, is from `(x, y)`.
fn cell_distance(cell_size: f64, key: CellKey, x: f64, y: f64) -> f64 {
    let gap = |p: f64, index: i32| {
        let low = f64::from(index) * cell_size;
        (low - p).max(p - (low + cell_size)).max(0.0)
    };
    gap(x, key.0).hypot(gap(y, key.1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_robot_keeps_about_ten_cells_half_a_metre_past_its_radius_not_fourteen() {
        // The mean number of cells within `r` of a robot, over a grid of
        // positions in one cell of the default 3.5 m (BENCHMARKS.md,
        // build 0676a74: `cargo test -p shoal-broker keeps_about_ten --
        // --nocapture` prints them).
        let (cell, radius) = (3.5, 3.5);
        let cells = CellExchange::new(cell);
        let mean = |r: f64| {
            let steps = 40;
            let at = |i: usize| (i as f64 + 0.5) * cell / steps as f64;
            let total: usize = (0..steps)
                .flat_map(|i| (0..steps).map(move |j| (at(i), at(j))))
                .map(|(x, y)| cells.cells_within(x, y, r).len())
                .sum();
            total as f64 / (steps * steps) as f64
        };
        let needed = mean(radius);
        let kept = mean(radius + LISTEN_SLACK_M);
        let half_a_cell = mean(radius + cell / 2.0);
        println!(
            "cells within {radius} m: {needed:.2}; kept now: {kept:.2}; half a cell: {half_a_cell:.2}"
        );
        assert!((7.5..9.0).contains(&needed), "{needed}");
        assert!(kept < 10.5, "{kept}");
        assert!(half_a_cell > 13.5, "{half_a_cell}");
    }

    #[test]
    fn a_robot_listens_to_the_cells_its_disc_touches_and_no_corner_beyond() {
        let cells = CellExchange::new(1.75);
        let (x, y, radius) = (10.3, 4.1, 3.5);
        let listened = cells.cells_within(x, y, radius);
        // Every point within the radius lies in a listened cell.
        for step in 0..720 {
            let angle = f64::from(step) * core::f64::consts::PI / 360.0;
            for r in [0.0, radius / 2.0, radius * 0.999] {
                let key = cells.cell_of(x + r * angle.cos(), y + r * angle.sin());
                assert!(listened.contains(&key), "{key:?} at {r} m, {angle} rad");
            }
        }
        // A square of cells around the robot's own would be 5 x 5 = 25 cells
        // of 3.06 m^2; the disc leaves out its corners.
        assert!(listened.len() < 25, "{}", listened.len());
        assert_eq!(cells.cells_within(x, y, 0.0), vec![cells.cell_of(x, y)]);
    }

    #[test]
    fn a_cell_service_name_gives_back_its_cell() {
        let name = names::cell("s", -3, 12);
        let end = name.strip_prefix(&names::cell_prefix("s"));
        assert_eq!(end.and_then(parse_cell_key), Some((-3, 12)));
        assert_eq!(parse_cell_key("3"), None);
        assert_eq!(parse_cell_key("a_1"), None);
    }
}
