//! Lockstep: a clock publishes ticks; each robot steps once per tick and
//! acknowledges by publishing its pose to the roster and notifying the clock.
//! The clock waits for every live robot (or a timeout) before the next tick,
//! so a run is deterministic for a seed and as fast as the robots compute.

use core::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;

use iceoryx2::port::listener::ListenerWaitError;

use crate::bus::{Bus, BusError, Topic};

/// A signal that interrupts a wait is not an error: the caller's loop checks
/// for termination next.
fn waited(result: Result<u64, ListenerWaitError>, what: &str) -> Result<(), BusError> {
    match result {
        Ok(_) | Err(ListenerWaitError::InterruptSignal) => Ok(()),
        Err(e) => Err(BusError::iceoryx(what, e)),
    }
}
use crate::names;
use crate::ports::{Receiver, Sender};
use crate::wire::ClockTick;

fn ticks(bus: &Bus) -> Topic {
    let limits = bus.limits;
    Topic {
        name: names::clock(&bus.swarm),
        publishers: 2,
        subscribers: limits.max_agents + limits.max_observers,
        buffer: 2,
        history: 1,
    }
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
    publisher: Sender<ClockTick>,
    notifier: Notifier<ipc::Service>,
    acks: Listener<ipc::Service>,
}

impl ClockSource {
    pub fn new(bus: &Bus) -> Result<Self, BusError> {
        let publisher = Sender::open(bus, &ticks(bus))?;
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
        self.publisher.publish(&tick)?;
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
    ticks: Receiver<ClockTick>,
    listener: Listener<ipc::Service>,
    ack: Notifier<ipc::Service>,
    /// The newest tick accepted, to refuse one that leaps impossibly far.
    newest: core::cell::Cell<Option<u64>>,
}

/// The clock steps one tick at a time and a robot reads every few ticks at
/// worst; a tick this far past the newest one seen is a forgery that would
/// leave the robot waiting for ticks that never come.
const MAX_TICK_LEAP: u64 = 100_000;

impl ClockListener {
    pub fn new(bus: &Bus) -> Result<Self, BusError> {
        let ticks = Receiver::open(bus, &ticks(bus), "clock tick")?;
        let listener = open_clock_event(bus)?
            .listener_builder()
            .create()
            .map_err(|e| BusError::iceoryx("listen to clock", e))?;
        let ack = open_ack_event(bus)?
            .notifier_builder()
            .create()
            .map_err(|e| BusError::iceoryx("acknowledge clock", e))?;
        Ok(Self {
            ticks,
            listener,
            ack,
            newest: core::cell::Cell::new(None),
        })
    }

    /// The newest valid tick already published, without waiting.
    pub fn latest(&self) -> Result<Option<ClockTick>, BusError> {
        let mut latest = None;
        self.ticks.receive(|tick| {
            let leaps = self
                .newest
                .get()
                .is_some_and(|newest| tick.tick > newest.saturating_add(MAX_TICK_LEAP));
            if leaps {
                self.ticks.reject("it leaps too far ahead");
            } else {
                let newest = self.newest.get().map_or(tick.tick, |n| n.max(tick.tick));
                self.newest.set(Some(newest));
                latest = Some(tick);
            }
        })?;
        Ok(latest)
    }

    /// Ticks that failed their check since this listener was made.
    pub fn rejected(&self) -> u64 {
        self.ticks.rejected()
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
