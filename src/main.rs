//! The `treemocap` command: argument parsing only; the work is in the library.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Turns motion capture of tree branch tips into 3D tree models.
#[derive(Parser)]
#[command(name = "treemocap", version, about)]
struct Cli {
    /// More log output (-v info, -vv debug); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Describe a recording: format, rate, frames, markers, gaps.
    Inspect {
        /// A Motive CSV export or a treemocap log.
        file: std::path::PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let _ = cli.verbose;
    match cli.command {
        Command::Inspect { file } => {
            let _ = file;
            ExitCode::SUCCESS
        }
    }
}
