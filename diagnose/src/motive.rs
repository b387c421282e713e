//! OptiTrack Motive's CSV export, as a lab's motion capture writes it:
//! a line of the take's settings, then rows naming each column's type
//! (`Rigid Body`, `Marker`, ...), its body, what it measures (`Rotation`,
//! `Position`) and its axis, then a frame a row, with empty cells where the
//! body was not tracked. Motive's world has Y up unless it was exported with
//! Z up: the ground plane is taken from the data (`mocap::on_the_ground`).

use crate::input::{Empty, Field, InputError, Read, number, rows_of};
use crate::mocap::{Records, Rotation, error_in, on_the_ground};
use crate::recording::Poses;

/// Whether `text` is a Motive export: its first line names the format.
pub fn looks_like_motive(text: &str) -> bool {
    text.trim_start_matches('\u{feff}')
        .starts_with("Format Version,")
}

/// The rigid bodies an export holds, by name, in the order of its columns.
fn rigid_bodies(types: &[String], names: &[String]) -> Vec<String> {
    let mut bodies: Vec<String> = Vec::new();
    for (kind, name) in types.iter().zip(names) {
        if kind.eq_ignore_ascii_case("Rigid Body") && !bodies.contains(name) {
            bodies.push(name.clone());
        }
    }
    bodies
}

