//! A motion-capture body's poses in 3-D, as its exports write them, on the
//! ground plane: which axis is up is taken from the data (a ground robot
//! moves least along its height), and the heading is where the body's first
//! axis across it points. A body's axes are the world's when it was defined,
//! so that axis need not be the robot's front: `track::driving_axis` turns
//! the headings by the quarter turns that make them so.

use crate::input::{InputError, LineFinder, Read, Rows, poses_from};
use crate::recording::Poses;

/// An export's CSV records (of any length, fields trimmed), each with the
/// line it starts on.
pub(crate) struct Records<'a> {
    records: csv::StringRecordsIntoIter<&'a [u8]>,
    lines: LineFinder<'a>,
    file: &'a str,
}

/// An error of `file`, at a line where one is known.
pub(crate) fn error_in(file: &str) -> impl Fn(Option<usize>, String) -> InputError + '_ {
    move |line, message| InputError {
        file: file.to_owned(),
        line,
        message,
    }
}

impl<'a> Records<'a> {
    /// `text`'s records, past a byte-order mark.
    pub(crate) fn of(text: &'a str, file: &'a str) -> Self {
        let text = text.trim_start_matches('\u{feff}');
        let reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        Self {
            records: reader.into_records(),
            lines: LineFinder::new(text),
            file,
        }
    }

    /// The next record and its line; none at the end.
    pub(crate) fn next(&mut self) -> Result<Option<(usize, Vec<String>)>, InputError> {
        match self.records.next() {
            None => Ok(None),
            Some(Err(e)) => Err(error_in(self.file)(
                self.lines.line_of(e.position()),
                format!("not CSV: {e}"),
            )),
            Some(Ok(record)) => Ok(Some((
                self.lines.line_of(record.position()).unwrap_or(0),
                record.iter().map(str::to_owned).collect(),
            ))),
        }
    }
}

/// How an export writes a body's rotation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Rotation {
    /// Columns X, Y, Z, W.
    Quaternion,
    /// Columns X, Y, Z in degrees, composed in this order.
    Euler(glam::EulerRot, [usize; 3]),
    /// Columns X, Y, Z: the rotation's axis scaled by its angle in
    /// degrees (Vicon's helical angles).
    Helical,
}

impl Rotation {
    /// Motive's setting `Rotation Type`.
    pub(crate) fn named(name: &str) -> Option<Self> {
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

    pub(crate) fn columns(self) -> &'static [&'static str] {
        match self {
            Self::Quaternion => &["X", "Y", "Z", "W"],
            Self::Euler(..) | Self::Helical => &["X", "Y", "Z"],
        }
    }

    pub(crate) fn name(self) -> String {
        match self {
            Self::Quaternion => "quaternions".to_owned(),
            Self::Euler(order, _) => format!("Euler angles in degrees ({order:?})"),
            Self::Helical => "helical angles in degrees".to_owned(),
        }
    }

    /// The rotation of a row's rotation fields, in the capture's world.
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
            Self::Helical => glam::DQuat::from_scaled_axis(
                glam::DVec3::new(fields[0], fields[1], fields[2]) * 1f64.to_radians(),
            ),
        }
    }
}

/// `rows` of a time, a position (X, Y, Z, in units `to_metres` makes
/// metres) and `rotation`'s fields, as poses on the ground plane, and which
/// axis was taken for up (`default_up` where none stands out).
pub(crate) fn on_the_ground(
    rows: Rows,
    file: &str,
    rotation: Rotation,
    to_metres: f64,
    default_up: usize,
    body: &str,
) -> Result<(Read<Poses>, Up), InputError> {
    let up = up_axis(&rows.rows, default_up);
    let (a, b) = up.plane();
    // The body's first axis across the up axis.
    let forward =
        [glam::DVec3::X, glam::DVec3::Y, glam::DVec3::Z][if up.index == 0 { 1 } else { 0 }];
    let planar = |row: &[f64]| -> Option<[f64; 3]> {
        let p = glam::DVec3::new(row[1], row[2], row[3]) * to_metres;
        let q = rotation.of(&row[4..]);
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
        return Err(error_in(file)(
            Some(line),
            format!("the rotation of `{body}` is not a rotation (a quaternion of zero length)"),
        ));
    }
    Ok((read, up))
}

/// Which of the capture's axes is up, and how it was told.
pub(crate) struct Up {
    index: usize,
    /// Its positions' spread against the least of the other two's.
    spread_share: f64,
}

/// The axis along which a ground robot moves least: its height. Where no
/// axis stands out (a robot that hardly moved), `default`.
fn up_axis(rows: &[(usize, Vec<f64>)], default: usize) -> Up {
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
            index: default,
            spread_share: f64::NAN,
        }
    }
}

impl Up {
    /// The ground plane's x and y axes in the capture's world,
    /// right-handed about up: with Y up (Motive's default) x is X and y
    /// is -Z.
    fn plane(&self) -> (glam::DVec3, glam::DVec3) {
        use glam::DVec3;
        match self.index {
            0 => (DVec3::Y, DVec3::Z),
            1 => (DVec3::X, -DVec3::Z),
            _ => (DVec3::X, DVec3::Y),
        }
    }

    pub(crate) fn sentence(&self) -> String {
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
            "{name} up ({how}): x is the capture's {x}, y its {y}, the heading the body's {forward} axis about {name}"
        )
    }
}
