//! fit.png: left, the observed path with the regions where an effect was
//! found; right, each held-out segment's position error over time with the
//! input model and with the fitted one. Text is drawn with DejaVu Sans,
//! embedded in the binary, so no fonts are needed on the machine.

use std::path::Path;
use std::sync::Once;

use anyhow::{Result, anyhow};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use shoal_diagnose::{Diagnosis, Recording};

/// The family name the embedded font is registered under.
const FONT: &str = "sans-serif";

fn register_embedded_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The bytes are a valid TrueType font shipped by the dejavu crate;
        // were they not, text would be missing, not the plot.
        let _ = register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

pub fn fit_png(path: &Path, recording: &Recording, diagnosis: &Diagnosis) -> Result<()> {
    register_embedded_font();
    let error = |e: &dyn std::fmt::Display| anyhow!("cannot draw {}: {e}", path.display());
    let root = BitMapBackend::new(path, (1400, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| error(&e))?;
    let root = root
        .titled(
            "shoal diagnose: where the model and the run differ, and the fit",
            (FONT, 24),
        )
        .map_err(|e| error(&e))?;
    let (left, right) = root.split_horizontally(640);
    draw_path(&left, recording, diagnosis).map_err(|e| error(&e))?;
    draw_errors(&right, diagnosis).map_err(|e| error(&e))?;
    root.present().map_err(|e| error(&e))?;
    Ok(())
}

/// Where the plot draws: the bitmap, in pixels.
type Area<'b> = DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>;

/// The left chart: the observed path and the regions where an effect was found.
fn draw_path(area: &Area, recording: &Recording, diagnosis: &Diagnosis) -> DrawResult {
    let p = &recording.poses;
    let bounds = |v: &[f64]| {
        let lo = v.iter().copied().fold(f64::MAX, f64::min);
        let hi = v.iter().copied().fold(f64::MIN, f64::max);
        let pad = ((hi - lo) * 0.05).max(0.1);
        (lo - pad)..(hi + pad)
    };
    let (xr, yr) = (bounds(&p.x), bounds(&p.y));
    let side = (xr.end - xr.start).max(yr.end - yr.start);
    let mut path_chart = ChartBuilder::on(area)
        .caption("Observed path and located regions", (FONT, 18))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(xr.start..xr.start + side, yr.start..yr.start + side)?;
    draw_axes(&mut path_chart, "x (m)", "y (m)")?;
    let zone_colour = RGBColor(255, 200, 120);
    let mut zone_labelled = false;
    for effect in &diagnosis.effects {
        if let Some([x0, y0, x1, y1]) = effect.place.region {
            let series = path_chart.draw_series(std::iter::once(Rectangle::new(
                [(x0, y0), (x1, y1)],
                zone_colour.filled(),
            )))?;
            if !zone_labelled {
                zone_labelled = true;
                series
                    .label(format!("region of {}", effect.kind))
                    .legend(move |(x, y)| {
                        Rectangle::new([(x, y - 5), (x + 16, y + 5)], zone_colour.filled())
                    });
            }
        }
    }
    path_chart
        .draw_series(LineSeries::new(
            p.x.iter().zip(&p.y).step_by(2).map(|(&x, &y)| (x, y)),
            BLACK.stroke_width(1),
        ))?
        .label("observed path")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK.stroke_width(2)));
    draw_legend(&mut path_chart)?;
    Ok(())
}

/// The right chart: each held-out segment's position error over time, with
/// the input model and with the fitted one.
fn draw_errors(area: &Area, diagnosis: &Diagnosis) -> DrawResult {
    let errors = &diagnosis.heldout_errors;
    let t_end = errors.last().map_or(1.0, |e| e.0).max(1.0);
    let e_max_mm = errors
        .iter()
        .map(|e| e.1.max(e.2))
        .fold(0.0, f64::max)
        .max(1e-6)
        * 1e3;
    let mut error_chart = ChartBuilder::on(area)
        .caption(
            format!(
                "Held-out {:.0} s prediction error: RMSE {:.1} -> {:.1} mm",
                diagnosis.horizon_s,
                diagnosis.baseline.heldout_rmse_pos_m * 1e3,
                diagnosis.improved.heldout_rmse_pos_m * 1e3
            ),
            (FONT, 18),
        )
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, 0.0..e_max_mm * 1.05)?;
    draw_axes(
        &mut error_chart,
        "time into the run (s)",
        "position error of the segment (mm)",
    )?;
    error_chart
        .draw_series(
            errors
                .iter()
                .map(|&(t, plain, _)| Circle::new((t, plain * 1e3), 2, RED.filled())),
        )?
        .label("input model")
        .legend(|(x, y)| Circle::new((x + 8, y), 4, RED.filled()));
    error_chart
        .draw_series(
            errors
                .iter()
                .map(|&(t, _, better)| Circle::new((t, better * 1e3), 2, BLUE.filled())),
        )?
        .label("with the effects found")
        .legend(|(x, y)| Circle::new((x + 8, y), 4, BLUE.filled()));
    draw_legend(&mut error_chart)?;
    Ok(())
}

/// Both charts plot metres or seconds against millimetres or metres.
type Chart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;
type DrawResult =
    Result<(), DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>>;

/// Axes with tick labels and their descriptions, no inner grid.
fn draw_axes<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>, x: &str, y: &str) -> DrawResult {
    chart
        .configure_mesh()
        .x_desc(x)
        .y_desc(y)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .light_line_style(WHITE.mix(0.0))
        .draw()
}

/// The legend of the series drawn with labels, top right.
fn draw_legend<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>) -> DrawResult {
    chart
        .configure_series_labels()
        .label_font((FONT, 13))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
}
