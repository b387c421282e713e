//! The standard ROS 2 messages of commands and poses, decoded by their
//! known CDR layouts (`.db3` files of Humble and older carry no message
//! definitions), with the `cdr-encoding` crate.

use serde::Deserialize;
use shoal_physics::Pose;

pub const COMMAND_TYPES: [&str; 2] = ["geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped"];
pub const POSE_TYPES: [&str; 11] = [
    "geometry_msgs/msg/PoseStamped",
    // What motion-capture bridges (vicon_bridge) publish per body.
    "geometry_msgs/msg/TransformStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "nav_msgs/msg/Odometry",
    // What `ros_gz_bridge` makes of a Gazebo (gz sim) pose: no header, so
    // timed by the bag's log times.
    POSE_TYPE,
    TURTLESIM_POSE_TYPE,
    TF_TYPE,
    MODEL_STATES_TYPE,
    LINK_STATES_TYPE,
    // Positions only: each heading is taken from the track in diagnosis.
    POINT_TYPE,
    NAV_SAT_FIX_TYPE,
];
/// A tracked point (a one-marker tracker, a UWB tag): a position, no heading.
pub const POINT_TYPE: &str = "geometry_msgs/msg/PointStamped";
/// A GPS fix: latitude and longitude (degrees), no heading. A run's fixes
/// are put on the floor in metres east and north of its first
/// (`run::on_the_floor`).
pub const NAV_SAT_FIX_TYPE: &str = "sensor_msgs/msg/NavSatFix";
/// A pose without a header.
pub const POSE_TYPE: &str = "geometry_msgs/msg/Pose";
/// turtlesim's pose (`/turtle1/pose`), the robot of ROS 2's own tutorials,
/// `ros2 bag record`'s among them: x, y and theta as `float32`, no header.
pub const TURTLESIM_POSE_TYPE: &str = "turtlesim/msg/Pose";
/// Poses as transforms between named frames (`/tf`): the robot's is chosen
/// by its child frame.
pub const TF_TYPE: &str = "tf2_msgs/msg/TFMessage";
/// Gazebo Classic's ground truth (`gazebo_ros_state`'s `/model_states` and
/// `/link_states`): every model's (or link's) pose by name, no header.
pub const MODEL_STATES_TYPE: &str = "gazebo_msgs/msg/ModelStates";
pub const LINK_STATES_TYPE: &str = "gazebo_msgs/msg/LinkStates";

/// Whether each message of `kind` holds the poses of several named frames
/// or models, of which the robot's is chosen by name.
pub fn holds_named_poses(kind: &str) -> bool {
    matches!(kind, TF_TYPE | MODEL_STATES_TYPE | LINK_STATES_TYPE)
}

/// A type's name as ROS 2 spells it, `package/msg/Type`. Writers outside
/// ROS (the `mcap` Python examples, `mcap-ros2-support`'s own README)
/// often register `package/Type`, the ROS 1 spelling, for the same
/// message; both name one layout.
pub fn full_type_name(name: &str) -> String {
    match name.split_once('/') {
        Some((package, message))
            if !package.is_empty() && !message.is_empty() && !message.contains('/') =>
        {
            format!("{package}/msg/{message}")
        }
        _ => name.to_owned(),
    }
}

/// The simulation clock a Gazebo bag records beside its topics.
pub const CLOCK_TYPE: &str = "rosgraph_msgs/msg/Clock";

