//! Which robots a SLAM process follows: named ones, or every robot of the
//! swarm, those that join later included.

use std::fmt;
use std::str::FromStr;

#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "FollowInToml", into = "FollowInToml")]
pub enum Follow {
    /// Every robot the roster shows, followed from the first pose it reports.
    All,
    /// These robots' ids.
    Robots(Vec<u32>),
}

impl Default for Follow {
    /// No robot: no SLAM process.
    fn default() -> Self {
        Follow::Robots(Vec::new())
    }
}

/// [`Follow`] as a scenario writes it: `follow = "all"` or `follow = [0, 3]`.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
enum FollowInToml {
    Word(String),
    Ids(Vec<u32>),
}

impl TryFrom<FollowInToml> for Follow {
    type Error = String;

    fn try_from(value: FollowInToml) -> Result<Self, Self::Error> {
        match value {
            FollowInToml::Ids(ids) => Ok(Follow::Robots(ids)),
            FollowInToml::Word(word) if word == "all" => Ok(Follow::All),
            FollowInToml::Word(word) => Err(format!(
                "`{word}` is neither \"all\" nor a list of robot ids such as [0, 3]"
            )),
        }
    }
}

impl From<Follow> for FollowInToml {
    fn from(follow: Follow) -> Self {
        match follow {
            Follow::All => FollowInToml::Word("all".into()),
            Follow::Robots(ids) => FollowInToml::Ids(ids),
        }
    }
}

impl Follow {
    /// Whether `id` is to be followed.
    pub fn includes(&self, id: u32) -> bool {
        match self {
            Follow::All => true,
            Follow::Robots(ids) => ids.contains(&id),
        }
    }

    /// The ids named up front (none for [`Follow::All`], whose robots are
    /// found as they report).
    pub fn named(&self) -> &[u32] {
        match self {
            Follow::All => &[],
            Follow::Robots(ids) => ids,
        }
    }

    pub fn is_empty(&self) -> bool {
        matches!(self, Follow::Robots(ids) if ids.is_empty())
    }

    /// Every robot either follows: `all` if either is, else both lists,
    /// each id once, in the order first named.
    pub fn and(self, other: &Follow) -> Follow {
        match (self, other) {
            (Follow::All, _) | (_, Follow::All) => Follow::All,
            (Follow::Robots(mut ids), Follow::Robots(more)) => {
                for id in more {
                    if !ids.contains(id) {
                        ids.push(*id);
                    }
                }
                Follow::Robots(ids)
            }
        }
    }

    /// The ids followed in a swarm of `count` robots numbered from 0.
    pub fn ids_among(&self, count: usize) -> Vec<u32> {
        match self {
            Follow::All => (0..count as u32).collect(),
            Follow::Robots(ids) => ids.clone(),
        }
    }
}

impl FromStr for Follow {
    type Err = String;

    /// `all`, or robot ids separated by commas (`0,3`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        if text.trim() == "all" {
            return Ok(Follow::All);
        }
        text.split(',')
            .map(|id| {
                id.trim().parse::<u32>().map_err(|_| {
                    format!(
                        "`{id}` is not a robot id: give `all` or ids separated by commas, e.g. 0,3"
                    )
                })
            })
            .collect::<Result<Vec<u32>, String>>()
            .map(Follow::Robots)
    }
}

impl fmt::Display for Follow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Follow::All => write!(f, "all"),
            Follow::Robots(ids) => {
                let ids: Vec<String> = ids.iter().map(u32::to_string).collect();
                write!(f, "{}", ids.join(","))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_and_ids_parse_and_print_back() {
        assert_eq!("all".parse::<Follow>(), Ok(Follow::All));
        assert_eq!("0,3".parse::<Follow>(), Ok(Follow::Robots(vec![0, 3])));
        assert_eq!(Follow::Robots(vec![0, 3]).to_string(), "0,3");
        assert!("0,x".parse::<Follow>().is_err());
        assert!(Follow::All.includes(77));
        assert!(!Follow::Robots(vec![1]).includes(2));
    }

    #[test]
    fn two_choices_of_robots_join_and_all_takes_in_any() {
        let some = Follow::Robots(vec![0, 3]);
        assert_eq!(
            some.clone().and(&Follow::Robots(vec![3, 5])),
            Follow::Robots(vec![0, 3, 5])
        );
        assert_eq!(some.clone().and(&Follow::All), Follow::All);
        assert_eq!(Follow::All.and(&some), Follow::All);
        assert_eq!(some.ids_among(20), vec![0, 3]);
        assert_eq!(Follow::All.ids_among(3), vec![0, 1, 2]);
    }

    #[test]
    fn a_scenario_names_all_or_a_list_and_anything_else_is_refused() {
        let read = |text: &str| toml::from_str::<SlamSection>(text).map(|s| s.follow);
        assert_eq!(read("follow = \"all\""), Ok(Follow::All));
        assert_eq!(read("follow = [0, 3]"), Ok(Follow::Robots(vec![0, 3])));
        assert_eq!(read(""), Ok(Follow::default()));
        let error = read("follow = \"some\"").expect_err("not a word it knows");
        assert!(error.to_string().contains("`some` is neither"), "{error}");
        let written = toml::to_string(&SlamSection {
            follow: Follow::All,
        })
        .expect("writes");
        assert_eq!(read(&written), Ok(Follow::All));
    }
}

/// The most robots a scenario may name for SLAM to follow.
const MAX_FOLLOWED: usize = 64;

/// The scenario's `[slam]` section: the robots a SLAM process follows when
/// the swarm starts.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlamSection {
    /// `"all"` (every robot, those that join later included), or the ids
    /// of the robots to follow; none starts no SLAM process.
    pub follow: Follow,
}

impl shoal_scenario::Section for SlamSection {
    const NAME: &'static str = "slam";

    fn check(&self, check: &mut shoal_scenario::RangeCheck) {
        check.count("follow", self.follow.named().len(), 0, MAX_FOLLOWED);
    }
}
