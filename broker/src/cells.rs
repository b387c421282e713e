//! Neighbour discovery by spatial cells: a robot publishes its pose into the
//! service of the grid cell it stands in and listens to the cells around it.
//! What it costs depends on how many robots stand nearby, not on swarm size.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use crate::bus::{Bus, BusError};
use crate::check::Rejected;
use crate::names;
use crate::ports::{Sender, Topic, receive_checked, subscribe};
use crate::wire::PoseSample;

pub type CellKey = (i32, i32);

/// Subscribers hold at most this many unread samples per publisher; the
/// exchange only needs the newest one or two.
const CELL_BUFFER: usize = 2;
const RETRY_AFTER: Duration = Duration::from_secs(1);

/// Publishers of the cells a robot stood in most recently. A robot on a
/// border crosses back and forth; keeping its last few publishers avoids
/// re-creating one each time.
const KEPT_PUBLISHERS: usize = 4;

pub struct CellExchange {
    cell_size: f64,
    /// Most recent first; the first is the cell the robot stands in.
    publishers: Vec<(CellKey, Sender<PoseSample>)>,
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
            publishers: Vec::new(),
            subscribers: HashMap::new(),
            failed: HashMap::new(),
            failures: 0,
            rejected: Rejected::default(),
        }
    }

    pub fn cell_of(&self, x: f64, y: f64) -> CellKey {
        (
            (x / self.cell_size).floor() as i32,
            (y / self.cell_size).floor() as i32,
        )
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

    /// Publishes into the cell under the sample's pose, moving to a new cell's
    /// service when the robot crossed a border.
    pub fn publish(&mut self, bus: &Bus, sample: &PoseSample) -> Result<(), BusError> {
        let key = self.cell_of(sample.x, sample.y);
        match self.publishers.iter().position(|(k, _)| *k == key) {
            Some(0) => {}
            Some(index) => {
                let entry = self.publishers.remove(index);
                self.publishers.insert(0, entry);
            }
            None => {
                let publisher = Sender::open(bus, &Self::topic(bus, key))
                    .inspect_err(|_| self.failures += 1)?;
                self.publishers.insert(0, (key, publisher));
                self.publishers.truncate(KEPT_PUBLISHERS);
            }
        }
        self.publishers[0].1.publish(sample)
    }

    /// Listens to every cell within `ring` cells of `center` and to no other.
    pub fn listen(&mut self, bus: &Bus, center: CellKey, ring: u32) -> Result<(), BusError> {
        let ring = ring as i32;
        let wanted = |k: &CellKey| (k.0 - center.0).abs() <= ring && (k.1 - center.1).abs() <= ring;
        self.subscribers.retain(|k, _| wanted(k));
        let mut first_error = None;
        for dx in -ring..=ring {
            for dy in -ring..=ring {
                let key = (center.0 + dx, center.1 + dy);
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
                let subscriber = subscribe(bus, &Self::topic(bus, key));
                match subscriber {
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
