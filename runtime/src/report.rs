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
        Some(Value::Array(list)) => list
            .iter()
            .map(|v| cell(Some(v)))
            .collect::<Vec<_>>()
            .join(", "),
        Some(other) => other.to_string(),
    }
}

/// A fields-and-values record of each row.
type Record = Vec<(String, Value)>;

/// The table of `report`: its one list of records (the first field that is a
/// list of objects, perhaps empty), or, where it has none, the report itself as one record
/// (nested figures flattened, a list of numbers one cell). Columns are every
/// field any record has, what a row is about first.
fn table_of(report: &Value) -> (Vec<String>, Vec<Record>) {
    let listed = report.as_object().and_then(|o| {
        o.values().find_map(|v| {
            v.as_array()
                .filter(|list| list.iter().all(Value::is_object))
        })
    });
    let records: Vec<Record> = match listed {
        Some(list) => list.iter().collect::<Vec<_>>(),
        None if report.is_object() => vec![report],
        None => Vec::new(),
    }
    .into_iter()
    .map(|record| {
        let mut fields = Vec::new();
        flattened("", record, &mut fields);
        fields
    })
    .collect();
    let mut columns: Vec<String> = Vec::new();
    for (name, _) in records.iter().flatten() {
        if !columns.contains(name) {
            columns.push(name.clone());
        }
    }
    // What a row is about comes first.
    if let Some(at) = columns
        .iter()
        .position(|c| ["name", "measure"].contains(&c.as_str()))
    {
        let name = columns.remove(at);
        columns.insert(0, name);
    }
    (columns, records)
}

/// Prints `report` as JSON, or its one list of records as a Markdown table:
/// one column per field any record has, what a row is about first.
pub fn print(report: &impl serde::Serialize, json: bool) -> anyhow::Result<()> {
    let value = serde_json::to_value(report)?;
    if json {
        return print_out(|out| writeln!(out, "{value}"));
    }
    let (columns, records) = table_of(&value);
    if columns.is_empty() {
        return Ok(());
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

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_list_of_records_is_the_table_and_nested_figures_are_dotted_columns() {
        let report =
            json!({"rows": [{"name": "a", "cpu": {"share": 0.5}}, {"name": "b", "extra": 1}]});
        let (columns, records) = table_of(&report);
        assert_eq!(columns, ["name", "cpu.share", "extra"]);
        assert_eq!(records.len(), 2);
    }

    #[test]
    fn a_report_without_a_list_of_records_is_one_row_not_its_first_list_of_numbers() {
        // shoal-bench link's report: figures, nested figures and a pair of counts.
        let report = json!({"added_p50_ms": 1.8, "border_only": {"wire_bytes_per_robot_per_s": 1443.0}, "poses_timed": [120, 120]});
        let (columns, records) = table_of(&report);
        assert_eq!(records.len(), 1);
        assert_eq!(
            columns,
            [
                "added_p50_ms",
                "border_only.wire_bytes_per_robot_per_s",
                "poses_timed"
            ]
        );
        let poses = records[0]
            .iter()
            .find(|(name, _)| name == "poses_timed")
            .map(|(_, v)| v);
        assert_eq!(cell(poses), "120, 120");
    }
}
