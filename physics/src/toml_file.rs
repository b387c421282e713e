//! A TOML file read as a user wrote it: every error names the file, the
//! line and the field. Scenarios and motion-model files both use it.

use std::fmt;

/// A scenario that could not be used, with the place it went wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct ScenarioError {
    pub file: String,
    pub line: Option<usize>,
    pub field: Option<String>,
    pub message: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(field) = &self.field {
            write!(f, ": field `{field}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

fn line_of_offset(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// Parses TOML `text` into `T`; errors name `file`, the line and the field.
pub fn parse_toml<T: serde::de::DeserializeOwned>(
    text: &str,
    file: &str,
) -> Result<T, ScenarioError> {
    let error = |line, field: Option<String>, message: String| ScenarioError {
        file: file.to_owned(),
        line,
        field,
        message,
    };
    let deserializer = toml::Deserializer::parse(text).map_err(|e| {
        error(
            e.span().map(|s| line_of_offset(text, s.start)),
            None,
            e.message().to_owned(),
        )
    })?;
    serde_path_to_error::deserialize(deserializer).map_err(|e| {
        let field = e.path().to_string();
        let inner = e.into_inner();
        let line = inner.span().map(|s| line_of_offset(text, s.start));
        let line = line.or_else(|| line_of_field(text, &field));
        error(line, Some(field), inner.message().to_owned())
    })
}

/// The line of the `index`-th `[[name]]` table in `text`.
pub fn line_of_nth_table(text: &str, name: &str, index: usize) -> Option<usize> {
    let header = format!("[[{name}]]");
    text.lines()
        .enumerate()
        .filter(|(_, line)| line.trim() == header)
        .nth(index)
        .map(|(number, _)| number + 1)
}

/// The line where `section.key` is written, for errors found after parsing.
pub fn line_of_field(text: &str, field: &str) -> Option<usize> {
    let (section, key) = match field.rsplit_once('.') {
        Some((section, key)) => (section, key),
        None => ("", field),
    };
    // `arena.surfaces[1].region`: the key inside the second `[[arena.surfaces]]`.
    if let Some((table, index)) = section
        .strip_suffix(']')
        .and_then(|s| s.rsplit_once('['))
        .and_then(|(table, index)| Some((table, index.parse::<usize>().ok()?)))
    {
        let header = line_of_nth_table(text, table, index)?;
        let found = text
            .lines()
            .enumerate()
            .skip(header)
            .take_while(|(_, line)| !line.trim_start().starts_with('['))
            .find(|(_, line)| line.split('=').next().map(str::trim) == Some(key))
            .map(|(number, _)| number + 1);
        return found.or(Some(header));
    }
    let key = key.split('[').next().unwrap_or(key);
    let mut current = String::new();
    let mut section_line = None;
    for (index, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if let Some(header) = line.strip_prefix('[') {
            current = header
                .trim_start_matches('[')
                .trim_end_matches(']')
                .trim()
                .to_owned();
            if current == section || (section.is_empty() && current == key) {
                section_line = Some(index + 1);
            }
            continue;
        }
        let written_key = line.split('=').next().unwrap_or("").trim();
        if current == section && written_key == key {
            return Some(index + 1);
        }
    }
    section_line
}
