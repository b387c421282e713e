//! The diagnosis's inputs: a CSV pair or run folder, a ROS 2 bag (file or
//! folder), a Shoal recording (`.rrd`), MRCLAM's files. Each names the file
//! and line of what it cannot read, and says how it timed what it read.

use std::path::Path;

use anyhow::{Context, Result, bail};
use serde::Serialize;
use shoal_bags::{Bag, StampsPreference};
use shoal_diagnose::Recording;
use shoal_diagnose::input::{
    Read, commands_csv, commands_unit_notes, mrclam_groundtruth, mrclam_odometry, poses_file,
};
use shoal_diagnose::recording::{Commands, Poses};

use crate::DiagnoseArgs;

pub fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))
}

/// What the diagnosis read, and what the reading decided on the user's
/// behalf: reported with the diagnosis (text and JSON).
#[derive(Debug, Default, Serialize)]
pub struct InputNotes {
    /// For a bag: the clock commands and poses were compared on (the
    /// first bag's, of several).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clock: Option<ClockNote>,
    /// The recordings fitted together, in the order given (each one
    /// held-out block, in time order: see `blocks`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub recordings: Vec<String>,
    /// CSV columns read in another unit than Shoal's (seconds, metres,
    /// radians), and why; how a motion-capture export's body, units and
    /// axes were read.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub units: Vec<String>,
    /// Rows a file held out of time order, read sorted.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub order: Vec<String>,
    /// Pose rows without a value (the body not tracked), left out.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub dropouts: Vec<String>,
}

#[derive(Debug, Serialize)]
pub struct ClockNote {
    pub commands_topic: String,
    pub poses_topic: String,
    /// How each topic was timed.
    pub commands: String,
    pub poses: String,
    /// Why this clock.
    pub reason: String,
    /// What it means for a delay fitted between command and motion.
    pub delay: String,
    /// Where the poses were composed through the TF tree, how.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose_chain: Option<String>,
}

/// A run read for diagnosis, with what was decided reading it.
pub struct Loaded {
    pub recording: Recording,
    pub notes: InputNotes,
}

impl From<Recording> for Loaded {
    fn from(recording: Recording) -> Self {
        Self {
            recording,
            notes: InputNotes::default(),
        }
    }
}

/// A commands file and a poses file; `body` names the rigid body of a
/// motion-capture export that holds several.
pub fn load_commands_and_poses(
    commands: &Path,
    poses: &Path,
    body: Option<&str>,
) -> Result<Loaded> {
    let (commands_file, poses_file_name) =
        (commands.display().to_string(), poses.display().to_string());
    let (commands_text, poses_text) = (read(commands)?, read(poses)?);
    let (poses, poses_notes) = poses_file(&poses_text, &poses_file_name, body)?;
    let units = [
        commands_unit_notes(&commands_text, &commands_file),
        poses_notes,
    ]
    .concat();
    Ok(read_files(
        commands_csv(&commands_text, &commands_file)?,
        poses,
        units,
    ))
}

/// A run of commands and poses files as read, with what reading them put
/// in order, left out, or read in another unit (`units`).
fn read_files(commands: Read<Commands>, poses: Read<Poses>, units: Vec<String>) -> Loaded {
    Loaded {
        notes: InputNotes {
            units,
            order: [commands.order, poses.order]
                .into_iter()
                .flatten()
                .collect(),
            dropouts: poses.dropouts.into_iter().collect(),
            ..InputNotes::default()
        },
        recording: Recording::from_absolute(commands.data, poses.data),
    }
}

/// One robot of a Shoal recording: its true poses and the commands it
/// executed, as the recorder logged them.
fn load_rrd(path: &Path, robot: Option<u32>) -> Result<Recording> {
    let file = path.display().to_string();
    let rows = shoal_viewer_log::motion::read_motion(path)?;
    if let Some(messages) = rows.truncated_after {
        eprintln!(
            "shoal diagnose: {file} ends mid-message after {messages} messages (was its recorder killed?); reading what came before"
        );
    }
    let Some(robot) = robot else {
        bail!(
            "{file}: which robot? give --robot N; the recording holds robots {}",
            shoal_viewer_log::motion::list_ids(&rows.robots())
        );
    };
    let track = rows.track(robot, &file)?;
    let mut commands = shoal_diagnose::recording::Commands::default();
    for [t, v, omega] in track.commands {
        commands.hold(t, v, omega);
    }
    let mut poses = shoal_diagnose::recording::Poses::default();
    for [t, x, y, theta] in track.poses {
        poses.observe(t, x, y, theta);
    }
    Ok(Recording::from_absolute(commands, poses))
}

