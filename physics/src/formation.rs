//! Formation control from the thesis, chapter III: each agent picks N
//! neighbours (one per sector), sums pairwise forces, adds an optional goal
//! pull and ignores net forces inside a dead band.

use std::f64::consts::TAU;

use glam::DVec2;
use serde::{Deserialize, Serialize};

/// The pairwise force law. Positive pulls, negative pushes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ForceLaw {
    /// `k (d^2 - s^4 / d^2)`: pushes without bound as `d -> 0`.
    #[default]
    Thesis,
    /// Sugawara's `-k ((s/d)^3 - (s/d)^2)`: bounded pull at long range.
    Sugawara,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FormationParams {
    /// How many neighbours each agent tracks (the thesis's N).
    pub neighbours: usize,
    /// Pick the nearest agent in each of N sectors instead of the N nearest.
    pub sectors: bool,
    /// Fill sectors that hold no agent with the next nearest agents, as the
    /// thesis does. Off by default: the fill-ins are second-ring agents whose
    /// pull compresses the formation (see EXPERIMENTS.md), and they add no
    /// connectivity, since every non-empty sector is already tracked.
    pub fill_empty_sectors: bool,
    pub law: ForceLaw,
    /// The force coefficient k (or c for Sugawara's law).
    pub gain: f64,
    /// The desired spacing s between neighbours, metres.
    pub spread: f64,
    /// Net forces smaller than this are ignored, so a formed lattice stops jittering.
    pub dead_band: f64,
    /// An optional goal that only pulls, harder on the farthest agents.
    pub goal: Option<[f64; 2]>,
    pub goal_gain: f64,
}

impl Default for FormationParams {
    fn default() -> Self {
        Self {
            neighbours: 4,
            sectors: true,
            fill_empty_sectors: false,
            law: ForceLaw::Thesis,
            gain: 1.0,
            spread: 1.0,
            dead_band: 0.15,
            goal: None,
            goal_gain: 0.2,
        }
    }
}

impl FormationParams {
    /// Signed force magnitude between two agents `distance` apart.
    pub fn pair_force(&self, distance: f64) -> f64 {
        let d = distance.max(1e-3);
        let s = self.spread;
        match self.law {
            ForceLaw::Thesis => self.gain * (d * d - s.powi(4) / (d * d)) / (s * s),
            ForceLaw::Sugawara => -self.gain * ((s / d).powi(3) - (s / d).powi(2)),
        }
    }
}

/// Another agent as this agent sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Neighbour {
    pub id: u32,
    pub position: DVec2,
}

/// Picks up to `params.neighbours` agents: with sectors, the nearest in each of
/// N equal sectors around `me` (and, if asked, the nearest of the rest for
/// empty sectors); without, simply the N nearest. Ties break by id, so the choice is
/// deterministic.
pub fn choose_neighbours(
    me: DVec2,
    others: &[Neighbour],
    params: &FormationParams,
) -> Vec<Neighbour> {
    let n = params.neighbours;
    let mut by_distance: Vec<(f64, Neighbour)> = others
        .iter()
        .map(|o| (o.position.distance_squared(me), *o))
        .collect();
    by_distance.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.id.cmp(&b.1.id)));
    if !params.sectors {
        return by_distance.into_iter().take(n).map(|(_, o)| o).collect();
    }
    // Sectors start at the nearest agent's bearing, so the split does not
    // depend on how the world's axes happen to lie.
    let origin = by_distance
        .first()
        .map_or(0.0, |(_, o)| (o.position - me).to_angle());
    let half_sector = TAU / n as f64 / 2.0;
    let sector_of = |p: DVec2| {
        let angle = ((p - me).to_angle() - origin + half_sector).rem_euclid(TAU);
        ((angle / TAU * n as f64) as usize).min(n - 1)
    };
    let mut filled = vec![false; n];
    let mut taken = vec![false; by_distance.len()];
    let mut chosen = Vec::with_capacity(n);
    for (i, (_, other)) in by_distance.iter().enumerate() {
        let sector = sector_of(other.position);
        if !filled[sector] {
            filled[sector] = true;
            taken[i] = true;
            chosen.push(*other);
        }
    }
    for (i, (_, other)) in by_distance.iter().enumerate() {
        if chosen.len() >= n || !params.fill_empty_sectors {
            break;
        }
        if !taken[i] {
            chosen.push(*other);
        }
    }
    chosen
}

