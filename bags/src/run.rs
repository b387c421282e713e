//! A bag read for diagnosis: velocity commands from one topic, observed
//! poses from another, both on the one clock `clock::choose` picks.

use std::collections::BTreeMap;

use crate::BagError;
use crate::clock::{ClockChoice, LogToClock, StampsPreference, Timing};
use crate::ros::{self, Stamped};
use crate::storage::{Bag, RawMessage};
use crate::tf;
use shoal_physics::Pose;

/// Which topics to read, and for poses topics that hold several (TF,
/// Gazebo's states) which is the robot's.
#[derive(Clone, Debug, Default)]
pub struct Selection<'a> {
    pub commands_topic: &'a str,
    pub poses_topic: &'a str,
    /// For topics that hold several poses only: the robot's.
    pub pose_name: ros::PoseName<'a>,
}

/// The topic Gazebo and every ROS 2 simulator publishes simulation time on.
pub const CLOCK_TOPIC: &str = "/clock";

/// Where ROS 2 publishes the transforms that never change (a robot's
/// `base_footprint -> base_link`), once, latched.
pub const TF_STATIC_TOPIC: &str = "/tf_static";

/// What a bag holds for diagnosis. Times are seconds after the first
/// command, taken in whole nanoseconds: as `f64` seconds since 1970 they
/// would be off by up to a quarter of a microsecond.
#[derive(Clone, Debug)]
pub struct BagRun {
    /// (t, v, omega), in time order.
    pub commands: Vec<(f64, f64, f64)>,
    /// (t, x, y, yaw), in time order.
    pub poses: Vec<(f64, f64, f64, f64)>,
    /// The chosen clock's time of the first command, in seconds.
    pub t_origin: f64,
    pub clock: ClockChoice,
    /// Files of the bag its recorder left unfinished, said as sentences
    /// (see `storage::Reading::unfinished`); what they hold was read.
    pub unfinished: Vec<String>,
    /// Where the poses were composed through a TF tree (no one transform
    /// from `--parent` to `--frame`), how, in words.
    pub pose_chain: Option<String>,
}

