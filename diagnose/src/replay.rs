//! The comparison diagnosis made, segment by segment, as something to look
//! at: where the input model and the fitted one predicted the robot would be
//! over each segment, and how far from the observed end each was.

use shoal_physics::{Pose, UnicycleModel};

use crate::likelihood::{Residual, traced_residuals};
use crate::prepared::{Options, Prepared, prepare};
use crate::recording::Recording;

/// One model's prediction over one segment.
#[derive(Clone, Debug, PartialEq)]
pub struct Prediction {
    /// Run seconds of each predicted pose.
    pub t: Vec<f64>,
    /// Predicted positions (m), the segment's observed start first.
    pub path: Vec<[f64; 2]>,
    /// Observed minus predicted at the end: along, across (m), heading (rad).
    pub residual: Residual,
}

/// One segment: the input model's prediction and the fitted model's.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentReplay {
    pub t_start: f64,
    pub t_end: f64,
    pub input: Prediction,
    pub fitted: Prediction,
}

/// Every segment diagnosis compared, predicted by `input` (the model the
/// user gave) and `fitted` (the model diagnosis wrote), from the same
/// observed starts diagnosis used ([`prepare`]).
pub fn replay(
    recording: &Recording,
    input: &UnicycleModel,
    fitted: &UnicycleModel,
    options: &Options,
) -> Vec<SegmentReplay> {
    let Prepared { grid, segments, .. } = prepare(recording, options);
    let predict = |model: &UnicycleModel| -> Vec<Prediction> {
        let mut predictions: Vec<Prediction> = segments
            .iter()
            .map(|s| Prediction {
                t: vec![s.t_start],
                path: vec![[s.start.x, s.start.y]],
                residual: [0.0; 3],
            })
            .collect();
        let residuals = traced_residuals(model, &grid, &segments, |index, step, pose: Pose| {
            if let Some(p) = predictions.get_mut(index) {
                p.t.push(grid.time(step) + grid.dt);
                p.path.push([pose.x, pose.y]);
            }
        });
        for (p, residual) in predictions.iter_mut().zip(residuals) {
            p.residual = residual;
        }
        predictions
    };
    predict(input)
        .into_iter()
        .zip(predict(fitted))
        .zip(&segments)
        .map(|((input, fitted), s)| SegmentReplay {
            t_start: s.t_start,
            t_end: s.t_end,
            input,
            fitted,
        })
        .collect()
}
