//! `--rrd FILE`: the diagnosis as a Rerun recording. On the `time` timeline
//! (seconds into the run): the observed pose; at the end of each compared
//! segment, the observed path over it beside where the input model and the
//! fitted model predicted it, and the three residuals of each; the held-out
//! position errors. Static: the whole observed path, the located regions and
//! the fitted zones as boxes, the report as a document.

use std::path::Path;

use anyhow::{Context, Result};
use rerun::{Color, RecordingStream};
use shoal_diagnose::replay::{Prediction, SegmentReplay};
use shoal_diagnose::{Diagnosis, Recording};

const TIMELINE: &str = "time";
const OBSERVED: [u8; 3] = [30, 30, 30];
const WHOLE_PATH: [u8; 3] = [170, 170, 170];
const LOCATED: [u8; 3] = [255, 170, 60];
const ZONE: [u8; 3] = [70, 130, 230];

/// The two models every prediction and series is drawn for: entity name,
/// legend label, colour.
const MODELS: [(&str, &str, [u8; 3]); 2] = [
    ("input", "input model", [220, 50, 40]),
    ("fitted", "fitted model", [30, 150, 60]),
];

/// The residual series, in the order of a residual's components, with the
/// factor from metres or radians to their unit.
const RESIDUALS: [(&str, f64); 3] = [
    ("residuals/along_mm", 1e3),
    ("residuals/across_mm", 1e3),
    ("residuals/heading_deg", 180.0 / std::f64::consts::PI),
];
const HELDOUT: &str = "heldout/position_error_mm";

fn colour([r, g, b]: [u8; 3]) -> Color {
    Color::from_rgb(r, g, b)
}

/// Observed poses are logged at most this often: enough to follow the
/// robot, and a 10-minute run at 100 Hz stays a few megabytes.
const POSE_EVERY_S: f64 = 0.05;

/// Writes the recording to `path`; the caller renames it into place.
pub fn write(
    path: &Path,
    recording: &Recording,
    diagnosis: &Diagnosis,
    segments: &[SegmentReplay],
    report: &str,
) -> Result<()> {
    // Encoded in memory and written with one checked write: Rerun's file
    // sink writes on a thread of its own and reports a failed write (a full
    // disk) only as a writer that "shut down prematurely".
    let (rec, stored) = rerun::RecordingStreamBuilder::new("shoal-diagnose")
        .memory()
        .context("starting the diagnosis recording")?;
    log_all(&rec, recording, diagnosis, segments, report)
        .with_context(|| format!("cannot log the diagnosis for {}", path.display()))?;
    rec.flush_blocking()
        .with_context(|| format!("cannot finish {}", path.display()))?;
    let bytes = stored
        .drain_as_bytes()
        .with_context(|| format!("cannot encode {}", path.display()))?;
    std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))
}

fn log_all(
    rec: &RecordingStream,
    recording: &Recording,
    diagnosis: &Diagnosis,
    segments: &[SegmentReplay],
    report: &str,
) -> rerun::RecordingStreamResult<()> {
    rec.log_static(
        "diagnosis/report",
        &rerun::TextDocument::from_markdown(report),
    )?;
    log_regions(rec, diagnosis)?;
    log_series_styles(rec)?;
    log_glitches(rec, recording, diagnosis)?;

    let poses = &recording.poses;
    let path: Vec<[f32; 2]> = poses
        .x
        .iter()
        .zip(&poses.y)
        .map(|(&x, &y)| [x as f32, y as f32])
        .collect();
    rec.log_static(
        "world/observed/path",
        &rerun::LineStrips2D::new([path]).with_colors([colour(WHOLE_PATH)]),
    )?;
    let mut next_pose_t = f64::MIN;
    for i in 0..poses.t.len() {
        if poses.t[i] < next_pose_t {
            continue;
        }
        next_pose_t = poses.t[i] + POSE_EVERY_S;
        rec.set_duration_secs(TIMELINE, poses.t[i]);
        rec.log(
            "world/observed/pose",
            &rerun::Points2D::new([[poses.x[i] as f32, poses.y[i] as f32]])
                .with_colors([colour(OBSERVED)])
                .with_radii([0.03]),
        )?;
    }

    for segment in segments {
        rec.set_duration_secs(TIMELINE, segment.t_end);
        rec.log(
            "world/segment/observed",
            &rerun::LineStrips2D::new([observed_over(recording, segment)])
                .with_colors([colour(OBSERVED)]),
        )?;
        for ((name, _, rgb), prediction) in
            MODELS.into_iter().zip([&segment.input, &segment.fitted])
        {
            rec.log(
                format!("world/segment/{name}_model"),
                &rerun::LineStrips2D::new([strip(prediction)]).with_colors([colour(rgb)]),
            )?;
            for ((series, unit), value) in RESIDUALS.into_iter().zip(prediction.residual) {
                rec.log(
                    format!("{series}/{name}"),
                    &rerun::Scalars::new([value * unit]),
                )?;
            }
        }
    }
    for &(t, input, fitted) in &diagnosis.heldout_errors {
        rec.set_duration_secs(TIMELINE, t);
        for ((name, _, _), error_m) in MODELS.into_iter().zip([input, fitted]) {
            rec.log(
                format!("{HELDOUT}/{name}"),
                &rerun::Scalars::new([error_m * 1e3]),
            )?;
        }
    }
    Ok(())
}

