//! ROS 2 bags (MCAP, CDR-encoded messages) as diagnosis input: velocity
//! commands from one topic, observed poses from another. The container is
//! read by the `mcap` crate and messages are decoded by the `cdr-encoding`
//! crate against the ROS 2 message layouts below. Errors name the file, the
//! topic and the message.

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::input::InputError;
use crate::recording::{Commands, Poses, Recording};

/// A topic of the bag: its name, message type and how many messages it has.
#[derive(Clone, Debug, PartialEq)]
pub struct Topic {
    pub name: String,
    pub message_type: String,
    pub messages: u64,
}

/// Which topics to read, and for `tf2_msgs/msg/TFMessage` which transform.
#[derive(Clone, Debug, Default)]
pub struct Selection<'a> {
    pub commands_topic: &'a str,
    pub poses_topic: &'a str,
    /// The child frame whose transform is the robot's pose (TF topics only).
    pub frame: Option<&'a str>,
    /// Only transforms from this parent frame (TF topics only).
    pub parent: Option<&'a str>,
}

/// Where a topic's times came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeSource {
    /// The messages' own `header.stamp`.
    HeaderStamps,
    /// The time the bag logged each message (the type has no header, or its
    /// stamps were not set).
    LogTimes,
}

impl std::fmt::Display for TimeSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            TimeSource::HeaderStamps => "the messages' header stamps",
            TimeSource::LogTimes => "the bag's log times",
        })
    }
}

/// What a bag holds for diagnosis, and where each topic's times came from.
/// Times are seconds after the first command, taken in whole nanoseconds:
/// as `f64` seconds since 1970 they would be off by up to a quarter of a
/// microsecond, enough to move a command across a grid step.
#[derive(Clone, Debug)]
pub struct BagRun {
    pub commands: Commands,
    pub poses: Poses,
    /// Seconds since the epoch of the bag's clock at the first command.
    pub t_origin: f64,
    pub command_times: TimeSource,
    pub pose_times: TimeSource,
}

pub const COMMAND_TYPES: [&str; 2] = ["geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped"];
pub const POSE_TYPES: [&str; 4] = [
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "nav_msgs/msg/Odometry",
    "tf2_msgs/msg/TFMessage",
];

fn bag_error(file: &str, message: String) -> InputError {
    InputError {
        file: file.to_owned(),
        line: None,
        message,
    }
}

fn messages<'a>(
    bytes: &'a [u8],
    file: &str,
) -> Result<impl Iterator<Item = Result<mcap::Message<'a>, InputError>> + use<'a>, InputError> {
    let not_mcap = |why: String| {
        bag_error(
            file,
            format!(
                "not an MCAP file{why}; ROS 2 bags in the default sqlite3 storage (.db3) can be converted with `ros2 bag convert`, or recorded with `ros2 bag record -s mcap`"
            ),
        )
    };
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(not_mcap(String::new()));
    }
    let owned = file.to_owned();
    let stream = mcap::MessageStream::new(bytes).map_err(|e| not_mcap(format!(" ({e})")))?;
    Ok(stream.map(move |m| {
        m.map_err(|e| bag_error(&owned, format!("the bag is damaged or cut short: {e}")))
    }))
}

fn message_type(channel: &mcap::Channel) -> String {
    channel
        .schema
        .as_ref()
        .map_or_else(|| "(no schema)".to_owned(), |s| s.name.clone())
}

/// Every topic in the bag with its type and message count, by name.
pub fn topics(bytes: &[u8], file: &str) -> Result<Vec<Topic>, InputError> {
    let mut found: BTreeMap<String, Topic> = BTreeMap::new();
    for message in messages(bytes, file)? {
        let message = message?;
        found
            .entry(message.channel.topic.clone())
            .or_insert_with(|| Topic {
                name: message.channel.topic.clone(),
                message_type: message_type(&message.channel),
                messages: 0,
            })
            .messages += 1;
    }
    Ok(found.into_values().collect())
}

