//! Parsing the inputs of `shoal diagnose` from text: CSV files with named
//! columns and MRCLAM's whitespace-separated files. Every error names the
//! file and the line, so a user can open it and see what is wrong.

use crate::recording::{Commands, Poses};

#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{file}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct InputError {
    pub file: String,
    pub line: Option<usize>,
    pub message: String,
}

/// How the fields of a line are separated.
#[derive(Clone, Copy)]
enum Layout<'a> {
    /// Comma separated with a header naming the columns.
    Csv { columns: &'a [&'a str] },
    /// Whitespace separated, `#` comments, columns by position.
    Whitespace { columns: &'a [&'a str] },
}

/// What a row that holds no value in a column (empty, or NaN) is.
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Empty {
    /// A sample not taken: a motion capture that lost the body writes its
    /// frame's time with empty cells (OptiTrack's and Vicon's exports,
    /// pandas' NaN). Such a pose is a dropout, left out and said.
    Dropout,
    /// Refused at its line: a command row must say what was commanded.
    Refused,
}

/// Rows of numbers in the requested column order, with their line numbers,
/// in time order, and the rows that came out of it.
pub(crate) struct Rows {
    pub(crate) rows: Vec<(usize, Vec<f64>)>,
    /// Each row that came before a later time in the file: its line and
    /// how far (seconds) behind the latest time before it.
    out_of_order: Vec<(usize, f64)>,
    /// The lines of rows that held no value in some column ([`Empty::Dropout`]).
    dropouts: Vec<usize>,
    /// The time column's name.
    time: String,
}

/// The furthest a row's time may lie behind an earlier row's and still be
/// read as a logger's jitter (threads that write as they finish, a
/// message stamped before one logged ahead of it): such rows are sorted
/// into time order, and said so. A time further back is a clock reset or
/// two recordings joined, and is refused at its line.
const OUT_OF_ORDER_S: f64 = 0.5;

/// What a file held, in time order, and what reading it put in order or
/// left out.
#[derive(Debug)]
pub struct Read<T> {
    pub data: T,
    /// Rows that came out of time order and were sorted, in words; none
    /// where the file was in order.
    pub order: Option<String>,
    /// Rows left out as samples not taken (a pose with empty or NaN
    /// fields), in words; none where every row held its values.
    pub dropouts: Option<String>,
}

impl Rows {
    /// The rows made into `T` by `make`, with what reading put in order.
    pub(crate) fn read<T>(
        self,
        file: &str,
        make: impl FnOnce(Vec<(usize, Vec<f64>)>) -> Result<T, InputError>,
    ) -> Result<Read<T>, InputError> {
        let (order, dropouts) = (self.order_note(file), self.dropout_note(file));
        Ok(Read {
            data: make(self.rows)?,
            order,
            dropouts,
        })
    }

    /// What reading left out as samples not taken, in words, if anything.
    fn dropout_note(&self, file: &str) -> Option<String> {
        let first = self.dropouts.first()?;
        let rows = self.dropouts.len();
        Some(format!(
            "{file}: {rows} row{} without a pose (an empty or NaN field: the body was not tracked; the first at line {first}), left out as dropouts",
            if rows == 1 { "" } else { "s" },
        ))
    }

    /// What reading put in order, in words, if anything.
    fn order_note(&self, file: &str) -> Option<String> {
        let (&(first, _), most) = (
            self.out_of_order.first()?,
            self.out_of_order.iter().map(|r| r.1).fold(0.0, f64::max),
        );
        let rows = self.out_of_order.len();
        Some(format!(
            "{file}: {rows} row{} out of time order (the first at line {first}; at most {most:.3} s behind an earlier row), read sorted by `{}`",
            if rows == 1 { "" } else { "s" },
            self.time
        ))
    }
}

fn read_rows(text: &str, file: &str, layout: Layout, empty: Empty) -> Result<Rows, InputError> {
    let (columns, rows_of_fields) = match layout {
        Layout::Csv { columns } => (columns, csv_fields(text, file, columns)?),
        Layout::Whitespace { columns } => (columns, whitespace_fields(text, columns)),
    };
    rows_of(text, file, columns, rows_of_fields, empty)
}

/// The rows of `text`'s fields, read as `columns` (the first the time):
/// checked, with samples not taken set aside as `empty` says, in time order.
pub(crate) fn rows_of(
    text: &str,
    file: &str,
    columns: &[&str],
    rows_of_fields: Vec<(usize, Vec<Field>)>,
    empty: Empty,
) -> Result<Rows, InputError> {
    let error = |line: usize, message: String| InputError {
        file: file.to_owned(),
        line: Some(line),
        message,
    };
    // Many tools end a file without a newline: a last line that reads
    // whole is a row. One that does not is a file cut short, and is said so.
    let unterminated = (!text.is_empty() && !text.ends_with('\n')).then(|| text.lines().count());
    let error = |line: usize, message: String| {
        if Some(line) == unterminated {
            error(
                line,
                format!("the file ends in the middle of a line (was it cut short?): {message}"),
            )
        } else {
            error(line, message)
        }
    };
    let mut rows = Vec::new();
    let mut out_of_order = Vec::new();
    let mut dropouts = Vec::new();
    let mut latest = f64::NEG_INFINITY;
    for (number, fields) in rows_of_fields {
        let values = numbers(fields, columns).map_err(|message| error(number, message))?;
        if let Some(k) = values.iter().position(|v| v.is_nan()) {
            // A sample not taken still has its time; a row cut short (the
            // last, unterminated) is no dropout.
            if k == 0 || empty == Empty::Refused || Some(number) == unterminated {
                return Err(error(
                    number,
                    format!("field `{}` is empty or NaN", columns[k]),
                ));
            }
            dropouts.push(number);
            continue;
        }
        let first_time = rows
            .first()
            .map_or(values[0], |(_, r): &(usize, Vec<f64>)| r[0]);
        check_time(columns[0], values[0], latest, first_time)
            .map_err(|message| error(number, message))?;
        if values[0] < latest {
            out_of_order.push((number, latest - values[0]));
        }
        latest = latest.max(values[0]);
        rows.push((number, values));
    }
    if rows.len() < 2 {
        return Err(InputError {
            file: file.to_owned(),
            line: None,
            message: format!("needs at least two rows of data, found {}", rows.len()),
        });
    }
    // Stable: rows of one time keep the file's order.
    rows.sort_by(|a, b| a.1[0].total_cmp(&b.1[0]));
    Ok(Rows {
        rows,
        out_of_order,
        dropouts,
        time: columns[0].to_owned(),
    })
}

/// A field of a row, read as a number, or what is wrong with it.
pub(crate) type Field = Result<f64, String>;

/// A whitespace-separated file's fields, each row with its line number;
/// blank lines and `#` comments skipped.
fn whitespace_fields(text: &str, columns: &[&str]) -> Vec<(usize, Vec<Field>)> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
        .map(|(index, line)| {
            (
                index + 1,
                line.split_whitespace()
                    .zip(columns)
                    .map(|(field, column)| number(field, column))
                    .collect(),
            )
        })
        .collect()
}