/// Each plotted series is named and coloured once, so the viewer's legends
/// say which model a line belongs to.
fn log_series_styles(rec: &RecordingStream) -> rerun::RecordingStreamResult<()> {
    for parent in RESIDUALS
        .map(|(series, _)| series)
        .into_iter()
        .chain([HELDOUT])
    {
        for (name, label, rgb) in MODELS {
            rec.log_static(
                format!("{parent}/{name}"),
                &rerun::SeriesLines::new()
                    .with_names([label])
                    .with_colors([colour(rgb)]),
            )?;
        }
    }
    Ok(())
}

/// Located regions (where the input model's residuals differ) and the
/// regions of fitted effects, as labelled boxes.
fn log_regions(rec: &RecordingStream, diagnosis: &Diagnosis) -> rerun::RecordingStreamResult<()> {
    let located = diagnosis.located.iter().filter_map(|l| {
        l.region.map(|r| {
            (
                r,
                format!("{} residual differs (z {:.1})", l.component, l.z),
            )
        })
    });
    rec.log_static("world/located", &boxes(located, LOCATED))?;
    let zones = diagnosis
        .effects
        .iter()
        .filter_map(|e| e.place.region.map(|r| (r, e.kind.to_string())));
    rec.log_static("world/fitted_zones", &boxes(zones, ZONE))
}

/// Labelled boxes of `[x0, y0, x1, y1]` regions.
fn boxes(regions: impl Iterator<Item = ([f64; 4], String)>, rgb: [u8; 3]) -> rerun::Boxes2D {
    let (mut mins, mut sizes, mut labels) = (Vec::new(), Vec::new(), Vec::new());
    for (r, label) in regions {
        mins.push([r[0] as f32, r[1] as f32]);
        sizes.push([(r[2] - r[0]) as f32, (r[3] - r[1]) as f32]);
        labels.push(label);
    }
    rerun::Boxes2D::from_mins_and_sizes(mins, sizes)
        .with_labels(labels)
        .with_colors([colour(rgb)])
}

fn strip(prediction: &Prediction) -> Vec<[f32; 2]> {
    prediction
        .path
        .iter()
        .map(|&[x, y]| [x as f32, y as f32])
        .collect()
}

/// The observed positions within the segment's time span.
fn observed_over(recording: &Recording, segment: &SegmentReplay) -> Vec<[f32; 2]> {
    let p = &recording.poses;
    let first = p.t.partition_point(|&t| t < segment.t_start);
    let last = p.t.partition_point(|&t| t <= segment.t_end);
    (first..last)
        .map(|i| [p.x[i] as f32, p.y[i] as f32])
        .collect()
}

/// What was set aside as not the body's own motion: an event on the time timeline
/// where each stretch starts, and where the robot was then, in red.
fn log_glitches(
    rec: &RecordingStream,
    recording: &Recording,
    diagnosis: &Diagnosis,
) -> rerun::RecordingStreamResult<()> {
    for glitch in &diagnosis.glitches {
        rec.set_duration_secs(TIMELINE, glitch.t_start);
        rec.log(
            "diagnosis/set_aside",
            &rerun::TextLog::new(format!(
                "{:?} {:.2}-{:.2} s: {} frames set aside{}",
                glitch.kind,
                glitch.t_start,
                glitch.t_end,
                glitch.frames,
                match glitch.size_text() {
                    size if size.is_empty() => size,
                    size => format!(", {size}"),
                }
            ))
            .with_level(rerun::TextLogLevel::WARN),
        )?;
        if let Some(at) = recording.poses.at(glitch.t_start) {
            rec.log(
                "world/set_aside",
                &rerun::Points2D::new([[at.x as f32, at.y as f32]])
                    .with_colors([rerun::Color::from_rgb(230, 40, 40)])
                    .with_radii([0.05]),
            )?;
        }
    }
    Ok(())
}
