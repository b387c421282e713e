//! How a particle's next pose is drawn when the scan can say where the
//! robot went: GMapping's improved proposal (Grisetti, Stachniss and
//! Burgard, "Improved Techniques for Grid Mapping with Rao-Blackwellized
//! Particle Filters", 2007). The pose is scan-matched against the
//! particle's own map, the posterior around the match is approximated by a
//! Gaussian from a few poses scored by scan and motion model together, the
//! new pose is drawn from it, and the particle is weighted by that
//! Gaussian's normaliser. A motion-model proposal scatters particles over
//! the whole spread of a step and keeps the few the scan likes; this one
//! puts every particle where the scan and the motion agree, so a few
//! hundred hold a robot that the other needs thousands for. Pure logic.

use glam::DVec2;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use shoal_physics::legged::CommandModel;
use shoal_physics::range::RangeSensor;
use shoal_physics::{Mixture2, Pose};

use crate::grid::{TiledGrid, Tolerance};

/// Beams whose likelihoods are multiplied before one logarithm is taken.
const BEAMS_PER_LOG: usize = 200;

/// The returned beams of one scan as each particle scores them: where each
/// ends in the robot's frame, and how far off an obstacle it may end.
pub struct ScoredBeams {
    pub local_ends: Vec<DVec2>,
    pub tolerances: Vec<Tolerance>,
}

impl ScoredBeams {
    /// The beams of a scan that a step scores: every `stride`-th of
    /// `sensor`'s that returned a range. Where each beam ends in the
    /// robot's frame is the same for every particle: computed once, then
    /// turned by each particle's heading (the profile in BENCHMARKS.md,
    /// "SLAM", had a sine and cosine per particle and beam at 12% of the
    /// filter's time). The range noise grows with the range: so does how
    /// far off an obstacle a beam may end.
    pub fn of_scan(ranges: &[f64], sensor: &RangeSensor, stride: usize, cell_size: f64) -> Self {
        let returned: Vec<usize> = (0..ranges.len().min(sensor.beams))
            .step_by(stride.max(1))
            .filter(|&b| ranges[b] < sensor.max_range)
            .collect();
        Self {
            local_ends: returned
                .iter()
                .map(|&b| DVec2::from_angle(sensor.bearing(b)) * ranges[b])
                .collect(),
            tolerances: returned
                .iter()
                .map(|&b| Tolerance::new(sensor.noise_per_m * ranges[b], cell_size))
                .collect(),
        }
    }

    pub fn len(&self) -> usize {
        self.local_ends.len()
    }

    pub fn is_empty(&self) -> bool {
        self.local_ends.is_empty()
    }

    /// Every `stride`-th of these beams.
    pub fn every(&self, stride: usize) -> Self {
        let stride = stride.max(1);
        Self {
            local_ends: self.local_ends.iter().copied().step_by(stride).collect(),
            tolerances: self.tolerances.iter().cloned().step_by(stride).collect(),
        }
    }

    /// The scan's log-likelihood from `pose` in `map`: each beam as likely
    /// as an obstacle lies near its end, with a floor for beams that end in
    /// the open (a person, a robot, a reflection).
    pub fn log_likelihood(&self, map: &TiledGrid, pose: &Pose) -> f64 {
        let (origin, heading) = (pose.position(), DVec2::from_angle(pose.theta));
        let likelihoods = self
            .local_ends
            .iter()
            .zip(&self.tolerances)
            .map(|(local, tolerance)| {
                let end = origin + heading.rotate(*local);
                f64::from(0.05 + 0.9 * map.occupancy_within(end, tolerance))
            });
        // The logarithm of products of up to BEAMS_PER_LOG beams, each at
        // least 0.05 (0.05^200 is still a normal f64): one `ln` per chunk
        // instead of one per beam, which was a tenth of the filter's time.
        let mut sum = 0.0;
        let (mut product, mut count) = (1.0, 0);
        for likelihood in likelihoods {
            product *= likelihood;
            count += 1;
            if count == BEAMS_PER_LOG {
                sum += product.ln();
                (product, count) = (1.0, 0);
            }
        }
        sum + product.ln()
    }
}