/// A decoded value with its header stamp (if the type has one and it was
/// set) and the bag's log time, both in nanoseconds.
pub struct Stamped<T> {
    pub stamp: Option<i64>,
    pub log_time: i64,
    pub value: T,
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

pub fn decode_command(
    kind: &str,
    data: &[u8],
    log_time: i64,
) -> Result<Stamped<(f64, f64)>, String> {
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

/// Which of the poses a message holds is the robot's, for the types that
/// hold several (`holds_named_poses`): a TF transform's child frame (and,
/// if given, its parent frame), or a Gazebo model's or link's name.
#[derive(Clone, Copy, Debug, Default)]
pub struct PoseName<'a> {
    pub name: Option<&'a str>,
    pub parent: Option<&'a str>,
}

/// The robot's poses in one message of `kind`: its one pose, or those of
/// the frame or model `which` names. Where a name means nothing to the
/// type (`--frame` for a type of one pose a message, `--parent` for
/// Gazebo's states) the message is refused, never read as if unnamed.
pub fn decode_poses(
    kind: &str,
    data: &[u8],
    log_time: i64,
    which: PoseName,
) -> Result<Vec<Stamped<Pose>>, String> {
    let one = |header: msg::Header, pose: msg::Pose| -> Result<Vec<_>, String> {
        Ok(vec![planar(
            header.stamp.nanoseconds(),
            log_time,
            &pose.position,
            &pose.orientation,
        )?])
    };
    if which.name.is_some() && !holds_named_poses(kind) {
        return Err(
            "--frame chooses among the poses a TF or Gazebo states topic holds; \
             this type holds one pose a message: leave --frame out"
                .to_owned(),
        );
    }
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
        "geometry_msgs/msg/TransformStamped" => {
            let m = decode::<msg::TransformStamped>(data)?;
            Ok(vec![transformed(&m, log_time)?])
        }
        POSE_TYPE => {
            let m = decode::<msg::Pose>(data)?;
            Ok(vec![planar(None, log_time, &m.position, &m.orientation)?])
        }
        TURTLESIM_POSE_TYPE => {
            let m = decode::<msg::TurtlesimPose>(data)?;
            let (x, y, theta) = (f64::from(m.x), f64::from(m.y), f64::from(m.theta));
            finite(&[("x", x), ("y", y), ("theta", theta)])?;
            Ok(vec![Stamped {
                stamp: None,
                log_time,
                value: Pose::new(x, y, theta),
            }])
        }
        POINT_TYPE => {
            let m = decode::<msg::PointStamped>(data)?;
            finite(&[("point.x", m.point.x), ("point.y", m.point.y)])?;
            Ok(vec![Stamped {
                stamp: m.header.stamp.nanoseconds(),
                log_time,
                value: Pose::new(m.point.x, m.point.y, f64::NAN),
            }])
        }
        NAV_SAT_FIX_TYPE => {
            let m = decode::<msg::NavSatFix>(data)?;
            // A receiver without a fix (status -1) sends one all the same,
            // often with NaN in it: no position, as a dropout is none.
            if m.status.status < 0 || !(m.latitude.is_finite() && m.longitude.is_finite()) {
                return Ok(Vec::new());
            }
            if m.latitude.abs() > 90.0 || m.longitude.abs() > 180.0 {
                return Err(format!(
                    "latitude {} and longitude {} are not degrees on the Earth",
                    m.latitude, m.longitude
                ));
            }
            // Degrees for now; `run::on_the_floor` puts them in metres.
            Ok(vec![Stamped {
                stamp: m.header.stamp.nanoseconds(),
                log_time,
                value: Pose::new(m.longitude, m.latitude, f64::NAN),
            }])
        }
        named if holds_named_poses(named) => {
            chosen_poses(kind, named_poses(kind, data)?, which, log_time)
        }
        other => Err(format!(
            "poses must be {}, not {other}",
            POSE_TYPES.join(", ")
        )),
    }
}

/// One of the poses a message of a `holds_named_poses` type holds, as
/// written (a leading `/` kept), not yet checked as a pose on the floor.
pub struct NamedPose {
    /// A TF transform's parent frame; Gazebo's states have none.
    pub parent: Option<String>,
    /// A TF transform's child frame, or a Gazebo model's (or link's) name.
    pub name: String,
    stamp: Option<i64>,
    position: msg::Vector3,
    orientation: msg::Quaternion,
}

impl NamedPose {
    /// The pose on the floor, timed by its stamp (if it has one) and `log_time`.
    pub fn on_the_floor(&self, log_time: i64) -> Result<Stamped<Pose>, String> {
        planar(self.stamp, log_time, &self.position, &self.orientation)
    }
}

/// Every pose a message of a `holds_named_poses` type holds: decoded once,
/// both to list what it holds and to choose the robot's.
pub fn named_poses(kind: &str, data: &[u8]) -> Result<Vec<NamedPose>, String> {
    match kind {
        TF_TYPE => Ok(decode::<msg::TfMessage>(data)?
            .transforms
            .into_iter()
            .map(|t| NamedPose {
                stamp: t.header.stamp.nanoseconds(),
                parent: Some(t.header.frame_id),
                name: t.child_frame_id,
                position: t.transform.translation,
                orientation: t.transform.rotation,
            })
            .collect()),
        MODEL_STATES_TYPE | LINK_STATES_TYPE => {
            let m = gazebo_states(data)?;
            Ok(m.name
                .into_iter()
                .zip(m.pose)
                .map(|(name, pose)| NamedPose {
                    parent: None,
                    name,
                    stamp: None,
                    position: pose.position,
                    orientation: pose.orientation,
                })
                .collect())
        }
        other => Err(format!("{other} holds one pose a message, none by name")),
    }
}

