//! 20 robots among 400 random obstacles (thesis III.F.3).

use anyhow::Result;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use shoal_physics::Obstacle;
use shoal_scenario::Scenario;

use super::{run_until_settled, swarm_name};
use shoal_swarm::RunningSwarm;

#[derive(Debug, Serialize)]
pub struct Case {
    pub name: String,
    pub agents: usize,
    pub obstacles: usize,
    pub components: usize,
    pub spacing_ratio: f64,
    pub spacing_cv: f64,
    /// Seconds until one group at the desired spacing, for good; `None` if never.
    pub heal_s: Option<f64>,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub cases: Vec<Case>,
}

/// The default arena with `count` discs of 5-15 cm radius scattered by `seed`.
pub fn cluttered(count: usize, seed: u64) -> Scenario {
    let mut scenario = Scenario::default_arena();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0b57_ac1e);
    let (w, h) = (scenario.arena.width, scenario.arena.height);
    scenario.arena.obstacles = (0..count)
        .map(|_| Obstacle::Disc {
            center: [
                rng.random_range(0.5..w - 0.5),
                rng.random_range(0.5..h - 0.5),
            ],
            radius: rng.random_range(0.05..0.15),
        })
        .collect();
    scenario
}

pub fn run(agents: usize, seeds: u64, max_s: f64) -> Result<Report> {
    let mut cases = Vec::new();
    let mut settings: Vec<(String, usize, u64)> = (1..=seeds)
        .map(|s| (format!("clear-seed-{s}"), 0, s))
        .collect();
    settings.extend((1..=seeds).map(|s| (format!("400-obstacles-seed-{s}"), 400, s)));
    for (index, (name, obstacles, seed)) in settings.into_iter().enumerate() {
        let mut scenario = cluttered(obstacles, seed);
        scenario.agents.count = agents;
        scenario.agents.seed = seed;
        let mut swarm = RunningSwarm::launch(&swarm_name("obstacles", index), scenario, true)?;
        let outcome = run_until_settled(&mut swarm, max_s, 10.0)?;
        swarm.shutdown()?;
        eprintln!(
            "obstacles: {name}: groups {}, spacing {:.2}, formed after {:?} s",
            outcome.metrics.components, outcome.metrics.spacing_ratio, outcome.converge_s
        );
        cases.push(Case {
            name,
            agents,
            obstacles,
            components: outcome.metrics.components,
            spacing_ratio: outcome.metrics.spacing_ratio,
            spacing_cv: outcome.metrics.spacing_cv,
            heal_s: outcome.converge_s,
        });
    }
    Ok(Report { cases })
}
