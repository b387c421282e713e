//! Particle-filter SLAM over pose and occupancy grid (DP-SLAM style, with
//! copy-on-write maps), learning the motion model from the particles as it goes.

use std::collections::BTreeMap;

use glam::DVec2;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use shoal_physics::legged::Param;
use shoal_physics::range::RangeSensor;
use shoal_physics::{Command, MotionModel, Pose};

use crate::grid::TiledGrid;
use crate::learning::{Draw, MixtureLearner};
use crate::proposal::{
    MotionPrior, PROPOSAL_POSES_SCORED, Proposed, ScoredBeams, improved_proposal, match_scan,
};

/// The range of scales exploring particles apply to a drawn motion.
const EXPLORE_SCALE: (f64, f64) = (0.3, 1.7);

/// The exponent on a scan's likelihood in the particles' weights. Beams
/// are scored as if independent, but neighbouring beams err together (one
/// pose error moves them all), so the product is far too sure of itself: in
/// a crowd, where robots hide most walls, a few steps of it left one
/// particle's heading, 0.3 rad off, to map the rest of the run (an offline
/// crowd of 20 of the demo's robots, `slam/tests/crowd.rs`). Tempering the
/// likelihood keeps the cloud wide until walls decide.
const BEAM_TEMPERING: f64 = 0.5;

/// How much an exploring particle counts in the posterior, relative to
/// one drawn from the model. Explorers are drawn from a wider distribution
/// than the model, for the learner; counted in full, a wild turn that
/// happened to fit a sparse scan took over the cloud and rotated the map
/// (importance sampling would discount them by the model's density over
/// the wider one; a fixed tenth does the same in effect).
const EXPLORER_WEIGHT: f64 = 0.1;

/// How far the map reaches beyond the arena.
const MAP_MARGIN_M: f64 = 0.5;

/// The finest cell [`cell_for`] chooses.
pub const FINEST_CELL_M: f64 = 0.025;

/// The coarsest cell [`cell_for`] chooses: GMapping's default, and this
/// filter's for any sensor before cells followed the sensor.
pub const COARSEST_CELL_M: f64 = 0.05;

/// The most cells [`cell_for`] lets a map hold before it coarsens them:
/// about a 9 x 9 m arena on 2.5 cm cells. Each particle holds its own map,
/// and a SLAM process that follows 20 robots holds 1000 of them.
pub const MAX_MAP_CELLS: f64 = 131_072.0;

/// The cell a filter maps `width` x `height` metres with, seen by
/// `sensor`: as wide as the sensor's range noise at half its reach (what
/// a typical beam can tell), between [`FINEST_CELL_M`] and
/// [`COARSEST_CELL_M`], and no finer than keeps the map (with its margin)
/// within [`MAX_MAP_CELLS`]. Cells much wider than the noise draw walls
/// coarser than the scans see them: on 5 cm cells a scan matched on a map
/// drawn from the true poses peaks 3.1 cm off the truth, on 2.5 cm cells
/// 1.9 cm (EXPERIMENTS.md 8b). Cells much finer than the noise only cost:
/// with 10 m beams (10 cm of noise at their reach) the demo's crowd did
/// worse on 2.5 cm cells than on 5 cm, at 2.3 times the time.
pub fn cell_for(sensor: &RangeSensor, width: f64, height: f64) -> f64 {
    let seen = (sensor.noise_per_m * sensor.max_range / 2.0).max(FINEST_CELL_M);
    let area = (width + 2.0 * MAP_MARGIN_M) * (height + 2.0 * MAP_MARGIN_M);
    let within_budget = (area / MAX_MAP_CELLS).sqrt();
    seen.max(within_budget).min(COARSEST_CELL_M)
}

#[derive(Clone, Debug, PartialEq)]
pub struct FilterConfig {
    pub particles: usize,
    /// The fewest particles a follower short of time sheds to
    /// ([`crate::follower::Follower::catch_up`]); none: a fifth of
    /// `particles`. As many as `particles` never sheds.
    pub fewest_particles: Option<usize>,
    /// Score every n-th beam (scoring every beam adds little but time).
    pub score_stride: usize,
    /// Map with every n-th beam. A scan taken from a pose known exactly
    /// (the start, another robot's first look) is mapped with every beam.
    pub map_stride: usize,
    /// The occupancy grid's cell, metres; none: [`cell_for`], as fine as
    /// the sensor can tell, the map kept within [`MAX_MAP_CELLS`].
    pub cell_size: Option<f64>,
    pub learning: bool,
    /// Whether a step that fits far worse than usual is matched again
    /// from turns the model does not reach ([`REMATCH_DROP_PER_BEAM`]);
    /// off only to measure what it buys.
    pub rematch: bool,
    /// The learning window k.
    pub window: usize,
    /// Share of particles whose motion is scaled at random (0.3-1.7x) to
    /// keep a wrong model's truth within reach of the learner (only while
    /// learning).
    pub explore: f64,
    pub sensor: RangeSensor,
    pub proposal: Proposal,
    /// Resample when the effective sample size falls below this share of
    /// the particles (GMapping's `resampleThreshold`, 0.5). A quarter and
    /// three quarters were both further off in the demo's crowd
    /// (EXPERIMENTS.md 8b).
    pub resample_below: f64,
}

/// Where a particle's next pose comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Proposal {
    /// A step drawn from the motion model, weighted by the scan.
    Motion,
    /// GMapping's improved proposal (see [`crate::proposal`]), where the
    /// scan returned enough beams to match; the motion model's otherwise.
    ScanMatched,
}

/// Fewer returned beams than this are too few to match a scan on: the
/// step falls back to the motion model's proposal.
const MIN_MATCHED_BEAMS: usize = 8;

/// The scan matcher's search scores every this many of the scored beams.
const MATCH_BEAM_STRIDE: usize = 2;

/// What the improved proposal did in one step.
struct Matching {
    /// Each particle's next pose, drawn around its match.
    poses: Vec<Pose>,
    /// Each particle's log weight update.
    log_weights: Vec<f64>,
    /// Poses scored: the matcher's search and the proposal's probes.
    poses_scored: usize,
    beam_evaluations: usize,
    /// The best particle's fit: its tempered scan score at its match, per
    /// scored beam.
    best_fit: f64,
}

/// A step whose best fit falls this far (tempered log-likelihood per
/// scored beam) below the usual fit ([`FIT_MEMORY`]) is matched again from
/// turns the model does not reach. The usual fit of the lone robot's rooms
/// is -0.14 to -0.26 a beam from step to step; a turn 0.9 rad past the
/// model's mean (a draw from the body's skewed tail, the two rooms' seed 7
/// at step 78, EXPERIMENTS.md 8b) left the best particle at -1.64 while the
/// true pose scored -0.28 on its map.
const REMATCH_DROP_PER_BEAM: f64 = 0.5;
/// How far past the turn the model leads to the second matching reaches,
/// each way, in steps of [`REMATCH_STEP_RAD`]: a turn as far past the
/// model as a leg's turn can go.
const REMATCH_REACH_RAD: f64 = 1.2;
const REMATCH_STEP_RAD: f64 = 0.2;
/// The second matching is kept only if its best fit beats the first's by
/// this much a beam: where nothing fits better (a crowd hiding the walls),
/// the step stays as the model placed it.
const REMATCH_GAIN_PER_BEAM: f64 = 0.25;
/// How much of the usual fit each matched step keeps: about the last ten.
const FIT_MEMORY: f64 = 0.9;