/// Reads the selected topics' commands and poses, sorted by time.
pub fn read_bag(bytes: &[u8], file: &str, selection: &Selection) -> Result<BagRun, InputError> {
    let mut commands: Vec<Stamped<(f64, f64)>> = Vec::new();
    let mut poses: Vec<Stamped<(f64, f64, f64)>> = Vec::new();
    let mut seen = [0_u64; 2];
    for message in messages(bytes, file)? {
        let message = message?;
        let topic = message.channel.topic.as_str();
        let index = if topic == selection.commands_topic {
            0
        } else if topic == selection.poses_topic {
            1
        } else {
            continue;
        };
        seen[index] += 1;
        let kind = message_type(&message.channel);
        let at = |what: String| {
            bag_error(
                file,
                format!("topic {topic}, message {} ({kind}): {what}", seen[index]),
            )
        };
        if message.channel.message_encoding != "cdr" {
            return Err(at(format!(
                "messages are encoded as `{}`; ROS 2 bags use `cdr`",
                message.channel.message_encoding
            )));
        }
        let log_time = i64::try_from(message.log_time).map_err(|_| {
            at(format!(
                "log time {} ns is past the year 2262",
                message.log_time
            ))
        })?;
        if index == 0 {
            commands.push(decode_command(&kind, &message.data, log_time).map_err(at)?);
        } else {
            poses.extend(decode_poses(&kind, &message.data, log_time, selection).map_err(at)?);
        }
    }
    for (index, topic, types) in [
        (0, selection.commands_topic, &COMMAND_TYPES[..]),
        (1, selection.poses_topic, &POSE_TYPES[..]),
    ] {
        if seen[index] == 0 {
            return Err(bag_error(
                file,
                format!(
                    "no messages on topic {topic}; `shoal diagnose --bag {file}` lists the topics (expected one of type {})",
                    types.join(", ")
                ),
            ));
        }
    }
    if poses.is_empty() {
        return Err(bag_error(
            file,
            format!(
                "topic {} has no transform to child frame {}{}",
                selection.poses_topic,
                selection.frame.unwrap_or("?"),
                selection
                    .parent
                    .map(|p| format!(" from parent {p}"))
                    .unwrap_or_default()
            ),
        ));
    }
    let command_times = time_source(&commands);
    let pose_times = time_source(&poses);
    let commands = in_time_order(commands, command_times);
    let poses = in_time_order(poses, pose_times);
    let origin_ns = commands.first().map_or(0, |c| c.0);
    let seconds = |ns: i64| (ns - origin_ns) as f64 * 1e-9;
    let mut run = BagRun {
        commands: Commands::default(),
        poses: Poses::default(),
        t_origin: origin_ns as f64 * 1e-9,
        command_times,
        pose_times,
    };
    for (ns, (v, omega)) in commands {
        run.commands.hold(seconds(ns), v, omega);
    }
    for (ns, (x, y, theta)) in poses {
        run.poses.observe(seconds(ns), x, y, theta);
    }
    Ok(run)
}

/// A decoded value with its header stamp (if the type has one and it was
/// set) and the bag's log time, both in nanoseconds.
struct Stamped<T> {
    stamp: Option<i64>,
    log_time: i64,
    value: T,
}

/// Header stamps if every message of the topic has one, else log times: one
/// clock per topic, never a mix.
fn time_source<T>(messages: &[Stamped<T>]) -> TimeSource {
    if messages.iter().all(|m| m.stamp.is_some()) {
        TimeSource::HeaderStamps
    } else {
        TimeSource::LogTimes
    }
}

fn in_time_order<T>(messages: Vec<Stamped<T>>, source: TimeSource) -> Vec<(i64, T)> {
    let mut timed: Vec<(i64, T)> = messages
        .into_iter()
        .map(|m| {
            let t = match source {
                TimeSource::HeaderStamps => m.stamp.unwrap_or(m.log_time),
                TimeSource::LogTimes => m.log_time,
            };
            (t, m.value)
        })
        .collect();
    timed.sort_by_key(|m| m.0);
    timed
}

