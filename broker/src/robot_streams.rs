//! Per-robot streams between a robot and the SLAM process following it:
//! scans from the robot, pose estimates and model updates back to it. One
//! service each per robot, so following a robot costs nothing to the others.

use core::fmt::Debug;

use iceoryx2::prelude::*;

use crate::bus::{Bus, BusError, Topic};
use crate::check::Wire;
use crate::names;
use crate::ports::{Receiver, Sender};
use crate::wire::{
    EstimateSample, HelperProgress, ModelUpdate, ScanSample, SlamMap, SlamParticles,
};

/// A follower may fall this many samples behind before the oldest are overwritten.
const BUFFER: usize = 32;

/// One robot's stream, or one helper's: a publisher or two, and the swarm's observers.
fn topic(bus: &Bus, name: String) -> Topic {
    Topic {
        name,
        publishers: 2,
        subscribers: bus.limits.max_observers,
        buffer: BUFFER,
        history: 0,
    }
}

fn sender<T: Debug + ZeroCopySend + Copy + 'static>(
    bus: &Bus,
    name: String,
) -> Result<Sender<T>, BusError> {
    Sender::open(bus, &topic(bus, name))
}

fn receiver<T: Debug + ZeroCopySend + Copy + Wire + 'static>(
    bus: &Bus,
    name: String,
) -> Result<Receiver<T>, BusError> {
    Receiver::open(bus, &topic(bus, name), core::any::type_name::<T>())
}

pub fn scan_publisher(bus: &Bus, id: u32) -> Result<Sender<ScanSample>, BusError> {
    sender(bus, names::scan(&bus.swarm, id))
}

pub fn scan_subscriber(bus: &Bus, id: u32) -> Result<Receiver<ScanSample>, BusError> {
    receiver(bus, names::scan(&bus.swarm, id))
}

pub fn estimate_publisher(bus: &Bus, id: u32) -> Result<Sender<EstimateSample>, BusError> {
    sender(bus, names::estimate(&bus.swarm, id))
}

pub fn estimate_subscriber(bus: &Bus, id: u32) -> Result<Receiver<EstimateSample>, BusError> {
    receiver(bus, names::estimate(&bus.swarm, id))
}

pub fn model_publisher(bus: &Bus, id: u32) -> Result<Sender<ModelUpdate>, BusError> {
    sender(bus, names::model(&bus.swarm, id))
}

pub fn model_subscriber(bus: &Bus, id: u32) -> Result<Receiver<ModelUpdate>, BusError> {
    receiver(bus, names::model(&bus.swarm, id))
}

/// The name the recorder's progress reports go by (a lockstep clock paces to it).
pub const RECORDER_PROGRESS: &str = "recorder";
/// The name SLAM's progress reports go by.
pub const SLAM_PROGRESS: &str = "slam";

pub fn progress_publisher(bus: &Bus, helper: &str) -> Result<Sender<HelperProgress>, BusError> {
    sender(bus, names::progress(&bus.swarm, helper))
}

pub fn progress_subscriber(bus: &Bus, helper: &str) -> Result<Receiver<HelperProgress>, BusError> {
    receiver(bus, names::progress(&bus.swarm, helper))
}

pub fn slam_particles_publisher(bus: &Bus) -> Result<Sender<SlamParticles>, BusError> {
    sender(bus, names::slam_particles(&bus.swarm))
}

pub fn slam_particles_subscriber(bus: &Bus) -> Result<Receiver<SlamParticles>, BusError> {
    receiver(bus, names::slam_particles(&bus.swarm))
}

pub fn slam_map_publisher(bus: &Bus) -> Result<Sender<SlamMap>, BusError> {
    sender(bus, names::slam_map(&bus.swarm))
}

pub fn slam_map_subscriber(bus: &Bus) -> Result<Receiver<SlamMap>, BusError> {
    receiver(bus, names::slam_map(&bus.swarm))
}