/// The types a topic may have, as a listing names them: without their
/// package, those whose robot is chosen by name said so.
fn type_names(types: &[&str]) -> String {
    let last = |t: &str| t.rsplit('/').next().unwrap_or(t).to_owned();
    // Two packages' types of one name (geometry_msgs' and turtlesim's Pose)
    // keep their package, so the listing can tell them apart.
    let short = |t: &&&str| {
        let name = last(t);
        let shared = types.iter().filter(|o| last(o) == name).count() > 1;
        match t.split_once('/') {
            Some((package, _)) if shared => format!("{package}/{name}"),
            _ => name,
        }
    };
    let (named, one_pose): (Vec<&&str>, Vec<&&str>) = types
        .iter()
        .partition(|t| shoal_bags::ros::holds_named_poses(t));
    let one_pose: Vec<String> = one_pose.iter().map(short).collect();
    if named.is_empty() {
        return one_pose.join(" or ");
    }
    let named: Vec<String> = named.iter().map(short).collect();
    format!(
        "{}, or with --frame NAME {}",
        one_pose.join(", "),
        named.join(", ")
    )
}

/// A ROS 2 bag: its topics listed, or the chosen ones read on one clock.
fn load_bag(path: &Path, args: &DiagnoseArgs) -> Result<Loaded> {
    let bag = Bag::open(path)?;
    let listed = bag.topics()?;
    let topics = listed.found;
    // /tf_static's transforms never move: read beside /tf, never a robot's poses.
    let of = |types: &[&str]| -> Vec<String> {
        topics
            .iter()
            .filter(|t| types.contains(&t.message_type.as_str()))
            .filter(|t| t.name != shoal_bags::run::TF_STATIC_TOPIC)
            .map(|t| t.name.clone())
            .collect()
    };
    let (command_topics, pose_topics) = (
        of(&shoal_bags::ros::COMMAND_TYPES),
        of(&shoal_bags::ros::POSE_TYPES),
    );
    let (commands_topic, poses_topic) = match (&args.commands_topic, &args.poses_topic) {
        (Some(c), Some(p)) => (c.clone(), p.clone()),
        _ => {
            let mut listing = format!("{} holds {} topics:\n", path.display(), topics.len());
            for t in &topics {
                listing.push_str(&format!(
                    "  {}  {}  ({} messages)\n",
                    t.name, t.message_type, t.messages
                ));
            }
            for note in &listed.unfinished {
                listing.push_str(&format!("  ({note})\n"));
            }
            bail!(
                "{listing}choose the commands with --commands-topic ({}: {}) and the poses with --poses-topic ({}: {}){}",
                type_names(&shoal_bags::ros::COMMAND_TYPES),
                or_none(&command_topics),
                type_names(&shoal_bags::ros::POSE_TYPES),
                or_none(&pose_topics),
                the_choices(path, &command_topics, &pose_topics, &topics),
            );
        }
    };
    let run = shoal_bags::read_run(
        &bag,
        &shoal_bags::Selection {
            commands_topic: &commands_topic,
            poses_topic: &poses_topic,
            pose_name: shoal_bags::ros::PoseName {
                name: args.frame.as_deref(),
                parent: args.parent.as_deref(),
            },
        },
        args.stamps.into(),
    )?;
    // As a recording cut short is read: said once, on stderr, beside the
    // diagnosis of what came before.
    for note in &run.unfinished {
        eprintln!("shoal diagnose: {note}");
    }
    let mut commands = shoal_diagnose::recording::Commands::default();
    for &(t, v, omega) in &run.commands {
        commands.hold(t, v, omega);
    }
    let mut poses = shoal_diagnose::recording::Poses::default();
    for &(t, x, y, yaw) in &run.poses {
        poses.observe(t, x, y, yaw);
    }
    let clock = ClockNote {
        commands: run.clock.commands.to_string(),
        poses: run.clock.poses.to_string(),
        reason: run.clock.reason.clone(),
        delay: run.clock.delay_note.clone(),
        pose_chain: run.pose_chain.clone(),
        commands_topic,
        poses_topic,
    };
    Ok(Loaded {
        recording: Recording {
            commands,
            poses,
            t_origin: run.t_origin,
            joins: Vec::new(),
        },
        notes: InputNotes {
            clock: Some(clock),
            ..InputNotes::default()
        },
    })
}