/// The poses of rigid body `body` (the only one, where `None`) of a Motive
/// export, on the ground plane, and how they were read, in words.
pub fn poses_motive(
    text: &str,
    file: &str,
    body: Option<&str>,
) -> Result<(Read<Poses>, String), InputError> {
    let error = error_in(file);
    let mut records = Records::of(text, file);
    let mut next = || records.next();
    let Some((_, settings)) = next()? else {
        return Err(error(None, "is empty".to_owned()));
    };
    let setting = |key: &str| {
        settings
            .chunks(2)
            .find(|pair| pair[0].eq_ignore_ascii_case(key))
            .and_then(|pair| pair.get(1))
            .map(String::as_str)
    };
    let version = setting("Format Version").unwrap_or("?").to_owned();
    let rotation = match setting("Rotation Type") {
        None => Rotation::Quaternion,
        Some(name) => Rotation::named(name).ok_or_else(|| {
            error(
                Some(1),
                format!("Rotation Type `{name}` is not a quaternion or an order of Euler angles (XYZ, ..., ZYX)"),
            )
        })?,
    };
    let (to_metres, unit) = match setting("Length Units")
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        None | Some("meters") | Some("metres") => (1.0, "metres"),
        Some("centimeters") | Some("centimetres") => (1e-2, "centimetres"),
        Some("millimeters") | Some("millimetres") => (1e-3, "millimetres"),
        Some(other) => {
            return Err(error(
                Some(1),
                format!("Length Units `{other}` is not meters, centimeters or millimeters"),
            ));
        }
    };
    // The rows that name the columns, up to the one that starts `Frame`.
    let mut labelled: Vec<(usize, Vec<String>)> = Vec::new();
    let (frame_line, axes) = loop {
        let Some((line, cells)) = next()? else {
            return Err(error(
                None,
                "holds no row starting `Frame,Time (Seconds)` (a Motive export names its columns so)".to_owned(),
            ));
        };
        if cells
            .first()
            .is_some_and(|c| c.eq_ignore_ascii_case("Frame"))
        {
            break (line, cells);
        }
        labelled.push((line, cells));
    };
    let row_labelled = |label: &str| {
        labelled
            .iter()
            .find(|(_, cells)| cells.iter().take(2).any(|c| c.eq_ignore_ascii_case(label)))
            .map(|(_, cells)| cells.clone())
    };
    let (Some(types), Some(names)) = (row_labelled("Type"), row_labelled("Name")) else {
        return Err(error(
            Some(frame_line),
            "no `Type` and `Name` rows above the column names: which columns are a rigid body's is unknown".to_owned(),
        ));
    };
    // What each column measures: the row just above the axes.
    let measures = labelled
        .last()
        .map(|(_, cells)| cells.clone())
        .unwrap_or_default();
    let bodies = rigid_bodies(&types, &names);
    let listed = bodies
        .iter()
        .map(|b| format!("`{b}`"))
        .collect::<Vec<_>>()
        .join(", ");
    let body = match (body, bodies.as_slice()) {
        (_, []) => {
            return Err(error(
                Some(frame_line),
                "holds no rigid body (only markers): export the robot's rigid body".to_owned(),
            ));
        }
        (None, [only]) => only.clone(),
        (None, _) => {
            return Err(error(
                None,
                format!("holds rigid bodies {listed}: say which is the robot with --frame NAME"),
            ));
        }
        (Some(wanted), _) => bodies
            .iter()
            .find(|b| b.as_str() == wanted)
            .cloned()
            .ok_or_else(|| {
                error(
                    None,
                    format!("holds no rigid body `{wanted}`; it holds {listed}"),
                )
            })?,
    };
    let cell = |row: &[String], k: usize| row.get(k).map_or("", String::as_str).to_owned();
    let column = |measure: &str, axis: &str| {
        (0..axes.len()).find(|&k| {
            cell(&types, k).eq_ignore_ascii_case("Rigid Body")
                && cell(&names, k) == body
                && cell(&measures, k).eq_ignore_ascii_case(measure)
                && cell(&axes, k).eq_ignore_ascii_case(axis)
        })
    };
    let time = (0..axes.len())
        .find(|&k| cell(&axes, k).to_ascii_lowercase().starts_with("time"))
        .ok_or_else(|| error(Some(frame_line), "no `Time (Seconds)` column".to_owned()))?;
    let mut wanted = vec![(time, "Time (Seconds)".to_owned())];
    for (measure, axes) in [
        ("Position", &["X", "Y", "Z"][..]),
        ("Rotation", rotation.columns()),
    ] {
        for axis in axes {
            let k = column(measure, axis).ok_or_else(|| {
                error(
                    Some(frame_line),
                    format!("rigid body `{body}` has no {measure} {axis} column"),
                )
            })?;
            wanted.push((k, format!("{body} {measure} {axis}")));
        }
    }
    let names: Vec<&str> = wanted.iter().map(|(_, name)| name.as_str()).collect();
    let mut fields: Vec<(usize, Vec<Field>)> = Vec::new();
    while let Some((line, cells)) = next()? {
        if cells.iter().all(String::is_empty) {
            continue;
        }
        // A row shorter than the body's columns lost them: a frame where
        // nothing past them was tracked may be cut after its last value.
        let row = wanted
            .iter()
            .map(|(k, name)| number(cells.get(*k).map_or("", String::as_str), name))
            .collect();
        fields.push((line, row));
    }
    let rows = rows_of(text, file, &names, fields, Empty::Dropout)?;
    // Motive's world has Y up unless exported otherwise.
    let (read, up) = on_the_ground(rows, file, rotation, to_metres, 1, &body)?;
    let others = if bodies.len() > 1 {
        format!(" (of {listed})")
    } else {
        String::new()
    };
    Ok((
        read,
        format!(
            "{file}: an OptiTrack Motive export (format {version}), rigid body `{body}`{others}; lengths in {unit}, rotations as {}; {}",
            rotation.name(),
            up.sentence(),
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Motive 1.23 export of two rigid bodies with their markers, Y up,
    /// in millimetres; `robot` drives along -Z (its heading +90° on the
    /// ground plane) and is lost for a frame.
    fn export(rotation_type: &str, rotation: &[&str]) -> String {
        let mut text = format!(
            "Format Version,1.23,Take Name,Take 2026-11-30,Take Notes,,Capture Frame Rate,120.000000,Export Frame Rate,120.000000,Capture Start Time,2026-11-30 01.00.00.000 PM,Total Frames in Take,4,Total Exported Frames,4,Rotation Type,{rotation_type},Length Units,Millimeters,Coordinate Space,Global\r\n\r\n"
        );
        let n = rotation.len();
        let body = |name: &str| vec![name.to_owned(); n + 3];
        let row = |label: &str, cells: Vec<String>| format!(",{label},{}\r\n", cells.join(","));
        let mut types = vec!["Rigid Body".to_owned(); 2 * (n + 3)];
        types.extend(vec!["Rigid Body Marker".to_owned(); 3]);
        let mut names = body("other");
        names.extend(body("robot"));
        names.extend(vec!["robot:Marker1".to_owned(); 3]);
        let mut measures = vec!["Rotation".to_owned(); n];
        measures.extend(vec!["Position".to_owned(); 3]);
        let measures: Vec<String> =
            [measures.clone(), measures, vec!["Position".to_owned(); 3]].concat();
        let mut axes: Vec<String> = rotation.iter().map(|a| a.to_string()).collect();
        axes.extend(["X", "Y", "Z"].map(str::to_owned));
        let axes = [
            axes.clone(),
            axes,
            ["X", "Y", "Z"].map(str::to_owned).to_vec(),
        ]
        .concat();
        text += &row("Type", types);
        text += &row("Name", names);
        text += &row("ID", vec!["1".to_owned(); measures.len()]);
        text += &format!(",,{}\r\n", measures.join(","));
        text += &format!("Frame,Time (Seconds),{}\r\n", axes.join(","));
        text
    }

    #[test]
    fn a_rigid_body_of_a_motive_export_is_read_on_the_ground_plane_with_y_up() {
        // Turned +90° about Y: its X axis points along -Z, the plane's +y.
        let (s, c) = (
            std::f64::consts::FRAC_PI_4.sin(),
            std::f64::consts::FRAC_PI_4.cos(),
        );
        let mut text = export("Quaternion", &["X", "Y", "Z", "W"]);
        let other = "0,0,0,1,500,60,500";
        for (frame, z) in [(0, 0.0), (1, -10.0), (2, -20.0), (3, -30.0)] {
            let t = frame as f64 / 120.0;
            if frame == 2 {
                text += &format!("{frame},{t:.6},{other},,,,,,,,,,\r\n");
                continue;
            }
            text += &format!(
                "{frame},{t:.6},{other},0,{s},0,{c},{x},61.5,{z},1,2,3\r\n",
                x = 1000.0 + frame as f64 * 0.01,
            );
        }
        let (read, note) = poses_motive(&text, "take.csv", Some("robot")).expect("reads");
        let poses = read.data;
        assert_eq!(poses.len(), 3, "a frame without the body is a dropout");
        assert!(read.dropouts.is_some());
        assert!(
            (poses.x[1] - 1.0).abs() < 1e-3 && (poses.y[1] - 0.01).abs() < 1e-9,
            "{poses:?}"
        );
        assert!((poses.theta[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert!(
            note.contains("Y up") && note.contains("`robot` (of `other`, `robot`)"),
            "{note}"
        );
        let several = poses_motive(&text, "take.csv", None).expect_err("two bodies");
        assert!(several.message.contains("--frame"), "{several}");
        let none = poses_motive(&text, "take.csv", Some("robt")).expect_err("no such body");
        assert!(none.message.contains("`other`, `robot`"), "{none}");
    }

    #[test]
    fn euler_angles_and_a_cell_that_is_not_a_number_are_read_or_named() {
        let mut text = export("XYZ", &["X", "Y", "Z"]);
        for frame in 0..3 {
            text += &format!(
                "{frame},{:.6},0,0,0,0,0,0,0,-90,0,{},0,5,1,2,3\r\n",
                frame as f64 / 120.0,
                frame as f64 * 10.0
            );
        }
        let (read, _) = poses_motive(&text, "take.csv", Some("robot")).expect("reads");
        // -90° about Y: X turns to +Z, the plane's -y.
        assert!((read.data.theta[0] + std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        text += "3,0.025,0,0,0,0,0,0,0,x,0,30,0,5,1,2,3\r\n";
        let bad = poses_motive(&text, "take.csv", Some("robot")).expect_err("a letter");
        assert_eq!(bad.line, Some(11));
        assert!(bad.message.contains("robot Rotation Y"), "{bad}");
    }
}