/// The robot's poses among `named` (from a message of `kind`), as `which`
/// names them: a TF transform's child frame and, if given, its parent;
/// a Gazebo model's (or link's) name.
pub fn chosen_poses(
    kind: &str,
    named: Vec<NamedPose>,
    which: PoseName,
    log_time: i64,
) -> Result<Vec<Stamped<Pose>>, String> {
    let is_tf = kind == TF_TYPE;
    let name = which.name.ok_or(if is_tf {
        "a TF topic needs --frame CHILD: the robot's frame (e.g. base_link)"
    } else {
        "Gazebo's states need --frame NAME: the robot's model (or link)"
    })?;
    if !is_tf && which.parent.is_some() {
        return Err(
            "--parent chooses among TF transforms; Gazebo's states name each model once".to_owned(),
        );
    }
    let same = |a: &str, b: &str| crate::tf::frame(a) == crate::tf::frame(b);
    named
        .into_iter()
        .filter(|p| same(&p.name, name))
        .filter(|p| {
            which
                .parent
                .is_none_or(|wanted| p.parent.as_deref().is_some_and(|had| same(had, wanted)))
        })
        .map(|p| p.on_the_floor(log_time))
        .collect()
}

/// A Gazebo states message, its names and poses checked to pair up.
fn gazebo_states(data: &[u8]) -> Result<msg::GazeboStates, String> {
    let m = decode::<msg::GazeboStates>(data)?;
    if m.name.len() != m.pose.len() {
        return Err(format!(
            "{} names but {} poses: each name must have its pose",
            m.name.len(),
            m.pose.len()
        ));
    }
    Ok(m)
}

/// The pose a stamped transform gives its child frame.
fn transformed(t: &msg::TransformStamped, log_time: i64) -> Result<Stamped<Pose>, String> {
    planar(
        t.header.stamp.nanoseconds(),
        log_time,
        &t.transform.translation,
        &t.transform.rotation,
    )
}

/// A pose on the floor: position and yaw (heading about z).
fn planar(
    stamp: Option<i64>,
    log_time: i64,
    p: &msg::Vector3,
    q: &msg::Quaternion,
) -> Result<Stamped<Pose>, String> {
    finite(&[
        ("position.x", p.x),
        ("position.y", p.y),
        ("orientation.x", q.x),
        ("orientation.y", q.y),
        ("orientation.z", q.z),
        ("orientation.w", q.w),
    ])?;
    let yaw = shoal_physics::yaw_of_quaternion(q.x, q.y, q.z, q.w)
        .map_err(|why| format!("orientation is {why}"))?;
    Ok(Stamped {
        stamp,
        log_time,
        value: Pose::new(p.x, p.y, yaw),
    })
}

/// A `/clock` message: the simulation time when the recorder received it.
pub fn decode_clock(data: &[u8]) -> Result<i64, String> {
    let clock = decode::<msg::Clock>(data)?;
    clock
        .clock
        .nanoseconds()
        .ok_or_else(|| "the clock message holds time zero".to_owned())
}

/// A message as a ROS 2 bag holds it: the little-endian CDR encapsulation
/// header, then the body.
pub fn encode<T: serde::Serialize>(message: &T) -> Result<Vec<u8>, String> {
    let body = cdr_encoding::to_vec::<T, byteorder::LittleEndian>(message)
        .map_err(|e| format!("cannot encode a message: {e}"))?;
    Ok([&[0, 1, 0, 0][..], &body].concat())
}

/// The ROS 2 message layouts read here, field for field as CDR lays them out.
pub mod msg {
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

    /// `gazebo_msgs/msg/ModelStates` and `LinkStates`: one layout.
    #[derive(Deserialize, Serialize)]
    pub struct GazeboStates {
        pub name: Vec<String>,
        pub pose: Vec<Pose>,
        pub twist: Vec<Twist>,
    }

    /// `geometry_msgs/msg/PointStamped`: a tracked point, no heading.
    #[derive(Deserialize, Serialize)]
    pub struct PointStamped {
        pub header: Header,
        pub point: Vector3,
    }

    /// `sensor_msgs/msg/NavSatStatus`: a status below 0 is no fix.
    #[derive(Deserialize, Serialize)]
    pub struct NavSatStatus {
        pub status: i8,
        pub service: u16,
    }

    /// `sensor_msgs/msg/NavSatFix`: latitude and longitude in degrees.
    #[derive(Deserialize, Serialize)]
    pub struct NavSatFix {
        pub header: Header,
        pub status: NavSatStatus,
        pub latitude: f64,
        pub longitude: f64,
        pub altitude: f64,
        pub position_covariance: [f64; 9],
        pub position_covariance_type: u8,
    }

    /// `turtlesim/msg/Pose`.
    #[derive(Deserialize, Serialize)]
    pub struct TurtlesimPose {
        pub x: f32,
        pub y: f32,
        pub theta: f32,
        pub linear_velocity: f32,
        pub angular_velocity: f32,
    }

    #[derive(Deserialize, Serialize)]
    pub struct Clock {
        pub clock: Time,
    }
}