/// `field` of `column` as a finite number, NaN where the row holds no value
/// there (an empty field, or NaN, as pandas and motion-capture exports
/// write a sample they do not have: [`read_rows`] decides what such a row
/// is), or what is wrong with it.
pub(crate) fn number(field: &str, column: &str) -> Field {
    if field.is_empty() || field.eq_ignore_ascii_case("nan") {
        return Ok(f64::NAN);
    }
    let value: f64 =
        decimal(field).ok_or_else(|| format!("field `{column}` is not a number: `{field}`"))?;
    if !value.is_finite() {
        return Err(format!("field `{column}` is not finite: `{field}`"));
    }
    Ok(value)
}

/// `field` as a number: written with a decimal point, or with the decimal
/// comma of a spreadsheet set to most of Europe's locales (`0,25`; a comma
/// inside a field is one only where the fields are separated otherwise,
/// or the field is quoted).
fn decimal(field: &str) -> Option<f64> {
    field.parse().ok().or_else(|| {
        (field.matches(',').count() == 1 && !field.contains('.'))
            .then(|| field.replace(',', ".").parse().ok())
            .flatten()
    })
}

/// A row's numbers, one per column, or the first thing wrong.
fn numbers(fields: Vec<Field>, columns: &[&str]) -> Result<Vec<f64>, String> {
    if let Some(column) = columns.get(fields.len()) {
        // A field the row lacks: the first column past those it has.
        fields.into_iter().collect::<Result<Vec<f64>, String>>()?;
        return Err(format!("missing field `{column}`"));
    }
    fields.into_iter().collect()
}

/// A row's time `t` (column `name`) no more than [`OUT_OF_ORDER_S`] behind
/// the latest before it and within [`MAX_SPAN_S`] of the first row's, or
/// what is wrong.
fn check_time(name: &str, t: f64, latest: f64, first_time: f64) -> Result<(), String> {
    if latest - t > OUT_OF_ORDER_S {
        return Err(format!(
            "times go back {:.3} s: `{name}` = {t} after {latest}; rows a little out of order (up to {OUT_OF_ORDER_S} s) are sorted, but this is a clock reset or two recordings joined: split the file there",
            latest - t
        ));
    }
    if t - first_time > MAX_SPAN_S {
        return Err(format!(
            "`{name}` = {t} is {:.0} s after the first row; runs longer than {} h are not diagnosed (a time in the wrong unit?)",
            t - first_time,
            MAX_SPAN_S / 3600.0
        ));
    }
    Ok(())
}

/// The line of each CSV record, from its byte offset. The reader's
/// positions are unreliable with CRLF and comments (they can point at the
/// previous record's line end, and its line count skips comments), so a
/// record's line is found past line ends and comment lines to where the
/// record's text starts. Records come in order, so counting on from the
/// previous one keeps this linear in the file's length.
pub(crate) struct LineFinder<'a> {
    bytes: &'a [u8],
    /// Byte counted up to, and the line number there.
    counted: (usize, usize),
}

impl<'a> LineFinder<'a> {
    pub(crate) fn new(text: &'a str) -> Self {
        Self {
            bytes: text.as_bytes(),
            counted: (0, 1),
        }
    }

    pub(crate) fn line_of(&mut self, position: Option<&csv::Position>) -> Option<usize> {
        let bytes = self.bytes;
        position.map(|p| {
            let mut at = (p.byte() as usize).clamp(self.counted.0, bytes.len());
            loop {
                while at < bytes.len() && matches!(bytes[at], b'\r' | b'\n') {
                    at += 1;
                }
                let line_start = at == 0 || bytes[at - 1] == b'\n';
                if at < bytes.len() && bytes[at] == b'#' && line_start {
                    at = bytes[at..]
                        .iter()
                        .position(|&b| b == b'\n')
                        .map_or(bytes.len(), |n| at + n + 1);
                    continue;
                }
                break;
            }
            self.counted.1 += bytes[self.counted.0..at]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            self.counted.0 = at;
            self.counted.1
        })
    }
}

/// A CSV file's fields in `columns`' order, each row with its line number:
/// the `csv` crate reads it (quoted fields, CRLF line ends, a UTF-8 byte
/// order mark), columns are found by the header's names, and lines that
/// start with `#` are comments.
fn csv_fields(
    text: &str,
    file: &str,
    columns: &[&str],
) -> Result<Vec<(usize, Vec<Field>)>, InputError> {
    let error = |line: Option<usize>, message: String| InputError {
        file: file.to_owned(),
        line,
        message,
    };
    let mut reader = csv_reader(text);
    let mut lines = LineFinder::new(text);
    let mut line_of = |position: Option<&csv::Position>| lines.line_of(position);
    let header = reader
        .headers()
        .map_err(|e| {
            error(
                line_of(e.position()),
                format!("cannot read the header: {e}"),
            )
        })?
        .clone();
    if header.is_empty() || header.iter().all(str::is_empty) {
        return Err(error(
            None,
            format!("empty file; expected a header `{}`", columns.join(",")),
        ));
    }
    let header_line = line_of(header.position()).unwrap_or(1);
    let mut positions = Vec::with_capacity(columns.len());
    for column in columns {
        let p = column_source(&header, column).map_err(|message| {
            error(
                Some(header_line),
                format!(
                    "{message}: the header must name {} (it names {})",
                    columns.join(", "),
                    header.iter().collect::<Vec<_>>().join(", ")
                ),
            )
        })?;
        positions.push(p);
    }
    let mut rows = Vec::new();
    let mut unit_read = columns.first() != Some(&"t");
    for record in reader.records() {
        let record =
            record.map_err(|e| error(line_of(e.position()), format!("not valid CSV: {e}")))?;
        let line = line_of(record.position()).unwrap_or(0);
        if record.iter().all(str::is_empty) {
            continue;
        }
        if !unit_read {
            positions[0] = scaled_by_size(positions[0], &record);
            unit_read = true;
        }
        // A field the row lacks stays missing, reported by name.
        let fields = positions
            .iter()
            .zip(columns)
            .map_while(|(source, column)| source.field(&record, column))
            .collect();
        rows.push((line, fields));
    }
    Ok(rows)
}

