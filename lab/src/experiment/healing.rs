//! Removing the 4 central robots of 20; adding 6 at the edge of 19 (thesis III.F.4).

use anyhow::{Result, bail};
use glam::DVec2;
use serde::Serialize;
use shoal_physics::Pose;
use shoal_physics::metrics::centroid;
use shoal_scenario::Scenario;

use super::{run_until, run_until_settled, swarm_name};
use shoal_swarm::RunningSwarm;

/// A hole counts as closed once a robot stands this close (in spreads) to its centre.
const HOLE_CLOSED_SPREADS: f64 = 0.75;

#[derive(Debug, Serialize)]
pub struct Case {
    pub name: String,
    pub seed: u64,
    /// Robots after the change.
    pub agents: usize,
    pub components: usize,
    pub spacing_ratio: f64,
    pub spacing_cv: f64,
    /// Seconds from the change until the formation was whole again, for good.
    pub heal_s: Option<f64>,
    /// Seconds the formation took to form before the change.
    pub formed_before_s: Option<f64>,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub cases: Vec<Case>,
}

pub fn remove_central(seed: u64, max_s: f64) -> Result<Case> {
    let mut scenario = Scenario::default_arena();
    scenario.agents.count = 20;
    scenario.agents.seed = seed;
    let spread = scenario.formation.spread;
    let mut swarm =
        RunningSwarm::launch(&swarm_name("heal-remove", seed as usize), scenario, true)?;
    let before = run_until_settled(&mut swarm, max_s, 5.0)?;
    let center = swarm.observer.centroid();
    let mut by_distance: Vec<(f64, u32)> = swarm
        .observer
        .samples()
        .map(|s| (DVec2::new(s.x, s.y).distance(center), s.agent_id))
        .collect();
    by_distance.sort_by(|a, b| a.0.total_cmp(&b.0));
    let removed: Vec<u32> = by_distance.iter().take(4).map(|(_, id)| *id).collect();
    let hole = centroid(
        &swarm
            .observer
            .samples()
            .filter(|s| removed.contains(&s.agent_id))
            .map(|s| DVec2::new(s.x, s.y))
            .collect::<Vec<_>>(),
    );
    for id in &removed {
        swarm.signal_robot(*id, libc::SIGKILL)?;
    }
    let after = run_until(&mut swarm, max_s, 5.0, |observer| {
        observer.len() == 16
            && observer
                .samples()
                .any(|s| DVec2::new(s.x, s.y).distance(hole) <= HOLE_CLOSED_SPREADS * spread)
    })?;
    swarm.shutdown()?;
    Ok(Case {
        name: "remove-4-central".into(),
        seed,
        agents: 16,
        components: after.metrics.components,
        spacing_ratio: after.metrics.spacing_ratio,
        spacing_cv: after.metrics.spacing_cv,
        heal_s: after.converge_s,
        formed_before_s: before.converge_s,
    })
}

pub fn add_at_edge(seed: u64, max_s: f64) -> Result<Case> {
    let mut scenario = Scenario::default_arena();
    scenario.agents.count = 19;
    scenario.agents.seed = seed;
    let spread = scenario.formation.spread;
    let mut swarm = RunningSwarm::launch(&swarm_name("heal-add", seed as usize), scenario, true)?;
    let before = run_until_settled(&mut swarm, max_s, 5.0)?;
    let center = swarm.observer.centroid();
    let reach = swarm
        .observer
        .samples()
        .map(|s| DVec2::new(s.x, s.y).distance(center))
        .fold(0.0, f64::max);
    let radius = reach + spread;
    for k in 0..6u32 {
        let angle = std::f64::consts::TAU * f64::from(k) / 6.0;
        let at = center + DVec2::from_angle(angle) * radius;
        if !swarm.scenario.arena.contains(at) {
            bail!("the edge of the formation leaves the arena at {at}");
        }
        swarm.start(19 + k, Pose::new(at.x, at.y, angle + std::f64::consts::PI))?;
    }
    let after = run_until(&mut swarm, max_s, 5.0, |observer| observer.len() == 25)?;
    swarm.shutdown()?;
    Ok(Case {
        name: "add-6-at-edge".into(),
        seed,
        agents: 25,
        components: after.metrics.components,
        spacing_ratio: after.metrics.spacing_ratio,
        spacing_cv: after.metrics.spacing_cv,
        heal_s: after.converge_s,
        formed_before_s: before.converge_s,
    })
}

pub fn run(seeds: u64, max_s: f64) -> Result<Report> {
    let mut cases = Vec::new();
    for seed in 1..=seeds {
        for case in [remove_central(seed, max_s)?, add_at_edge(seed, max_s)?] {
            eprintln!(
                "healing: {} (seed {seed}): groups {}, spacing {:.2}, healed after {:?} s",
                case.name, case.components, case.spacing_ratio, case.heal_s
            );
            cases.push(case);
        }
    }
    Ok(Report { cases })
}
