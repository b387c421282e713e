//! Bags as Shoal's generator writes them: a run as a ROS 2 bag (MCAP, CDR),
//! to try diagnosis without a robot.

use std::collections::BTreeMap;

use crate::ros::{encode, msg};

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

/// A run as a ROS 2 bag (MCAP, uncompressed): commands (t, v, omega) as
/// `geometry_msgs/msg/Twist` on [`WRITTEN_COMMANDS_TOPIC`] and its poses as
/// `geometry_msgs/msg/PoseStamped` on [`WRITTEN_POSES_TOPIC`] from poses
/// (t, x, y, yaw), in time order.
pub fn write_bag(
    commands: &[(f64, f64, f64)],
    poses: &[(f64, f64, f64, f64)],
) -> Result<Vec<u8>, String> {
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
    let mut messages: Vec<(i64, u16, Vec<u8>)> = Vec::with_capacity(commands.len() + poses.len());
    for &(t, v, omega) in commands {
        messages.push((nanos(t), commands_channel, encode(&twist_of(v, omega))?));
    }
    for &(t, x, y, theta) in poses {
        let ns = nanos(t);
        messages.push((
            ns,
            poses_channel,
            encode(&pose_stamped_of(ns, x, y, theta))?,
        ));
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

/// A command as a `Twist`: forward speed and turn rate.
fn twist_of(v: f64, omega: f64) -> msg::Twist {
    msg::Twist {
        linear: msg::Vector3 {
            x: v,
            y: 0.0,
            z: 0.0,
        },
        angular: msg::Vector3 {
            x: 0.0,
            y: 0.0,
            z: omega,
        },
    }
}

/// A planar pose as a `PoseStamped` in frame `map`, stamped `ns`.
fn pose_stamped_of(ns: i64, x: f64, y: f64, theta: f64) -> msg::PoseStamped {
    let half = 0.5 * theta;
    msg::PoseStamped {
        header: msg::Header {
            stamp: msg::Time {
                sec: (ns.div_euclid(1_000_000_000)) as i32,
                nanosec: ns.rem_euclid(1_000_000_000) as u32,
            },
            frame_id: "map".to_owned(),
        },
        pose: msg::Pose {
            position: msg::Vector3 { x, y, z: 0.0 },
            orientation: msg::Quaternion {
                x: 0.0,
                y: 0.0,
                z: half.sin(),
                w: half.cos(),
            },
        },
    }
}