/// What a pose topic holds, as its name and type tell, ranked: motion
/// capture or a simulator's ground truth first, then a localisation or a
/// fused estimate, then the wheels' odometry, which diagnosis can only
/// compare with the commands it was computed from.
fn pose_source(name: &str, message_type: &str) -> (u8, &'static str) {
    let name = name.to_ascii_lowercase();
    let any = |words: &[&str]| words.iter().any(|w| name.contains(w));
    if message_type == shoal_bags::ros::NAV_SAT_FIX_TYPE {
        (
            1,
            "a GPS: positions only, each heading taken from the track",
        )
    } else if message_type == shoal_bags::ros::POINT_TYPE {
        (1, "positions only: each heading taken from the track")
    } else if any(&[
        "vicon",
        "mocap",
        "optitrack",
        "vrpn",
        "qualisys",
        "natnet",
        "ground_truth",
        "groundtruth",
        "gazebo",
        "model_states",
        "/model/",
    ]) {
        (0, "ground truth")
    } else if any(&["amcl", "localiz", "localis", "filtered", "slam", "map"])
        || message_type.ends_with("PoseWithCovarianceStamped")
    {
        (
            1,
            "a localisation: its corrections jump, which costs power, not truth",
        )
    } else if any(&["odom"]) {
        (
            2,
            "wheel odometry: the robot's own estimate, blind to what its wheels do not feel (slip)",
        )
    } else {
        (1, "")
    }
}

/// The commands that diagnose the bag's robots, where its topics pair up:
/// in the whole bag, or in one namespace (`/robot1/cmd_vel` with
/// `/robot1/odom`), as a swarm's bag holds each robot's. Of several command
/// topics in one namespace, a navigation stack's chain (`cmd_vel_nav`,
/// `cmd_vel_smoothed`, ...), the one named `cmd_vel` is what the base
/// receives; of several pose topics that need no `--frame`, each is
/// offered, the better poses first, each said for what it is.
fn the_choices(
    path: &Path,
    command_topics: &[String],
    pose_topics: &[String],
    topics: &[shoal_bags::Topic],
) -> String {
    let type_of = |name: &String| {
        topics
            .iter()
            .find(|t| &t.name == name)
            .map_or("", |t| t.message_type.as_str())
    };
    let poses: Vec<&String> = pose_topics
        .iter()
        .filter(|t| !shoal_bags::ros::holds_named_poses(type_of(t)))
        .collect();
    let namespace = |topic: &str| topic.rsplit_once('/').map_or("", |(ns, _)| ns).to_owned();
    let last = |topic: &str| topic.rsplit('/').next().unwrap_or(topic).to_owned();
    let mut namespaces: Vec<String> = command_topics.iter().map(|c| namespace(c)).collect();
    namespaces.sort();
    namespaces.dedup();
    // One bag-wide pairing where the bag's commands are one robot's; else
    // each namespace's own.
    let one_robot = namespaces.len() == 1;
    let mut lines = Vec::new();
    let mut robots = 0;
    for ns in namespaces {
        let commands: Vec<&String> = command_topics
            .iter()
            .filter(|c| namespace(c) == ns)
            .collect();
        let Some(commands) = (match commands.as_slice() {
            [one] => Some(*one),
            several => several.iter().copied().find(|c| last(c) == "cmd_vel"),
        }) else {
            continue;
        };
        let mut candidates: Vec<&String> = poses
            .iter()
            .copied()
            .filter(|p| one_robot || namespace(p) == ns)
            .collect();
        if candidates.is_empty() {
            continue;
        }
        candidates.sort_by_key(|p| pose_source(p, type_of(p)).0);
        robots += 1;
        let said = candidates.len() > 1;
        for poses in candidates {
            let what = pose_source(poses, type_of(poses)).1;
            let note = if said && !what.is_empty() {
                format!("    # {what}")
            } else {
                String::new()
            };
            lines.push(format!(
                "  shoal diagnose {} --commands-topic {commands} --poses-topic {poses}{note}",
                path.display()
            ));
        }
    }
    match (robots, lines.len()) {
        (0, _) => String::new(),
        (1, 1) => format!("; this bag's are:\n{}", lines[0]),
        (1, _) => format!(
            "; this bag's robot, with each of its pose topics (the better poses first):\n{}",
            lines.join("\n")
        ),
        _ => format!("; its robots, one at a time:\n{}", lines.join("\n")),
    }
}

fn or_none(names: &[String]) -> String {
    if names.is_empty() {
        "none in this bag".to_owned()
    } else {
        names.join(", ")
    }
}

