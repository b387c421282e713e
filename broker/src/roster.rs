//! The roster: every robot also publishes its pose here, for observers that
//! read the whole swarm (status, recorder, SLAM, the lockstep clock). Robots
//! never subscribe to it, so it adds nothing to a robot's per-period cost.

use crate::bus::{Bus, BusError};
use crate::names;
use crate::ports::{Receiver, Sender, Topic};
use crate::wire::PoseSample;

const ROSTER_BUFFER: usize = 8;

/// A robot's end of the roster.
pub type RosterPublisher = Sender<PoseSample>;
/// An observer's end of the roster.
pub type RosterReader = Receiver<PoseSample>;

fn topic(bus: &Bus) -> Topic {
    Topic {
        name: names::roster(&bus.swarm),
        publishers: bus.limits.max_agents,
        subscribers: bus.limits.max_observers,
        buffer: ROSTER_BUFFER,
        history: 1,
    }
}

pub fn publisher(bus: &Bus) -> Result<RosterPublisher, BusError> {
    Sender::open(bus, &topic(bus))
}

pub fn reader(bus: &Bus) -> Result<RosterReader, BusError> {
    Receiver::open(bus, &topic(bus), "roster pose")
}
