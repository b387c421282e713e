//! Vicon's CSV export (Nexus, Tracker), as a lab's motion capture writes
//! it: sections, each a name line (`Segments`, `Objects`, `Trajectories`,
//! ...), the capture's rate, a row naming each body over its columns, the
//! columns' names (`Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ`) and their units
//! (`deg`, `mm`), then a frame a row, with empty cells where the body was
//! not tracked. A body's pose is its section `Segments` (Nexus) or
//! `Objects` (Tracker): helical angles and a position. Vicon's world has Z
//! up; the ground plane is taken from the data (`mocap::on_the_ground`).

use crate::input::{Empty, Field, InputError, Read, number, rows_of};
use crate::mocap::{Records, Rotation, error_in, on_the_ground};
use crate::recording::Poses;

/// The sections that hold a body's pose.
const POSE_SECTIONS: [&str; 2] = ["Segments", "Objects"];

/// The sections a Vicon export may open with.
const SECTIONS: [&str; 7] = [
    "Segments",
    "Objects",
    "Trajectories",
    "Devices",
    "Joints",
    "Model Outputs",
    "Trajectory export",
];

/// Whether `text` is a Vicon export: its first line names a section.
pub fn looks_like_vicon(text: &str) -> bool {
    let first = text
        .trim_start_matches('\u{feff}')
        .lines()
        .next()
        .unwrap_or_default()
        .trim()
        .trim_end_matches(',');
    SECTIONS.iter().any(|s| s.eq_ignore_ascii_case(first))
}

