//! Online motion-model learning and particle-filter SLAM (thesis chapter IV).
//! Pure logic: the SLAM process feeds it from the bus.

pub mod filter;
pub mod follow;
pub mod follower;
pub mod grid;
pub mod learning;
pub mod metrics;
pub mod proposal;
pub mod report;