#[cfg(test)]
mod tests {
    use super::msg::{GazeboStates, Pose, Quaternion, TurtlesimPose, Twist, Vector3};
    use super::{
        MODEL_STATES_TYPE, PoseName, TURTLESIM_POSE_TYPE, decode_poses, encode, full_type_name,
        named_poses,
    };

    fn states() -> GazeboStates {
        let at = |x: f64| Pose {
            position: Vector3 { x, y: 2.0, z: 0.0 },
            orientation: Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                w: 1.0,
            },
        };
        let still = || Twist {
            linear: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.0,
            },
            angular: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.0,
            },
        };
        GazeboStates {
            name: vec!["ground_plane".into(), "burger".into()],
            pose: vec![at(0.0), at(1.5)],
            twist: vec![still(), still()],
        }
    }

    #[test]
    fn gazebos_states_give_the_named_models_pose_and_list_every_name() {
        let data = encode(&states()).expect("encode");
        let burger = PoseName {
            name: Some("burger"),
            parent: None,
        };
        let poses = decode_poses(MODEL_STATES_TYPE, &data, 7, burger).expect("decode");
        assert_eq!(poses.len(), 1);
        assert_eq!(poses[0].value, shoal_physics::Pose::new(1.5, 2.0, 0.0));
        assert_eq!((poses[0].stamp, poses[0].log_time), (None, 7));
        let names: Vec<String> = named_poses(MODEL_STATES_TYPE, &data)
            .expect("names")
            .into_iter()
            .map(|p| p.name)
            .collect();
        assert_eq!(names, ["ground_plane", "burger"]);
        // A parent frame means nothing to Gazebo's states: refused, not ignored.
        let with_parent = PoseName {
            parent: Some("world"),
            ..burger
        };
        assert!(decode_poses(MODEL_STATES_TYPE, &data, 7, with_parent).is_err());
    }

    #[test]
    fn gazebos_states_cut_or_corrupted_are_refused_without_a_panic() {
        let mut unpaired = states();
        unpaired.pose.pop();
        let data = encode(&unpaired).expect("encode");
        let err = named_poses(MODEL_STATES_TYPE, &data)
            .err()
            .expect("names without poses");
        assert!(err.contains("2 names but 1 poses"), "{err}");
        let data = encode(&states()).expect("encode");
        let burger = PoseName {
            name: Some("burger"),
            parent: None,
        };
        for cut in 0..data.len() {
            assert!(decode_poses(MODEL_STATES_TYPE, &data[..cut], 0, burger).is_err());
        }
        for at in 4..data.len() {
            let mut corrupted = data.clone();
            corrupted[at] ^= 0xff;
            // Either refused or read; never a panic or an allocation the
            // bytes cannot hold.
            let _ = decode_poses(MODEL_STATES_TYPE, &corrupted, 0, burger);
            let _ = named_poses(MODEL_STATES_TYPE, &corrupted);
        }
    }

    #[test]
    fn a_ros_1_spelling_names_the_ros_2_type() {
        assert_eq!(
            full_type_name("geometry_msgs/Twist"),
            "geometry_msgs/msg/Twist"
        );
        assert_eq!(
            full_type_name("nav_msgs/msg/Odometry"),
            "nav_msgs/msg/Odometry"
        );
        // Not a type name: left as written, for the error to quote.
        assert_eq!(full_type_name("(no schema)"), "(no schema)");
        assert_eq!(full_type_name("/Twist"), "/Twist");
    }

    #[test]
    fn turtlesims_pose_is_read_as_written_and_refused_when_cut_or_not_finite() {
        let turtle = |x: f32| TurtlesimPose {
            x,
            y: 5.5,
            theta: -1.25,
            linear_velocity: 2.0,
            angular_velocity: 0.5,
        };
        let data = encode(&turtle(3.0)).expect("encode");
        let poses = decode_poses(TURTLESIM_POSE_TYPE, &data, 42, PoseName::default())
            .expect("a turtlesim pose");
        assert_eq!(poses.len(), 1);
        assert_eq!(poses[0].value, shoal_physics::Pose::new(3.0, 5.5, -1.25));
        // No header: timed by the log time alone.
        assert_eq!((poses[0].stamp, poses[0].log_time), (None, 42));
        for cut in 0..data.len() {
            assert!(
                decode_poses(TURTLESIM_POSE_TYPE, &data[..cut], 42, PoseName::default()).is_err()
            );
        }
        let nan = encode(&turtle(f32::NAN)).expect("encode");
        let error = decode_poses(TURTLESIM_POSE_TYPE, &nan, 42, PoseName::default())
            .err()
            .unwrap_or_default();
        assert!(error.contains("field x is not finite"), "{error}");
    }
}