/// Decodes a serialized ROS 2 message: a 4-byte encapsulation header (its
/// second byte says the byte order) and the CDR body, whose alignment
/// counts from the body's start.
fn decode<'de, T: Deserialize<'de>>(data: &'de [u8]) -> Result<T, String> {
    let (Some(&[_, representation, _, _]), Some(body)) = (data.first_chunk::<4>(), data.get(4..))
    else {
        return Err(format!("{} bytes, too short for a CDR message", data.len()));
    };
    let decoded = match representation {
        0 => cdr_encoding::from_bytes::<T, byteorder::BigEndian>(body),
        1 => cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(body),
        other => {
            return Err(format!(
                "encapsulation {other} is not plain CDR (0 or 1); XCDR2 and parameter lists are not read"
            ));
        }
    };
    decoded
        .map(|(message, _)| message)
        .map_err(|e| format!("cannot decode the message: {e}"))
}

fn finite(values: &[(&str, f64)]) -> Result<(), String> {
    match values.iter().find(|(_, v)| !v.is_finite()) {
        Some((name, v)) => Err(format!("field {name} is not finite: {v}")),
        None => Ok(()),
    }
}

fn decode_command(kind: &str, data: &[u8], log_time: i64) -> Result<Stamped<(f64, f64)>, String> {
    let (stamp, twist) = match kind {
        "geometry_msgs/msg/Twist" => (None, decode::<msg::Twist>(data)?),
        "geometry_msgs/msg/TwistStamped" => {
            let m = decode::<msg::TwistStamped>(data)?;
            (m.header.stamp.nanoseconds(), m.twist)
        }
        other => {
            return Err(format!(
                "commands must be {}, not {other}",
                COMMAND_TYPES.join(" or ")
            ));
        }
    };
    finite(&[("linear.x", twist.linear.x), ("angular.z", twist.angular.z)])?;
    Ok(Stamped {
        stamp,
        log_time,
        value: (twist.linear.x, twist.angular.z),
    })
}

fn decode_poses(
    kind: &str,
    data: &[u8],
    log_time: i64,
    selection: &Selection,
) -> Result<Vec<Stamped<(f64, f64, f64)>>, String> {
    let one = |header: msg::Header, pose: msg::Pose| -> Result<Vec<_>, String> {
        Ok(vec![planar(
            header.stamp.nanoseconds(),
            log_time,
            &pose.position,
            &pose.orientation,
        )?])
    };
    match kind {
        "geometry_msgs/msg/PoseStamped" => {
            let m = decode::<msg::PoseStamped>(data)?;
            one(m.header, m.pose)
        }
        "geometry_msgs/msg/PoseWithCovarianceStamped" => {
            let m = decode::<msg::PoseWithCovarianceStamped>(data)?;
            one(m.header, m.pose.pose)
        }
        "nav_msgs/msg/Odometry" => {
            let m = decode::<msg::Odometry>(data)?;
            one(m.header, m.pose.pose)
        }
        "tf2_msgs/msg/TFMessage" => {
            let frame = selection
                .frame
                .ok_or("a TF topic needs --frame CHILD: the robot's frame (e.g. base_link)")?;
            let m = decode::<msg::TfMessage>(data)?;
            let same = |a: &str, b: &str| a.trim_start_matches('/') == b.trim_start_matches('/');
            m.transforms
                .into_iter()
                .filter(|t| same(&t.child_frame_id, frame))
                .filter(|t| selection.parent.is_none_or(|p| same(&t.header.frame_id, p)))
                .map(|t| {
                    planar(
                        t.header.stamp.nanoseconds(),
                        log_time,
                        &t.transform.translation,
                        &t.transform.rotation,
                    )
                })
                .collect()
        }
        other => Err(format!(
            "poses must be {}, not {other}",
            POSE_TYPES.join(", ")
        )),
    }
}