/// One particle's drawn step, before the proposal places it.
struct Drawn {
    /// The particle it was drawn from.
    particle: usize,
    motion: [f64; 3],
    pose: Pose,
    explorer: bool,
}

/// The learner judges at least this many drawn motions a step. A filter
/// of fewer particles (the scan-matched proposal needs 50) draws the rest
/// from its particles in turn and scores each once against that
/// particle's map, a pose each where the matcher scores 60-70: with only
/// 50 draws, 10 of them explorers, a crowd's sparse scans left the
/// learned stride where it started.
const MIN_LEARNING_DRAWS: usize = 250;

impl FilterConfig {
    /// The fewest particles a follower sheds to: `fewest_particles`, or a
    /// fifth of `particles` (below that, coasting through scans is what is
    /// left), never more than `particles` nor fewer than one.
    pub fn fewest_particles(&self) -> usize {
        self.fewest_particles
            .unwrap_or(self.particles / 5)
            .clamp(1, self.particles.max(1))
    }

    /// The cell a filter of this config maps `width` x `height` metres
    /// with: its own, or [`cell_for`] its sensor there.
    pub fn cell_in(&self, width: f64, height: f64) -> f64 {
        self.cell_size
            .unwrap_or_else(|| cell_for(&self.sensor, width, height))
    }
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self {
            // GMapping's improved proposal with 50 particles: as accurate
            // as 500 drawn from the motion model on a lone robot and in the
            // demo's crowd, at a third of the cost in the demo's arena,
            // which is what lets one SLAM process follow all 20 of its
            // robots on two cores (EXPERIMENTS.md 8b, BENCHMARKS.md 4).
            particles: 50,
            fewest_particles: None,
            score_stride: 2,
            map_stride: 2,
            cell_size: None,
            learning: true,
            rematch: true,
            window: 8,
            explore: 0.2,
            sensor: RangeSensor::default(),
            proposal: Proposal::ScanMatched,
            resample_below: 0.5,
        }
    }
}

#[derive(Clone, Debug)]
pub struct Particle {
    pub pose: Pose,
    pub map: TiledGrid,
    pub weight: f64,
    /// How much farther than the model this particle's robot steps (along
    /// and across), held from step to step: see [`STRIDE_SCALE_SPREAD`].
    pub stride_scale: f64,
    /// How much farther than the model this particle's robot turns, held
    /// from step to step: see [`TURN_SCALE_SPREAD`].
    pub turn_scale: f64,
}

/// Each particle holds its own guess of how far the model's steps carry,
/// spread this much about 1 (a standard deviation, in shares of a step)
/// and relaxing back to 1 by [`GUESS_MEMORY`] a step. A model that
/// is wrong is wrong the same way at every step: where the scan says
/// nothing along the path (a corridor longer than the sensor's reach) the
/// particles then spread along it in proportion to the distance walked,
/// and the one whose guess was right is there when the scan speaks again.
/// Redrawn at every step, as the explorers are, guesses average out
/// and the cloud spreads with the square root of the steps only. The
/// guesses move the scan-matched proposal's particles (the default) and
/// coasting; the motion model's proposal (the thesis's filter) places its
/// particles where the learner's draws lead, unscaled.
const STRIDE_SCALE_SPREAD: f64 = 0.15;
const GUESS_MEMORY: f64 = 0.98;

/// Each particle also holds its own guess of how far the model's turns
/// carry, held and relaxing as the stride guess is, narrower: a body that
/// turns half as far again as the model (EXPERIMENTS.md 8b, "Bodies never
/// tuned on") was lost on 2 of 12 seeds while the learner caught up, as
/// every particle climbed the scan from a turn a third short under a prior
/// that pulled it back; with guesses spread 0.08 none was. Spread 0.15 as
/// the strides' held that body too, but put each turn's heading so far
/// apart that the usual room lost 7 mm on average.
const TURN_SCALE_SPREAD: f64 = 0.08;

/// A guess of how far the model's steps or turns carry, drawn from
/// `spread` about 1.
fn scale_drawn(spread: f64, rng: &mut impl Rng) -> f64 {
    let z: f64 = StandardNormal.sample(rng);
    scale_within_bounds(1.0 + spread * z, spread)
}

/// A guess one step later: relaxed towards 1 by [`GUESS_MEMORY`]
/// and wandered so that its spread stays `spread` (a first-order
/// autoregression).
fn scale_wandered(scale: f64, spread: f64, rng: &mut impl Rng) -> f64 {
    let rho = GUESS_MEMORY;
    let z: f64 = StandardNormal.sample(rng);
    let wandered = 1.0 + rho * (scale - 1.0) + spread * (1.0 - rho * rho).sqrt() * z;
    scale_within_bounds(wandered, spread)
}

/// A guess kept within three spreads of 1: never a step backwards.
fn scale_within_bounds(scale: f64, spread: f64) -> f64 {
    let bound = 3.0 * spread;
    scale.clamp(1.0 - bound, 1.0 + bound)
}

/// What one step concluded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    pub estimate: Pose,
    /// Effective sample size before resampling.
    pub effective_particles: f64,
    /// Share of scored beams that returned a range: how much this step knew.
    pub information: f64,
    pub resampled: bool,
    /// Whether the scan placed the particles (the improved proposal).
    pub matched: bool,
    /// Poses scored against a map this step, over all particles: the
    /// learner's draws, and the matcher's search and the proposal's probes.
    pub poses_scored: usize,
    /// Beams scored over all those poses: the filter's work in
    /// particle-beam evaluations (the matcher's search scores half the
    /// beams of each of its poses).
    pub beam_evaluations: usize,
    /// Beams each scored pose was scored with.
    pub scored_beams: usize,
    /// Whether the scan fitted so much worse than usual from where the
    /// model's turn led that the particles were matched again from turns
    /// the model does not reach, and fitted better there.
    pub rematched: bool,
}

#[derive(Clone)]
pub struct ParticleFilter {
    pub particles: Vec<Particle>,
    model: MotionModel,
    learners: Vec<[MixtureLearner; 3]>,
    config: FilterConfig,
    /// The map's cell, metres: the config's, or [`cell_for`] the arena.
    cell_size: f64,
    rng: StdRng,
    steps: u64,
    /// The usual best fit of a matched step (see [`REMATCH_DROP_PER_BEAM`]).
    usual_fit: Option<f64>,
}