/// The first steps of the matcher's search, and how many times it halves
/// them: a robot's step is a few centimetres and a few degrees off the
/// model's mean, within the first steps' reach; the last halving leaves a
/// fifth of a 5 cm cell.
const MATCH_STEP_M: f64 = 0.05;
const MATCH_STEP_RAD: f64 = 0.04;
const MATCH_HALVINGS: usize = 3;
/// At most this many moves per step size, so a match costs a bounded time.
const MATCH_MOVES_PER_STEP: usize = 3;

/// The matcher's moves at one step size (along, across, turn), in
/// opposite pairs: move `k ^ 1` undoes move `k`.
fn search_moves(linear: f64, angular: f64) -> [(f64, f64, f64); 6] {
    [
        (linear, 0.0, 0.0),
        (-linear, 0.0, 0.0),
        (0.0, linear, 0.0),
        (0.0, -linear, 0.0),
        (0.0, 0.0, angular),
        (0.0, 0.0, -angular),
    ]
}

/// Hill-climbs `start` to the pose from which `beams` best fit `map`
/// (coordinate ascent with halving steps, as GMapping's matcher): returns
/// the pose, its score and how many poses were scored.
pub fn match_scan(score: &impl Fn(&Pose) -> f64, start: Pose) -> (Pose, f64, usize) {
    let (mut best, mut best_score) = (start, score(&start));
    let mut scored = 1;
    let (mut linear, mut angular) = (MATCH_STEP_M, MATCH_STEP_RAD);
    for _ in 0..=MATCH_HALVINGS {
        // The move back along the one just taken leads to the pose left,
        // which scored less: it is not scored again (a sixth of the search
        // after each move).
        let mut came_by: Option<usize> = None;
        for _ in 0..MATCH_MOVES_PER_STEP {
            let back = came_by.map(|k| k ^ 1);
            let Some((taken, pose, value)) = search_moves(linear, angular)
                .iter()
                .enumerate()
                .filter(|(k, _)| Some(*k) != back)
                .map(|(k, (along, across, turn))| {
                    scored += 1;
                    let pose = best.advanced(*along, *across, *turn);
                    (k, pose, score(&pose))
                })
                .max_by(|a, b| a.2.total_cmp(&b.2))
            else {
                break;
            };
            if value <= best_score {
                break;
            }
            (best, best_score, came_by) = (pose, value, Some(taken));
        }
        linear /= 2.0;
        angular /= 2.0;
    }
    (best, best_score, scored)
}

/// The motion model's step as a Gaussian in a pose's frame: the moments of
/// each mixture. Widening it for a model still being learned (by a share
/// of each mean) was tried: the proposal then spread particles over half a
/// radian of heading wherever the scan was flat, and a crowd of 20 lost
/// its followed robot by metres; with a quarter of the mean it changed
/// nothing measurable. A wrong model is met by matching from each draw
/// (the explorers' among them) instead.
pub struct MotionPrior<'a> {
    pub model: &'a CommandModel,
    /// How much farther than the model this particle believes a step
    /// carries (along and across; see `filter::STRIDE_SCALE_SPREAD`).
    pub stride_scale: f64,
    /// How much farther than the model this particle believes a turn
    /// carries (see `filter::TURN_SCALE_SPREAD`).
    pub turn_scale: f64,
    /// Variance (rad^2) added to the model's turn: 0, but for a step whose
    /// scan no longer fits the map from where the model's turn leads (see
    /// `filter::RECOVERY_REACH_RAD`), where the model has just been shown
    /// wrong.
    pub turn_widening: f64,
}

