//! OptiTrack Motive's CSV export, as a lab's motion capture writes it:
//! a line of the take's settings, then rows naming each column's type
//! (`Rigid Body`, `Marker`, ...), its body, what it measures (`Rotation`,
//! `Position`) and its axis, then a frame a row, with empty cells where the
//! body was not tracked. Motive's world has Y up unless it was exported with
//! Z up, and a rigid body's axes are the world's when it was defined: the
//! ground plane and the heading are taken from the data, and said.

use crate::input::{Empty, Field, InputError, LineFinder, Read, number, poses_from, rows_of};
use crate::recording::Poses;

/// Whether `text` is a Motive export: its first line names the format.
pub fn looks_like_motive(text: &str) -> bool {
    text.trim_start_matches('\u{feff}')
        .starts_with("Format Version,")
}

/// How the export's rotations are written: Motive's setting `Rotation
/// Type`.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Rotation {
    /// Columns X, Y, Z, W.
    Quaternion,
    /// Columns X, Y, Z in degrees, composed in this order.
    Euler(glam::EulerRot, [usize; 3]),
}

impl Rotation {
    fn named(name: &str) -> Option<Self> {
        use glam::EulerRot::*;
        // The angle about each axis, in the order the rotation composes them.
        let (order, axes) = match name.to_ascii_uppercase().as_str() {
            "QUATERNION" => return Some(Self::Quaternion),
            "XYZ" => (XYZ, [0, 1, 2]),
            "XZY" => (XZY, [0, 2, 1]),
            "YXZ" => (YXZ, [1, 0, 2]),
            "YZX" => (YZX, [1, 2, 0]),
            "ZXY" => (ZXY, [2, 0, 1]),
            "ZYX" => (ZYX, [2, 1, 0]),
            _ => return None,
        };
        Some(Self::Euler(order, axes))
    }

    fn columns(self) -> &'static [&'static str] {
        match self {
            Self::Quaternion => &["X", "Y", "Z", "W"],
            Self::Euler(..) => &["X", "Y", "Z"],
        }
    }

    /// The rotation of a row's rotation fields, in Motive's world.
    fn of(self, fields: &[f64]) -> glam::DQuat {
        match self {
            Self::Quaternion => {
                glam::DQuat::from_xyzw(fields[0], fields[1], fields[2], fields[3]).normalize()
            }
            Self::Euler(order, [a, b, c]) => glam::DQuat::from_euler(
                order,
                fields[a].to_radians(),
                fields[b].to_radians(),
                fields[c].to_radians(),
            ),
        }
    }
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
    let error = |line: Option<usize>, message: String| InputError {
        file: file.to_owned(),
        line,
        message,
    };
    let text = text.trim_start_matches('\u{feff}');
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let mut records = reader.records();
    let mut lines = LineFinder::new(text);
    let mut next = || -> Result<Option<(usize, Vec<String>)>, InputError> {
        match records.next() {
            None => Ok(None),
            Some(Err(e)) => Err(error(lines.line_of(e.position()), format!("not CSV: {e}"))),
            Some(Ok(record)) => Ok(Some((
                lines.line_of(record.position()).unwrap_or(0),
                record.iter().map(str::to_owned).collect(),
            ))),
        }
    };
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
    let up = up_axis(&rows.rows);
    let planar = |row: &Vec<f64>| -> Option<[f64; 3]> {
        let p = glam::DVec3::new(row[1], row[2], row[3]) * to_metres;
        let q = rotation.of(&row[4..]);
        let (a, b) = up.plane();
        // The rigid body's first axis across the up axis: Motive defines
        // a body's axes as the world's, so it lies on the ground.
        let forward =
            [glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z][if up.index == 0 { 1 } else { 0 }];
        let pointing = q * forward;
        let heading = pointing.dot(b).atan2(pointing.dot(a));
        (q.is_finite() && heading.is_finite()).then_some([p.dot(a), p.dot(b), heading])
    };
    let mut not_rotations = Vec::new();
    let read = rows.read(file, |rows| {
        let mut kept = Vec::with_capacity(rows.len());
        for (line, row) in rows {
            match planar(&row) {
                Some([x, y, theta]) => kept.push((line, vec![row[0], x, y, theta])),
                None => not_rotations.push(line),
            }
        }
        poses_from(kept)
    })?;
    if let Some(&line) = not_rotations.first() {
        return Err(error(
            Some(line),
            format!(
                "the rotation of rigid body `{body}` is not a rotation (a quaternion of zero length)"
            ),
        ));
    }
    let others = if bodies.len() > 1 {
        format!(" (of {listed})")
    } else {
        String::new()
    };
    Ok((
        read,
        format!(
            "{file}: an OptiTrack Motive export (format {version}), rigid body `{body}`{others}; lengths in {unit}, rotations as {}; {}",
            match rotation {
                Rotation::Quaternion => "quaternions".to_owned(),
                Rotation::Euler(order, _) => format!("Euler angles in degrees ({order:?})"),
            },
            up.sentence(),
        ),
    ))
}

/// Which of Motive's axes is up, and how it was told.
struct Up {
    index: usize,
    /// Its positions' spread against the least of the other two's.
    spread_share: f64,
}

/// The axis along which a ground robot moves least: its height. Where no
/// axis stands out (a robot that hardly moved), Motive's default, Y.
fn up_axis(rows: &[(usize, Vec<f64>)]) -> Up {
    let spread = |k: usize| {
        let n = rows.len().max(1) as f64;
        let mean = rows.iter().map(|(_, r)| r[k]).sum::<f64>() / n;
        (rows.iter().map(|(_, r)| (r[k] - mean).powi(2)).sum::<f64>() / n).sqrt()
    };
    let spreads = [spread(1), spread(2), spread(3)];
    let least = (0..3)
        .min_by(|&a, &b| spreads[a].total_cmp(&spreads[b]))
        .unwrap_or(1);
    let next = (0..3)
        .filter(|&k| k != least)
        .map(|k| spreads[k])
        .fold(f64::INFINITY, f64::min);
    let spread_share = spreads[least] / next;
    // A height that varies a fifth as much as the floor's extent is no height.
    if spread_share.is_finite() && spread_share < 0.2 {
        Up {
            index: least,
            spread_share,
        }
    } else {
        Up {
            index: 1,
            spread_share: f64::NAN,
        }
    }
}

impl Up {
    /// The ground plane's x and y axes in Motive's world, right-handed
    /// about up: with Y up (Motive's default) x is X and y is -Z.
    fn plane(&self) -> (glam::DVec3, glam::DVec3) {
        use glam::DVec3;
        match self.index {
            0 => (DVec3::Y, DVec3::Z),
            1 => (DVec3::X, -DVec3::Z),
            _ => (DVec3::X, DVec3::Y),
        }
    }

    fn sentence(&self) -> String {
        let name = ["X", "Y", "Z"][self.index];
        let how = if self.spread_share.is_nan() {
            "no axis held the body's height apart from the floor's extent, so Motive's default"
                .to_owned()
        } else {
            format!(
                "the axis the body moved least along ({:.1}% of the least other)",
                100.0 * self.spread_share
            )
        };
        let (x, y, forward) = match self.index {
            0 => ("Y", "Z", "Y"),
            1 => ("X", "-Z", "X"),
            _ => ("X", "Y", "X"),
        };
        format!(
            "{name} up ({how}): x is Motive's {x}, y its {y}, the heading the rigid body's {forward} axis about {name}"
        )
    }
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