impl ParticleFilter {
    /// A filter that starts certain of `start`, in a map of `width` x `height`
    /// metres (with a margin, so walls on the border are mapped too).
    pub fn new(
        start: Pose,
        model: MotionModel,
        config: FilterConfig,
        width: f64,
        height: f64,
        seed: u64,
    ) -> Self {
        let margin = DVec2::splat(MAP_MARGIN_M);
        let cell_size = config.cell_in(width, height);
        let map = TiledGrid::covering(-margin, DVec2::new(width, height) + margin, cell_size);
        let weight = 1.0 / config.particles.max(1) as f64;
        let mut rng = StdRng::seed_from_u64(seed);
        let particles = (0..config.particles.max(1))
            .map(|_| Particle {
                pose: start,
                map: map.clone(),
                weight,
                stride_scale: scale_drawn(STRIDE_SCALE_SPREAD, &mut rng),
                turn_scale: scale_drawn(TURN_SCALE_SPREAD, &mut rng),
            })
            .collect();
        let learners = Command::ALL
            .iter()
            .map(|c| {
                Param::ALL.map(|p| MixtureLearner::new(*model.command(*c).param(p), config.window))
            })
            .collect();
        Self {
            particles,
            model,
            learners,
            config,
            cell_size,
            rng,
            steps: 0,
            usual_fit: None,
        }
    }

    pub fn model(&self) -> &MotionModel {
        &self.model
    }

    /// The map's cell, metres.
    pub fn cell_size(&self) -> f64 {
        self.cell_size
    }