/// A pose on the floor: position and yaw (heading about z).
fn planar(
    stamp: Option<i64>,
    log_time: i64,
    p: &msg::Vector3,
    q: &msg::Quaternion,
) -> Result<Stamped<(f64, f64, f64)>, String> {
    finite(&[
        ("position.x", p.x),
        ("position.y", p.y),
        ("orientation.x", q.x),
        ("orientation.y", q.y),
        ("orientation.z", q.z),
        ("orientation.w", q.w),
    ])?;
    let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
    if !(0.5..=1.5).contains(&norm) {
        return Err(format!(
            "orientation is not a rotation: its quaternion has norm {norm:.3}"
        ));
    }
    let yaw = (2.0 * (q.w * q.z + q.x * q.y)).atan2(1.0 - 2.0 * (q.y * q.y + q.z * q.z));
    Ok(Stamped {
        stamp,
        log_time,
        value: (p.x, p.y, yaw),
    })
}

/// Commands on this topic in bags Shoal writes.
pub const WRITTEN_COMMANDS_TOPIC: &str = "/cmd_vel";
/// Poses on this topic in bags Shoal writes.
pub const WRITTEN_POSES_TOPIC: &str = "/mocap/pose";
/// The bag clock's time of a run's 0 s in bags Shoal writes (a wall clock's).
const WRITTEN_EPOCH_NS: i64 = 1_700_000_000_000_000_000;

/// The message definitions a ROS 2 bag carries as each topic's schema
/// (`ros2msg`: the type, then each type it uses after a separator line).
const TWIST_DEFINITION: &str = "Vector3 linear\nVector3 angular\n\
================================================================================\n\
MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";
const POSE_STAMPED_DEFINITION: &str = "std_msgs/Header header\nPose pose\n\
================================================================================\n\
MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
================================================================================\n\
MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\
================================================================================\n\
MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n\
================================================================================\n\
MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n\
================================================================================\n\
MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n";

/// A run as a ROS 2 bag (MCAP, uncompressed): its commands as
/// `geometry_msgs/msg/Twist` on [`WRITTEN_COMMANDS_TOPIC`] and its poses as
/// `geometry_msgs/msg/PoseStamped` on [`WRITTEN_POSES_TOPIC`], in time order.
pub fn write_bag(recording: &Recording) -> Result<Vec<u8>, String> {
    let error = |e: mcap::McapError| format!("cannot write the bag: {e}");
    let mut writer = mcap::WriteOptions::new()
        .compression(None)
        .profile("ros2")
        .create(std::io::Cursor::new(Vec::new()))
        .map_err(error)?;
    let no_metadata = BTreeMap::new();
    let twist = writer
        .add_schema(
            "geometry_msgs/msg/Twist",
            "ros2msg",
            TWIST_DEFINITION.as_bytes(),
        )
        .map_err(error)?;
    let pose = writer
        .add_schema(
            "geometry_msgs/msg/PoseStamped",
            "ros2msg",
            POSE_STAMPED_DEFINITION.as_bytes(),
        )
        .map_err(error)?;
    let commands_channel = writer
        .add_channel(twist, WRITTEN_COMMANDS_TOPIC, "cdr", &no_metadata)
        .map_err(error)?;
    let poses_channel = writer
        .add_channel(pose, WRITTEN_POSES_TOPIC, "cdr", &no_metadata)
        .map_err(error)?;
    let nanos = |t: f64| WRITTEN_EPOCH_NS + (t * 1e9).round() as i64;
    let (c, p) = (&recording.commands, &recording.poses);
    let mut messages: Vec<(i64, u16, Vec<u8>)> = Vec::with_capacity(c.t.len() + p.t.len());
    for i in 0..c.t.len() {
        let message = msg::Twist {
            linear: msg::Vector3 {
                x: c.v[i],
                y: 0.0,
                z: 0.0,
            },
            angular: msg::Vector3 {
                x: 0.0,
                y: 0.0,
                z: c.omega[i],
            },
        };
        messages.push((nanos(c.t[i]), commands_channel, encode(&message)?));
    }
    for i in 0..p.t.len() {
        let ns = nanos(p.t[i]);
        let half = 0.5 * p.theta[i];
        let message = msg::PoseStamped {
            header: msg::Header {
                stamp: msg::Time {
                    sec: (ns.div_euclid(1_000_000_000)) as i32,
                    nanosec: ns.rem_euclid(1_000_000_000) as u32,
                },
                frame_id: "map".to_owned(),
            },
            pose: msg::Pose {
                position: msg::Vector3 {
                    x: p.x[i],
                    y: p.y[i],
                    z: 0.0,
                },
                orientation: msg::Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: half.sin(),
                    w: half.cos(),
                },
            },
        };
        messages.push((ns, poses_channel, encode(&message)?));
    }
    messages.sort_by_key(|m| m.0);
    for (sequence, (ns, channel_id, data)) in messages.into_iter().enumerate() {
        let time = u64::try_from(ns).map_err(|_| format!("time {ns} ns is before 1970"))?;
        writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id,
                    sequence: sequence as u32,
                    log_time: time,
                    publish_time: time,
                },
                &data,
            )
            .map_err(error)?;
    }
    writer.finish().map_err(error)?;
    Ok(writer.into_inner().into_inner())
}

