//! Each robot's true pose and executed command, in the recording itself, so
//! that `shoal diagnose run.rrd --robot N` reads a run from its `.rrd` alone.
//!
//! One row per tick at [`ENTITY`] holds every robot that reported in it (one
//! batch per component, as for the robots' points), so the cost does not grow
//! with an entity per robot. The command is given as the velocity it means
//! under the model the robot ran with, over the period that ended at the pose;
//! [`PERIOD`] (static) says how long that period is.

use std::io::BufReader;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, bail};
use rerun::external::arrow::array::{ArrayRef, Float64Array, UInt32Array};
use rerun::external::re_log_encoding::DecoderApp;
use rerun::external::re_log_types::{LogMsg, StoreKind};
use rerun::log::Chunk;
use shoal_broker::PoseSample;
use shoal_physics::{Command, MotionModel};

/// Where the rows are logged.
pub const ENTITY: &str = "robots/motion";
/// The timeline the rows are read on: simulated seconds.
pub const TIMELINE: &str = "sim_time";
const AGENT_ID: &str = "agent_id";
const X: &str = "x";
const Y: &str = "y";
const THETA: &str = "theta";
/// Forward speed of the executed command, m/s.
const V: &str = "command_v";
/// Turn rate of the executed command, rad/s.
const OMEGA: &str = "command_omega";
/// Static: seconds each command was held before the pose it is logged with.
const PERIOD: &str = "period_s";

/// The velocity a sample's executed command means under `motion`: what the
/// robot was asked to do over the period that ended at this sample. `None`
/// for a command index the model does not know.
pub fn executed_velocity(
    motion: &MotionModel,
    period_s: f64,
    sample: &PoseSample,
) -> Option<(f64, f64)> {
    let command = Command::from_index(sample.command as usize)?;
    let mean = motion.mean(command);
    Some((mean.along / period_s, mean.turn / period_s))
}

/// Logs the period once, as a static property of [`ENTITY`].
pub fn log_period(rec: &rerun::RecordingStream, period_s: f64) -> Result<()> {
    rec.log_static(
        ENTITY,
        &rerun::AnyValues::default()
            .with_component_from_data(PERIOD, Arc::new(Float64Array::from(vec![period_s]))),
    )?;
    Ok(())
}

/// Logs one tick's samples as one row, at the recording's current time.
pub fn log_tick(
    rec: &rerun::RecordingStream,
    motion: &MotionModel,
    period_s: f64,
    samples: &[&PoseSample],
) -> Result<()> {
    let column = |f: &dyn Fn(&PoseSample) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from_iter_values(samples.iter().map(|s| f(s))))
    };
    let velocities: Vec<Option<(f64, f64)>> = samples
        .iter()
        .map(|s| executed_velocity(motion, period_s, s))
        .collect();
    rec.log(
        ENTITY,
        &rerun::AnyValues::default()
            .with_component_from_data(
                AGENT_ID,
                Arc::new(UInt32Array::from_iter_values(
                    samples.iter().map(|s| s.agent_id),
                )),
            )
            .with_component_from_data(X, column(&|s| s.x))
            .with_component_from_data(Y, column(&|s| s.y))
            .with_component_from_data(THETA, column(&|s| s.theta))
            .with_component_from_data(
                V,
                Arc::new(Float64Array::from(
                    velocities
                        .iter()
                        .map(|v| v.map(|v| v.0))
                        .collect::<Vec<_>>(),
                )),
            )
            .with_component_from_data(
                OMEGA,
                Arc::new(Float64Array::from(
                    velocities
                        .iter()
                        .map(|v| v.map(|v| v.1))
                        .collect::<Vec<_>>(),
                )),
            ),
    )?;
    Ok(())
}

/// One robot's run as its recording holds it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RobotTrack {
    /// (t, x, y, theta), t in simulated seconds.
    pub poses: Vec<[f64; 4]>,
    /// (t, v, omega): the command held from t for one period.
    pub commands: Vec<[f64; 3]>,
}

/// One robot at one tick.
#[derive(Clone, Copy, Debug)]
struct MotionRow {
    t: f64,
    id: u32,
    pose: [f64; 3],
    /// (v, omega); none for a command index the model did not know.
    velocity: Option<[f64; 2]>,
}