    /// Weighted mean of the particles (circular mean for the heading).
    pub fn estimate(&self) -> Pose {
        let (mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
        for p in &self.particles {
            x += p.weight * p.pose.x;
            y += p.weight * p.pose.y;
            s += p.weight * p.pose.theta.sin();
            c += p.weight * p.pose.theta.cos();
        }
        Pose::new(x, y, s.atan2(c))
    }

    /// Builds the first map from a scan taken at the start pose, before any
    /// motion: every particle shares it, so all poses are measured against
    /// one frame. It is mapped with every beam, not every `map_stride`-th:
    /// it is mapped once for all particles, and the first steps are matched
    /// against it alone; walls mapped from every other beam lie in dots up
    /// to 10 cm apart at 3 m, which held the lone robot's first strides (a
    /// quarter short in its model) 5-8 cm behind, and the map drawn from
    /// there kept the lag (EXPERIMENTS.md 8b).
    pub fn observe_start(&mut self, ranges: &[f64]) {
        let mut first = self.particles[0].clone();
        integrate(&mut first, &mapped_beams(ranges, &self.config.sensor, 1));
        for p in &mut self.particles {
            p.map = first.map.clone();
        }
        self.steps += 1;
    }

    /// Maps a scan another robot took from a pose known in this filter's
    /// frame (its first, where the roster announced it) into every
    /// particle's map: walls this robot has not seen yet are then known
    /// when it does.
    pub fn observe_from(&mut self, pose: Pose, ranges: &[f64]) {
        let beams = mapped_beams(ranges, &self.config.sensor, 1);
        let seer = |p: &mut Particle| {
            let own = p.pose;
            p.pose = pose;
            integrate(p, &beams);
            p.pose = own;
        };
        if self.steps <= 1 {
            // Before the first motion every particle holds the start's map
            // (`observe_start` handed them one): mapped once and shared, a
            // twentieth of the work of the crowd's first looks.
            debug_assert!(
                self.particles
                    .iter()
                    .all(|p| { p.map.shared_tiles(&self.particles[0].map) == p.map.tile_count() })
            );
            seer(&mut self.particles[0]);
            let map = self.particles[0].map.clone();
            for p in &mut self.particles[1..] {
                p.map = map.clone();
            }
        } else {
            self.particles.par_iter_mut().for_each(seer);
        }
    }

    /// One step: the robot executed `command` (a wall or robot stopped its
    /// translation if `bumped`), then its sensor read `ranges`.
    pub fn step(&mut self, command: Command, bumped: bool, ranges: &[f64]) -> StepReport {
        self.wander_guesses();
        let n = self.particles.len();
        let learns = self.config.learning && self.steps > 0;
        let draws = if learns { self.draws() } else { n };
        // The first n draws are the particles' own (draw k is particle k's).
        let drawn = self.draw_motions(command, bumped, draws);
        let (beams, information) = scored_beams(ranges, &self.config, self.cell_size);
        let matched = self.config.proposal == Proposal::ScanMatched
            && self.steps > 0
            && !bumped
            && beams.len() >= MIN_MATCHED_BEAMS;
        // The learner judges each motion drawn from the model (and each
        // explorer's) by the whole scan at the pose it leads to. It never
        // sees where the scan matcher then puts the particle: the matcher's
        // correction is the scan's knowledge, not the motion's, and learned
        // from it the model would learn the map's pull instead of the robot.
        // The motion model's proposal weighs its particles by the same
        // scores; the matched one needs them only to learn.
        let scored = self.steps > 0 && (learns || !matched);
        let at_drawn: Vec<f64> = if scored {
            // Each draw is scored against its particle's own map, shared
            // out over the cores.
            drawn
                .par_iter()
                .map(|d| beams.log_likelihood(&self.particles[d.particle].map, &d.pose))
                .collect()
        } else {
            vec![0.0; draws]
        };
        if learns {
            self.learn(command, bumped, &drawn, &at_drawn, information);
        }
        let mut poses_scored = if scored { draws } else { 0 };
        let mut beam_evaluations = poses_scored * beams.len();
        let (drawn, at_drawn) = (&drawn[..n], &at_drawn[..n]);
        let mut rematched = false;
        let log_weights = if matched {
            let mut matching = self.propose_by_matching(command, &beams, drawn, 0.0);
            poses_scored += matching.poses_scored;
            beam_evaluations += matching.beam_evaluations;
            if self.config.rematch
                && self
                    .usual_fit
                    .is_some_and(|usual| matching.best_fit < usual - REMATCH_DROP_PER_BEAM)
            {
                let wide = self.propose_by_matching(command, &beams, drawn, REMATCH_REACH_RAD);
                poses_scored += wide.poses_scored;
                beam_evaluations += wide.beam_evaluations;
                if wide.best_fit > matching.best_fit + REMATCH_GAIN_PER_BEAM {
                    matching = wide;
                    rematched = true;
                }
            }
            self.usual_fit = Some(self.usual_fit.map_or(matching.best_fit, |usual| {
                FIT_MEMORY * usual + (1.0 - FIT_MEMORY) * matching.best_fit
            }));
            for (p, pose) in self.particles.iter_mut().zip(&matching.poses) {
                p.pose = *pose;
            }
            matching.log_weights
        } else {
            // The motion model's proposal: each particle goes where its
            // draw took it, weighted by the scan there, tempered (see
            // BEAM_TEMPERING); an explorer counts a tenth (EXPLORER_WEIGHT).
            self.particles
                .iter_mut()
                .zip(drawn)
                .zip(at_drawn)
                .map(|((p, d), l)| {
                    p.pose = d.pose;
                    l * BEAM_TEMPERING
                        + if d.explorer {
                            EXPLORER_WEIGHT.ln()
                        } else {
                            0.0
                        }
                })
                .collect()
        };
        let effective_particles = self.reweigh(&log_weights);
        let estimate = self.estimate();
        let resampled = effective_particles < n as f64 * self.config.resample_below;
        if resampled {
            self.resample();
        }
        let mapped = mapped_beams(ranges, &self.config.sensor, self.config.map_stride);
        self.particles
            .par_iter_mut()
            .for_each(|p| integrate(p, &mapped));
        self.steps += 1;
        StepReport {
            estimate,
            effective_particles,
            information,
            resampled,
            matched,
            poses_scored,
            beam_evaluations,
            scored_beams: beams.len(),
            rematched,
        }
    }

    /// Each particle's stride and turn guesses relax towards 1 and wander
    /// ([`scale_wandered`]): resampling keeps the guesses the scan bears out.
    fn wander_guesses(&mut self) {
        for p in &mut self.particles {
            p.stride_scale = scale_wandered(p.stride_scale, STRIDE_SCALE_SPREAD, &mut self.rng);
            p.turn_scale = scale_wandered(p.turn_scale, TURN_SCALE_SPREAD, &mut self.rng);
        }
    }

    /// How many particles the filter holds now: the config's, or fewer
    /// while a follower short of time sheds them ([`ParticleFilter::resize`]).
    pub fn particle_count(&self) -> usize {
        self.particles.len()
    }

    /// Holds `n` particles (at least one) from now on. Fewer are drawn by
    /// weight (systematic resampling); more come from splitting the
    /// heaviest in two, each half its weight, which leaves what the filter
    /// believes exactly as it was (the halves part at the next step's
    /// draws). Maps are shared tile by tile, so a split copies none.
    pub fn resize(&mut self, n: usize) {
        let n = n.max(1);
        if n < self.particles.len() {
            self.resample_to(n);
        }
        while self.particles.len() < n {
            let mut heaviest: Vec<usize> = (0..self.particles.len()).collect();
            heaviest.sort_by(|&a, &b| {
                self.particles[b]
                    .weight
                    .total_cmp(&self.particles[a].weight)
            });
            heaviest.truncate(n - self.particles.len());
            for i in heaviest {
                self.particles[i].weight /= 2.0;
                let half = self.particles[i].clone();
                self.particles.push(half);
            }
        }
    }

    /// How many motions a step draws: one per particle, and while learning
    /// at least [`MIN_LEARNING_DRAWS`].
    fn draws(&self) -> usize {
        let n = self.particles.len();
        if self.config.learning {
            n.max(MIN_LEARNING_DRAWS)
        } else {
            n
        }
    }

    /// Moves every particle by one motion drawn from the model for
    /// `command`, with no scan: where a scan was not stepped (a SLAM
    /// process behind its robots), its command still moved the robot. No
    /// scan is scored, nothing is learned and no map is written; the spread
    /// the draws add is what the next scored step's proposal searches.
    pub fn coast(&mut self, command: Command, bumped: bool) {
        self.wander_guesses();
        for particle in &mut self.particles {
            let motion = self.model.sample(command, &mut self.rng);
            let scale = particle.stride_scale;
            let turn = particle.turn_scale * motion.turn;
            particle.pose = if bumped {
                particle.pose.advanced(0.0, 0.0, turn)
            } else {
                particle
                    .pose
                    .advanced(scale * motion.along, scale * motion.across, turn)
            };
        }
    }

    /// `count` motions drawn from the model, from the particles in turn
    /// (draw k from particle k mod n), some scaled at random (explorers)
    /// while learning.
    fn draw_motions(&mut self, command: Command, bumped: bool, count: usize) -> Vec<Drawn> {
        // Exploring serves the learner; without learning the model is taken as is.
        let explore = if self.config.learning {
            self.config.explore
        } else {
            0.0
        };
        let explorers = (explore * count as f64).round() as usize;
        let mut drawn = Vec::with_capacity(count);
        let from = self.particles.iter().enumerate().cycle().take(count);
        for (k, (i, particle)) in from.enumerate() {
            let mut motion = self.model.sample(command, &mut self.rng);
            // Some particles try the command carrying farther or less far than
            // the model says: when the model is wrong (a new surface, another
            // robot), they keep the truth within reach, and their qualities
            // show the learner where it lies.
            let explorer = k % count.max(1).div_ceil(explorers.max(1)) == 0 && explorers > 0;
            if explorer {
                let scale = self.rng.random_range(EXPLORE_SCALE.0..EXPLORE_SCALE.1);
                motion.along *= scale;
                motion.across *= scale;
                motion.turn *= self.rng.random_range(EXPLORE_SCALE.0..EXPLORE_SCALE.1);
            }
            let pose = if bumped {
                particle.pose.advanced(0.0, 0.0, motion.turn)
            } else {
                particle
                    .pose
                    .advanced(motion.along, motion.across, motion.turn)
            };
            drawn.push(Drawn {
                particle: i,
                motion: [motion.along, motion.across, motion.turn],
                pose,
                explorer,
            });
        }
        drawn
    }

    /// Updates the motion model of `command` from the drawn motions, each
    /// as good as the whole scan found the pose it led to.
    fn learn(
        &mut self,
        command: Command,
        bumped: bool,
        drawn: &[Drawn],
        log_likelihoods: &[f64],
        information: f64,
    ) {
        let best = log_likelihoods
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        let weights: Vec<f64> = log_likelihoods.iter().map(|l| (l - best).exp()).collect();
        let total: f64 = weights.iter().sum();
        // NaN (every likelihood -inf) learns nothing, as a zero total does.
        if total.is_nan() || total <= 0.0 {
            return;
        }
        for (k, param) in Param::ALL.iter().enumerate() {
            // A bumped step says nothing about how far the command carries.
            if bumped && *param != Param::T {
                continue;
            }
            let qualities: Vec<Draw> = drawn
                .iter()
                .zip(&weights)
                .map(|(d, w)| Draw {
                    value: d.motion[k],
                    quality: w / total * information,
                })
                .collect();
            let learner = &mut self.learners[command.index()][k];
            learner.update(&qualities);
            *self.model.command_mut(command).param_mut(*param) = learner.mixture;
        }
    }

    /// Each particle's next pose by the improved proposal (see
    /// [`crate::proposal`]): matched from where its drawn step took it,
    /// drawn around the match; the particles stay where they are, so a
    /// step may be matched twice. With `turn_reach` (rad) above 0, each
    /// particle's search starts from the best of the turns within that
    /// reach of its drawn one, under a prior whose turn is as wide as the
    /// reach (see [`REMATCH_DROP_PER_BEAM`]).
    fn propose_by_matching(
        &mut self,
        command: Command,
        beams: &ScoredBeams,
        drawn: &[Drawn],
        turn_reach: f64,
    ) -> Matching {
        let model = self.model.command(command);
        let seeds: Vec<u64> = (0..self.particles.len())
            .map(|_| self.rng.random())
            .collect();
        // The search climbs on every other beam, counted twice: it only has
        // to find the peak, which half the beams place as well, at half
        // the cost of its 50-70 poses; the proposal around the peak, which
        // sets the particle's pose and weight, is scored with every beam.
        let search_beams = beams.every(MATCH_BEAM_STRIDE);
        let search_scale = beams.len() as f64 / search_beams.len().max(1) as f64;
        // Matched again, the search starts from the best of the turns
        // within reach of the drawn one.
        let turns = (turn_reach / REMATCH_STEP_RAD).round() as i32;
        let proposed: Vec<(Proposed, usize)> = self
            .particles
            .par_iter()
            .zip(drawn)
            .zip(seeds)
            .map(|((p, d), seed)| {
                let score = |pose: &Pose| BEAM_TEMPERING * beams.log_likelihood(&p.map, pose);
                let from = p.pose;
                // The particle's own stride guess: the learner judged the
                // draw as the model made it (`d.motion`); the particle
                // starts its search where its guess takes that motion.
                let prior = MotionPrior {
                    model,
                    stride_scale: p.stride_scale,
                    turn_scale: p.turn_scale,
                    turn_widening: turn_reach * turn_reach,
                };
                let [along, across, turn] = d.motion;
                let start = from.advanced(
                    p.stride_scale * along,
                    p.stride_scale * across,
                    p.turn_scale * turn,
                );
                // Each particle matches from its own draw: a model that is
                // still wrong puts its mean beyond the matcher's reach, and
                // the draws (the explorers' above all) keep the truth within it.
                let posterior = |pose: &Pose| {
                    search_scale * BEAM_TEMPERING * search_beams.log_likelihood(&p.map, pose)
                        + prior.log_density(&from, pose)
                };
                let (start, tried) = if turns > 0 {
                    let mut best = (start, posterior(&start));
                    for k in (-turns..=turns).filter(|&k| k != 0) {
                        let pose = start.advanced(0.0, 0.0, k as f64 * REMATCH_STEP_RAD);
                        let value = posterior(&pose);
                        if value > best.1 {
                            best = (pose, value);
                        }
                    }
                    (best.0, 2 * turns as usize + 1)
                } else {
                    (start, 0)
                };
                let (matched, _, scored) = match_scan(&posterior, start);
                let mut rng = StdRng::seed_from_u64(seed);
                let proposed = improved_proposal(&score, &prior, &from, matched, &mut rng);
                (proposed, scored + tried)
            })
            .collect();
        let searched: usize = proposed.iter().map(|(_, s)| s).sum();
        let probed = PROPOSAL_POSES_SCORED * proposed.len();
        let best_match = proposed
            .iter()
            .map(|(p, _)| p.scan_at_match)
            .fold(f64::NEG_INFINITY, f64::max);
        Matching {
            poses: proposed.iter().map(|(p, _)| p.pose).collect(),
            log_weights: proposed.iter().map(|(p, _)| p.log_weight).collect(),
            poses_scored: searched + probed,
            beam_evaluations: searched * search_beams.len() + probed * beams.len(),
            best_fit: best_match / beams.len().max(1) as f64,
        }
    }

    /// Multiplies the particles' weights by `exp(log_weights)` and
    /// normalises them; returns the effective sample size.
    fn reweigh(&mut self, log_weights: &[f64]) -> f64 {
        let n = self.particles.len();
        let best = log_weights
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        for (p, l) in self.particles.iter_mut().zip(log_weights) {
            p.weight *= (l - best).exp();
        }
        let total: f64 = self.particles.iter().map(|p| p.weight).sum();
        for p in &mut self.particles {
            p.weight = if total > 0.0 && total.is_finite() {
                p.weight / total
            } else {
                1.0 / n as f64
            };
        }
        1.0 / self
            .particles
            .iter()
            .map(|p| p.weight * p.weight)
            .sum::<f64>()
    }

    /// Low-variance resampling: one random offset, evenly spaced picks, so
    /// particles survive in proportion to their weight without needless loss.
    fn resample(&mut self) {
        self.resample_to(self.particles.len());
    }

    /// Draws `n` particles by weight (systematic resampling), each then
    /// weighing `1/n`.
    fn resample_to(&mut self, n: usize) {
        let held = self.particles.len();
        let step = 1.0 / n as f64;
        let mut target = self.rng.random::<f64>() * step;
        let mut cumulative = self.particles[0].weight;
        let mut i = 0;
        let mut next = Vec::with_capacity(n);
        for _ in 0..n {
            while target > cumulative && i + 1 < held {
                i += 1;
                cumulative += self.particles[i].weight;
            }
            let mut chosen = self.particles[i].clone();
            chosen.weight = step;
            next.push(chosen);
            target += step;
        }
        self.particles = next;
    }
}

/// How close to another robot a beam must end to be taken for a hit on it.
const BODY_REACH_M: f64 = 0.35;

/// Marks with NaN the ranges of beams that, seen from `pose`, end on one of
/// the robots `bodies` sweep (each from where it stood to where it stands
/// next): robots move, so they do not belong in the map.
pub fn mask_bodies(
    ranges: &mut [f64],
    pose: &Pose,
    sensor: &RangeSensor,
    bodies: impl Iterator<Item = [DVec2; 2]>,
) {
    let bodies: Vec<[DVec2; 2]> = bodies.collect();
    for (b, range) in ranges.iter_mut().enumerate() {
        if *range >= sensor.max_range {
            continue;
        }
        let end = beam_end(pose, sensor.bearing(b), *range);
        if bodies
            .iter()
            .any(|[from, to]| distance_to_segment(end, *from, *to) < BODY_REACH_M)
        {
            *range = f64::NAN;
        }
    }
}

/// How far `point` lies from the segment `from`-`to`.
fn distance_to_segment(point: DVec2, from: DVec2, to: DVec2) -> f64 {
    let along = to - from;
    let length_squared = along.length_squared();
    if length_squared == 0.0 {
        return point.distance(from);
    }
    let share = ((point - from).dot(along) / length_squared).clamp(0.0, 1.0);
    point.distance(from + along * share)
}

/// Where the swarm's robots stood, tick by tick, for [`mask_bodies`]: a
/// scan is masked with the robots where they stood at its tick and the
/// tick before ([`Bodies::others_at`] says why). A SLAM
/// process a second or two behind its robots (20 followed beside the
/// swarm on two cores) masked with where they stood then, half a metre on:
/// robots went into the map as walls and walls were masked as robots. A
/// robot silent for longer than `gone_after_ticks` has died or left: its
/// body is forgotten, or it would hide that spot of the map for ever.
#[derive(Debug)]
pub struct Bodies {
    positions: PositionsByTick,
    newest_tick: u64,
    gone_after_ticks: u64,
}

/// Ticks of each robot's positions kept: 13 s at 5 Hz, more than a SLAM
/// process trails its robots before it drops their scans.
const BODY_TICKS: usize = 64;

impl Bodies {
    pub fn new(gone_after_ticks: u64) -> Self {
        Self {
            positions: PositionsByTick::new(BODY_TICKS),
            newest_tick: 0,
            gone_after_ticks,
        }
    }

