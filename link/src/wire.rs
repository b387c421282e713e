//! What crosses the network between hosts: a robot's pose in a fixed
//! little-endian layout (not the in-memory one: hosts may differ), with the
//! clock origin of the host it comes from, and a host's 1 Hz summary of its
//! robots in JSON.

use crate::report::RemoteRobot;
use serde::{Deserialize, Serialize};
use shoal_broker::{MAX_NEIGHBOURS, PoseSample};

/// Marks a pose message and its layout's version.
const POSE_MAGIC: [u8; 4] = *b"SHP1";
/// Magic, clock origin, then the sample's fields in declaration order.
pub const POSE_MESSAGE_BYTES: usize = 4 + 8 + 8 + 8 + 9 * 8 + 4 * 4 + 4 * MAX_NEIGHBOURS + 2 * 4;

#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    #[error("{0} bytes where a pose message has {POSE_MESSAGE_BYTES}")]
    Length(usize),
    #[error("not a Shoal pose message (or another version of it)")]
    Magic,
}

/// A pose as it travels between hosts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RemotePose {
    /// When the sending host's clock started, ms since the Unix epoch: a
    /// sample's `sim_time` counts from it.
    pub epoch_unix_ms: u64,
    pub sample: PoseSample,
}

impl RemotePose {
    pub fn encode(&self) -> Vec<u8> {
        let s = &self.sample;
        let mut out = Vec::with_capacity(POSE_MESSAGE_BYTES);
        out.extend_from_slice(&POSE_MAGIC);
        out.extend_from_slice(&self.epoch_unix_ms.to_le_bytes());
        out.extend_from_slice(&s.agent_id.to_le_bytes());
        out.extend_from_slice(&s.pid.to_le_bytes());
        out.extend_from_slice(&s.tick.to_le_bytes());
        for value in [
            s.sim_time,
            s.x,
            s.y,
            s.theta,
            s.believed_x,
            s.believed_y,
            s.believed_theta,
            s.vx,
            s.vy,
        ] {
            out.extend_from_slice(&value.to_le_bytes());
        }
        for value in [s.command, s.health, s.visible, s.neighbour_count] {
            out.extend_from_slice(&value.to_le_bytes());
        }
        for id in s.neighbours {
            out.extend_from_slice(&id.to_le_bytes());
        }
        out.extend_from_slice(&s.missed_periods.to_le_bytes());
        out.extend_from_slice(&s.neighbour_age_ms.to_le_bytes());
        out
    }

    /// Reads a message; says nothing of whether its values are plausible
    /// (the receiver's [`shoal_broker::SampleCheck`] does).
    pub fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        if bytes.len() != POSE_MESSAGE_BYTES {
            return Err(DecodeError::Length(bytes.len()));
        }
        let mut at = Cursor { bytes, at: 0 };
        if at.take::<4>() != POSE_MAGIC {
            return Err(DecodeError::Magic);
        }
        let epoch_unix_ms = u64::from_le_bytes(at.take());
        let mut sample = PoseSample::standing(0, 0, 0, 0.0, 0.0, 0.0);
        sample.agent_id = at.u32();
        sample.pid = at.u32();
        sample.tick = u64::from_le_bytes(at.take());
        for field in [
            &mut sample.sim_time,
            &mut sample.x,
            &mut sample.y,
            &mut sample.theta,
            &mut sample.believed_x,
            &mut sample.believed_y,
            &mut sample.believed_theta,
            &mut sample.vx,
            &mut sample.vy,
        ] {
            *field = f64::from_le_bytes(at.take());
        }
        for field in [
            &mut sample.command,
            &mut sample.health,
            &mut sample.visible,
            &mut sample.neighbour_count,
        ] {
            *field = at.u32();
        }
        for id in &mut sample.neighbours {
            *id = at.u32();
        }
        sample.missed_periods = at.u32();
        sample.neighbour_age_ms = at.u32();
        Ok(Self {
            epoch_unix_ms,
            sample,
        })
    }

    /// The sample in the receiving host's time: `sim_time` counted from
    /// `local_epoch_unix_ms` and the tick that time falls in, so a robot
    /// here measures its age as it does a local neighbour's. None for a
    /// sample from before this host's clock started. Assumes the hosts'
    /// wall clocks agree (NTP), as any real-time swarm across machines does.
    pub fn in_local_time(&self, local_epoch_unix_ms: u64, period_s: f64) -> Option<PoseSample> {
        let shift_s = (self.epoch_unix_ms as f64 - local_epoch_unix_ms as f64) / 1000.0;
        let sim_time = self.sample.sim_time + shift_s;
        // NaN fails both comparisons, so it is refused too.
        let valid = sim_time >= 0.0 && period_s > 0.0;
        if !valid {
            return None;
        }
        Some(PoseSample {
            sim_time,
            tick: (sim_time / period_s).round() as u64,
            ..self.sample
        })
    }
}

struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Cursor<'_> {
    /// The next `N` bytes; the caller checked the length, so a shorter
    /// message cannot reach here (it would read zeros, not panic).
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0; N];
        if let Some(chunk) = self.bytes.get(self.at..self.at + N) {
            out.copy_from_slice(chunk);
        }
        self.at += N;
        out
    }

    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
}

/// What a host says of itself once a second: who runs there, for the other
/// hosts' `shoal status` and for refusing a robot id two hosts use.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HostSummary {
    pub host: String,
    pub epoch_unix_ms: u64,
    pub robots: Vec<RemoteRobot>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> PoseSample {
        let mut s = PoseSample::standing(7, 4321, 55, 1.5, -2.25, 0.5);
        s.sim_time = 11.0;
        s.vx = 0.1;
        s.neighbour_count = 2;
        s.neighbours[..2].copy_from_slice(&[3, 9]);
        s.missed_periods = 4;
        s.neighbour_age_ms = 210;
        s
    }

    #[test]
    fn a_pose_survives_the_wire_and_a_broken_message_does_not_pass() {
        let pose = RemotePose {
            epoch_unix_ms: 1_700_000_000_123,
            sample: sample(),
        };
        let bytes = pose.encode();
        assert_eq!(bytes.len(), POSE_MESSAGE_BYTES);
        assert_eq!(RemotePose::decode(&bytes), Ok(pose));
        assert_eq!(
            RemotePose::decode(&bytes[1..]),
            Err(DecodeError::Length(POSE_MESSAGE_BYTES - 1))
        );
        let mut wrong = bytes.clone();
        wrong[0] = b'X';
        assert_eq!(RemotePose::decode(&wrong), Err(DecodeError::Magic));
        assert_eq!(RemotePose::decode(&[]), Err(DecodeError::Length(0)));
    }

    #[test]
    fn a_remote_time_is_shifted_to_the_local_clock() {
        let pose = RemotePose {
            epoch_unix_ms: 10_000,
            sample: sample(),
        };
        // This host started 1 s after the sender: its clock reads 1 s less.
        let local = pose.in_local_time(11_000, 0.2).expect("after our start");
        assert!((local.sim_time - 10.0).abs() < 1e-12);
        assert_eq!(local.tick, 50);
        assert_eq!((local.agent_id, local.x), (7, 1.5));
        // A sample from before this host's clock started has no local time.
        assert_eq!(pose.in_local_time(30_000, 0.2), None);
        assert_eq!(pose.in_local_time(11_000, 0.0), None);
    }
}