/// Reads the selected topics of `bag` (and its `/clock`, if it has one).
pub fn read_run(
    bag: &Bag,
    selection: &Selection,
    preference: StampsPreference,
) -> Result<BagRun, BagError> {
    let wanted = [
        selection.commands_topic,
        selection.poses_topic,
        CLOCK_TOPIC,
        TF_STATIC_TOPIC,
    ];
    let mut commands: Vec<Stamped<(f64, f64)>> = Vec::new();
    let mut poses: Vec<Stamped<Pose>> = Vec::new();
    let mut without_fix = 0;
    let mut clock: Vec<(i64, i64)> = Vec::new();
    let mut seen = [0_u64; 2];
    // The poses a TF or Gazebo states topic holds, (parent, name) ->
    // messages holding it: what the user may choose from when the robot's
    // is not found.
    let mut pose_names: BTreeMap<(Option<String>, String), u64> = BTreeMap::new();
    let mut poses_type = String::new();
    // Decoded only if the poses are composed through the TF tree: a bag
    // whose /tf_static is broken is still read for what it needs.
    let mut tf_static: Vec<(i64, Vec<u8>)> = Vec::new();
    let read = bag.messages(Some(&wanted))?;
    for message in read.found {
        let RawMessage {
            topic,
            message_type,
            encoding,
            log_time_ns,
            data,
        } = message;
        let index = if topic == selection.commands_topic {
            0
        } else if topic == selection.poses_topic {
            1
        } else {
            if topic == TF_STATIC_TOPIC && message_type == ros::TF_TYPE {
                tf_static.push((log_time_ns, data));
                continue;
            }
            // The bag's own /clock, when it is not one of the chosen topics.
            if message_type == ros::CLOCK_TYPE
                && let Ok(sim) = ros::decode_clock(&data)
            {
                clock.push((log_time_ns, sim));
            }
            continue;
        };
        seen[index] += 1;
        let at = |what: String| message_error(bag, &topic, seen[index], &message_type, what);
        if encoding != "cdr" {
            return Err(at(format!(
                "messages are encoded as `{encoding}`; ROS 2 bags use `cdr`"
            )));
        }
        if index == 0 {
            commands.push(ros::decode_command(&message_type, &data, log_time_ns).map_err(at)?);
        } else {
            if ros::holds_named_poses(&message_type) {
                let named = ros::named_poses(&message_type, &data).map_err(at)?;
                for pose in &named {
                    *pose_names
                        .entry((pose.parent.clone(), pose.name.clone()))
                        .or_default() += 1;
                }
                // Without a name, refused once all are counted, with what
                // the topic holds.
                if selection.pose_name.name.is_some() {
                    poses.extend(
                        ros::chosen_poses(&message_type, named, selection.pose_name, log_time_ns)
                            .map_err(at)?,
                    );
                }
            } else {
                let decoded =
                    ros::decode_poses(&message_type, &data, log_time_ns, selection.pose_name)
                        .map_err(at)?;
                // Only a GPS message without a fix holds no pose.
                without_fix += usize::from(decoded.is_empty());
                poses.extend(decoded);
            }
            poses_type = message_type;
        }
    }
    let mut pose_chain = None;
    if poses.is_empty()
        && poses_type == ros::TF_TYPE
        && let (Some(leaf), Some(root)) = (selection.pose_name.name, selection.pose_name.parent)
        && let Some(composed) = composed_through_tree(
            bag,
            selection.poses_topic,
            &pose_names,
            &tf_static,
            root,
            leaf,
        )?
    {
        poses = composed.poses;
        pose_chain = Some(composed.note);
    }
    check_found(
        bag,
        selection,
        seen,
        poses.is_empty(),
        &poses_type,
        &pose_names,
    )?;
    let (choice, map) = crate::clock::choose(&times(&commands), &times(&poses), &clock, preference)
        .map_err(|e| BagError::new(&bag.path, e))?;
    let commands = on_clock(commands, choice.commands, map.as_ref());
    let mut poses = on_clock(poses, choice.poses, map.as_ref());
    if poses_type == ros::NAV_SAT_FIX_TYPE {
        pose_chain = Some(on_the_floor(&mut poses, without_fix));
    }
    let origin_ns = commands.first().map_or(0, |c| c.0);
    // Division by 1e9 rounds correctly; a product with 1e-9 (itself
    // inexact) can put a time a hair past the one written.
    let seconds = |ns: i64| (ns - origin_ns) as f64 / 1e9;
    Ok(BagRun {
        commands: commands
            .into_iter()
            .map(|(ns, (v, omega))| (seconds(ns), v, omega))
            .collect(),
        poses: poses
            .into_iter()
            .map(|(ns, p)| (seconds(ns), p.x, p.y, p.theta))
            .collect(),
        t_origin: origin_ns as f64 / 1e9,
        clock: choice,
        unfinished: read.unfinished,
        pose_chain,
    })
}

/// GPS fixes (longitude and latitude in degrees, as `ros::decode_poses`
/// leaves them) put on the floor: metres east and north of the first fix,
/// on the WGS 84 ellipsoid's radii of curvature there (a plane tangent to
/// it, good to a millimetre over a few hundred metres); said in words,
/// with the messages `without_fix` (status -1), left out as dropouts.
fn on_the_floor(poses: &mut [(i64, Pose)], without_fix: usize) -> String {
    const EQUATORIAL_RADIUS_M: f64 = 6_378_137.0;
    const ECCENTRICITY_SQUARED: f64 = 6.694_379_990_14e-3;
    let Some(&(_, first)) = poses.first() else {
        return String::new();
    };
    let (longitude, latitude) = (first.x, first.y);
    let sin = latitude.to_radians().sin();
    let across = 1.0 - ECCENTRICITY_SQUARED * sin * sin;
    let east_west = EQUATORIAL_RADIUS_M / across.sqrt();
    let north_south = EQUATORIAL_RADIUS_M * (1.0 - ECCENTRICITY_SQUARED) / across.powf(1.5);
    for (_, pose) in poses.iter_mut() {
        *pose = Pose::new(
            east_west * latitude.to_radians().cos() * (pose.x - longitude).to_radians(),
            north_south * (pose.y - latitude).to_radians(),
            pose.theta,
        );
    }
    let dropouts = match without_fix {
        0 => String::new(),
        n => format!("; {n} messages without a fix (status -1) left out as dropouts"),
    };
    format!(
        "GPS fixes (NavSatFix) put in metres east (x) and north (y) of the first, at {latitude:.6}, {longitude:.6}{dropouts}"
    )
}

