//! Per-robot streams between a robot and the SLAM process following it:
//! scans from the robot, pose estimates and model updates back to it. One
//! service each per robot, so following a robot costs nothing to the others.

use core::fmt::Debug;

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use crate::bus::{Bus, BusError};
use crate::check::{Rejected, Wire};
use crate::names;
use crate::wire::{
    EstimateSample, HelperProgress, ModelUpdate, ScanSample, SlamMap, SlamParticles,
};

/// A follower may fall this many samples behind before the oldest are overwritten.
const BUFFER: usize = 32;

fn open<T: Debug + ZeroCopySend + 'static>(
    bus: &Bus,
    name: &str,
) -> Result<
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>,
    BusError,
> {
    bus.publish_subscribe::<T>(name, 2, bus.limits.max_observers, BUFFER, 0)
}

/// The sending end of one robot's stream of `T`.
pub struct StreamPublisher<T: Debug + ZeroCopySend + 'static> {
    publisher: Publisher<ipc::Service, T, ()>,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> StreamPublisher<T> {
    fn new(bus: &Bus, name: &str) -> Result<Self, BusError> {
        let publisher = open::<T>(bus, name)?
            .publisher_builder()
            .create()
            .map_err(|e| BusError::iceoryx(format!("publish {name}"), e))?;
        Ok(Self { publisher })
    }

    pub fn publish(&self, value: &T) -> Result<(), BusError> {
        self.publisher
            .send_copy(*value)
            .map(|_| ())
            .map_err(|e| BusError::iceoryx("send", e))
    }
}

/// The receiving end of one robot's stream of `T`.
pub struct StreamSubscriber<T: Debug + ZeroCopySend + 'static> {
    subscriber: Subscriber<ipc::Service, T, ()>,
    rejected: Rejected,
}

impl<T: Debug + ZeroCopySend + Copy + Wire + 'static> StreamSubscriber<T> {
    fn new(bus: &Bus, name: &str) -> Result<Self, BusError> {
        let subscriber = open::<T>(bus, name)?
            .subscriber_builder()
            .create()
            .map_err(|e| BusError::iceoryx(format!("follow {name}"), e))?;
        Ok(Self {
            subscriber,
            rejected: Rejected::default(),
        })
    }

    /// Hands every waiting sample that passes its [`Wire::check`] to `on_value`.
    pub fn receive(&self, mut on_value: impl FnMut(T)) -> Result<(), BusError> {
        while let Some(sample) = self
            .subscriber
            .receive()
            .map_err(|e| BusError::iceoryx("receive", e))?
        {
            if self.rejected.filter(core::any::type_name::<T>(), &*sample) {
                on_value(*sample);
            }
        }
        Ok(())
    }

    /// Samples that failed their check since this subscriber was made.
    pub fn rejected(&self) -> u64 {
        self.rejected.count()
    }
}

pub fn scan_publisher(bus: &Bus, id: u32) -> Result<StreamPublisher<ScanSample>, BusError> {
    StreamPublisher::new(bus, &names::scan(&bus.swarm, id))
}

pub fn scan_subscriber(bus: &Bus, id: u32) -> Result<StreamSubscriber<ScanSample>, BusError> {
    StreamSubscriber::new(bus, &names::scan(&bus.swarm, id))
}

pub fn estimate_publisher(bus: &Bus, id: u32) -> Result<StreamPublisher<EstimateSample>, BusError> {
    StreamPublisher::new(bus, &names::estimate(&bus.swarm, id))
}

pub fn estimate_subscriber(
    bus: &Bus,
    id: u32,
) -> Result<StreamSubscriber<EstimateSample>, BusError> {
    StreamSubscriber::new(bus, &names::estimate(&bus.swarm, id))
}

pub fn model_publisher(bus: &Bus, id: u32) -> Result<StreamPublisher<ModelUpdate>, BusError> {
    StreamPublisher::new(bus, &names::model(&bus.swarm, id))
}

pub fn model_subscriber(bus: &Bus, id: u32) -> Result<StreamSubscriber<ModelUpdate>, BusError> {
    StreamSubscriber::new(bus, &names::model(&bus.swarm, id))
}

pub fn progress_publisher(
    bus: &Bus,
    helper: &str,
) -> Result<StreamPublisher<HelperProgress>, BusError> {
    StreamPublisher::new(bus, &names::progress(&bus.swarm, helper))
}

pub fn progress_subscriber(
    bus: &Bus,
    helper: &str,
) -> Result<StreamSubscriber<HelperProgress>, BusError> {
    StreamSubscriber::new(bus, &names::progress(&bus.swarm, helper))
}

pub fn slam_particles_publisher(bus: &Bus) -> Result<StreamPublisher<SlamParticles>, BusError> {
    StreamPublisher::new(bus, &names::slam_particles(&bus.swarm))
}

pub fn slam_particles_subscriber(bus: &Bus) -> Result<StreamSubscriber<SlamParticles>, BusError> {
    StreamSubscriber::new(bus, &names::slam_particles(&bus.swarm))
}

pub fn slam_map_publisher(bus: &Bus) -> Result<StreamPublisher<SlamMap>, BusError> {
    StreamPublisher::new(bus, &names::slam_map(&bus.swarm))
}

pub fn slam_map_subscriber(bus: &Bus) -> Result<StreamSubscriber<SlamMap>, BusError> {
    StreamSubscriber::new(bus, &names::slam_map(&bus.swarm))
}