impl MotionPrior<'_> {
    /// Log-density (up to a constant) of the step from `from` to `to`, as
    /// the Gaussian of [`MotionPrior::seen_from`]. The matcher climbs the
    /// scan's likelihood times this: on the scan alone, a crowd that hides
    /// all but a dozen beams let it slide a pose half a metre onto some
    /// other wall.
    pub fn log_density(&self, from: &Pose, to: &Pose) -> f64 {
        let (mean, variance) = self.seen_from(from, from);
        let step = to.relative_to(from);
        let floors = [MIN_SIGMA_M, MIN_SIGMA_M, MIN_SIGMA_RAD];
        [step.x, step.y, step.theta]
            .iter()
            .zip(mean)
            .zip(variance)
            .zip(floors)
            .map(|(((value, mean), variance), floor)| {
                -0.5 * (value - mean).powi(2) / variance.max(floor * floor)
            })
            .sum()
    }

    /// The model's step from `from`, seen from `at`: the offset of its mean
    /// (along, across, turn in `at`'s frame) and its variance on each axis
    /// (the along-across covariance turned into `at`'s frame, its diagonal
    /// kept).
    fn seen_from(&self, from: &Pose, at: &Pose) -> ([f64; 3], [f64; 3]) {
        let variance = |mixture: &Mixture2| mixture.variance();
        let (d, c, t) = (&self.model.d, &self.model.c, &self.model.t);
        let scale = self.stride_scale;
        let mean = from
            .advanced(
                scale * d.mean(),
                scale * c.mean(),
                self.turn_scale * t.mean(),
            )
            .relative_to(at);
        let (sin, cos) = (at.theta - from.theta).sin_cos();
        let (along, across) = (variance(d), variance(c));
        (
            [mean.x, mean.y, mean.theta],
            [
                cos * cos * along + sin * sin * across,
                sin * sin * along + cos * cos * across,
                variance(t) + self.turn_widening,
            ],
        )
    }
}

/// The steps over which the scan's slope and curvature are taken around
/// the match: a cell and about a degree.
const PROBE_M: f64 = 0.05;
const PROBE_RAD: f64 = 0.02;
/// The proposal's spread is never narrower than this, so a particle is
/// never certain past the map's resolution.
const MIN_SIGMA_M: f64 = 0.005;
const MIN_SIGMA_RAD: f64 = 0.003;

/// How many poses [`improved_proposal`] scores: the match and a step each
/// way on three axes.
pub const PROPOSAL_POSES_SCORED: usize = 7;

/// A pose drawn from the improved proposal, and the log of its normaliser
/// (the particle's weight update).
pub struct Proposed {
    pub pose: Pose,
    pub log_weight: f64,
    /// The scan's score at the match: how well the scan fits the map there.
    pub scan_at_match: f64,
}

