//! Lockstep pacing: a lockstep clock waits each tick for the helpers
//! (recorder, SLAM) to keep up, within the buffers between them and the robots.

use std::time::{Duration, Instant};

use anyhow::Result;
use shoal_broker::HelperProgress;
use shoal_broker::robot_streams::{self, RECORDER_PROGRESS, SLAM_PROGRESS};

use crate::process::{RECORDER_BINARY, SLAM_BINARY};

/// A helper's progress, which a lockstep clock must not outrun by more than
/// the buffers between robots and helpers (8 roster samples, 32 scans).
pub(crate) struct Pace {
    pub(crate) helper: &'static str,
    /// Ticks the clock may run ahead of this helper.
    lag: u64,
    pub(crate) progress: shoal_broker::Receiver<HelperProgress>,
    tick: Option<u64>,
}

/// The name a helper's progress reports go by, which a lockstep clock paces to.
pub(crate) fn pace_name(binary: &str) -> &str {
    match binary {
        RECORDER_BINARY => RECORDER_PROGRESS,
        SLAM_BINARY => SLAM_PROGRESS,
        other => other,
    }
}

/// Ticks a lockstep clock may run ahead of its recorder (within the
/// roster's buffer); SLAM gets none, so its estimates reach the robot the
/// next tick.
pub(crate) const RECORDER_LAG_TICKS: u64 = 4;
pub(crate) const SLAM_LAG_TICKS: u64 = 0;
/// A helper silent this long is no longer waited for.
const HELPER_PATIENCE: Duration = Duration::from_secs(10);

impl Pace {
    /// Follows the progress reports of helper `helper`, which the clock may
    /// outrun by `lag` ticks.
    pub(crate) fn open(bus: &shoal_broker::Bus, helper: &'static str, lag: u64) -> Result<Self> {
        Ok(Self {
            helper,
            lag,
            progress: robot_streams::progress_subscriber(bus, helper)?,
            tick: None,
        })
    }

    /// Waits until the helper has read up to `tick - lag`;
    /// false when it stopped answering. Reports it rejects are added to `rejected`.
    pub(crate) fn wait_for(&mut self, tick: u64, rejected: &mut u64) -> Result<bool> {
        let started = Instant::now();
        loop {
            let mut newest = self.tick;
            self.progress.receive(|p| {
                // A helper cannot have read a tick the clock has not sent yet.
                if p.tick > tick {
                    *rejected += 1;
                } else {
                    newest = Some(newest.map_or(p.tick, |n: u64| n.max(p.tick)));
                }
            })?;
            // A helper that just joined has missed nothing it could have
            // read: it is caught up with the tick at which it first spoke.
            self.tick = newest.map(|t| match self.tick {
                None => t.max(tick),
                Some(_) => t,
            });
            if self.tick.is_some_and(|t| t + self.lag >= tick) {
                return Ok(true);
            }
            if started.elapsed() > HELPER_PATIENCE {
                return Ok(false);
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers_report_progress_under_their_short_names() {
        assert_eq!(pace_name(RECORDER_BINARY), "recorder");
        assert_eq!(pace_name("shoal-slam"), "slam");
        assert_eq!(pace_name("shoal-link"), "shoal-link");
    }
}
