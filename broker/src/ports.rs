//! Typed ports on the swarm's publish-subscribe services. Every sender and
//! receiver of the broker is one of these, and every sample received passes
//! its wire check in one loop, [`receive_checked`].

use core::fmt::Debug;

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use crate::bus::{Bus, BusError, Topic};
use crate::check::{Rejected, Wire};

/// The sending end of a topic.
pub struct Sender<T: Debug + ZeroCopySend + 'static> {
    publisher: Publisher<ipc::Service, T, ()>,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Sender<T> {
    pub(crate) fn open(bus: &Bus, topic: &Topic) -> Result<Self, BusError> {
        let publisher = bus
            .publish_subscribe::<T>(topic)?
            .publisher_builder()
            .create()
            .map_err(|e| BusError::iceoryx(format!("publish into {}", topic.name), e))?;
        Ok(Self { publisher })
    }

    pub fn publish(&self, value: &T) -> Result<(), BusError> {
        self.publisher
            .send_copy(*value)
            .map(|_| ())
            .map_err(|e| BusError::iceoryx("send", e))
    }
}

/// The receiving end of a topic; counts what fails its wire check.
pub struct Receiver<T: Debug + ZeroCopySend + 'static> {
    subscriber: Subscriber<ipc::Service, T, ()>,
    /// What a sample is, for the warning on a rejected one.
    what: &'static str,
    rejected: Rejected,
}

impl<T: Debug + ZeroCopySend + Copy + Wire + 'static> Receiver<T> {
    pub(crate) fn open(bus: &Bus, topic: &Topic, what: &'static str) -> Result<Self, BusError> {
        Ok(Self {
            subscriber: subscribe(bus, topic)?,
            what,
            rejected: Rejected::default(),
        })
    }

    /// Hands every waiting sample that passes its [`Wire::check`] to `on_value`.
    pub fn receive(&self, on_value: impl FnMut(T)) -> Result<(), BusError> {
        receive_checked(&self.subscriber, &self.rejected, self.what, on_value)
    }

    /// Samples that failed their check since this receiver was made.
    pub fn rejected(&self) -> u64 {
        self.rejected.count()
    }

    /// Counts a sample that passed its wire check but that the reader
    /// itself found unusable.
    pub(crate) fn reject(&self, why: &str) {
        self.rejected.count_one(self.what, why);
    }
}

pub(crate) fn subscribe<T: Debug + ZeroCopySend + 'static>(
    bus: &Bus,
    topic: &Topic,
) -> Result<Subscriber<ipc::Service, T, ()>, BusError> {
    bus.publish_subscribe::<T>(topic)?
        .subscriber_builder()
        .create()
        .map_err(|e| BusError::iceoryx(format!("subscribe to {}", topic.name), e))
}

/// The one receive loop: every waiting sample of `subscriber` that passes
/// its wire check goes to `on_value`; the others are counted in `rejected`.
pub(crate) fn receive_checked<T: Debug + ZeroCopySend + Copy + Wire + 'static>(
    subscriber: &Subscriber<ipc::Service, T, ()>,
    rejected: &Rejected,
    what: &str,
    mut on_value: impl FnMut(T),
) -> Result<(), BusError> {
    while let Some(sample) = subscriber
        .receive()
        .map_err(|e| BusError::iceoryx(format!("receive {what}"), e))?
    {
        if rejected.filter(what, &*sample) {
            on_value(*sample);
        }
    }
    Ok(())
}