/// Draws the particle's next pose from the Gaussian that `score` (the scan)
/// and `prior` (the motion from `from`) together give around `matched`.
/// On each axis of the matched pose's frame the scan's log-likelihood is
/// taken as a parabola (slope and curvature from a step each way, as
/// GMapping samples a few poses around the match) and the motion model as
/// a Gaussian; their product is the proposal, and its integral the weight.
/// Where the scan is flat (a corridor's length, walls the crowd hides) the
/// proposal is the motion model's: drawn from points around the match
/// alone, it would be a few centimetres wide there, and the particles
/// would agree on a position the scan never measured.
pub fn improved_proposal(
    score: &impl Fn(&Pose) -> f64,
    prior: &MotionPrior,
    from: &Pose,
    matched: Pose,
    rng: &mut impl Rng,
) -> Proposed {
    let here = score(&matched);
    let (prior_mean, prior_variance) = prior.seen_from(from, &matched);
    let mut offset = [0.0; 3];
    let mut log_weight = here;
    for axis in 0..3 {
        let h = if axis == 2 { PROBE_RAD } else { PROBE_M };
        let probe = |sign: f64| {
            let mut step = [0.0; 3];
            step[axis] = sign * h;
            score(&matched.advanced(step[0], step[1], step[2]))
        };
        let (ahead, behind) = (probe(1.0), probe(-1.0));
        // The parabola holds near the match only: the scan's own optimum
        // is kept within a probe of it, and a scan that does not curve
        // down there (flat, or the matcher stopped short on a slope) says
        // nothing on this axis. Extrapolated, a slope with no curvature
        // sent particles metres away.
        let curvature = ((2.0 * here - ahead - behind) / (h * h)).max(0.0);
        let slope = ((ahead - behind) / (2.0 * h)).clamp(-curvature * h, curvature * h);
        let floor = if axis == 2 {
            MIN_SIGMA_RAD
        } else {
            MIN_SIGMA_M
        };
        let prior_precision = 1.0 / prior_variance[axis].max(floor * floor);
        let m = prior_mean[axis];
        // exp(slope u - curvature u^2 / 2) N(u; m, 1 / p), integrated over u.
        let precision = curvature + prior_precision;
        let linear = slope + prior_precision * m;
        let mean = linear / precision;
        log_weight += 0.5 * (prior_precision / precision).ln() + 0.5 * linear * linear / precision
            - 0.5 * prior_precision * m * m;
        let sigma = (1.0 / precision).sqrt().max(floor);
        let z: f64 = StandardNormal.sample(rng);
        offset[axis] = mean + sigma * z;
    }
    Proposed {
        pose: matched.advanced(offset[0], offset[1], offset[2]),
        log_weight,
        scan_at_match: here,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    const HALF_SIDE: f64 = 1.775;

    /// A square room's walls, marked in a map, and a scan of them from `at`.
    fn room_and_scan(at: Pose) -> (TiledGrid, ScoredBeams) {
        let mut map = TiledGrid::new(4.0, 4.0, 0.05);
        let centre = DVec2::new(2.0, 2.0);
        let walls = |angle: f64| {
            // Distance from the centre to the square's wall, on the
            // middle of a row of cells (so the map holds it unbiased).
            let d = DVec2::from_angle(angle);
            centre + d * (HALF_SIDE / d.x.abs().max(d.y.abs()))
        };
        for k in 0..720 {
            let end = walls(k as f64 * std::f64::consts::TAU / 720.0);
            for _ in 0..4 {
                map.integrate_beam(centre, end, true);
            }
        }
        let mut local_ends = Vec::new();
        for k in 0..90 {
            let bearing = k as f64 * std::f64::consts::TAU / 90.0;
            // Ray from `at` to the wall: march until outside the square.
            let direction = DVec2::from_angle(at.theta + bearing);
            let mut range = 0.0;
            while (at.position() + direction * range - centre)
                .abs()
                .max_element()
                < 1.8
            {
                range += 0.005;
            }
            local_ends.push(DVec2::from_angle(bearing) * range);
        }
        let tolerances = local_ends
            .iter()
            .map(|_| Tolerance::new(0.03, 0.05))
            .collect();
        (
            map,
            ScoredBeams {
                local_ends,
                tolerances,
            },
        )
    }

    #[test]
    fn a_scans_log_likelihood_is_the_sum_of_its_beams_logs_past_a_chunk() {
        let at = Pose::new(1.7, 2.4, 0.3);
        let (map, one) = room_and_scan(at);
        // Five scans' beams at once: more than one chunk of BEAMS_PER_LOG,
        // off the pose so some beams end in the open.
        let beams = ScoredBeams {
            local_ends: one.local_ends.repeat(5),
            tolerances: (0..5)
                .flat_map(|_| one.tolerances.iter().cloned())
                .collect(),
        };
        assert!(beams.len() > BEAMS_PER_LOG);
        let off = at.advanced(0.04, 0.02, 0.03);
        let (origin, heading) = (off.position(), DVec2::from_angle(off.theta));
        let by_beam: f64 = beams
            .local_ends
            .iter()
            .zip(&beams.tolerances)
            .map(|(l, t)| {
                let end = origin + heading.rotate(*l);
                f64::from(0.05 + 0.9 * map.occupancy_within(end, t)).ln()
            })
            .sum();
        let chunked = beams.log_likelihood(&map, &off);
        assert!(
            (chunked - by_beam).abs() < 1e-9 * by_beam.abs(),
            "{chunked} against {by_beam}"
        );
    }

    #[test]
    fn the_matcher_finds_the_pose_a_scan_was_taken_from() {
        let truth = Pose::new(1.7, 2.4, 0.3);
        let (map, beams) = room_and_scan(truth);
        let score = |p: &Pose| beams.log_likelihood(&map, p);
        let (found, _, _) = match_scan(&score, truth.advanced(0.06, -0.05, 0.05));
        // Within a 5 cm cell of the truth: the map resolves no finer.
        assert!(
            found.position().distance(truth.position()) < 0.035
                && (found.theta - truth.theta).abs() < 0.02,
            "{found:?} against {truth:?}"
        );
    }

    /// The matcher as it was before it skipped the move back: every move
    /// of every round scored.
    fn match_scoring_every_move(score: &impl Fn(&Pose) -> f64, start: Pose) -> (Pose, usize) {
        let (mut best, mut best_score, mut scored) = (start, score(&start), 1);
        let (mut linear, mut angular) = (MATCH_STEP_M, MATCH_STEP_RAD);
        for _ in 0..=MATCH_HALVINGS {
            for _ in 0..MATCH_MOVES_PER_STEP {
                let moves = search_moves(linear, angular);
                scored += moves.len();
                let (pose, value) = moves
                    .iter()
                    .map(|(a, c, t)| {
                        let pose = best.advanced(*a, *c, *t);
                        (pose, score(&pose))
                    })
                    .max_by(|a, b| a.1.total_cmp(&b.1))
                    .expect("six moves");
                if value <= best_score {
                    break;
                }
                (best, best_score) = (pose, value);
            }
            linear /= 2.0;
            angular /= 2.0;
        }
        (best, scored)
    }

    #[test]
    fn the_matcher_skips_the_move_back_and_finds_what_scoring_every_move_finds() {
        use rand::Rng;
        let truth = Pose::new(1.7, 2.4, 0.3);
        let (map, beams) = room_and_scan(truth);
        let score = |p: &Pose| beams.log_likelihood(&map, p);
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let (mut skipping, mut every) = (0, 0);
        for _ in 0..50 {
            let start = truth.advanced(
                rng.random_range(-0.12..0.12),
                rng.random_range(-0.12..0.12),
                rng.random_range(-0.1..0.1),
            );
            let (found, _, scored) = match_scan(&score, start);
            let (reference, reference_scored) = match_scoring_every_move(&score, start);
            assert!(
                found.position().distance(reference.position()) < 1e-9
                    && (found.theta - reference.theta).abs() < 1e-9,
                "from {start:?}: {found:?} against {reference:?}"
            );
            skipping += scored;
            every += reference_scored;
        }
        assert!(
            skipping < every,
            "the move back is never scored: {skipping} poses against {every}"
        );
    }

    #[test]
    fn the_proposal_draws_near_the_match_and_weighs_by_how_well_scan_and_motion_agree() {
        let truth = Pose::new(1.7, 2.4, 0.3);
        let from = truth.advanced(-0.1, 0.0, 0.0);
        let (map, beams) = room_and_scan(truth);
        let score = |p: &Pose| 0.5 * beams.log_likelihood(&map, p);
        let agreeing = CommandModel {
            d: Mixture2::gaussian(0.1, 0.02),
            c: Mixture2::gaussian(0.0, 0.02),
            t: Mixture2::gaussian(0.0, 0.05),
        };
        let disagreeing = CommandModel {
            d: Mixture2::gaussian(1.0, 0.02),
            ..agreeing
        };
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let (matched, _, _) = match_scan(&score, from);
        let near = improved_proposal(
            &score,
            &MotionPrior {
                model: &agreeing,
                stride_scale: 1.0,
                turn_scale: 1.0,
                turn_widening: 0.0,
            },
            &from,
            matched,
            &mut rng,
        );
        let far = improved_proposal(
            &score,
            &MotionPrior {
                model: &disagreeing,
                stride_scale: 1.0,
                turn_scale: 1.0,
                turn_widening: 0.0,
            },
            &from,
            matched,
            &mut rng,
        );
        assert!(
            near.pose.position().distance(truth.position()) < 0.05,
            "{:?}",
            near.pose
        );
        assert!(
            near.log_weight > far.log_weight + 2.0,
            "a model that puts the step where the scan does weighs more: {} against {}",
            near.log_weight,
            far.log_weight
        );
    }
}