/// What a recording holds of [`ENTITY`]: every robot's rows, and whether the
/// file ended mid-message (a recorder killed while writing).
#[derive(Debug, Default)]
pub struct MotionRows {
    period_s: Option<f64>,
    rows: Vec<MotionRow>,
    pub truncated_after: Option<u64>,
}

impl MotionRows {
    /// Robot ids the recording holds, ascending.
    pub fn robots(&self) -> Vec<u32> {
        let mut ids: Vec<u32> = self.rows.iter().map(|r| r.id).collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    }

    /// Robot `id`'s poses and commands, by time. Fails, naming the file, when
    /// the recording has no motion rows (made before Shoal logged them) or
    /// does not hold this robot.
    pub fn track(&self, id: u32, file: &str) -> Result<RobotTrack> {
        let Some(period_s) = self.period_s else {
            bail!(
                "{file}: the recording holds no `{ENTITY}` (it was made by a Shoal recorder older than `shoal diagnose run.rrd` support, or is not a Shoal recording); \
                 diagnose it through the folder its recorder wrote with --tum"
            );
        };
        let robots = self.robots();
        if !robots.contains(&id) {
            bail!(
                "{file}: no robot {id} in this recording; it holds robots {}",
                list_ids(&robots)
            );
        }
        let mut track = RobotTrack::default();
        for row in self.rows.iter().filter(|r| r.id == id) {
            let [x, y, theta] = row.pose;
            track.poses.push([row.t, x, y, theta]);
            if let Some([v, omega]) = row.velocity {
                track.commands.push([row.t - period_s, v, omega]);
            }
        }
        track.poses.sort_by(|a, b| a[0].total_cmp(&b[0]));
        track.commands.sort_by(|a, b| a[0].total_cmp(&b[0]));
        Ok(track)
    }
}

/// "0-5, 7, 9": ids as ranges, for messages.
pub fn list_ids(ids: &[u32]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < ids.len() {
        let mut j = i;
        while j + 1 < ids.len() && ids[j + 1] == ids[j] + 1 {
            j += 1;
        }
        parts.push(if j > i {
            format!("{}-{}", ids[i], ids[j])
        } else {
            ids[i].to_string()
        });
        i = j + 1;
    }
    if parts.is_empty() {
        "none".to_owned()
    } else {
        parts.join(", ")
    }
}

/// Reads every motion row of a `.rrd` file with Rerun's own decoder. A file
/// that ends mid-message (its recorder was killed) is read up to the last
/// whole message, and says so in `truncated_after`.
pub fn read_motion(path: &Path) -> Result<MotionRows> {
    let file = path.display().to_string();
    let reader = std::fs::File::open(path).with_context(|| format!("cannot read {file}"))?;
    let messages = DecoderApp::decode_eager(BufReader::new(reader))
        .map_err(|e| anyhow::anyhow!("{file}: not a Rerun recording (.rrd): {e}"))?;
    let mut out = MotionRows::default();
    for (decoded, message) in (0u64..).zip(messages) {
        let message = match message {
            Ok(m) => m,
            Err(e) if decoded > 0 => {
                // What came before is whole; a killed recorder leaves a cut tail.
                tracing::debug!("{file}: stops decoding: {e}");
                out.truncated_after = Some(decoded);
                break;
            }
            Err(e) => bail!("{file}: not a Rerun recording (.rrd): {e}"),
        };
        let LogMsg::ArrowMsg(store, arrow) = message else {
            continue;
        };
        if store.kind() != StoreKind::Recording {
            continue;
        }
        let chunk = Chunk::from_arrow_msg(&arrow)
            .map_err(|e| anyhow::anyhow!("{file}: message {decoded}: {e}"))?;
        if chunk.entity_path().to_string() != format!("/{ENTITY}") {
            continue;
        }
        add_chunk(&mut out, &chunk)
            .with_context(|| format!("{file}: message {decoded} ({ENTITY})"))?;
    }
    Ok(out)
}