/// A robot's poses composed through a TF tree, and how, in words.
struct Composed {
    poses: Vec<Stamped<Pose>>,
    note: String,
}

/// The pose of `leaf` in `root`'s frame composed through the TF tree the
/// poses topic and `/tf_static` hold, where no one transform joins them (a
/// localised robot: `map -> odom -> base_link`); none where no chain does.
fn composed_through_tree(
    bag: &Bag,
    poses_topic: &str,
    pose_names: &BTreeMap<(Option<String>, String), u64>,
    tf_static: &[(i64, Vec<u8>)],
    root: &str,
    leaf: &str,
) -> Result<Option<Composed>, BagError> {
    let link = |parent: &str, child: &str| tf::Link {
        parent: tf::frame(parent).to_owned(),
        child: tf::frame(child).to_owned(),
    };
    let mut statics: BTreeMap<tf::Link, Pose> = BTreeMap::new();
    for (k, (log_time, data)) in tf_static.iter().enumerate() {
        let at = |what: String| message_error(bag, TF_STATIC_TOPIC, k + 1, ros::TF_TYPE, what);
        for named in ros::named_poses(ros::TF_TYPE, data).map_err(at)? {
            if let Some(parent) = &named.parent {
                let pose = named.on_the_floor(*log_time).map_err(at)?.value;
                statics.insert(link(parent, &named.name), pose);
            }
        }
    }
    let moving: Vec<tf::Link> = pose_names
        .keys()
        .filter_map(|(parent, child)| Some(link(parent.as_deref()?, child)))
        .collect();
    let all: Vec<tf::Link> = moving.iter().chain(statics.keys()).cloned().collect();
    let Some(down) = tf::chain(&all, root, leaf) else {
        return Ok(None);
    };
    // Each moving link's samples, read in a second pass over the poses
    // topic (the first counted the links; holding every link of a swarm's
    // /tf would take gigabytes).
    let mut samples: BTreeMap<tf::Link, Vec<Stamped<Pose>>> = down
        .iter()
        .filter(|l| moving.contains(l))
        .map(|l| (l.clone(), Vec::new()))
        .collect();
    let read = bag.messages(Some(&[poses_topic]))?;
    for (k, message) in read.found.into_iter().enumerate() {
        let at = |what: String| message_error(bag, poses_topic, k + 1, ros::TF_TYPE, what);
        for named in ros::named_poses(&message.message_type, &message.data).map_err(at)? {
            let into = named
                .parent
                .as_deref()
                .and_then(|parent| samples.get_mut(&link(parent, &named.name)));
            if let Some(into) = into {
                into.push(named.on_the_floor(message.log_time_ns).map_err(at)?);
            }
        }
    }
    let transforms: Vec<tf::Transforms> = down
        .iter()
        .map(|l| match samples.remove(l) {
            Some(moving) => tf::Transforms::Moving(moving),
            None => tf::Transforms::Static(statics.get(l).copied().unwrap_or_default()),
        })
        .collect();
    let (composed, left_out) = tf::compose(transforms);
    let names: Vec<String> = down.iter().map(|l| l.to_string()).collect();
    let fixed: Vec<String> = down
        .iter()
        .filter(|l| !moving.contains(l))
        .map(|l| l.to_string())
        .collect();
    let mut note = format!(
        "{leaf} in {root} composed through the TF tree: {}",
        names.join(", ")
    );
    if !fixed.is_empty() {
        note += &format!(" ({} from {TF_STATIC_TOPIC})", fixed.join(", "));
    }
    if left_out > 0 {
        note += &format!(
            "; {left_out} of {} times left out where a transform of the chain has no sample on both sides (as tf2 refuses to extrapolate)",
            composed.len() + left_out
        );
    }
    Ok(Some(Composed {
        poses: composed,
        note,
    }))
}

/// What is wrong with the `number`-th message (from 1) of `topic`.
fn message_error(
    bag: &Bag,
    topic: &str,
    number: impl std::fmt::Display,
    message_type: &str,
    what: String,
) -> BagError {
    BagError::new(
        &bag.path,
        format!("topic {topic}, message {number} ({message_type}): {what}"),
    )
}

/// How many of the poses a TF or Gazebo states topic holds an error lists.
const POSE_NAMES_LISTED: usize = 20;

