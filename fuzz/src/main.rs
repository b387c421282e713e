//! `shoal-fuzz`: every parser and bus check against generated inputs.
//! `shoal-fuzz --inputs 1000000 --json` is the figure in EXPERIMENTS.md.

use clap::Parser;
use shoal_fuzz::{Seeds, Target, fuzz};

#[derive(Parser)]
#[command(
    version,
    about = "Fuzz Shoal's file parsers and bus checks; fails on any panic or unclear error"
)]
struct Args {
    /// Generated inputs per target.
    #[arg(long, default_value_t = 10_000)]
    inputs: u64,
    /// Input i of a target is generated from seed + i.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Only these targets (default: all).
    #[arg(long, value_enum)]
    target: Vec<Target>,
    #[arg(long)]
    json: bool,
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    // Panics are caught and counted per input; printing each would bury the report.
    std::panic::set_hook(Box::new(|_| {}));
    let seeds = match Seeds::new() {
        Ok(seeds) => seeds,
        Err(e) => {
            eprintln!("shoal-fuzz: a seed cannot be built: {e:#}");
            return std::process::ExitCode::FAILURE;
        }
    };
    let targets = if args.target.is_empty() {
        Target::ALL.to_vec()
    } else {
        args.target.clone()
    };
    let mut reports = Vec::new();
    for target in targets {
        let report = fuzz(target, args.inputs, args.seed, &seeds);
        if !args.json {
            println!(
                "{:<18} {:>9} inputs  {:>9} accepted  {:>9} rejected ({:>9} with a line)  {} panics  {} unclear  {:.1} s",
                report.target,
                report.inputs,
                report.accepted,
                report.rejected,
                report.with_line,
                report.panics,
                report.unclear,
                report.seconds
            );
            for problem in [
                &report.first_panic,
                &report.first_unclear,
                &report.example_without_line,
            ]
            .into_iter()
            .flatten()
            {
                println!("    {problem}");
            }
        }
        reports.push(report);
    }
    let passed = reports.iter().all(|r| r.passed());
    if args.json {
        match serde_json::to_string_pretty(&reports) {
            Ok(json) => println!("{json}"),
            Err(e) => {
                eprintln!("shoal-fuzz: {e}");
                return std::process::ExitCode::FAILURE;
            }
        }
    }
    if passed {
        std::process::ExitCode::SUCCESS
    } else {
        eprintln!("shoal-fuzz: some inputs panicked or were rejected without a clear error");
        std::process::ExitCode::FAILURE
    }
}