/// Other names tools give a column: PlotJuggler's `__time`,
/// `/cmd_vel/linear/x` and the yaw it adds beside a quaternion
/// (`/odom/pose/pose/orientation/yaw`), a ROS message's flattened fields
/// (`twist.angular.z`, `pose.position.x`, `pose.orientation.w`), `yaw`.
/// Compared with `.`, `_` and `/` taken as one separator and case ignored:
/// a name with a separator matches the end of a header's name, a single
/// word the whole of it.
fn aliases(column: &str) -> &'static [&'static str] {
    match column {
        "t" => &["time", "timestamp", "stamp", "time/s", "t/s"],
        "v" => &["linear/x", "vx", "v/x"],
        "omega" => &["angular/z", "wz", "w/z", "yaw/rate"],
        "x" => &["position/x", "translation/x"],
        "y" => &["position/y", "translation/y"],
        "theta" => &["yaw", "heading", "orientation/yaw"],
        "orientation.x" => &["orientation/x", "rotation/x", "qx"],
        "orientation.y" => &["orientation/y", "rotation/y", "qy"],
        "orientation.z" => &["orientation/z", "rotation/z", "qz"],
        "orientation.w" => &["orientation/w", "rotation/w", "qw"],
        "stamp.sec" => &["stamp/sec", "stamp/secs"],
        "stamp.nanosec" => &["stamp/nanosec", "stamp/nsecs"],
        _ => &[],
    }
}

/// Where a column's field is in each record.
#[derive(Clone, Copy)]
enum Source {
    Column(usize),
    /// A ROS header stamp's two integer fields, seconds and nanoseconds
    /// (`header.stamp.sec` and `.nanosec`; ROS 1's `secs` and `nsecs`),
    /// read as one time in seconds.
    Stamp {
        seconds: usize,
        nanoseconds: usize,
    },
    /// A time in integer nanoseconds: ROS 1's `rostopic echo -p` writes its
    /// `%time` so.
    Nanoseconds(usize),
    /// A quantity in another unit than Shoal's (seconds, metres, radians),
    /// said by the column's name (`timestamp_ns`, `yaw_deg`, `x [mm]`) or,
    /// for a time, by the size of its first value.
    Scaled {
        position: usize,
        unit: Unit,
    },
    /// A date and time (`2023-11-14 22:13:20.0111`, RFC 3339's
    /// `2023-11-14T22:13:20.0111Z`), as pandas writes a datetime index.
    DateTime(usize),
}

/// A date and time as seconds of Unix time: RFC 3339 (`T` or a space, `Z`
/// or an offset), or without an offset, taken as UTC (only differences
/// between times matter, and both files of a run are written alike).
fn unix_seconds(field: &str) -> Option<f64> {
    let seconds = |t: chrono::DateTime<chrono::Utc>| {
        t.timestamp() as f64 + f64::from(t.timestamp_subsec_nanos()) * 1e-9
    };
    if let Ok(t) = chrono::DateTime::parse_from_rfc3339(field) {
        return Some(seconds(t.to_utc()));
    }
    ["%Y-%m-%d %H:%M:%S%.f", "%Y-%m-%dT%H:%M:%S%.f"]
        .iter()
        .find_map(|format| chrono::NaiveDateTime::parse_from_str(field, format).ok())
        .map(|t| seconds(t.and_utc()))
}

/// A column's unit where it is not Shoal's: what one of it is in Shoal's
/// units (seconds, metres, radians and their rates), and its name.
/// Loggers, pandas and bag exports write Unix times in milliseconds,
/// microseconds or nanoseconds as often as in seconds, and headings in
/// degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unit {
    pub to_shoals: f64,
    pub name: &'static str,
}

const fn unit(to_shoals: f64, name: &'static str) -> Unit {
    Unit { to_shoals, name }
}

const SECONDS: Unit = unit(1.0, "seconds");
const MILLISECONDS: Unit = unit(1e-3, "milliseconds");
const MICROSECONDS: Unit = unit(1e-6, "microseconds");
const NANOSECONDS: Unit = unit(1e-9, "nanoseconds");
const RADIANS: Unit = unit(1.0, "radians");
const DEGREES: Unit = unit(std::f64::consts::PI / 180.0, "degrees");
const RADIANS_PER_SECOND: Unit = unit(1.0, "radians a second");
const DEGREES_PER_SECOND: Unit = unit(std::f64::consts::PI / 180.0, "degrees a second");
const METRES: Unit = unit(1.0, "metres");
const CENTIMETRES: Unit = unit(1e-2, "centimetres");
const MILLIMETRES: Unit = unit(1e-3, "millimetres");
const METRES_PER_SECOND: Unit = unit(1.0, "metres a second");
const MILLIMETRES_PER_SECOND: Unit = unit(1e-3, "millimetres a second");

impl Unit {
    /// The unit a header name ends with (`_ns`, `.deg`, ` [mm]`,
    /// `(deg/s)`) for Shoal's column `column`, and the name without it.
    fn of_name(column: &str, name: &str) -> Option<(Unit, String)> {
        let lower = name.to_lowercase();
        let words: Vec<&str> = lower
            .split(['.', '_', '-', ' ', '/', '[', ']', '(', ')'])
            .filter(|w| !w.is_empty())
            .collect();
        let suffixes: &[(&[&str], Unit)] = match column {
            "t" => &[
                (&["s"], SECONDS),
                (&["sec"], SECONDS),
                (&["ms"], MILLISECONDS),
                (&["msec"], MILLISECONDS),
                (&["us"], MICROSECONDS),
                (&["µs"], MICROSECONDS),
                (&["usec"], MICROSECONDS),
                (&["ns"], NANOSECONDS),
                (&["nsec"], NANOSECONDS),
            ],
            "theta" => &[
                (&["rad"], RADIANS),
                (&["deg"], DEGREES),
                (&["degrees"], DEGREES),
            ],
            "omega" => &[
                (&["rad", "s"], RADIANS_PER_SECOND),
                (&["deg", "s"], DEGREES_PER_SECOND),
                (&["dps"], DEGREES_PER_SECOND),
            ],
            "x" | "y" => &[
                (&["m"], METRES),
                (&["cm"], CENTIMETRES),
                (&["mm"], MILLIMETRES),
            ],
            "v" => &[
                (&["m", "s"], METRES_PER_SECOND),
                (&["mps"], METRES_PER_SECOND),
                (&["mm", "s"], MILLIMETRES_PER_SECOND),
            ],
            _ => &[],
        };
        suffixes.iter().find_map(|(suffix, unit)| {
            (words.len() > suffix.len() && words.ends_with(suffix))
                .then(|| (*unit, words[..words.len() - suffix.len()].join("_")))
        })
    }

    /// The unit of a Unix time as large as `first`: past 10^11 (the year
    /// 5138 in seconds) a time is in milliseconds, past 10^14 in
    /// microseconds, past 10^17 in nanoseconds. A run's time from its own
    /// start stays in seconds (and one past a day is refused as such).
    fn of_unix_time(first: f64) -> Option<Unit> {
        match first.abs() {
            t if t >= 1e17 => Some(NANOSECONDS),
            t if t >= 1e14 => Some(MICROSECONDS),
            t if t >= 1e11 => Some(MILLISECONDS),
            _ => None,
        }
    }
}

