//! The lab: the swarm's experiments and the demo. Each runs real robot
//! processes through `shoal-swarm` and returns a report; `shoal experiment`
//! and `shoal demo` print them, and `shoal-bench` reuses the runs.

pub mod demo;
pub mod experiment;

/// The mean of `values`; None if there are none.
pub(crate) fn mean_of(values: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, count) = values.fold((0.0, 0usize), |(sum, count), v| (sum + v, count + 1));
    (count > 0).then(|| sum / count as f64)
}