/// Reads what the arguments name.
pub fn load(args: &DiagnoseArgs) -> Result<Loaded> {
    if let (Some(c), Some(p)) = (&args.commands, &args.poses) {
        return load_commands_and_poses(c, p, args.frame.as_deref());
    }
    if let Some(bag) = &args.bag {
        return load_bag(bag, args);
    }
    if let Some(dir) = &args.mrclam {
        let robot = args.robot.context("--mrclam needs --robot N")?;
        return load_mrclam(dir, robot);
    }
    match args.run.as_slice() {
        [] => {}
        [run] => return load_positional(run, args),
        runs => {
            let mut loaded = Vec::with_capacity(runs.len());
            for run in runs {
                loaded.push(load_positional(run, args)?);
            }
            let notes = InputNotes {
                clock: loaded.iter_mut().find_map(|l| l.notes.clock.take()),
                recordings: runs.iter().map(|r| r.display().to_string()).collect(),
                units: loaded
                    .iter_mut()
                    .flat_map(|l| std::mem::take(&mut l.notes.units))
                    .collect(),
                order: loaded
                    .iter_mut()
                    .flat_map(|l| std::mem::take(&mut l.notes.order))
                    .collect(),
                dropouts: loaded
                    .iter_mut()
                    .flat_map(|l| std::mem::take(&mut l.notes.dropouts))
                    .collect(),
            };
            let recording = Recording::joined(loaded.into_iter().map(|l| l.recording).collect());
            return Ok(Loaded { recording, notes });
        }
    }
    bail!(
        "nothing to diagnose: give a run folder, a ROS 2 bag (file or folder), a Shoal recording (.rrd), \
         --commands and --poses, or --mrclam DIR --robot N"
    )
}

/// Robot `robot` of an MRCLAM dataset folder: its commands and ground truth.
fn load_mrclam(dir: &Path, robot: u32) -> Result<Loaded> {
    let odometry = dir.join(format!("Robot{robot}_Odometry.dat"));
    let truth = dir.join(format!("Robot{robot}_Groundtruth.dat"));
    Ok(read_files(
        mrclam_odometry(&read(&odometry)?, &odometry.display().to_string())?,
        mrclam_groundtruth(&read(&truth)?, &truth.display().to_string())?,
        Vec::new(),
    ))
}

/// A path given as a positional argument: a Shoal recording, a run folder
/// (commands.csv and poses.csv), an MRCLAM folder (with --robot, unless it
/// holds one robot), or a ROS 2 bag (file or folder).
fn load_positional(run: &Path, args: &DiagnoseArgs) -> Result<Loaded> {
    if run.extension().is_some_and(|e| e == "rrd") {
        return load_rrd(run, args.robot).map(Loaded::from);
    }
    if let Some(robot) = args.robot
        && run.join(format!("Robot{robot}_Odometry.dat")).is_file()
    {
        return load_mrclam(run, robot);
    }
    let (commands, poses) = (run.join("commands.csv"), run.join("poses.csv"));
    // Poses kept as a TUM trajectory (evo's) beside the commands.
    let poses = match run.join("poses.tum") {
        tum if !poses.is_file() && tum.is_file() => tum,
        _ => poses,
    };
    if run.is_dir() && (commands.is_file() || poses.is_file()) {
        return load_commands_and_poses(&commands, &poses, args.frame.as_deref());
    }
    if shoal_bags::looks_like_bag(run) {
        return load_bag(run, args);
    }
    if !run.exists() {
        bail!("{}: no such file or folder", run.display());
    }
    let robots = if run.is_dir() {
        mrclam_robots(run)?
    } else {
        Vec::new()
    };
    if let ([robot], None) = (robots.as_slice(), args.robot) {
        return load_mrclam(run, *robot);
    }
    if !robots.is_empty() {
        let listed: Vec<String> = robots.iter().map(u32::to_string).collect();
        bail!(
            "{}: an MRCLAM dataset of robots {}{}: say which with --robot N",
            run.display(),
            listed.join(", "),
            args.robot
                .map(|r| format!(" (no Robot{r}_Odometry.dat here)"))
                .unwrap_or_default()
        );
    }
    bail!(
        "{}: not a Shoal recording (.rrd), a run folder (commands.csv and poses.csv or poses.tum), an MRCLAM \
         dataset folder (RobotN_Odometry.dat, with --robot N) or a ROS 2 bag (.mcap, .db3, or a \
         bag folder with metadata.yaml)",
        run.display()
    )
}

