//! The roster: every robot also publishes its pose here, for observers that
//! read the whole swarm (status, recorder, SLAM, the lockstep clock). Robots
//! never subscribe to it, so it adds nothing to a robot's per-period cost.

use crate::bus::{Bus, BusError, Topic};
use crate::names;
use crate::ports::{Receiver, Sender};
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

/// Joins swarm `swarm` as tool `role` (see [`Bus::join_tool`]) and opens a
/// reader of its roster: what every observer of the whole swarm starts with.
pub fn join_reader(
    swarm: &str,
    role: &str,
    limits: crate::BusLimits,
) -> Result<(Bus, RosterReader), BusError> {
    let bus = Bus::join_tool(swarm, role, limits)?;
    let roster = reader(&bus)?;
    Ok((bus, roster))
}

/// How many observers read the roster now: a host's link carries the whole
/// swarm's poses only while someone here (a recorder, `shoal status`) reads
/// them.
pub struct RosterReaders {
    service: iceoryx2::service::port_factory::publish_subscribe::PortFactory<
        iceoryx2::prelude::ipc::Service,
        PoseSample,
        (),
    >,
}

impl RosterReaders {
    pub fn open(bus: &Bus) -> Result<Self, BusError> {
        Ok(Self {
            service: bus.publish_subscribe::<PoseSample>(&topic(bus))?,
        })
    }

    pub fn count(&self) -> usize {
        use iceoryx2::service::port_factory::PortFactory;
        self.service.dynamic_config().number_of_subscribers()
    }
}