impl Source {
    /// The field of `column` in `record`, read as a number; none if the
    /// record is too short to hold it.
    fn field(&self, record: &csv::StringRecord, column: &str) -> Option<Field> {
        match *self {
            Source::Column(p) => record.get(p).map(|field| number(field, column)),
            Source::Stamp {
                seconds,
                nanoseconds,
            } => {
                let (s, ns) = (record.get(seconds)?, record.get(nanoseconds)?);
                Some(match (s.parse::<i64>(), ns.parse::<u32>()) {
                    (Ok(s), Ok(ns)) if ns < 1_000_000_000 => Ok(s as f64 + f64::from(ns) * 1e-9),
                    _ => Err(format!(
                        "the header stamp (`{column}`) is not whole seconds and nanoseconds below 10^9: `{s}` s, `{ns}` ns"
                    )),
                })
            }
            Source::Scaled { position, unit } => record
                .get(position)
                .map(|field| number(field, column).map(|value| value * unit.to_shoals)),
            Source::DateTime(p) => record.get(p).map(|field| {
                unix_seconds(field).ok_or_else(|| {
                    format!("field `{column}` is not a date and time as the first row's: `{field}`")
                })
            }),
            Source::Nanoseconds(p) => {
                let ns = record.get(p)?;
                Some(ns.parse::<i64>().map(|ns| ns as f64 / 1e9).map_err(|_| {
                    format!("field `{column}` (`%time`) is not whole nanoseconds: `{ns}`")
                }))
            }
        }
    }
}

/// Where `column`'s field is: the column itself; for the time `t` without
/// one, `rostopic echo -p`'s `%time` or a ROS header stamp's seconds and
/// nanoseconds; else a column named with its unit (`timestamp_ns`,
/// `yaw_deg`), read in that unit.
fn column_source(header: &csv::StringRecord, column: &str) -> Result<Source, String> {
    let found = column_position(header, column);
    if found.is_ok() {
        return found.map(Source::Column);
    }
    if column == "t" {
        if let Some(p) = header.iter().position(|name| name == "%time") {
            return Ok(Source::Nanoseconds(p));
        }
        if let (Ok(seconds), Ok(nanoseconds)) = (
            column_position(header, "stamp.sec"),
            column_position(header, "stamp.nanosec"),
        ) {
            return Ok(Source::Stamp {
                seconds,
                nanoseconds,
            });
        }
    }
    let units: Vec<Option<(Unit, String)>> = header
        .iter()
        .map(|name| Unit::of_name(column, name))
        .collect();
    let stems: csv::StringRecord = header
        .iter()
        .zip(&units)
        .map(|(name, unit)| unit.as_ref().map_or(name, |(_, stem)| stem.as_str()))
        .collect();
    match column_position(&stems, column) {
        Ok(position) => match units[position] {
            Some((unit, _)) => Ok(Source::Scaled { position, unit }),
            None => found.map(Source::Column),
        },
        Err(_) => found.map(Source::Column),
    }
}

/// A time column without a unit in its name, read as its first value
/// says: in the unit of a Unix time that size (`Unit::of_unix_time`),
/// or as dates and times.
fn scaled_by_size(source: Source, first: &csv::StringRecord) -> Source {
    let Source::Column(position) = source else {
        return source;
    };
    let Some(field) = first.get(position) else {
        return source;
    };
    match decimal(field).ok_or(()) {
        Ok(value) => match Unit::of_unix_time(value) {
            Some(unit) => Source::Scaled { position, unit },
            None => source,
        },
        Err(_) if unix_seconds(field).is_some() => Source::DateTime(position),
        Err(_) => source,
    }
}

/// How a CSV file's columns were read where not as written in Shoal's
/// units, one sentence each: for the report, since a unit chosen on the
/// user's behalf is said.
fn unit_notes(text: &str, file: &str, columns: &[&str]) -> Vec<String> {
    let mut reader = csv_reader(text);
    let Ok(header) = reader.headers().cloned() else {
        return Vec::new();
    };
    let Some(first) = reader
        .records()
        .filter_map(Result::ok)
        .find(|r| !r.iter().all(str::is_empty))
    else {
        return Vec::new();
    };
    let named = |p: usize| header.get(p).unwrap_or_default();
    columns
        .iter()
        .filter_map(|&column| {
            let source = column_source(&header, column).ok()?;
            let by_name = matches!(source, Source::Scaled { .. });
            let source = if column == "t" {
                scaled_by_size(source, &first)
            } else {
                source
            };
            match source {
                Source::DateTime(p) => Some(format!(
                    "{file}: `{}` read as dates and times (the first, `{}`; UTC where no offset is given)",
                    named(p),
                    first.get(p).unwrap_or_default()
                )),
                Source::Scaled { position, unit } if unit.to_shoals != 1.0 => {
                    let why = if by_name {
                        "as its name says".to_owned()
                    } else {
                        format!(
                            "its first value, {}, is a Unix time in {}",
                            first.get(position).unwrap_or_default(),
                            unit.name
                        )
                    };
                    Some(format!(
                        "{file}: `{}` read in {} ({why})",
                        named(position),
                        unit.name
                    ))
                }
                _ => None,
            }
        })
        .collect()
}

/// `unit_notes` for a commands CSV.
pub fn commands_unit_notes(text: &str, file: &str) -> Vec<String> {
    unit_notes(text, file, &COMMAND_COLUMNS)
}

/// `unit_notes` for a poses CSV.
pub fn poses_unit_notes(text: &str, file: &str) -> Vec<String> {
    unit_notes(text, file, &POSE_COLUMNS)
}