fn add_chunk(out: &mut MotionRows, chunk: &Chunk) -> Result<()> {
    if chunk.is_static() {
        if let Some(period) = chunk.iter_slices::<f64>(PERIOD.into()).next() {
            match period {
                [p] if p.is_finite() && *p > 0.0 => out.period_s = Some(*p),
                _ => bail!("field {PERIOD}: expected one positive number, found {period:?}"),
            }
        }
        return Ok(());
    }
    let timeline = rerun::external::re_log_types::TimelineName::from_static_str(TIMELINE);
    let times: Vec<i64> = chunk
        .iter_component_indices(timeline, AGENT_ID.into())
        .map(|(t, _)| t.as_i64())
        .collect();
    let ids: Vec<&[u32]> = chunk.iter_slices::<u32>(AGENT_ID.into()).collect();
    let numbers =
        |name: &'static str| -> Vec<&[f64]> { chunk.iter_slices::<f64>(name.into()).collect() };
    let (xs, ys, thetas) = (numbers(X), numbers(Y), numbers(THETA));
    // Commands may be null (an unknown command index): read them as options.
    let optional = |name: &'static str| -> Vec<Vec<Option<f64>>> {
        chunk
            .iter_slices::<Option<f64>>(name.into())
            .map(|s| s.collect())
            .collect()
    };
    let (vs, omegas) = (optional(V), optional(OMEGA));
    let rows = ids.len();
    if times.len() != rows
        || [&xs, &ys, &thetas].iter().any(|c| c.len() != rows)
        || vs.len() != rows
        || omegas.len() != rows
    {
        bail!(
            "a row lacks a field of {AGENT_ID}, {X}, {Y}, {THETA}, {V}, {OMEGA} on the {TIMELINE} timeline, or one has another type"
        );
    }
    for row in 0..rows {
        let n = ids[row].len();
        if [
            xs[row].len(),
            ys[row].len(),
            thetas[row].len(),
            vs[row].len(),
            omegas[row].len(),
        ]
        .iter()
        .any(|len| *len != n)
        {
            bail!("row {row}: {n} robots but fields of other lengths");
        }
        let t = times[row] as f64 * 1e-9;
        for i in 0..n {
            let velocity = vs[row][i].zip(omegas[row][i]).map(|(v, w)| [v, w]);
            out.rows.push(MotionRow {
                t,
                id: ids[row][i],
                pose: [xs[row][i], ys[row][i], thetas[row][i]],
                velocity,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_listed_as_ranges() {
        assert_eq!(list_ids(&[0, 1, 2, 3, 5, 7, 8]), "0-3, 5, 7-8");
        assert_eq!(list_ids(&[]), "none");
    }

    /// What is logged comes back from the file, robot by robot, with each
    /// command placed at the start of the period it was held over.
    #[test]
    fn a_recording_round_trips_each_robots_poses_and_commands() {
        let dir = std::env::temp_dir().join(format!("shoal-motion-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("motion.rrd");
        let motion = MotionModel::legged_default();
        let period = 0.2;
        {
            let rec = rerun::RecordingStreamBuilder::new("shoal-test")
                .save(&path)
                .expect("save");
            log_period(&rec, period).expect("period");
            for tick in 1..=10u64 {
                let t = tick as f64 * period;
                rec.set_duration_secs(TIMELINE, t);
                let mut a = PoseSample::standing(3, 1, tick, t, 2.0, 0.1);
                a.command = 1;
                let b = PoseSample::standing(4, 1, tick, -t, 0.0, 0.0);
                log_tick(&rec, &motion, period, &[&a, &b]).expect("log");
            }
            rec.flush_blocking().expect("flush");
        }
        let rows = read_motion(&path).expect("read");
        assert_eq!(rows.robots(), vec![3, 4]);
        let track = rows.track(3, "motion.rrd").expect("track");
        assert_eq!(track.poses.len(), 10);
        assert!((track.poses[9][0] - 2.0).abs() < 1e-9);
        assert!((track.poses[9][1] - 2.0).abs() < 1e-12);
        let expected = motion.mean(Command::ALL[1]);
        assert_eq!(track.commands.len(), 10);
        assert!(
            (track.commands[0][0] - 0.0).abs() < 1e-9,
            "{:?}",
            track.commands[0]
        );
        assert!((track.commands[0][1] - expected.along / period).abs() < 1e-12);
        let missing = rows.track(9, "motion.rrd").expect_err("no robot 9");
        assert!(
            missing.to_string().contains("holds robots 3-4"),
            "{missing}"
        );
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn a_file_that_is_not_a_recording_is_named() {
        let dir = std::env::temp_dir().join(format!("shoal-motion-bad-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("notes.rrd");
        std::fs::write(&path, "t,x,y\n1,2,3\n").expect("write");
        let err = read_motion(&path).expect_err("not an rrd");
        assert!(
            err.to_string().contains("notes.rrd: not a Rerun recording"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }
}