    pub fn saw(&mut self, id: u32, at: DVec2, tick: u64) {
        self.newest_tick = self.newest_tick.max(tick);
        self.positions.saw(id, tick, at);
    }

    /// Forgets the robots that fell silent.
    pub fn forget_gone(&mut self) {
        let since = self.newest_tick.saturating_sub(self.gone_after_ticks);
        self.positions.keep_seen_since(since);
    }

    /// Every robot's body but `id`'s as a scan of `tick` may have seen it:
    /// anywhere from where it stood at the tick before to where it stood at
    /// `tick` (each its newest position at or before that tick, or its
    /// oldest kept if all are newer). A robot scans after its step with its
    /// neighbours where it last heard of them: at the tick before in a
    /// swarm that steps together, at `tick` for one that stepped first.
    /// Masked only at `tick`, a neighbour a stride on from where the scan saw
    /// it went into the map as a wall; the map moved with the crowd and held
    /// robots metres off (a crowd of 20 followed offline, mean error over
    /// the last 10 s 1.27 m against 0.43 m masked where the scan saw them).
    pub fn others_at(&self, id: u32, tick: u64) -> impl Iterator<Item = [DVec2; 2]> + '_ {
        self.positions
            .robots()
            .filter(move |other| *other != id)
            .filter_map(move |other| {
                let now = self.positions.near(other, tick)?;
                let before = self.positions.near(other, tick.saturating_sub(1))?;
                Some([before, now])
            })
    }
}

