//! Reports of experiments and benchmarks: JSON, or a Markdown table of their one list of records.

use crate::process_main::print_out;
use serde_json::Value;

/// A record's fields, nested objects flattened into dotted names
/// (`learning.pos_rmse_m`), so every cell of the table is one value.
fn flattened(prefix: &str, value: &Value, out: &mut Vec<(String, Value)>) {
    match value {
        Value::Object(fields) => {
            for (key, field) in fields {
                let name = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                flattened(&name, field, out);
            }
        }
        other => out.push((prefix.to_owned(), other.clone())),
    }
}

fn cell(value: Option<&Value>) -> String {
    match value {
        Some(Value::Number(n)) => n.as_f64().map_or_else(
            || n.to_string(),
            |f| {
                if f.fract() == 0.0 {
                    format!("{f}")
                } else {
                    format!("{f:.3}")
                }
            },
        ),
        None | Some(Value::Null) => "-".to_owned(),
        Some(Value::String(s)) => s.clone(),
        Some(other) => other.to_string(),
    }
}

/// Prints `report` as JSON, or its one list of records as a Markdown table:
/// one column per field any record has, what a row is about first.
pub fn print(report: &impl serde::Serialize, json: bool) -> anyhow::Result<()> {
    let value = serde_json::to_value(report)?;
    if json {
        return print_out(|out| writeln!(out, "{value}"));
    }
    let records: Vec<Vec<(String, Value)>> = value
        .as_object()
        .and_then(|o| o.values().find_map(|v| v.as_array()))
        .into_iter()
        .flatten()
        .map(|record| {
            let mut fields = Vec::new();
            flattened("", record, &mut fields);
            fields
        })
        .collect();
    let mut columns: Vec<&str> = Vec::new();
    for (name, _) in records.iter().flatten() {
        if !columns.contains(&name.as_str()) {
            columns.push(name);
        }
    }
    if columns.is_empty() {
        return Ok(());
    }
    // What a row is about comes first.
    if let Some(at) = columns.iter().position(|c| ["name", "measure"].contains(c)) {
        let name = columns.remove(at);
        columns.insert(0, name);
    }
    print_out(|out| {
        writeln!(out, "| {} |", columns.join(" | "))?;
        writeln!(out, "|{}", "---|".repeat(columns.len()))?;
        for record in &records {
            let cells: Vec<String> = columns
                .iter()
                .map(|c| cell(record.iter().find(|(name, _)| name == c).map(|(_, v)| v)))
                .collect();
            writeln!(out, "| {} |", cells.join(" | "))?;
        }
        Ok(())
    })
}