/// Where `column` is in `header`: by its own name, else by one of its
/// aliases if exactly one header name has one.
fn column_position(header: &csv::StringRecord, column: &str) -> Result<usize, String> {
    if let Some(p) = header.iter().position(|n| n == column) {
        return Ok(p);
    }
    let separated = |name: &str| name.to_lowercase().replace(['.', '_'], "/");
    let matches = |name: &str| {
        let name = separated(name);
        let name = name.trim_start_matches('/');
        aliases(column).iter().any(|alias| {
            name == *alias || (alias.contains('/') && name.ends_with(&format!("/{alias}")))
        })
    };
    let found: Vec<usize> = header
        .iter()
        .enumerate()
        .filter(|(_, name)| matches(name))
        .map(|(p, _)| p)
        .collect();
    match found[..] {
        [p] => Ok(p),
        [] => Err(format!("missing column `{column}`")),
        _ => Err(format!(
            "column `{column}` is ambiguous: {} could each be it",
            found
                .iter()
                .filter_map(|&p| header.get(p))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// A commands CSV's columns, and a poses CSV's (with a heading column).
const COMMAND_COLUMNS: [&str; 3] = ["t", "v", "omega"];
const POSE_COLUMNS: [&str; 4] = ["t", "x", "y", "theta"];

/// The longest run read: the command grid is sized from the time span, so a
/// stray time (1e10) must be an error, not an allocation of terabytes.
const MAX_SPAN_S: f64 = 24.0 * 3600.0;

fn commands_from(rows: Vec<(usize, Vec<f64>)>) -> Result<Commands, InputError> {
    let mut commands = Commands::default();
    for (_, row) in rows {
        commands.hold(row[0], row[1], row[2]);
    }
    Ok(commands)
}

pub(crate) fn poses_from(rows: Vec<(usize, Vec<f64>)>) -> Result<Poses, InputError> {
    let mut poses = Poses::default();
    for (_, row) in rows {
        poses.observe(row[0], row[1], row[2], row[3]);
    }
    Ok(poses)
}

/// A commands CSV: header `t,v,omega`.
pub fn commands_csv(text: &str, file: &str) -> Result<Read<Commands>, InputError> {
    read_rows(
        text,
        file,
        Layout::Csv {
            columns: &COMMAND_COLUMNS,
        },
        Empty::Refused,
    )?
    .read(file, commands_from)
}

/// A poses CSV: header `t,x,y,theta`. A pose exported from a ROS message
/// (a PoseStamped's or an Odometry's flattened fields) holds its heading as
/// a quaternion: without a heading column, the yaw of the columns
/// `orientation.x,orientation.y,orientation.z,orientation.w` (or their
/// aliases) is read. With neither, the file holds positions only (`t,x,y`),
/// and each heading is left NaN, for `track::headed` to take from the track.
pub fn poses_csv(text: &str, file: &str) -> Result<Read<Poses>, InputError> {
    let columns = POSE_COLUMNS;
    let quaternion = [
        "t",
        "x",
        "y",
        "orientation.x",
        "orientation.y",
        "orientation.z",
        "orientation.w",
    ];
    let header = csv_header(text);
    let lacks = |column: &str| {
        header
            .as_ref()
            .is_some_and(|header| column_source(header, column).is_err())
    };
    let names_quaternion = lacks("theta") && !lacks("orientation.z");
    if lacks("theta") && lacks("orientation.z") && !lacks("x") && !lacks("y") {
        // Positions only (a GPS, a tracked marker): each heading is taken
        // from the track once the run is cleaned (`track::headed`).
        return read_rows(
            text,
            file,
            Layout::Csv {
                columns: &POSE_COLUMNS[..3],
            },
            Empty::Dropout,
        )?
        .read(file, |rows| {
            poses_from(
                rows.into_iter()
                    .map(|(line, row)| (line, vec![row[0], row[1], row[2], f64::NAN]))
                    .collect(),
            )
        });
    }
    if !names_quaternion {
        return read_rows(
            text,
            file,
            Layout::Csv { columns: &columns },
            Empty::Dropout,
        )?
        .read(file, poses_from);
    }
    read_rows(
        text,
        file,
        Layout::Csv {
            columns: &quaternion,
        },
        Empty::Dropout,
    )?
    .read(file, |rows| {
        yawed(rows, file, 3, "orientation.x, .y, .z, .w")
    })
}

/// Poses from rows of a time, x, y and (from column `quaternion_at` on) a
/// quaternion x, y, z, w (`named` so), the heading its yaw.
fn yawed(
    rows: Vec<(usize, Vec<f64>)>,
    file: &str,
    quaternion_at: usize,
    named: &str,
) -> Result<Poses, InputError> {
    let mut yawed = Vec::with_capacity(rows.len());
    for (line, row) in rows {
        let q = &row[quaternion_at..quaternion_at + 4];
        let yaw =
            shoal_physics::yaw_of_quaternion(q[0], q[1], q[2], q[3]).map_err(|why| InputError {
                file: file.to_owned(),
                line: Some(line),
                message: format!("the orientation ({named}) is {why}"),
            })?;
        yawed.push((line, vec![row[0], row[1], row[2], yaw]));
    }
    poses_from(yawed)
}

/// A TUM trajectory, as evo and SLAM benchmarks keep one: `timestamp tx
/// ty tz qx qy qz qw` a line, separated by spaces, `#` comments, times in
/// seconds; the heading is the quaternion's yaw.
pub fn poses_tum(text: &str, file: &str) -> Result<Read<Poses>, InputError> {
    let columns = ["timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"];
    read_rows(
        text,
        file,
        Layout::Whitespace { columns: &columns },
        Empty::Dropout,
    )?
    .read(file, |rows| yawed(rows, file, 4, "qx qy qz qw"))
}

/// Whether `text` is a TUM trajectory rather than a CSV file: its first
/// line that is not a comment holds eight numbers separated by spaces.
pub fn looks_like_tum(text: &str) -> bool {
    text.lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .is_some_and(|line| {
            let fields: Vec<&str> = line.split_whitespace().collect();
            fields.len() == 8 && fields.iter().all(|f| f.parse::<f64>().is_ok())
        })
}

/// Poses from a CSV file or a TUM trajectory, whichever `text` is.
pub fn poses_csv_or_tum(text: &str, file: &str) -> Result<Read<Poses>, InputError> {
    if looks_like_tum(text) {
        poses_tum(text, file)
    } else {
        poses_csv(text, file)
    }
}

/// Poses from any file `--poses` takes: an OptiTrack Motive or a Vicon
/// export (its body `body`, or its only one), a TUM trajectory or a CSV file;
/// with how reading it decided what the columns mean, in words.
pub fn poses_file(
    text: &str,
    file: &str,
    body: Option<&str>,
) -> Result<(Read<Poses>, Vec<String>), InputError> {
    if crate::motive::looks_like_motive(text) {
        let (read, note) = crate::motive::poses_motive(text, file, body)?;
        return Ok((read, vec![note]));
    }
    if crate::vicon::looks_like_vicon(text) {
        let (read, note) = crate::vicon::poses_vicon(text, file, body)?;
        return Ok((read, vec![note]));
    }
    Ok((poses_csv_or_tum(text, file)?, poses_unit_notes(text, file)))
}

/// The header of a CSV file as `csv_fields` reads it, if it has one.
fn csv_header(text: &str) -> Option<csv::StringRecord> {
    csv_reader(text).headers().ok().cloned()
}

/// How every CSV file is read: fields trimmed, `#` lines comments, rows of
/// any length (a field a row lacks is reported by name), separated as the
/// header is ([`delimiter`]).
fn csv_reader(text: &str) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new()
        .delimiter(delimiter(text))
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .flexible(true)
        .from_reader(text.as_bytes())
}

/// What a CSV file separates its fields with: of a comma, the semicolon a
/// spreadsheet with a decimal comma writes (Excel in most of Europe,
/// pandas' `sep=';'`) and a tab, the one its header holds most of outside
/// quotes; a comma where it holds none.
fn delimiter(text: &str) -> u8 {
    let header = text
        .trim_start_matches('\u{feff}')
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .unwrap_or_default();
    let mut quoted = false;
    let mut counts = [0usize; 3];
    const CANDIDATES: [u8; 3] = [b',', b';', b'\t'];
    for byte in header.bytes() {
        match byte {
            b'"' => quoted = !quoted,
            _ if quoted => {}
            _ => {
                if let Some(k) = CANDIDATES.iter().position(|&c| c == byte) {
                    counts[k] += 1;
                }
            }
        }
    }
    // Ties go to the earlier candidate: a comma first.
    let (best, most) =
        counts.iter().enumerate().fold(
            (0, 0),
            |(best, most), (k, &n)| if n > most { (k, n) } else { (best, most) },
        );
    if most == 0 { b',' } else { CANDIDATES[best] }
}

/// MRCLAM `Robot{n}_Odometry.dat`: time, v, omega (the commands sent).
pub fn mrclam_odometry(text: &str, file: &str) -> Result<Read<Commands>, InputError> {
    let columns = ["time", "forward velocity", "angular velocity"];
    read_rows(
        text,
        file,
        Layout::Whitespace { columns: &columns },
        Empty::Refused,
    )?
    .read(file, commands_from)
}

/// MRCLAM `Robot{n}_Groundtruth.dat`: time, x, y, orientation (motion capture).
pub fn mrclam_groundtruth(text: &str, file: &str) -> Result<Read<Poses>, InputError> {
    let columns = ["time", "x", "y", "orientation"];
    read_rows(
        text,
        file,
        Layout::Whitespace { columns: &columns },
        Empty::Dropout,
    )?
    .read(file, poses_from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_are_found_by_name() {
        let commands = commands_csv("omega,t,v\n0.1,0,0.2\n0.2,1,0.3\n", "c.csv").expect("valid");
        assert_eq!(commands.data.t, vec![0.0, 1.0]);
        assert_eq!(commands.data.v, vec![0.2, 0.3]);
        assert_eq!(commands.data.omega, vec![0.1, 0.2]);
    }

    #[test]
    fn columns_are_found_by_the_names_other_tools_give_them() {
        // PlotJuggler's CSV export of /cmd_vel.
        let commands = commands_csv(
            "__time,/cmd_vel/linear/x,/cmd_vel/linear/y,/cmd_vel/angular/z\n0,0.2,0,0.1\n1,0.3,0,0.2\n",
            "c.csv",
        )
        .expect("PlotJuggler");
        assert_eq!(commands.data.v, vec![0.2, 0.3]);
        assert_eq!(commands.data.omega, vec![0.1, 0.2]);
        // A message's flattened fields, and a pose's yaw.
        let commands = commands_csv(
            "timestamp,twist.linear.x,twist.angular.z\n0,0.2,0.1\n1,0.2,0.1\n",
            "c.csv",
        )
        .expect("flattened");
        assert_eq!((commands.data.v[0], commands.data.omega[0]), (0.2, 0.1));
        let poses = poses_csv(
            "time,pose.position.x,pose.position.y,yaw\n0,1,2,0.5\n1,1.1,2,0.5\n",
            "p.csv",
        )
        .expect("flattened pose");
        assert_eq!(
            (poses.data.x[0], poses.data.y[0], poses.data.theta[0]),
            (1.0, 2.0, 0.5)
        );
        // An Odometry's flattened fields: the heading as a quaternion.
        let (s, c) = (0.25_f64.sin(), 0.25_f64.cos());
        let poses = poses_csv(
            &format!(
                "time,pose.pose.position.x,pose.pose.position.y,pose.pose.orientation.x,\
                 pose.pose.orientation.y,pose.pose.orientation.z,pose.pose.orientation.w\n\
                 0,1,2,0,0,{s},{c}\n1,1.1,2,0,0,{s},{c}\n"
            ),
            "odom.csv",
        )
        .expect("a quaternion");
        assert!(
            (poses.data.theta[0] - 0.5).abs() < 1e-12,
            "{}",
            poses.data.theta[0]
        );
        // PlotJuggler's export of /odom, with the yaw it adds.
        let poses = poses_csv(
            "__time,/odom/pose/pose/position/x,/odom/pose/pose/position/y,/odom/pose/pose/orientation/z,\
             /odom/pose/pose/orientation/w,/odom/pose/pose/orientation/yaw\n0,1,2,0,1,0.3\n1,1,2,0,1,0.3\n",
            "pj.csv",
        )
        .expect("PlotJuggler's yaw");
        assert_eq!(poses.data.theta[0], 0.3);
        // A header stamp's two fields, as a message flattened holds its time.
        let poses = poses_csv(
            "header.stamp.sec,header.stamp.nanosec,pose.position.x,pose.position.y,yaw\n\
             1764000000,250000000,1,2,0\n1764000001,0,1,2,0\n",
            "p.csv",
        )
        .expect("a header stamp");
        assert_eq!(poses.data.t[1] - poses.data.t[0], 0.75);
        let error = poses_csv(
            "header.stamp.sec,header.stamp.nanosec,x,y,theta\n1,0,1,2,0\n2,x,1,2,0\n",
            "p.csv",
        )
        .expect_err("a stamp that is not a number");
        assert_eq!(error.line, Some(3), "{error}");
        assert!(error.message.contains("`2` s, `x` ns"), "{error}");
        // ROS 1's `rostopic echo -p /cmd_vel`: `%time` in nanoseconds.
        let commands = commands_csv(
            "%time,field.linear.x,field.linear.y,field.linear.z,field.angular.x,field.angular.y,field.angular.z\n\
             1764000000000000000,0.2,0,0,0,0,0.1\n1764000000500000000,0.3,0,0,0,0,0.2\n",
            "cmd_vel.csv",
        )
        .expect("rostopic echo -p");
        assert_eq!(commands.data.t[1] - commands.data.t[0], 0.5);
        assert_eq!((commands.data.v[1], commands.data.omega[1]), (0.3, 0.2));
        // An unset orientation (all zeros) is no heading: refused at its line.
        let error = poses_csv("t,x,y,qx,qy,qz,qw\n0,1,2,0,0,0,1\n1,1,2,0,0,0,0\n", "p.csv")
            .expect_err("a zero quaternion");
        assert_eq!(error.line, Some(3), "{error}");
        assert!(error.message.contains("not a rotation"), "{error}");
        // Two names that could each be one column: refused, both named.
        let error = commands_csv(
            "t,cmd.linear.x,odom.linear.x,omega\n0,1,1,0\n1,1,1,0\n",
            "c.csv",
        )
        .expect_err("ambiguous");
        assert_eq!(error.line, Some(1));
        assert!(
            error
                .to_string()
                .contains("column `v` is ambiguous: cmd.linear.x, odom.linear.x"),
            "{error}"
        );
    }

    #[test]
    fn quoted_fields_crlf_and_a_byte_order_mark_are_read() {
        let text = "\u{feff}\"t\",\"v\",\"omega\"\r\n\"0\",\"0.2\",0.1\r\n# a comment\r\n1,0.3,\"0.2\"\r\n";
        let commands = commands_csv(text, "c.csv").expect("valid");
        assert_eq!(commands.data.t, vec![0.0, 1.0]);
        assert_eq!(commands.data.v, vec![0.2, 0.3]);
        assert_eq!(commands.data.omega, vec![0.1, 0.2]);
        // Lines are still counted as the file has them, comments included.
        let error = commands_csv("t,v,omega\r\n0,1,0\r\n# c\r\n1,x,0\r\n", "c.csv")
            .expect_err("not a number");
        assert_eq!(error.line, Some(4), "{error}");
    }

    #[test]
    fn rows_a_little_out_of_time_order_are_sorted_and_said_and_a_clock_reset_is_refused() {
        // A logger's jitter: row 3 is 30 ms behind row 2, row 6 ties row 5.
        let text = "t,x,y,theta\n0,0,0,0\n0.13,0.3,0,0\n0.1,0.2,0,0\n0.2,0.4,0,0\n0.2,0.5,0,0\n";
        let read = poses_csv(text, "p.csv").expect("sorted");
        assert_eq!(read.data.t, vec![0.0, 0.1, 0.13, 0.2]);
        // Rows move whole; of two at one time the first in the file is kept.
        assert_eq!(read.data.x, vec![0.0, 0.2, 0.3, 0.4]);
        let note = read.order.expect("said");
        assert!(
            note.contains(
                "p.csv: 1 row out of time order (the first at line 4; at most 0.030 s behind"
            ) && note.contains("sorted by `t`"),
            "{note}"
        );
        let in_order = poses_csv("t,x,y,theta\n0,0,0,0\n0.1,0.2,0,0\n", "p.csv").expect("read");
        assert_eq!(in_order.order, None);
        // MRCLAM's files are read the same way.
        let swapped =
            mrclam_groundtruth("1.00 0 0 0\n1.02 0 0 0\n1.01 0 0 0\n", "R.dat").expect("sorted");
        assert_eq!(swapped.data.t, vec![1.0, 1.01, 1.02]);
        // Seconds back is no jitter: a clock reset, or two files joined.
        let error =
            commands_csv("t,v,omega\n10,1,0\n11,1,0\n3,1,0\n4,1,0\n", "c.csv").expect_err("reset");
        assert_eq!(error.line, Some(4), "{error}");
        assert!(
            error.message.contains("times go back 8.000 s")
                && error.message.contains("split the file there"),
            "{error}"
        );
    }

    #[test]
    fn poses_not_tracked_are_dropouts_and_said_where_a_command_or_time_without_a_value_is_refused()
    {
        // OptiTrack's and pandas' way: the frame's time, its pose empty or NaN.
        let text = "t,x,y,theta\n0,0,0,0\n0.1,,,\n0.2,NaN,nan,NaN\n0.3,0.3,0,\n0.4,0.4,0,0\n";
        let read = poses_csv(text, "p.csv").expect("dropouts");
        assert_eq!(read.data.t, vec![0.0, 0.4]);
        let note = read.dropouts.expect("said");
        assert!(
            note.contains("p.csv: 3 rows without a pose") && note.contains("the first at line 3"),
            "{note}"
        );
        assert_eq!(
            poses_csv("t,x,y,theta\n0,0,0,0\n1,1,0,0\n", "p.csv")
                .expect("read")
                .dropouts,
            None
        );
        let tum = poses_tum(
            "0 0 0 0 0 0 0 1\n0.1 nan nan 0 0 0 0 1\n0.2 1 0 0 0 0 0 1\n",
            "gt.tum",
        )
        .expect("TUM dropout");
        assert_eq!(tum.data.t, vec![0.0, 0.2]);
        // A pose row without its time, and a last line cut short, are refused.
        let error =
            poses_csv("t,x,y,theta\n0,0,0,0\n,1,0,0\n2,0,0,0\n", "p.csv").expect_err("time");
        assert!(
            error.line == Some(3) && error.message.contains("field `t` is empty or NaN"),
            "{error}"
        );
        let error = poses_csv("t,x,y,theta\n0,0,0,0\n1,1,0,0\n2,1,", "p.csv").expect_err("cut");
        assert!(
            error.message.contains("ends in the middle of a line"),
            "{error}"
        );
    }

    #[test]
    fn a_spreadsheets_semicolons_and_decimal_commas_and_tabs_are_read() {
        // Excel in a German or French locale, pandas' `sep=';', decimal=','`.
        let read =
            commands_csv("t;v;omega\r\n0;0,25;-0,1\r\n0,5;0,3;0\r\n", "c.csv").expect("semicolons");
        assert_eq!(read.data.t, vec![0.0, 0.5]);
        assert_eq!(read.data.v, vec![0.25, 0.3]);
        assert_eq!(read.data.omega, vec![-0.1, 0.0]);
        let read =
            poses_csv("t\tx\ty\ttheta\n0\t1.5\t2\t0\n1\t1.6\t2\t0.1\n", "p.tsv").expect("tabs");
        assert_eq!(read.data.x, vec![1.5, 1.6]);
        // A comma CSV whose decimal commas are quoted, as pandas writes them.
        let read = commands_csv("t,v,omega\n0,\"0,25\",0\n1,\"0,5\",0\n", "c.csv").expect("quoted");
        assert_eq!(read.data.v, vec![0.25, 0.5]);
        // Commas inside a quoted name do not make the comma the separator.
        let read = commands_csv(
            "t;v;omega;\"note, one, two, three\"\n0;1;0;a\n1;1;0;b\n",
            "c.csv",
        )
        .expect("a quoted name");
        assert_eq!(read.data.v, vec![1.0, 1.0]);
    }

    #[test]
    fn a_file_of_positions_only_leaves_each_heading_for_the_track() {
        // A GPS or a one-marker tracker, exported by name and unit.
        let read = poses_csv("time,x [mm],y [mm]\n0,1000,0\n0.1,1010,0\n", "gps.csv")
            .expect("positions only");
        assert_eq!(read.data.x, vec![1.0, 1.01]);
        assert!(read.data.theta.iter().all(|theta| theta.is_nan()));
        // A heading column in degrees is a heading, not a file without one.
        let read = poses_csv("t,x,y,yaw_deg\n0,0,0,90\n1,1,0,90\n", "p.csv").expect("degrees");
        assert!((read.data.theta[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        // Without positions it is still refused by name.
        let refused = poses_csv("t,x\n0,1\n1,2\n", "p.csv").expect_err("no y");
        assert!(
            refused.to_string().contains("missing column `y`"),
            "{refused}"
        );
    }

    #[test]
    fn bad_input_names_file_and_line() {
        let cases = [
            ("t,v\n0,1\n1,1\n", 1, "missing column `omega`"),
            (
                "t,v,omega\n0,1,0\n2,1,0\n1,1,0\n",
                4,
                "times go back 1.000 s",
            ),
            (
                "t,v,omega\n0,1,0\n1,NaN,0\n",
                3,
                "field `v` is empty or NaN",
            ),
            ("t,v,omega\n0,1,0\n1,,0\n", 3, "field `v` is empty or NaN"),
            ("t,v,omega\n0,1,0\n1,inf,0\n", 3, "not finite"),
            ("t,v,omega\n0,1,0\n1,1\n", 3, "missing field `omega`"),
            (
                "t,v,omega\n0,1,0\n1,1,0\n2,1,",
                4,
                "ends in the middle of a line",
            ),
            (
                "t,v,omega\n0,1,0\n1,1,0\n2,1",
                4,
                "ends in the middle of a line",
            ),
            ("t,v,omega\n0,1,0\n1,x,0\n", 3, "not a number"),
            ("t,v,omega\n0,1,0\n1e10,1,0\n", 3, "runs longer than 24 h"),
        ];
        for (text, line, message) in cases {
            let error = commands_csv(text, "cmds.csv").expect_err(text);
            assert_eq!(error.line, Some(line), "{error}");
            assert!(error.to_string().contains(message), "{error}");
            assert!(
                error.to_string().starts_with(&format!("cmds.csv:{line}: ")),
                "{error}"
            );
        }
    }

    #[test]
    fn a_whole_last_line_without_a_newline_is_a_row() {
        let commands = commands_csv("t,v,omega\n0,1,0\n1,0.5,0.2", "c.csv").expect("whole");
        assert_eq!(commands.data.t, vec![0.0, 1.0]);
        assert_eq!(commands.data.omega, vec![0.0, 0.2]);
        let commands = commands_csv("t,v,omega\r\n0,1,0\r\n1,0.5,0.2", "c.csv").expect("CRLF");
        assert_eq!(commands.data.v, vec![1.0, 0.5]);
        let odometry = mrclam_odometry("# a\n1.0 0.1 0.0\n2.0 0.1 0.1", "R.dat").expect("whole");
        assert_eq!(odometry.data.t.len(), 2);
    }

    #[test]
    fn units_are_read_by_the_columns_names_and_a_unix_times_size() {
        let seconds = |text: &str| commands_csv(text, "c.csv").expect("valid").data.t;
        // Named: `time_ns`, `t [ms]`, from the run's start.
        assert_eq!(
            seconds("time_ns,v,omega\n0,1,0\n500000000,1,0\n"),
            [0.0, 0.5]
        );
        assert_eq!(seconds("t [ms],v,omega\n0,1,0\n250,1,0\n"), [0.0, 0.25]);
        // Unix times in nanoseconds and milliseconds, as pandas and loggers
        // write them under a plain `timestamp`.
        let ns = seconds("timestamp,v,omega\n1700000000000000000,1,0\n1700000000500000000,1,0\n");
        assert!((ns[1] - ns[0] - 0.5).abs() < 1e-6 && (ns[0] - 1.7e9).abs() < 1.0);
        let ms = seconds("t,v,omega\n1700000000000,1,0\n1700000000250,1,0\n");
        assert!((ms[1] - ms[0] - 0.25).abs() < 1e-6);
        // Said in the report.
        let notes = commands_unit_notes("t,v,omega\n1700000000000,1,0\n", "c.csv");
        assert!(
            notes[0].contains("milliseconds") && notes[0].contains("1700000000000"),
            "{notes:?}"
        );
        assert!(commands_unit_notes("t,v,omega\n0,1,0\n1,1,0\n", "c.csv").is_empty());
        // Dates and times, as pandas writes a datetime index, and RFC 3339.
        let dates =
            seconds("time,v,omega\n2023-11-14 22:13:20.0111,1,0\n2023-11-14 22:13:20.5111,1,0\n");
        assert!((dates[1] - dates[0] - 0.5).abs() < 1e-6, "{dates:?}");
        let rfc =
            seconds("t,v,omega\n2023-11-14T22:13:20Z,1,0\n2023-11-14T23:13:20.25+01:00,1,0\n");
        assert!((rfc[1] - rfc[0] - 0.25).abs() < 1e-6, "{rfc:?}");
        let notes = commands_unit_notes("time,v,omega\n2023-11-14 22:13:20,1,0\n", "c.csv");
        assert!(notes[0].contains("dates and times"), "{notes:?}");
        let error = commands_csv("t,v,omega\n2023-11-14T22:13:20Z,1,0\n5,1,0\n", "c.csv")
            .expect_err("a number among dates");
        assert!(error.to_string().contains("c.csv:3"), "{error}");
        // A heading in degrees, a turn rate in degrees a second, positions
        // in millimetres and a speed in millimetres a second, by name.
        let poses = poses_csv(
            "t,x_mm,y [mm],yaw_deg\n0,1000,-500,90\n1,1100,-500,-90\n",
            "p.csv",
        )
        .expect("units by name");
        assert!((poses.data.x[1] - 1.1).abs() < 1e-12 && (poses.data.y[0] + 0.5).abs() < 1e-12);
        assert!((poses.data.theta[0] - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let commands = commands_csv("t,v (mm/s),omega_deg_s\n0,200,45\n1,200,45\n", "c.csv")
            .expect("rates by name");
        assert!((commands.data.v[0] - 0.2).abs() < 1e-12);
        assert!((commands.data.omega[0] - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        let notes = poses_unit_notes("t,x_mm,y [mm],yaw_deg\n0,1000,-500,90\n", "p.csv");
        assert_eq!(notes.len(), 3, "{notes:?}");
        assert!(notes[2].contains("`yaw_deg` read in degrees"), "{notes:?}");
        // Shoal's own units named are read as they are, and not noted.
        assert!(poses_unit_notes("time_s,x_m,y_m,yaw_rad\n0,1,2,3\n", "p.csv").is_empty());
        let si = poses_csv("time_s,x_m,y_m,yaw_rad\n0,1,2,3\n1,1,2,3\n", "p.csv").expect("SI");
        assert_eq!(si.data.x, [1.0, 1.0]);
        // A run in seconds that runs past a day is still refused as such.
        let error = commands_csv("t,v,omega\n0,1,0\n100000,1,0\n", "c.csv").expect_err("too long");
        assert!(error.to_string().contains("wrong unit"), "{error}");
    }

    #[test]
    fn a_tum_trajectory_is_read_with_its_quaternions_yaw() {
        let half = std::f64::consts::FRAC_PI_8;
        let text = format!(
            "# timestamp tx ty tz qx qy qz qw\n0.0 1 2 0 0 0 {} {}\n0.5 1.1 2 0 0 0 0 1\n",
            half.sin(),
            half.cos()
        );
        assert!(looks_like_tum(&text) && !looks_like_tum("t,x,y,theta\n0,1,2,3\n"));
        let poses = poses_csv_or_tum(&text, "gt.tum").expect("TUM");
        assert_eq!(poses.data.t, [0.0, 0.5]);
        assert!((poses.data.theta[0] - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        let cut =
            poses_csv_or_tum("0.0 1 2 0 0 0 0 1\n0.5 1.1 2 0 0 0\n", "gt.tum").expect_err("cut");
        assert!(
            cut.to_string().contains("gt.tum:2") && cut.to_string().contains("qz"),
            "{cut}"
        );
    }

    #[test]
    fn mrclam_files_skip_their_header() {
        let text = "# a\n# b\n# c\n# d\n1248444187.156 \t  0.086 \t -0.398 \n1248444187.186 \t  0.086 \t -0.398 \n";
        let commands = mrclam_odometry(text, "Robot1_Odometry.dat").expect("valid");
        assert_eq!(commands.data.t.len(), 2);
        assert_eq!(commands.data.omega[1], -0.398);
    }
}