/// Where each robot stood at each of its last few ticks: what SLAM masks
/// a scan with, and what a reader holds an estimate of a past tick against.
#[derive(Debug, Default)]
pub struct PositionsByTick {
    by_robot: BTreeMap<u32, BTreeMap<u64, DVec2>>,
    /// Ticks kept per robot, the newest.
    keep: usize,
}

impl PositionsByTick {
    pub fn new(keep: usize) -> Self {
        Self {
            by_robot: BTreeMap::new(),
            keep,
        }
    }

    pub fn saw(&mut self, id: u32, tick: u64, at: DVec2) {
        let ticks = self.by_robot.entry(id).or_default();
        ticks.insert(tick, at);
        while ticks.len() > self.keep {
            ticks.pop_first();
        }
    }

    /// Where robot `id` stood at `tick` exactly, if that tick is kept.
    pub fn at(&self, id: u32, tick: u64) -> Option<DVec2> {
        self.by_robot.get(&id)?.get(&tick).copied()
    }

    /// Where robot `id` stood at `tick`: its newest position at or before
    /// it, or its oldest kept if all are newer.
    pub fn near(&self, id: u32, tick: u64) -> Option<DVec2> {
        let ticks = self.by_robot.get(&id)?;
        ticks
            .range(..=tick)
            .next_back()
            .or_else(|| ticks.first_key_value())
            .map(|(_, at)| *at)
    }

    pub fn robots(&self) -> impl Iterator<Item = u32> + '_ {
        self.by_robot.keys().copied()
    }

    /// Forgets the robots last seen before `tick`.
    pub fn keep_seen_since(&mut self, tick: u64) {
        self.by_robot.retain(|_, ticks| {
            ticks
                .last_key_value()
                .is_some_and(|(newest, _)| *newest >= tick)
        });
    }
}

/// The beams a step scores with (every `score_stride`-th that returned a
/// range), and the share of those scored that returned: how much the
/// step knew.
fn scored_beams(ranges: &[f64], config: &FilterConfig, cell_size: f64) -> (ScoredBeams, f64) {
    let stride = config.score_stride.max(1);
    let scored = ranges.len().min(config.sensor.beams).div_ceil(stride);
    let beams = ScoredBeams::of_scan(ranges, &config.sensor, stride, cell_size);
    let information = if scored == 0 {
        0.0
    } else {
        beams.len() as f64 / scored as f64
    };
    (beams, information)
}

/// The beams a step maps with (every `stride`-th): where each ends in the
/// robot's frame, and whether it hit something. The same for every
/// particle, so computed once.
fn mapped_beams(ranges: &[f64], sensor: &RangeSensor, stride: usize) -> Vec<(DVec2, bool)> {
    (0..ranges.len().min(sensor.beams))
        .step_by(stride.max(1))
        .filter(|&b| !ranges[b].is_nan())
        .map(|b| {
            (
                DVec2::from_angle(sensor.bearing(b)) * ranges[b],
                ranges[b] < sensor.max_range,
            )
        })
        .collect()
}

/// Marks `beams` (from [`mapped_beams`]) into the particle's map from its pose.
fn integrate(particle: &mut Particle, beams: &[(DVec2, bool)]) {
    let (origin, heading) = (
        particle.pose.position(),
        DVec2::from_angle(particle.pose.theta),
    );
    for (local, hit) in beams {
        particle
            .map
            .integrate_beam(origin, origin + heading.rotate(*local), *hit);
    }
}

