//! The Shoal bus over iceoryx2 shared memory: the wire types, the service
//! names, the spatial-cell neighbour exchange, the roster that observers read,
//! the lockstep clock, and liveness. Every process links this crate; no
//! process is a central broker.

pub mod bus;
pub mod cells;
pub mod check;
pub mod clock;
pub mod error;
pub mod liveness;
pub mod names;
pub mod ports;
pub mod robot_streams;
pub mod roster;
pub mod wire;

pub use bus::{Bus, BusError, BusLimits, BusSection};
pub use cells::{CellExchange, CellKey, CellOccupancy, cell_at};
pub use check::{Rejected, Rejection, SampleCheck, Wire};
pub use clock::{ClockListener, ClockSource};
pub use liveness::{SwarmNode, SwarmNodeState};
pub use ports::{Receiver, Sender};
pub use roster::{RosterPublisher, RosterReader, RosterReaders};
pub use wire::{
    ClockTick, EstimateSample, Health, HelperProgress, MAX_BEAMS, MAX_MAP_SIDE, MAX_NEIGHBOURS,
    MAX_SHOWN_PARTICLES, ModelUpdate, PoseSample, ScanSample, SlamMap, SlamParticles,
};
