//! A robot's pose composed through a TF tree, as `tf2` looks one up: a
//! localised robot's bag holds no transform from `map` to `base_link`, but
//! `map -> odom` (its localisation) and `odom -> base_link` (its wheel
//! odometry), and often static ones (`base_footprint -> base_link`, on
//! `/tf_static`). The pose of `base_link` in `map` is their product, each
//! transform taken at the same time. On the floor: each transform is read
//! as its planar part (x, y, yaw), exact for a robot whose frames do not
//! roll or pitch.

use std::collections::BTreeMap;

use shoal_physics::{Pose, wrap_angle};

use crate::ros::Stamped;

/// A frame's name as TF compares them: without a leading `/` (ROS 1's
/// names had one, and many bridges still write it).
pub fn frame(name: &str) -> &str {
    name.trim_start_matches('/')
}

/// One transform of a chain: from `parent` to `child`.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Link {
    pub parent: String,
    pub child: String,
}

impl std::fmt::Display for Link {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} -> {}", self.parent, self.child)
    }
}

/// The links from `root` down to `leaf` in the tree the `links` make (each
/// child with one parent, as TF requires), root first; none if `leaf` does
/// not descend from `root`. A child given several parents (a broken tree)
/// is followed through none of them.
pub fn chain(links: &[Link], root: &str, leaf: &str) -> Option<Vec<Link>> {
    let mut parents: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for link in links {
        let parents_of = parents.entry(frame(&link.child)).or_default();
        if !parents_of.contains(&frame(&link.parent)) {
            parents_of.push(frame(&link.parent));
        }
    }
    let mut down = Vec::new();
    let mut at = frame(leaf);
    // A tree of n frames has a path of at most n links: more is a loop.
    for _ in 0..=parents.len() {
        if at == frame(root) {
            down.reverse();
            return (!down.is_empty()).then_some(down);
        }
        let [parent] = parents.get(at)?.as_slice() else {
            return None;
        };
        down.push(Link {
            parent: (*parent).to_owned(),
            child: at.to_owned(),
        });
        at = parent;
    }
    None
}

/// A chain's transforms: each link's samples over time, or its one static
/// transform.
pub enum Transforms {
    Moving(Vec<Stamped<Pose>>),
    Static(Pose),
}

/// The leaf's pose in the root's frame, composed along `links` (root
/// first), at the times of the moving link with the most samples; each
/// other moving link interpolated to that time between its samples
/// before and after, as `tf2` does. Where another link has no sample on
/// both sides of a time (`tf2`'s extrapolation), that time is left out;
/// returns the poses and how many times were left out. Times are header
/// stamps, or log times where a message has none.
pub fn compose(mut links: Vec<Transforms>) -> (Vec<Stamped<Pose>>, usize) {
    let time = |s: &Stamped<Pose>| s.stamp.unwrap_or(s.log_time);
    for link in &mut links {
        if let Transforms::Moving(samples) = link {
            samples.sort_by_key(time);
        }
    }
    let busiest = links
        .iter()
        .enumerate()
        .filter_map(|(k, l)| match l {
            Transforms::Moving(samples) => Some((k, samples)),
            Transforms::Static(_) => None,
        })
        .max_by_key(|(_, samples)| samples.len());
    let Some((timing, at)) = busiest else {
        return (Vec::new(), 0);
    };
    let mut composed = Vec::with_capacity(at.len());
    let mut left_out = 0;
    'times: for sample in at {
        let t = time(sample);
        let mut pose = Pose::default();
        for (k, link) in links.iter().enumerate() {
            let step = match link {
                _ if k == timing => sample.value,
                Transforms::Static(p) => *p,
                Transforms::Moving(samples) => match interpolated(samples, t, time) {
                    Some(p) => p,
                    None => {
                        left_out += 1;
                        continue 'times;
                    }
                },
            };
            pose = pose.compose(&step);
        }
        composed.push(Stamped {
            stamp: sample.stamp,
            log_time: sample.log_time,
            value: pose,
        });
    }
    (composed, left_out)
}