/// The net force on an agent at `me` from its chosen neighbours and the goal,
/// zeroed inside the dead band.
pub fn net_force(me: DVec2, neighbours: &[Neighbour], params: &FormationParams) -> DVec2 {
    let mut force: DVec2 = neighbours
        .iter()
        .map(|n| {
            let offset = n.position - me;
            let distance = offset.length();
            if distance < 1e-9 {
                DVec2::ZERO
            } else {
                offset / distance * params.pair_force(distance)
            }
        })
        .sum();
    if let Some(goal) = params.goal {
        // The goal is a virtual agent that only pulls, harder the farther it is.
        let offset = DVec2::from(goal) - me;
        force += offset * params.goal_gain;
    }
    if force.length() < params.dead_band {
        DVec2::ZERO
    } else {
        force
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn agent(id: u32, x: f64, y: f64) -> Neighbour {
        Neighbour {
            id,
            position: DVec2::new(x, y),
        }
    }

    #[test]
    fn both_laws_balance_at_the_desired_spread() {
        for law in [ForceLaw::Thesis, ForceLaw::Sugawara] {
            let params = FormationParams {
                law,
                spread: 1.5,
                ..Default::default()
            };
            assert!(params.pair_force(1.5).abs() < 1e-12);
            assert!(params.pair_force(2.0) > 0.0, "{law:?} pulls when far");
            assert!(params.pair_force(1.0) < 0.0, "{law:?} pushes when near");
        }
        let thesis = FormationParams::default();
        assert!(
            thesis.pair_force(0.01) < -1e3,
            "the thesis law pushes without bound"
        );
    }

    #[test]
    fn sectors_pick_a_far_agent_on_the_empty_side() {
        // Three close agents in the upper half-plane, one far agent below.
        let others = [
            agent(1, 1.0, 0.1),
            agent(2, 1.1, 0.2),
            agent(3, 0.9, 0.3),
            agent(4, 0.0, -5.0),
        ];
        let naive = FormationParams {
            neighbours: 2,
            sectors: false,
            ..Default::default()
        };
        let ids: Vec<u32> = choose_neighbours(DVec2::ZERO, &others, &naive)
            .iter()
            .map(|n| n.id)
            .collect();
        assert_eq!(ids, vec![3, 1]);
        let sectors = FormationParams {
            neighbours: 2,
            sectors: true,
            ..Default::default()
        };
        let ids: Vec<u32> = choose_neighbours(DVec2::ZERO, &others, &sectors)
            .iter()
            .map(|n| n.id)
            .collect();
        assert!(
            ids.contains(&4),
            "the lower half-plane's only agent is tracked: {ids:?}"
        );
    }

    #[test]
    fn empty_sectors_are_filled_with_the_next_nearest() {
        let others = [agent(1, 1.0, 0.0), agent(2, 2.0, 0.0), agent(3, 3.0, 0.0)];
        let params = FormationParams {
            neighbours: 4,
            fill_empty_sectors: true,
            ..Default::default()
        };
        assert_eq!(choose_neighbours(DVec2::ZERO, &others, &params).len(), 3);
        let params = FormationParams {
            neighbours: 4,
            fill_empty_sectors: false,
            ..Default::default()
        };
        assert_eq!(choose_neighbours(DVec2::ZERO, &others, &params).len(), 1);
    }

    #[test]
    fn small_net_forces_fall_in_the_dead_band() {
        let params = FormationParams {
            dead_band: 0.5,
            ..Default::default()
        };
        let near_balance = [agent(1, 1.05, 0.0)];
        assert_eq!(net_force(DVec2::ZERO, &near_balance, &params), DVec2::ZERO);
        let far = [agent(1, 3.0, 0.0)];
        assert!(net_force(DVec2::ZERO, &far, &params).x > 0.0);
    }

    #[test]
    fn the_goal_pulls_harder_from_farther_away() {
        let params = FormationParams {
            goal: Some([10.0, 0.0]),
            dead_band: 0.0,
            ..Default::default()
        };
        let near = net_force(DVec2::new(9.0, 0.0), &[], &params).length();
        let far = net_force(DVec2::new(0.0, 0.0), &[], &params).length();
        assert!(far > near && near > 0.0);
    }
}
