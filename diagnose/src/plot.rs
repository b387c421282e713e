//! fit.png: left, the observed path (black) with the regions where an effect
//! was found (orange); right, each held-out segment's position error over
//! time, plain model in red, improved model in blue. No text, so no fonts
//! are needed on the machine; the report says what the colours mean.

use std::path::Path;

use anyhow::{Result, anyhow};
use plotters::prelude::*;
use shoal_diagnose::{Diagnosis, Recording};

pub fn fit_png(path: &Path, recording: &Recording, diagnosis: &Diagnosis) -> Result<()> {
    let error = |e: &dyn std::fmt::Display| anyhow!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(path, (1200, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| error(&e))?;
    let (left, right) = root.split_horizontally(560);

    let p = &recording.poses;
    let bounds = |v: &[f64]| {
        let lo = v.iter().copied().fold(f64::MAX, f64::min);
        let hi = v.iter().copied().fold(f64::MIN, f64::max);
        let pad = ((hi - lo) * 0.05).max(0.1);
        (lo - pad)..(hi + pad)
    };
    let (xr, yr) = (bounds(&p.x), bounds(&p.y));
    let side = (xr.end - xr.start).max(yr.end - yr.start);
    let mut path_chart = ChartBuilder::on(&left.margin(20, 20, 20, 20))
        .build_cartesian_2d(xr.start..xr.start + side, yr.start..yr.start + side)
        .map_err(|e| error(&e))?;
    for effect in &diagnosis.effects {
        if let Some([x0, y0, x1, y1]) = effect.place.region {
            path_chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x0, y0), (x1, y1)],
                    RGBColor(255, 200, 120).filled(),
                )))
                .map_err(|e| error(&e))?;
        }
    }
    path_chart
        .draw_series(LineSeries::new(
            p.x.iter().zip(&p.y).step_by(2).map(|(&x, &y)| (x, y)),
            BLACK.stroke_width(1),
        ))
        .map_err(|e| error(&e))?;

    let errors = &diagnosis.heldout_errors;
    let t_end = errors.last().map_or(1.0, |e| e.0).max(1.0);
    let e_max = errors
        .iter()
        .map(|e| e.1.max(e.2))
        .fold(0.0, f64::max)
        .max(1e-6);
    let mut error_chart = ChartBuilder::on(&right.margin(20, 20, 20, 20))
        .build_cartesian_2d(0.0..t_end, 0.0..e_max * 1.05)
        .map_err(|e| error(&e))?;
    error_chart
        .draw_series(LineSeries::new(
            [(0.0, 0.0), (t_end, 0.0)],
            BLACK.stroke_width(1),
        ))
        .map_err(|e| error(&e))?;
    error_chart
        .draw_series(
            errors
                .iter()
                .map(|&(t, plain, _)| Circle::new((t, plain), 2, RED.filled())),
        )
        .map_err(|e| error(&e))?;
    error_chart
        .draw_series(
            errors
                .iter()
                .map(|&(t, _, better)| Circle::new((t, better), 2, BLUE.filled())),
        )
        .map_err(|e| error(&e))?;
    root.present().map_err(|e| error(&e))?;
    Ok(())
}
