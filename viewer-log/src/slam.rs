//! What the SLAM process shares with viewers: each followed robot's particles
//! (one Points2D batch per step), its map as a GridMap that fills in, and its
//! learned motion model as scalar plots.

use std::collections::BTreeMap;

use rerun::RecordingStream;
use shoal_broker::robot_streams;
use shoal_broker::{Bus, ModelUpdate, Receiver, SlamMap, SlamParticles};

pub struct SlamViews {
    particles: Receiver<SlamParticles>,
    maps: Receiver<SlamMap>,
    models: BTreeMap<u32, Receiver<ModelUpdate>>,
    /// The newest tick of each followed robot's SLAM step, for its model updates.
    ticks: BTreeMap<u32, (u64, f64)>,
}

/// Logs what follows at a SLAM step's tick.
fn at(rec: &RecordingStream, tick: u64, sim_time: f64) {
    rec.set_time_sequence("tick", tick as i64);
    rec.set_duration_secs("sim_time", sim_time);
}

impl SlamViews {
    pub fn new(bus: &Bus) -> anyhow::Result<Self> {
        Ok(Self {
            particles: robot_streams::slam_particles_subscriber(bus)?,
            maps: robot_streams::slam_map_subscriber(bus)?,
            models: BTreeMap::new(),
            ticks: BTreeMap::new(),
        })
    }

    /// Samples that failed their wire check so far.
    pub fn rejected(&self) -> u64 {
        self.particles.rejected()
            + self.maps.rejected()
            + self.models.values().map(|m| m.rejected()).sum::<u64>()
    }

    /// Logs what arrived. The subscribers pass only samples that pass their
    /// wire check, so counts and values here are within bounds.
    pub fn poll(&mut self, bus: &Bus, rec: &RecordingStream) -> anyhow::Result<()> {
        let mut batches = Vec::new();
        self.particles.receive(|p| batches.push(p))?;
        for p in batches {
            let count = p.count as usize;
            at(rec, p.tick, p.sim_time);
            rec.log(
                format!("world/slam/{}/particles", p.agent_id),
                &rerun::Points2D::new(p.xy[..count].iter().copied())
                    .with_radii([0.02f32])
                    .with_colors([rerun::Color::from_rgb(190, 90, 255)]),
            )?;
            self.ticks.insert(p.agent_id, (p.tick, p.sim_time));
            if let std::collections::btree_map::Entry::Vacant(slot) = self.models.entry(p.agent_id)
            {
                slot.insert(robot_streams::model_subscriber(bus, p.agent_id)?);
            }
        }
        self.log_maps(rec)?;
        self.log_models(rec)?;
        Ok(())
    }

    /// Each followed robot's newest map.
    fn log_maps(&mut self, rec: &RecordingStream) -> anyhow::Result<()> {
        let mut maps = Vec::new();
        self.maps.receive(|m| maps.push(m))?;
        for m in maps {
            let cells = (m.width as usize) * (m.height as usize);
            at(rec, m.tick, m.sim_time);
            rec.log(
                format!("world/slam/{}/map", m.agent_id),
                &rerun::GridMap::new(
                    m.cells[..cells].to_vec(),
                    rerun::components::ImageFormat::from_color_model(
                        [m.width, m.height],
                        rerun::ColorModel::L,
                        rerun::ChannelDatatype::U8,
                    ),
                    m.cell_size,
                )
                .with_translation([m.origin[0], m.origin[1], 0.0])
                .with_colormap(rerun::components::Colormap::RvizMap)
                .with_draw_order(-15.0),
            )?;
        }
        Ok(())
    }

    /// Each model update, as six scalars at the tick of its robot's last particles.
    fn log_models(&mut self, rec: &RecordingStream) -> anyhow::Result<()> {
        for (id, models) in &self.models {
            let mut updates = Vec::new();
            models.receive(|u| updates.push(u))?;
            let Some(&(tick, sim_time)) = self.ticks.get(id) else {
                continue;
            };
            for u in updates {
                // The subscriber passes only updates that pass their wire
                // check, which refuses indices that name nothing.
                let Some((command, param)) = u.target() else {
                    continue;
                };
                let values = [
                    u.weights[0],
                    u.weights[1],
                    u.means[0],
                    u.means[1],
                    u.variances[0],
                    u.variances[1],
                ];
                at(rec, tick, sim_time);
                // Entity paths keep to letters, digits and underscores.
                let name: String = command
                    .to_string()
                    .chars()
                    .map(|c| {
                        if c.is_ascii_alphanumeric() || c == '-' {
                            c
                        } else {
                            '_'
                        }
                    })
                    .collect();
                rec.log(
                    format!("slam/{id}/model/{}/{param:?}", name.trim_end_matches('_')),
                    &rerun::Scalars::new(values),
                )?;
            }
        }
        Ok(())
    }
}
