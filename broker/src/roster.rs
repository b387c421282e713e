//! The roster: every robot also publishes its pose here, for observers that
//! read the whole swarm (status, recorder, SLAM, the lockstep clock). Robots
//! never subscribe to it, so it adds nothing to a robot's per-period cost.

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use crate::bus::{Bus, BusError};
use crate::check::Rejected;
use crate::names;
use crate::wire::PoseSample;

const ROSTER_BUFFER: usize = 8;

fn open(
    bus: &Bus,
) -> Result<
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, PoseSample, ()>,
    BusError,
> {
    let limits = bus.limits;
    bus.publish_subscribe::<PoseSample>(
        &names::roster(&bus.swarm),
        limits.max_agents,
        limits.max_observers,
        ROSTER_BUFFER,
        1,
    )
}

pub struct RosterPublisher {
    publisher: Publisher<ipc::Service, PoseSample, ()>,
}

impl RosterPublisher {
    pub fn new(bus: &Bus) -> Result<Self, BusError> {
        let publisher = open(bus)?
            .publisher_builder()
            .create()
            .map_err(|e| BusError::iceoryx("publish into roster", e))?;
        Ok(Self { publisher })
    }

    pub fn publish(&self, sample: &PoseSample) -> Result<(), BusError> {
        self.publisher
            .send_copy(*sample)
            .map(|_| ())
            .map_err(|e| BusError::iceoryx("send roster pose", e))
    }
}

pub struct RosterReader {
    subscriber: Subscriber<ipc::Service, PoseSample, ()>,
    rejected: Rejected,
}

impl RosterReader {
    pub fn new(bus: &Bus) -> Result<Self, BusError> {
        let subscriber = open(bus)?
            .subscriber_builder()
            .create()
            .map_err(|e| BusError::iceoryx("read roster", e))?;
        Ok(Self {
            subscriber,
            rejected: Rejected::default(),
        })
    }

    /// Hands every waiting pose that passes its check to `on_sample`.
    pub fn receive(&self, mut on_sample: impl FnMut(PoseSample)) -> Result<(), BusError> {
        while let Some(sample) = self
            .subscriber
            .receive()
            .map_err(|e| BusError::iceoryx("receive roster", e))?
        {
            if self.rejected.filter("roster pose", &*sample) {
                on_sample(*sample);
            }
        }
        Ok(())
    }

    /// Poses that failed their check since this reader was made.
    pub fn rejected(&self) -> u64 {
        self.rejected.count()
    }
}
