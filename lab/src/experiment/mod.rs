//! `shoal experiment`: the thesis's results as numbers, with real robot
//! processes in lockstep.

pub mod chaos;
pub mod formation;
pub mod healing;
pub mod learning;
pub mod obstacles;
pub mod scale;

use anyhow::Result;
use shoal_physics::metrics::FormationMetrics;

use shoal_swarm::RunningSwarm;
use shoal_swarm::observer::Observer;

/// How a run ended.
#[derive(Clone, Copy, Debug)]
pub struct Outcome {
    pub metrics: FormationMetrics,
    /// Seconds from the start of the run until the formation was formed for good.
    pub converge_s: Option<f64>,
    pub ticks: u64,
}

/// Runs `swarm` for up to `max_s` simulated seconds; stops early once the
/// formation has stayed formed for `settle_s`.
pub fn run_until_settled(swarm: &mut RunningSwarm, max_s: f64, settle_s: f64) -> Result<Outcome> {
    run_until(swarm, max_s, settle_s, |_| true)
}

/// Like [`run_until_settled`], with `also` as a further condition of being formed.
pub fn run_until(
    swarm: &mut RunningSwarm,
    max_s: f64,
    settle_s: f64,
    also: impl Fn(&Observer) -> bool,
) -> Result<Outcome> {
    let spread = swarm.scenario.formation.spread;
    let start = swarm.sim_time();
    let start_tick = swarm.clock.as_ref().map_or(0, |c| c.tick);
    let mut formed_since: Option<f64> = None;
    while swarm.sim_time() - start < max_s {
        if swarm.termination_requested() {
            anyhow::bail!("interrupted");
        }
        swarm.advance()?;
        let now = swarm.sim_time() - start;
        let formed = swarm.observer.metrics(spread).is_formed() && also(&swarm.observer);
        match (formed, formed_since) {
            (true, None) => formed_since = Some(now),
            (false, Some(_)) => formed_since = None,
            (true, Some(since)) if now - since >= settle_s => break,
            _ => {}
        }
    }
    let ticks = match &swarm.clock {
        Some(clock) => clock.tick - start_tick,
        // In real time every robot keeps its own period: as many as passed.
        None => ((swarm.sim_time() - start) / swarm.scenario.timing.period_s).round() as u64,
    };
    Ok(Outcome {
        metrics: swarm.observer.metrics(spread),
        converge_s: formed_since,
        ticks,
    })
}

/// A swarm name no other run uses.
pub fn swarm_name(experiment: &str, index: usize) -> String {
    format!("x{}-{experiment}-{index}", std::process::id())
}