fn check_found(
    bag: &Bag,
    selection: &Selection,
    seen: [u64; 2],
    no_poses: bool,
    poses_type: &str,
    pose_names: &BTreeMap<(Option<String>, String), u64>,
) -> Result<(), BagError> {
    for (index, topic, types) in [
        (0, selection.commands_topic, &ros::COMMAND_TYPES[..]),
        (1, selection.poses_topic, &ros::POSE_TYPES[..]),
    ] {
        if seen[index] == 0 {
            return Err(BagError::new(
                &bag.path,
                format!(
                    "no messages on topic {topic}; `shoal diagnose {}` lists the topics \
                     (expected one of type {})",
                    bag.path.display(),
                    types.join(", ")
                ),
            ));
        }
    }
    if no_poses {
        // The poses held most first; a swarm's /tf can hold hundreds.
        let mut by_count: Vec<_> = pose_names.iter().collect();
        by_count.sort_by(|a, b| b.1.cmp(a.1));
        let mut held = by_count
            .iter()
            .take(POSE_NAMES_LISTED)
            .map(|((parent, name), n)| match parent {
                Some(parent) => format!("{parent} -> {name} ({n} messages)"),
                None => format!("{name} ({n} messages)"),
            })
            .collect::<Vec<_>>()
            .join(", ");
        if by_count.len() > POSE_NAMES_LISTED {
            held += &format!(" and {} more", by_count.len() - POSE_NAMES_LISTED);
        }
        let which = selection.pose_name;
        let (what, none) = if poses_type == ros::TF_TYPE {
            let what = match which.name {
                None => "is a TF topic: choose the robot's frame with --frame CHILD (and \
                         --parent PARENT where several parents hold it)"
                    .to_owned(),
                Some(child) => match which.parent {
                    Some(parent) => format!(
                        "has no transform to child frame {child} from parent {parent}, and no chain of its transforms (and {TF_STATIC_TOPIC}'s) leads from {parent} down to {child}"
                    ),
                    None => format!(
                        "has no transform to child frame {child} (to compose one through the TF tree, name the frame to see it from with --parent, e.g. map or odom)"
                    ),
                },
            };
            (what, "no transforms")
        } else {
            let what = match which.name {
                None => format!(
                    "holds Gazebo's states ({poses_type}): choose the robot's model with --frame NAME"
                ),
                Some(name) => format!("has no model named {name}"),
            };
            (what, "no models")
        };
        return Err(BagError::new(
            &bag.path,
            format!(
                "topic {} {what}; it holds {}",
                selection.poses_topic,
                if held.is_empty() { none } else { &held }
            ),
        ));
    }
    Ok(())
}

/// Each message's header stamp (if any) and log time.
fn times<T>(messages: &[Stamped<T>]) -> Vec<(Option<i64>, i64)> {
    messages.iter().map(|s| (s.stamp, s.log_time)).collect()
}

/// Each message's time on the chosen clock, in time order.
fn on_clock<T>(
    messages: Vec<Stamped<T>>,
    timing: Timing,
    map: Option<&LogToClock>,
) -> Vec<(i64, T)> {
    let mut timed: Vec<(i64, T)> = messages
        .into_iter()
        .map(|m| {
            let t = match (timing, map) {
                (Timing::HeaderStamps, _) => m.stamp.unwrap_or(m.log_time),
                (Timing::MappedLogTimes(_), Some(map)) => map.map(m.log_time),
                _ => m.log_time,
            };
            (t, m.value)
        })
        .collect();
    timed.sort_by_key(|m| m.0);
    timed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gps_fixes_are_put_in_metres_east_and_north_of_the_first() {
        // A thousandth of a degree at 45 degrees north: 111.13 m of
        // latitude (the meridian's arc there), 78.85 m of longitude.
        let mut fixes = vec![
            (0, Pose::new(7.0, 45.0, f64::NAN)),
            (1, Pose::new(7.001, 45.001, f64::NAN)),
        ];
        let said = on_the_floor(&mut fixes, 3);
        let (east, north) = (fixes[1].1.x, fixes[1].1.y);
        assert!((north - 111.13).abs() < 0.01, "{north} m north");
        assert!((east - 78.85).abs() < 0.01, "{east} m east");
        assert_eq!((fixes[0].1.x, fixes[0].1.y), (0.0, 0.0));
        assert!(fixes[1].1.theta.is_nan());
        assert!(
            said.contains("at 45.000000, 7.000000; 3 messages without a fix"),
            "{said}"
        );
    }
}
