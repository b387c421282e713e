//! Reports of experiments and benchmarks: JSON, or a Markdown table of their one list of records.

/// Prints `report` as JSON, or its one list of records as a Markdown table.
pub fn print(report: &impl serde::Serialize, json: bool) -> anyhow::Result<()> {
    let value = serde_json::to_value(report)?;
    if json {
        println!("{value}");
        return Ok(());
    }
    let records = value
        .as_object()
        .and_then(|o| o.values().find_map(|v| v.as_array()))
        .cloned()
        .unwrap_or_default();
    let Some(first) = records.first().and_then(|r| r.as_object()) else {
        return Ok(());
    };
    let columns: Vec<&String> = first.keys().collect();
    let cell = |v: &serde_json::Value| match v {
        serde_json::Value::Number(n) => n.as_f64().map_or_else(
            || n.to_string(),
            |f| {
                if f.fract() == 0.0 {
                    format!("{f}")
                } else {
                    format!("{f:.3}")
                }
            },
        ),
        serde_json::Value::Null => "-".to_owned(),
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    };
    println!(
        "| {} |",
        columns
            .iter()
            .map(|c| c.as_str())
            .collect::<Vec<_>>()
            .join(" | ")
    );
    println!("|{}", "---|".repeat(columns.len()));
    for record in &records {
        let cells: Vec<String> = columns.iter().map(|c| cell(&record[c.as_str()])).collect();
        println!("| {} |", cells.join(" | "));
    }
    Ok(())
}
