//! What viewers see of a filter: an even subsample of its particles and its
//! best particle's map, coarsened.

use shoal_broker::{MAX_MAP_SIDE, MAX_SHOWN_PARTICLES, SlamMap, SlamParticles};
use shoal_slam::follower::Stepped;

pub fn particles(id: u32, step: &Stepped<'_>) -> SlamParticles {
    let mut view = SlamParticles {
        agent_id: id,
        count: 0,
        tick: step.tick,
        sim_time: step.sim_time,
        xy: [[0.0; 2]; MAX_SHOWN_PARTICLES],
    };
    let every = step
        .filter
        .particles
        .len()
        .div_ceil(MAX_SHOWN_PARTICLES)
        .max(1);
    for (slot, particle) in view
        .xy
        .iter_mut()
        .zip(step.filter.particles.iter().step_by(every))
    {
        *slot = [particle.pose.x as f32, particle.pose.y as f32];
        view.count += 1;
    }
    view
}

pub fn map(id: u32, step: &Stepped<'_>) -> SlamMap {
    let mut view = SlamMap {
        agent_id: id,
        width: 0,
        height: 0,
        cell_size: 0.0,
        origin: [0.0; 2],
        tick: step.tick,
        sim_time: step.sim_time,
        cells: [255; MAX_MAP_SIDE * MAX_MAP_SIDE],
    };
    let Some(best) = step
        .filter
        .particles
        .iter()
        .max_by(|a, b| a.weight.total_cmp(&b.weight))
    else {
        return view;
    };
    let (width, height, cell_size, cells) = best.map.coarsened(MAX_MAP_SIDE);
    view.width = width as u32;
    view.height = height as u32;
    view.cell_size = cell_size as f32;
    view.origin = [best.map.origin.x as f32, best.map.origin.y as f32];
    view.cells[..cells.len()].copy_from_slice(&cells);
    view
}