/// `samples` (sorted by `time`) at `t`: linear between the samples on
/// either side, the heading the short way round; none outside their span.
fn interpolated(
    samples: &[Stamped<Pose>],
    t: i64,
    time: impl Fn(&Stamped<Pose>) -> i64,
) -> Option<Pose> {
    let after = samples.partition_point(|s| time(s) < t);
    let later = samples.get(after)?;
    if time(later) == t {
        return Some(later.value);
    }
    let earlier = samples.get(after.checked_sub(1)?)?;
    let (t0, t1) = (time(earlier), time(later));
    let share = (t - t0) as f64 / (t1 - t0) as f64;
    let (a, b) = (earlier.value, later.value);
    Some(Pose::new(
        a.x + share * (b.x - a.x),
        a.y + share * (b.y - a.y),
        wrap_angle(a.theta + share * wrap_angle(b.theta - a.theta)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(parent: &str, child: &str) -> Link {
        Link {
            parent: parent.to_owned(),
            child: child.to_owned(),
        }
    }

    fn at(t_ns: i64, x: f64, y: f64, theta: f64) -> Stamped<Pose> {
        Stamped {
            stamp: Some(t_ns),
            log_time: t_ns + 1_000,
            value: Pose::new(x, y, theta),
        }
    }

    #[test]
    fn a_chain_runs_from_the_root_down_to_the_leaf_through_the_tree() {
        let links = [
            link("map", "odom"),
            link("/odom", "base_footprint"),
            link("base_footprint", "base_link"),
            link("base_link", "laser"),
            link("map", "other_robot"),
        ];
        let down = chain(&links, "map", "/base_link").expect("a chain");
        let names: Vec<String> = down.iter().map(ToString::to_string).collect();
        assert_eq!(
            names,
            [
                "map -> odom",
                "odom -> base_footprint",
                "base_footprint -> base_link"
            ]
        );
        assert_eq!(chain(&links, "odom", "base_link").map(|c| c.len()), Some(2));
        // Not below the root, the root itself, a frame no one names.
        assert!(chain(&links, "base_link", "odom").is_none());
        assert!(chain(&links, "map", "map").is_none());
        assert!(chain(&links, "map", "nowhere").is_none());
        // A loop, and a child of two parents, lead nowhere.
        assert!(chain(&[link("a", "b"), link("b", "a")], "map", "a").is_none());
        assert!(chain(&[link("map", "b"), link("odom", "b")], "map", "b").is_none());
    }

    #[test]
    fn transforms_compose_at_the_busiest_links_times_and_never_extrapolate() {
        let quarter = std::f64::consts::FRAC_PI_2;
        // map -> odom: odom 1 m east of map's origin, turned a quarter left,
        // then 2 m east of it by t = 2 s (sampled at 0 and 2 s).
        let localisation = Transforms::Moving(vec![
            at(0, 1.0, 0.0, quarter),
            at(2_000_000_000, 3.0, 0.0, quarter),
        ]);
        // odom -> base_link: the robot 1 m along odom's x, at 10 times.
        let odometry = Transforms::Moving(
            (0..10)
                .map(|i| at(i * 250_000_000, 1.0, 0.0, 0.0))
                .collect(),
        );
        let lifted = Transforms::Static(Pose::new(0.0, 0.5, 0.0));
        let (poses, left_out) = compose(vec![localisation, odometry, lifted]);
        // Times 0 to 2 s are within map -> odom's span; 2.25 s is not.
        assert_eq!((poses.len(), left_out), (9, 1));
        let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
        // At 1 s odom is 2 m east, turned a quarter: the robot 1 m north of
        // it, the static link 0.5 m to the robot's left (west).
        let one_second = poses
            .iter()
            .find(|p| p.stamp == Some(1_000_000_000))
            .expect("a pose at 1 s");
        let p = one_second.value;
        assert!(
            close(p.x, 1.5) && close(p.y, 1.0) && close(p.theta, quarter),
            "{p:?}"
        );
        // The composed pose keeps the timing link's stamp and log time.
        assert_eq!(one_second.log_time, 1_000_001_000);
    }

    #[test]
    fn the_heading_is_interpolated_the_short_way_round() {
        let samples = [at(0, 0.0, 0.0, 3.0), at(10, 0.0, 0.0, -3.0)];
        let time = |s: &Stamped<Pose>| s.stamp.unwrap_or(s.log_time);
        let half = interpolated(&samples, 5, time).expect("within the span");
        // From 3 rad to -3 rad through pi, not through 0.
        assert!(half.theta.abs() > 3.1, "{half:?}");
        assert!(interpolated(&samples, 11, time).is_none());
        assert!(interpolated(&samples, -1, time).is_none());
    }
}