/// The poses of body `body` (the only one, where `None`; a subject's name
/// or its segment's will do) of a Vicon export, on the ground plane, and
/// how they were read, in words.
pub fn poses_vicon(
    text: &str,
    file: &str,
    body: Option<&str>,
) -> Result<(Read<Poses>, String), InputError> {
    let error = error_in(file);
    let mut records = Records::of(text, file);
    let mut next = || records.next();
    let is_section = |cells: &[String]| {
        cells.iter().skip(1).all(String::is_empty)
            && cells
                .first()
                .is_some_and(|c| c.parse::<f64>().is_err() && !c.is_empty())
    };
    // Past the sections before the one with the bodies' poses.
    let section = loop {
        let Some((_, cells)) = next()? else {
            return Err(error(
                None,
                "holds no `Segments` or `Objects` section: export the subject's segments (Nexus) or the objects (Tracker)".to_owned(),
            ));
        };
        if is_section(&cells)
            && let Some(name) = POSE_SECTIONS
                .iter()
                .find(|s| s.eq_ignore_ascii_case(&cells[0]))
        {
            break *name;
        }
    };
    let mut header = |what: &str| -> Result<(usize, Vec<String>), InputError> {
        next()?.ok_or_else(|| {
            error(
                None,
                format!("the `{section}` section ends before its {what}"),
            )
        })
    };
    let (rate_line, rate) = header("rate")?;
    let rate: f64 = rate
        .first()
        .and_then(|r| r.parse().ok())
        .filter(|r: &f64| r.is_finite() && *r > 0.0)
        .ok_or_else(|| {
            error(
                Some(rate_line),
                format!("the `{section}` section's rate (frames a second) is not a positive number: `{}`", rate.first().map_or("", String::as_str)),
            )
        })?;
    let (_, names) = header("bodies' names")?;
    let (columns_line, columns) = header("columns' names")?;
    if !columns
        .first()
        .is_some_and(|c| c.eq_ignore_ascii_case("Frame"))
    {
        return Err(error(
            Some(columns_line),
            format!("the `{section}` section's columns do not start `Frame,Sub Frame`"),
        ));
    }
    let (_, units) = header("units")?;
    let cell = |row: &[String], k: usize| row.get(k).map_or("", String::as_str).to_owned();
    let bodies: Vec<(usize, String)> = (2..names.len())
        .filter(|&k| !names[k].is_empty())
        .map(|k| (k, names[k].clone()))
        .collect();
    let listed = bodies
        .iter()
        .map(|(_, b)| format!("`{b}`"))
        .collect::<Vec<_>>()
        .join(", ");
    let named =
        |wanted: &str, name: &str| name == wanted || name.split(':').any(|part| part == wanted);
    let chosen: Vec<&(usize, String)> = match body {
        None => bodies.iter().collect(),
        Some(wanted) => bodies
            .iter()
            .filter(|(_, name)| named(wanted, name))
            .collect(),
    };
    let &(start, ref name) = match (chosen.as_slice(), body) {
        ([only], _) => *only,
        ([], None) => {
            return Err(error(
                Some(columns_line),
                format!("the `{section}` section names no body"),
            ));
        }
        ([], Some(wanted)) => {
            return Err(error(
                None,
                format!("holds no body `{wanted}`; it holds {listed}"),
            ));
        }
        (_, None) => {
            return Err(error(
                None,
                format!("holds bodies {listed}: say which is the robot with --frame NAME"),
            ));
        }
        (_, Some(wanted)) => {
            return Err(error(
                None,
                format!(
                    "`{wanted}` names more than one of its bodies ({listed}): give the whole name"
                ),
            ));
        }
    };
    // The body's columns run from its name to the next body's.
    let end = bodies
        .iter()
        .map(|(k, _)| *k)
        .find(|&k| k > start)
        .unwrap_or(columns.len());
    let column = |label: &str| {
        (start..end)
            .find(|&k| cell(&columns, k).eq_ignore_ascii_case(label))
            .ok_or_else(|| {
                error(
                    Some(columns_line),
                    format!(
                        "body `{name}` has no column `{label}` (it has {})",
                        columns
                            .get(start..end.min(columns.len()))
                            .unwrap_or_default()
                            .join(", ")
                    ),
                )
            })
    };
    let wanted = [
        column("TX")?,
        column("TY")?,
        column("TZ")?,
        column("RX")?,
        column("RY")?,
        column("RZ")?,
    ];
    let unit_of = |k: usize| cell(&units, k).to_ascii_lowercase();
    let to_metres = match unit_of(wanted[0]).as_str() {
        "" | "mm" => 1e-3,
        "cm" => 1e-2,
        "m" => 1.0,
        other => {
            return Err(error(
                Some(columns_line + 1),
                format!("body `{name}`'s position is in `{other}`, not mm, cm or m"),
            ));
        }
    };
    let angle_scale = match unit_of(wanted[3]).as_str() {
        "" | "deg" => 1.0,
        "rad" => 1.0_f64.to_degrees(),
        other => {
            return Err(error(
                Some(columns_line + 1),
                format!("body `{name}`'s rotation is in `{other}`, not deg or rad"),
            ));
        }
    };
    let field_names: Vec<String> = ["Frame", "TX", "TY", "TZ", "RX", "RY", "RZ"]
        .iter()
        .map(|c| format!("{name} {c}"))
        .collect();
    let field_names: Vec<&str> = field_names.iter().map(String::as_str).collect();
    let mut fields: Vec<(usize, Vec<Field>)> = Vec::new();
    let mut first_frame = None;
    while let Some((line, cells)) = next()? {
        if cells.iter().all(String::is_empty) {
            continue;
        }
        if is_section(&cells) {
            break;
        }
        let frame = number(&cell(&cells, 0), field_names[0]);
        let frame = frame.map(|f| {
            let first = *first_frame.get_or_insert(f);
            (f - first) / rate
        });
        let mut row = vec![frame];
        for (j, &k) in wanted.iter().enumerate() {
            let value = number(&cell(&cells, k), field_names[j + 1]);
            row.push(if j >= 3 {
                value.map(|v| v * angle_scale)
            } else {
                value
            });
        }
        fields.push((line, row));
    }
    let rows = rows_of(text, file, &field_names, fields, Empty::Dropout)?;
    // Vicon's world has Z up.
    let (read, up) = on_the_ground(rows, file, Rotation::Helical, to_metres, 2, name)?;
    let others = if bodies.len() > 1 {
        format!(" (of {listed})")
    } else {
        String::new()
    };
    Ok((
        read,
        format!(
            "{file}: a Vicon export, section `{section}` at {rate} frames a second (times from its first frame), body `{name}`{others}; positions in {}, rotations as helical angles; {}",
            match to_metres {
                1.0 => "metres",
                0.01 => "centimetres",
                _ => "millimetres",
            },
            up.sentence(),
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Nexus export: a `Segments` section of two subjects, then a
    /// `Trajectories` section of markers; the robot turned +90° about Z
    /// and driving along +Y, lost for a frame.
    fn export() -> String {
        let mut text = String::from(
            "Segments\r\n100\r\n,,Dock:Dock,,,,,,Robot1:Robot1,,,,,\r\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\r\n,,deg,deg,deg,mm,mm,mm,deg,deg,deg,mm,mm,mm\r\n",
        );
        for frame in 1..=4 {
            let robot = if frame == 3 {
                ",,,,,".to_owned()
            } else {
                format!(
                    "0,0,90,{},{},85",
                    500.0 + f64::from(frame),
                    f64::from(frame) * 10.0
                )
            };
            text += &format!("{frame},0,0,0,0,100,200,90,{robot}\r\n");
        }
        text += "\r\nTrajectories\r\n100\r\n,,Robot1:M1,,\r\nFrame,Sub Frame,X,Y,Z\r\n,,mm,mm,mm\r\n1,0,1,2,3\r\n";
        text
    }

    #[test]
    fn a_body_of_a_vicon_export_is_read_on_the_ground_plane_with_z_up() {
        let text = export();
        assert!(looks_like_vicon(&text));
        let (read, note) = poses_vicon(&text, "trial.csv", Some("Robot1")).expect("reads");
        let poses = read.data;
        assert_eq!(poses.len(), 3, "a frame without the body is a dropout");
        assert!((poses.t[2] - 0.03).abs() < 1e-12, "{:?}", poses.t);
        assert!((poses.x[0] - 0.501).abs() < 1e-12 && (poses.y[0] - 0.01).abs() < 1e-12);
        assert!((poses.theta[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert!(
            note.contains("Z up") && note.contains("`Robot1:Robot1`"),
            "{note}"
        );
        let several = poses_vicon(&text, "trial.csv", None).expect_err("two bodies");
        assert!(
            several.message.contains("`Dock:Dock`, `Robot1:Robot1`"),
            "{several}"
        );
        let bad = text.replace("4,0,0,0,0,100", "4,0,0,0,0,1x0");
        let bad = poses_vicon(&bad, "trial.csv", Some("Dock")).expect_err("a letter");
        assert_eq!(bad.line, Some(9));
        assert!(bad.message.contains("Dock:Dock TX"), "{bad}");
        // A body named past the columns' row (the fuzzer's input 57 of
        // seed 1: it panicked slicing the columns).
        let short = "Segments\n100\n,,,,,,,,robot\nFrame,Sub Frame\n,,\n1,0\n2,0\n";
        let short = poses_vicon(short, "trial.csv", None).expect_err("no columns");
        assert_eq!(short.line, Some(4), "{short}");
        assert!(short.message.contains("no column `TX`"), "{short}");
    }
}