/// The robots of an MRCLAM dataset folder: those with both a
/// `RobotN_Odometry.dat` and a `RobotN_Groundtruth.dat`, in order.
fn mrclam_robots(dir: &Path) -> Result<Vec<u32>> {
    let names = std::fs::read_dir(dir)
        .and_then(|entries| {
            entries
                .map(|entry| entry.map(|e| e.file_name()))
                .collect::<std::io::Result<Vec<_>>>()
        })
        .with_context(|| format!("{}: the folder cannot be listed", dir.display()))?;
    let mut robots: Vec<u32> = names
        .iter()
        .filter_map(|name| {
            name.to_str()?
                .strip_prefix("Robot")?
                .strip_suffix("_Odometry.dat")?
                .parse()
                .ok()
        })
        .filter(|r| dir.join(format!("Robot{r}_Groundtruth.dat")).is_file())
        .collect();
    robots.sort_unstable();
    Ok(robots)
}

/// The user's `--stamps`.
#[derive(Clone, Copy, Debug, Default, clap::ValueEnum)]
pub enum Stamps {
    /// Choose from the data and say why.
    #[default]
    Auto,
    /// The messages' header stamps.
    Header,
    /// The bag's log times.
    Log,
}

impl From<Stamps> for StampsPreference {
    fn from(s: Stamps) -> Self {
        match s {
            Stamps::Auto => StampsPreference::Auto,
            Stamps::Header => StampsPreference::Header,
            Stamps::Log => StampsPreference::Log,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn topic(name: &str, message_type: &str) -> shoal_bags::Topic {
        shoal_bags::Topic {
            name: name.to_owned(),
            message_type: message_type.to_owned(),
            messages: 1,
        }
    }

    fn choices(topics: &[shoal_bags::Topic]) -> String {
        let of = |types: &[&str]| -> Vec<String> {
            topics
                .iter()
                .filter(|t| types.contains(&t.message_type.as_str()))
                .map(|t| t.name.clone())
                .collect()
        };
        the_choices(
            Path::new("b"),
            &of(&shoal_bags::ros::COMMAND_TYPES),
            &of(&shoal_bags::ros::POSE_TYPES),
            topics,
        )
    }

    #[test]
    fn a_bags_robots_are_paired_by_namespace_and_tf_waits_for_a_frame() {
        let twist = "geometry_msgs/msg/Twist";
        let odometry = "nav_msgs/msg/Odometry";
        let tf = "tf2_msgs/msg/TFMessage";
        // One of each: paired whatever their names; /tf needs --frame.
        let one = choices(&[
            topic("/cmd_vel", twist),
            topic("/vicon/burger/burger", "geometry_msgs/msg/TransformStamped"),
            topic("/tf", tf),
        ]);
        assert!(
            one.ends_with("b --commands-topic /cmd_vel --poses-topic /vicon/burger/burger"),
            "{one}"
        );
        // A swarm's bag: each robot's topics in its namespace.
        let swarm = choices(&[
            topic("/robot1/cmd_vel", twist),
            topic("/robot1/odom", odometry),
            topic("/robot2/cmd_vel", twist),
            topic("/robot2/odom", odometry),
            topic("/robot3/cmd_vel", twist),
            topic("/tf", tf),
        ]);
        assert!(swarm.contains("--commands-topic /robot1/cmd_vel --poses-topic /robot1/odom"));
        assert!(swarm.contains("--commands-topic /robot2/cmd_vel --poses-topic /robot2/odom"));
        assert!(!swarm.contains("/robot3"), "{swarm}");
        // Two pose topics beside one command topic: both offered, the
        // ground truth first, each said for what it is.
        let two = choices(&[
            topic("/cmd_vel", twist),
            topic("/odom", odometry),
            topic("/ground_truth", odometry),
        ]);
        let truth = two.find("--poses-topic /ground_truth    # ground truth");
        let odom = two.find("--poses-topic /odom    # wheel odometry");
        assert!(truth.is_some() && odom.is_some() && truth < odom, "{two}");
        // A navigation stack's chain of velocity topics: the base's is /cmd_vel.
        let nav2 = choices(&[
            topic("/cmd_vel_nav", twist),
            topic("/cmd_vel_smoothed", twist),
            topic("/cmd_vel", twist),
            topic("/amcl_pose", "geometry_msgs/msg/PoseWithCovarianceStamped"),
            topic("/odom", odometry),
            topic("/tf", tf),
        ]);
        assert!(
            nav2.contains("--commands-topic /cmd_vel --poses-topic /amcl_pose    # a localisation")
                && nav2
                    .contains("--commands-topic /cmd_vel --poses-topic /odom    # wheel odometry")
                && !nav2.contains("cmd_vel_nav --poses"),
            "{nav2}"
        );
    }
}