fn beam_end(pose: &Pose, bearing: f64, range: f64) -> DVec2 {
    pose.position() + DVec2::from_angle(pose.theta + bearing) * range
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_follow_what_the_sensor_can_tell_within_a_bounded_map() {
        let short = RangeSensor::default();
        assert!((short.max_range - 4.0).abs() < 1e-12 && (short.noise_per_m - 0.01).abs() < 1e-12);
        // 4 m beams, 2 cm of noise half way: the finest cell, in a room.
        assert_eq!(cell_for(&short, 6.0, 5.0), FINEST_CELL_M);
        // The demo's 10 m beams, 5 cm of noise half way.
        let long = RangeSensor {
            max_range: 10.0,
            ..short.clone()
        };
        assert!((cell_for(&long, 20.0, 20.0) - 0.05).abs() < 1e-12);
        // Short beams in a 12 x 12 m arena: 2.5 cm cells would make each
        // particle's map 2.2 times the budget; coarsened to it.
        let wide = cell_for(&short, 12.0, 12.0);
        assert!(wide > FINEST_CELL_M && wide < COARSEST_CELL_M, "{wide}");
        assert!((169.0 / (wide * wide) - MAX_MAP_CELLS).abs() < 1.0);
        // Never coarser than 5 cm, however large the arena (the demo's
        // default 20 x 20 m arena with 4 m beams stays on 5 cm).
        assert_eq!(cell_for(&short, 20.0, 20.0), COARSEST_CELL_M);
        assert_eq!(cell_for(&short, 500.0, 500.0), COARSEST_CELL_M);
        // A filter without a cell of its own takes the rule's; one given
        // keeps it.
        let start = Pose::new(1.0, 1.0, 0.0);
        let model = MotionModel::legged_default();
        let derived =
            ParticleFilter::new(start, model.clone(), FilterConfig::default(), 6.0, 5.0, 1);
        assert_eq!(derived.cell_size(), FINEST_CELL_M);
        let given = FilterConfig {
            cell_size: Some(0.1),
            ..FilterConfig::default()
        };
        assert_eq!(
            ParticleFilter::new(start, model, given, 6.0, 5.0, 1).cell_size(),
            0.1
        );
    }

    /// A robot that turns 0.9 rad further than its model's mean turn, in a
    /// room with a wall that breaks its symmetry: the scan no longer fits
    /// from where the model's turn led, the step is matched again from the
    /// turns the model does not reach, and the filter keeps the heading.
    /// An ordinary turn is matched once.
    #[test]
    fn a_turn_far_past_the_model_is_matched_again_from_turns_it_does_not_reach() {
        use shoal_physics::{Arena, Wall, wrap_angle};
        let arena = Arena {
            width: 5.0,
            height: 4.0,
            walls: vec![Wall {
                from: [3.0, 0.0],
                to: [3.0, 1.5],
            }],
            obstacles: vec![],
            surfaces: vec![],
        };
        let sensor = RangeSensor::default();
        let config = FilterConfig {
            sensor: sensor.clone(),
            learning: false,
            ..FilterConfig::default()
        };
        let model = MotionModel::legged_default();
        let mut truth = Pose::new(1.5, 2.0, 0.3);
        let mut filter = ParticleFilter::new(truth, model.clone(), config, 5.0, 4.0, 3);
        let mut rng = StdRng::seed_from_u64(4);
        let scan = |at: &Pose, rng: &mut StdRng| sensor.read(&arena, at, &[], 0.15, rng);
        filter.observe_start(&scan(&truth, &mut rng));
        let turn = Command::Turn(2);
        let mean_turn = model.mean(turn).turn;
        let mut step = |filter: &mut ParticleFilter, truth: &mut Pose, command, turned| {
            *truth = truth.advanced(0.0, 0.0, turned);
            let report = filter.step(command, false, &scan(truth, &mut rng));
            let off = wrap_angle(report.estimate.theta - truth.theta).abs();
            (report.rematched, off)
        };
        for _ in 0..5 {
            let (rematched, off) = step(&mut filter, &mut truth, Command::Stand, 0.0);
            assert!(!rematched && off < 0.05, "standing: {off} rad off");
        }
        let (rematched, off) = step(&mut filter, &mut truth, turn, mean_turn);
        assert!(!rematched && off < 0.05, "an ordinary turn: {off} rad off");
        let far = mean_turn + 0.9;
        let mut without = filter.clone();
        without.config.rematch = false;
        let mut truth_without = truth;
        let (rematched, off) = step(&mut filter, &mut truth, turn, far);
        assert!(
            rematched,
            "a turn 0.9 rad past the model was not matched again"
        );
        assert!(off < 0.05, "a turn 0.9 rad past the model: {off} rad off");
        // The same step on the same filter, not matched again: the heading
        // is lost (0.83 rad off when measured).
        let (rematched, off) = step(&mut without, &mut truth_without, turn, far);
        assert!(
            !rematched && off > 0.3,
            "without matching again: {off} rad off"
        );
    }

    /// A filter of 400 particles at `start`, on an arena `width` x 20 m,
    /// whose model has almost no noise of its own: its particles part only
    /// by their guesses. Returned with that model.
    fn guesses_alone(start: Pose, width: f64) -> (ParticleFilter, MotionModel) {
        let mut model = MotionModel::legged_default();
        for command in Command::ALL {
            for param in Param::ALL {
                let m = model.command_mut(command).param_mut(param);
                *m = shoal_physics::Mixture2::gaussian(m.mean(), 1e-4);
            }
        }
        let config = FilterConfig {
            particles: 400,
            ..FilterConfig::default()
        };
        let filter = ParticleFilter::new(start, model.clone(), config, width, 20.0, 5);
        (filter, model)
    }

    /// Coasts `filter` through `command` until it has taken `steps` steps.
    fn coast_to(filter: &mut ParticleFilter, command: Command, steps: u64) {
        while filter.steps < steps {
            filter.coast(command, false);
            filter.steps += 1;
        }
    }

    #[test]
    fn where_the_scan_says_nothing_particles_spread_in_heading_with_the_turns_made() {
        // As the strides' test below: the particles part only by their turn
        // guesses, held from step to step, so the spread in heading grows
        // with the angle turned (near the guesses' spread of it).
        let (mut filter, model) = guesses_alone(Pose::new(10.0, 10.0, 0.0), 20.0);
        let turn = model.mean(Command::Turn(1)).turn;
        let heading_spread = |filter: &ParticleFilter| {
            let (sin, cos) = filter.particles.iter().fold((0.0, 0.0), |(s, c), p| {
                (s + p.pose.theta.sin(), c + p.pose.theta.cos())
            });
            let mean = sin.atan2(cos);
            let squares: f64 = filter
                .particles
                .iter()
                .map(|p| {
                    (p.pose.theta - mean)
                        .sin()
                        .atan2((p.pose.theta - mean).cos())
                        .powi(2)
                })
                .sum();
            (squares / filter.particles.len() as f64).sqrt()
        };
        let mut spreads = Vec::new();
        for steps in [5, 12] {
            coast_to(&mut filter, Command::Turn(1), steps);
            spreads.push(heading_spread(&filter) / (steps as f64 * turn));
        }
        for share in &spreads {
            assert!(
                (0.05..0.1).contains(share),
                "spread a share of the angle turned: {spreads:?}"
            );
        }
    }

    #[test]
    fn where_the_scan_says_nothing_particles_spread_with_the_distance_walked() {
        // A model with almost no noise of its own, walked with no scan:
        // the particles part only by their stride guesses, which are held
        // from step to step, so the spread along the path grows with the
        // distance (a tenth to a sixth of it), not with its square root.
        let (mut filter, model) = guesses_alone(Pose::new(1.0, 10.0, 0.0), 60.0);
        let stride = model.mean(Command::Walk(3)).along;
        let along_spread = |filter: &ParticleFilter| {
            let xs: Vec<f64> = filter.particles.iter().map(|p| p.pose.x).collect();
            let mean = xs.iter().sum::<f64>() / xs.len() as f64;
            (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64).sqrt()
        };
        let mut spreads = Vec::new();
        for steps in [10, 40] {
            coast_to(&mut filter, Command::Walk(3), steps);
            spreads.push(along_spread(&filter) / (steps as f64 * stride));
        }
        for share in &spreads {
            assert!(
                (0.08..0.17).contains(share),
                "spread a share of the distance: {spreads:?}"
            );
        }
    }

    #[test]
    fn a_filter_resized_keeps_what_it_believes() {
        let start = Pose::new(1.0, 1.0, 0.0);
        let mut filter = ParticleFilter::new(
            start,
            MotionModel::legged_default(),
            FilterConfig::default(),
            6.0,
            5.0,
            3,
        );
        filter.coast(Command::ALL[1], false);
        // Unequal weights, as a step leaves them.
        let n = filter.particle_count();
        for (i, p) in filter.particles.iter_mut().enumerate() {
            p.weight = (i + 1) as f64 / (n * (n + 1) / 2) as f64;
        }
        let before = filter.estimate();
        let total = |f: &ParticleFilter| f.particles.iter().map(|p| p.weight).sum::<f64>();
        // Grown by splitting: the estimate and the weights' total stay.
        filter.resize(n + 7);
        assert_eq!(filter.particle_count(), n + 7);
        assert!((total(&filter) - 1.0).abs() < 1e-12);
        let grown = filter.estimate();
        assert!(grown.position().distance(before.position()) < 1e-12);
        assert!((grown.theta - before.theta).abs() < 1e-12);
        // Shrunk by drawing by weight: equal weights, every pose one the
        // filter held.
        let held: Vec<Pose> = filter.particles.iter().map(|p| p.pose).collect();
        filter.resize(10);
        assert_eq!(filter.particle_count(), 10);
        assert!((total(&filter) - 1.0).abs() < 1e-12);
        assert!(filter.particles.iter().all(|p| held.contains(&p.pose)));
        // Grown past twice its size in one go, and never below one.
        filter.resize(45);
        assert_eq!(filter.particle_count(), 45);
        filter.resize(0);
        assert_eq!(filter.particle_count(), 1);
    }

    #[test]
    fn the_body_of_a_robot_that_fell_silent_is_forgotten() {
        let mut bodies = Bodies::new(3);
        bodies.saw(1, DVec2::new(1.0, 1.0), 10);
        bodies.saw(2, DVec2::new(2.0, 2.0), 10);
        bodies.saw(2, DVec2::new(2.0, 2.5), 14);
        bodies.forget_gone();
        assert_eq!(
            bodies.others_at(9, 14).collect::<Vec<_>>(),
            vec![[DVec2::new(2.0, 2.0), DVec2::new(2.0, 2.5)]]
        );
        assert_eq!(bodies.others_at(2, 14).count(), 0);
    }

    #[test]
    fn a_scan_is_masked_with_the_robots_where_they_stood_at_its_tick() {
        let mut bodies = Bodies::new(100);
        for tick in 10..20 {
            bodies.saw(1, DVec2::new(tick as f64, 0.0), tick);
        }
        let at = |tick| bodies.others_at(0, tick).collect::<Vec<_>>();
        let x = |x| DVec2::new(x, 0.0);
        assert_eq!(
            at(12),
            vec![[x(11.0), x(12.0)]],
            "from the tick before to the tick"
        );
        assert_eq!(at(30), vec![[x(19.0), x(19.0)]], "the newest before");
        assert_eq!(at(3), vec![[x(10.0), x(10.0)]], "the oldest kept");
    }

    #[test]
    fn the_start_and_first_looks_are_mapped_with_every_beam_and_a_step_with_every_other() {
        // Three beams at -90, 0 and +90 degrees; only the middle one (odd,
        // so skipped by a map stride of 2) returns a range.
        let sensor = RangeSensor {
            beams: 3,
            ..RangeSensor::default()
        };
        let config = FilterConfig {
            particles: 2,
            map_stride: 2,
            learning: false,
            sensor: sensor.clone(),
            ..FilterConfig::default()
        };
        let mut filter = ParticleFilter::new(
            Pose::new(1.0, 3.0125, 0.0),
            MotionModel::legged_default(),
            config,
            6.0,
            6.0,
            0,
        );
        let occupied = |filter: &ParticleFilter, at: DVec2| {
            filter.particles.iter().all(|p| {
                let map = &p.map;
                map.occupancy(map.cell_of(at).expect("inside the map")) > 0.6
            })
        };
        let far = sensor.max_range;
        // The start's scan sees a wall 2 m ahead, another robot's first
        // look (from 2 m to the south) one 2 m ahead of it; each ends in a
        // cell's middle.
        filter.observe_start(&[far, 2.0, far]);
        filter.observe_from(Pose::new(1.0, 1.0125, 0.0), &[far, 2.0, far]);
        assert!(
            occupied(&filter, DVec2::new(3.0125, 3.0125)),
            "the start's beam 1"
        );
        assert!(
            occupied(&filter, DVec2::new(3.0125, 1.0125)),
            "the look's beam 1"
        );
        // A step (standing still, a few millimetres of noise) maps every
        // other beam, 0 and 2: beam 1's obstacle, 0.3 m ahead, is not mapped.
        filter.step(Command::Stand, false, &[far, 0.3, far]);
        assert!(
            !occupied(&filter, DVec2::new(1.3125, 3.0125)),
            "a step's beam 1"
        );
    }

    #[test]
    fn a_beam_ending_where_a_robot_stood_the_tick_before_is_masked() {
        let sensor = RangeSensor {
            beams: 3,
            ..RangeSensor::default()
        };
        // The beam ahead ends at (2, 0); the robot there walked a stride
        // to (2.1, 0.6) by the scan's tick, and another stood between two
        // spots either side of the beam at -90 degrees.
        let mut ranges = vec![1.0, 2.0, 3.0];
        let swept = [
            [DVec2::new(2.1, 0.0), DVec2::new(2.1, 0.6)],
            [DVec2::new(-0.5, -1.0), DVec2::new(0.5, -1.0)],
        ];
        mask_bodies(
            &mut ranges,
            &Pose::new(0.0, 0.0, 0.0),
            &sensor,
            swept.into_iter(),
        );
        assert!(ranges[1].is_nan(), "where it stood the tick before");
        assert!(ranges[0].is_nan(), "between where it stood and stands");
        assert_eq!(ranges[2], 3.0, "a beam ending far from both");
    }

    #[test]
    fn beams_ending_on_other_robots_are_masked() {
        let sensor = RangeSensor {
            beams: 3,
            ..RangeSensor::default()
        };
        // Beams at -90, 0 and +90 degrees from a robot at the origin facing +x.
        let mut ranges = vec![1.0, 2.0, sensor.max_range];
        mask_bodies(
            &mut ranges,
            &Pose::new(0.0, 0.0, 0.0),
            &sensor,
            [[DVec2::new(2.1, 0.0); 2]].into_iter(),
        );
        assert_eq!(ranges[0], 1.0);
        assert!(ranges[1].is_nan(), "the beam ahead ends 0.1 m from a robot");
        assert_eq!(ranges[2], sensor.max_range, "no return is left alone");
    }
}
