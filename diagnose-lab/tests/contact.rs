//! A stop while driving is set aside as contact (`glitches::set_aside`):
//! no generator's body ever meets a wall, so none of their runs may hold
//! one, whatever physics or noise they carry. Effects that stop or slow a
//! robot (a latency, an actuator lag, an acceleration limit, a top speed,
//! slip, a fading battery, a zone) are the body's, and are fitted.

use rayon::prelude::*;
use shoal_diagnose::glitches::{GlitchKind, set_aside};
use shoal_diagnose_lab::experiment::{Generator, NoiseColour, case_run, run_settings};
use shoal_diagnose_lab::generate::generate;
use shoal_physics::UnicycleModel;

const DURATION_S: f64 = 600.0;

#[test]
fn no_generators_run_is_taken_for_a_robot_held_in_place() {
    // Every case and a null run of every generator under every colour of
    // noise, two seeds: 750 runs. Seeds 1000-1002, 2000-2029 and 5000-5002
    // (13 500 runs) held none either (EXPERIMENTS.md 7).
    let mut runs = Vec::new();
    for seed in [1000, 2000] {
        for generator in Generator::all() {
            for noise in NoiseColour::all() {
                for case in generator.cases(DURATION_S) {
                    runs.push((generator.clone(), Some(case), noise.clone(), seed));
                }
                runs.push((generator.clone(), None, noise.clone(), seed));
            }
        }
    }
    let held: Vec<String> = runs
        .par_iter()
        .flat_map(|(generator, case, noise, seed)| {
            let seed = *seed;
            let run = match case {
                Some(case) => case_run(generator, case, noise, seed, DURATION_S),
                None => generate(
                    &UnicycleModel::plain(),
                    &run_settings(generator, None, noise, seed, DURATION_S),
                ),
            };
            let (_, glitches) = set_aside(&run);
            glitches
                .into_iter()
                .filter(|g| g.kind == GlitchKind::HeldInPlace)
                .map(|g| {
                    format!(
                        "{} {} {} seed {seed}: {:.1}-{:.1} s",
                        generator.name,
                        case.as_ref().map_or("null", |c| c.name),
                        noise.name,
                        g.t_start,
                        g.t_end
                    )
                })
                .collect::<Vec<_>>()
        })
        .collect();
    assert!(
        held.is_empty(),
        "{} of {} runs: {held:?}",
        held.len(),
        runs.len()
    );
}