/// A message as a ROS 2 bag holds it: the little-endian CDR encapsulation
/// header, then the body.
fn encode<T: serde::Serialize>(message: &T) -> Result<Vec<u8>, String> {
    let body = cdr_encoding::to_vec::<T, byteorder::LittleEndian>(message)
        .map_err(|e| format!("cannot encode a message: {e}"))?;
    Ok([&[0, 1, 0, 0][..], &body].concat())
}

/// The ROS 2 message layouts read here, field for field as CDR lays them out.
mod msg {
    use serde::{Deserialize, Serialize};

    #[derive(Deserialize, Serialize)]
    pub struct Time {
        pub sec: i32,
        pub nanosec: u32,
    }

    impl Time {
        /// Nanoseconds, or `None` for an unset (zero) stamp.
        pub fn nanoseconds(&self) -> Option<i64> {
            (self.sec != 0 || self.nanosec != 0)
                .then(|| i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec))
        }
    }

    #[derive(Deserialize, Serialize)]
    pub struct Header {
        pub stamp: Time,
        pub frame_id: String,
    }

    /// Also `geometry_msgs/msg/Point`: the same three doubles.
    #[derive(Deserialize, Serialize)]
    pub struct Vector3 {
        pub x: f64,
        pub y: f64,
        pub z: f64,
    }

    #[derive(Deserialize, Serialize)]
    pub struct Quaternion {
        pub x: f64,
        pub y: f64,
        pub z: f64,
        pub w: f64,
    }

    #[derive(Deserialize, Serialize)]
    pub struct Twist {
        pub linear: Vector3,
        pub angular: Vector3,
    }

    #[derive(Deserialize, Serialize)]
    pub struct TwistStamped {
        pub header: Header,
        pub twist: Twist,
    }

    #[derive(Deserialize, Serialize)]
    pub struct Pose {
        pub position: Vector3,
        pub orientation: Quaternion,
    }

    #[derive(Deserialize, Serialize)]
    pub struct PoseStamped {
        pub header: Header,
        pub pose: Pose,
    }

    /// A fixed `float64[36]`: CDR writes it without a length, as six rows
    /// of six (serde derives arrays up to 32).
    type Covariance = [[f64; 6]; 6];

    #[derive(Deserialize, Serialize)]
    pub struct PoseWithCovariance {
        pub pose: Pose,
        #[allow(dead_code)]
        covariance: Covariance,
    }

    #[derive(Deserialize, Serialize)]
    pub struct PoseWithCovarianceStamped {
        pub header: Header,
        pub pose: PoseWithCovariance,
    }

    #[derive(Deserialize, Serialize)]
    pub struct TwistWithCovariance {
        #[allow(dead_code)]
        twist: Twist,
        #[allow(dead_code)]
        covariance: Covariance,
    }

    #[derive(Deserialize, Serialize)]
    pub struct Odometry {
        pub header: Header,
        #[allow(dead_code)]
        child_frame_id: String,
        pub pose: PoseWithCovariance,
        #[allow(dead_code)]
        twist: TwistWithCovariance,
    }

    #[derive(Deserialize, Serialize)]
    pub struct Transform {
        pub translation: Vector3,
        pub rotation: Quaternion,
    }

    #[derive(Deserialize, Serialize)]
    pub struct TransformStamped {
        pub header: Header,
        pub child_frame_id: String,
        pub transform: Transform,
    }

    #[derive(Deserialize, Serialize)]
    pub struct TfMessage {
        pub transforms: Vec<TransformStamped>,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{Settings, generate};
    use shoal_physics::UnicycleModel;

    fn written_run() -> (Recording, Vec<u8>) {
        let recording = generate(
            &UnicycleModel::plain(),
            &Settings {
                duration_s: 20.0,
                ..Settings::default()
            },
        );
        let bytes = write_bag(&recording).expect("write");
        (recording, bytes)
    }

    #[test]
    fn a_written_bag_reads_back_as_the_same_run() {
        let (recording, bytes) = written_run();
        let listed = topics(&bytes, "run.mcap").expect("topics");
        assert_eq!(
            listed
                .iter()
                .map(|t| (
                    t.name.as_str(),
                    t.message_type.as_str(),
                    t.messages as usize
                ))
                .collect::<Vec<_>>(),
            [
                (
                    "/cmd_vel",
                    "geometry_msgs/msg/Twist",
                    recording.commands.t.len()
                ),
                (
                    "/mocap/pose",
                    "geometry_msgs/msg/PoseStamped",
                    recording.poses.t.len()
                ),
            ]
        );
        let run = read_bag(
            &bytes,
            "run.mcap",
            &Selection {
                commands_topic: WRITTEN_COMMANDS_TOPIC,
                poses_topic: WRITTEN_POSES_TOPIC,
                ..Selection::default()
            },
        )
        .expect("read");
        assert_eq!(run.command_times, TimeSource::LogTimes);
        assert_eq!(run.pose_times, TimeSource::HeaderStamps);
        assert!((run.t_origin - 1.7e9).abs() < 1e-3);
        let close = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
        };
        assert!(close(&run.commands.t, &recording.commands.t));
        assert!(close(&run.commands.omega, &recording.commands.omega));
        assert!(close(&run.poses.t, &recording.poses.t));
        assert!(close(&run.poses.x, &recording.poses.x));
        // Headings come back through a quaternion, unwrapped as they went in.
        assert!(close(&run.poses.theta, &recording.poses.theta));
    }

    #[test]
    fn a_message_cut_short_is_a_decoding_error() {
        let data = encode(&msg::Twist {
            linear: msg::Vector3 {
                x: 0.1,
                y: 0.0,
                z: 0.0,
            },
            angular: msg::Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.2,
            },
        })
        .expect("encode");
        let error = decode_command("geometry_msgs/msg/Twist", &data[..30], 0).err();
        assert!(
            error
                .as_deref()
                .is_some_and(|e| e.contains("cannot decode")),
            "{error:?}"
        );
        let error = decode_command("geometry_msgs/msg/Twist", &data[..2], 0).err();
        assert!(
            error.as_deref().is_some_and(|e| e.contains("too short")),
            "{error:?}"
        );
    }
}
