//! One robot, one process: its simulated body, its formation controller, and
//! the loop that connects them to the bus.

pub mod member;
pub mod neighbours;
pub mod robot;
pub mod run;
pub mod sensing;
