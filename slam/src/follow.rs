//! Which robots a SLAM process follows: named ones, or every robot of the
//! swarm, those that join later included.

use std::fmt;
use std::str::FromStr;

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Follow {
    /// Every robot the roster shows, followed from the first pose it reports.
    All,
    /// These robots' ids.
    Robots(Vec<u32>),
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
}

/// The most robots a scenario may name for SLAM to follow.
const MAX_FOLLOWED: usize = 64;

/// The scenario's `[slam]` section: the robots a SLAM process follows when
/// the swarm starts.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SlamSection {
    /// Ids of the robots to follow; empty starts no SLAM process.
    pub follow: Vec<u32>,
}

impl shoal_scenario::Section for SlamSection {
    const NAME: &'static str = "slam";

    fn check(&self, check: &mut shoal_scenario::RangeCheck) {
        check.count("follow", self.follow.len(), 0, MAX_FOLLOWED);
    }
}
