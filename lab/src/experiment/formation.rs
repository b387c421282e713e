//! Tracked neighbours 1..10, with and without sectors (thesis III.F.1-2).

use anyhow::Result;
use serde::Serialize;
use shoal_scenario::Scenario;

use super::{run_until_settled, swarm_name};
use crate::mean_of;
use shoal_swarm::RunningSwarm;

#[derive(Debug, Serialize)]
pub struct Row {
    pub neighbours: usize,
    pub sectors: bool,
    /// The thesis's rule: empty sectors are filled with the next nearest robots.
    pub fill_empty_sectors: bool,
    pub agents: usize,
    pub seeds: usize,
    pub components: f64,
    pub spacing_ratio: f64,
    pub spacing_cv: f64,
    /// Mean over the seeds that converged; `None` if none did.
    pub converge_s: Option<f64>,
    pub converged_runs: usize,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub rows: Vec<Row>,
}

pub fn run(agents: usize, seeds: u64, max_s: f64) -> Result<Report> {
    let mut rows = Vec::new();
    let variants = [(true, false), (true, true), (false, false)];
    let mut index = 0;
    for (sectors, fill) in variants {
        for neighbours in 1..=10 {
            let mut outcomes = Vec::new();
            for seed in 1..=seeds {
                let mut scenario = Scenario::default_arena();
                scenario.agents.count = agents;
                scenario.agents.seed = seed;
                scenario.formation.neighbours = neighbours;
                scenario.formation.sectors = sectors;
                scenario.formation.fill_empty_sectors = fill;
                index += 1;
                let mut swarm =
                    RunningSwarm::launch(&swarm_name("formation", index), scenario, true)?;
                outcomes.push(run_until_settled(&mut swarm, max_s, max_s)?);
                swarm.shutdown()?;
            }
            let converged: Vec<f64> = outcomes.iter().filter_map(|o| o.converge_s).collect();
            let row = Row {
                neighbours,
                sectors,
                fill_empty_sectors: fill,
                agents,
                seeds: outcomes.len(),
                components: mean_of(outcomes.iter().map(|o| o.metrics.components as f64))
                    .unwrap_or(f64::NAN),
                spacing_ratio: mean_of(outcomes.iter().map(|o| o.metrics.spacing_ratio))
                    .unwrap_or(f64::NAN),
                spacing_cv: mean_of(outcomes.iter().map(|o| o.metrics.spacing_cv))
                    .unwrap_or(f64::NAN),
                converge_s: mean_of(converged.iter().copied()),
                converged_runs: converged.len(),
            };
            eprintln!(
                "formation: N={neighbours:2} sectors={sectors:5} fill={fill:5}: groups {:.1}, spacing {:.2}, cv {:.2}, converged {}/{}",
                row.components, row.spacing_ratio, row.spacing_cv, row.converged_runs, row.seeds
            );
            rows.push(row);
        }
    }
    Ok(Report { rows })
}
