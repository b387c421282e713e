//! Lockstep: a clock publishes ticks; each robot steps once per tick and
//! acknowledges by publishing its pose to the roster and notifying the clock.
//! The clock waits for every live robot (or a timeout) before the next tick,
//! so a run is deterministic for a seed and as fast as the robots compute.

use core::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use iceoryx2::port::listener::ListenerWaitError;

use crate::bus::{Bus, BusError};

/// A signal that interrupts a wait is not an error: the caller's loop checks
/// for termination next.
fn waited(result: Result<u64, ListenerWaitError>, what: &str) -> Result<(), BusError> {
    match result {
        Ok(_) | Err(ListenerWaitError::InterruptSignal) => Ok(()),
        Err(e) => Err(BusError::iceoryx(what, e)),
    }
}
use crate::check::Rejected;
use crate::names;
use crate::wire::ClockTick;

fn open_ticks(
    bus: &Bus,
) -> Result<
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, ClockTick, ()>,
    BusError,
> {
    let limits = bus.limits;
    bus.publish_subscribe::<ClockTick>(
        &names::clock(&bus.swarm),
        2,
        limits.max_agents + limits.max_observers,
        2,
        1,
    )
}

fn open_clock_event(
    bus: &Bus,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<ipc::Service>, BusError> {
    let limits = bus.limits;
    bus.event(
        &names::clock_event(&bus.swarm),
        2,
        limits.max_agents + limits.max_observers,
    )
}

fn open_ack_event(
    bus: &Bus,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<ipc::Service>, BusError> {
    let limits = bus.limits;
    bus.event(
        &names::ack_event(&bus.swarm),
        limits.max_agents + limits.max_observers,
        2,
    )
}

/// The clock's side.
pub struct ClockSource {
    publisher: Publisher<ipc::Service, ClockTick, ()>,
    notifier: Notifier<ipc::Service>,
    acks: Listener<ipc::Service>,
}

impl ClockSource {
    pub fn new(bus: &Bus) -> Result<Self, BusError> {
        let publisher = open_ticks(bus)?
            .publisher_builder()
            .create()
            .map_err(|e| BusError::iceoryx("publish clock", e))?;
        let notifier = open_clock_event(bus)?
            .notifier_builder()
            .create()
            .map_err(|e| BusError::iceoryx("notify clock", e))?;
        let acks = open_ack_event(bus)?
            .listener_builder()
            .create()
            .map_err(|e| BusError::iceoryx("listen for acks", e))?;
        Ok(Self {
            publisher,
            notifier,
            acks,
        })
    }

    pub fn tick(&self, tick: ClockTick) -> Result<(), BusError> {
        self.publisher
            .send_copy(tick)
            .map_err(|e| BusError::iceoryx("send tick", e))?;
        self.notifier
            .notify()
            .map_err(|e| BusError::iceoryx("notify tick", e))?;
        Ok(())
    }

    /// Blocks until some robot acknowledged or `timeout` passed.
    pub fn wait_for_acks(&self, timeout: Duration) -> Result<(), BusError> {
        waited(self.acks.timed_wait(|_| {}, timeout), "wait for acks")
    }
}

/// A robot's side.
pub struct ClockListener {
    subscriber: Subscriber<ipc::Service, ClockTick, ()>,
    listener: Listener<ipc::Service>,
    ack: Notifier<ipc::Service>,
    rejected: Rejected,
    /// The newest tick accepted, to refuse one that leaps impossibly far.
    newest: core::cell::Cell<Option<u64>>,
}

/// The clock steps one tick at a time and a robot reads every few ticks at
/// worst; a tick this far past the newest one seen is a forgery that would
/// leave the robot waiting for ticks that never come.
const MAX_TICK_LEAP: u64 = 100_000;

impl ClockListener {
    pub fn new(bus: &Bus) -> Result<Self, BusError> {
        let subscriber = open_ticks(bus)?
            .subscriber_builder()
            .create()
            .map_err(|e| BusError::iceoryx("follow clock", e))?;
        let listener = open_clock_event(bus)?
            .listener_builder()
            .create()
            .map_err(|e| BusError::iceoryx("listen to clock", e))?;
        let ack = open_ack_event(bus)?
            .notifier_builder()
            .create()
            .map_err(|e| BusError::iceoryx("acknowledge clock", e))?;
        Ok(Self {
            subscriber,
            listener,
            ack,
            rejected: Rejected::default(),
            newest: core::cell::Cell::new(None),
        })
    }

    /// The newest valid tick already published, without waiting.
    pub fn latest(&self) -> Result<Option<ClockTick>, BusError> {
        let mut latest = None;
        while let Some(sample) = self
            .subscriber
            .receive()
            .map_err(|e| BusError::iceoryx("receive tick", e))?
        {
            let leaps = self
                .newest
                .get()
                .is_some_and(|newest| sample.tick > newest.saturating_add(MAX_TICK_LEAP));
            if leaps {
                self.rejected
                    .count_one("clock tick", "it leaps too far ahead");
            } else if self.rejected.filter("clock tick", &*sample) {
                self.newest.set(Some(
                    self.newest
                        .get()
                        .map_or(sample.tick, |n| n.max(sample.tick)),
                ));
                latest = Some(*sample);
            }
        }
        Ok(latest)
    }

    /// Ticks that failed their check since this listener was made.
    pub fn rejected(&self) -> u64 {
        self.rejected.count()
    }

    /// The newest tick later than `after`, waiting up to `timeout` for one.
    pub fn wait_after(&self, after: u64, timeout: Duration) -> Result<Option<ClockTick>, BusError> {
        if let Some(tick) = self.latest()?.filter(|t| t.tick > after) {
            return Ok(Some(tick));
        }
        waited(self.listener.timed_wait(|_| {}, timeout), "wait for tick")?;
        Ok(self.latest()?.filter(|t| t.tick > after))
    }

    pub fn acknowledge(&self) -> Result<(), BusError> {
        self.ack
            .notify()
            .map(|_| ())
            .map_err(|e| BusError::iceoryx("acknowledge tick", e))
    }
}
