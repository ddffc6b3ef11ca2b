//! The `treemocap` command: argument parsing and printing only; the work is
//! in the library. Every failure becomes one line naming the file and what is
//! wrong, with exit code 2 for bad usage or config and 1 for everything else.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use treemocap::{Error, Result};

/// Turns motion capture of tree branch tips into 3D tree models
/// (Long & Jones 2013).
#[derive(Parser)]
#[command(name = "treemocap", version, about, long_about = None)]
struct Cli {
    /// More log output (-v info, -vv debug, -vvv trace). RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

/// Options shared by every command that loads the configuration.
#[derive(clap::Args, Debug, Clone)]
struct ConfigArgs {
    /// A TOML config file; it overrides only the keys it names
    /// (see config/default.toml for every key).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Override one setting, e.g. --set record.flush_interval_s=0.5 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

impl ConfigArgs {
    fn load(&self) -> Result<treemocap::config::Config> {
        treemocap::config::Config::load(self.config.as_deref(), &self.set)
    }
}

#[derive(Subcommand)]
enum Command {
    /// Describe a recording: format, rate, units, frames, markers, gaps.
    Inspect {
        /// A Motive CSV export or a treemocap log (detected by content).
        file: PathBuf,
        /// Print one JSON object instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Re-run the particle flow on saved tips (tips.json) and write
    /// tree.glb, tree.json and tree.png.
    Reconstruct {
        /// A tips.json written by `treemocap replay` (or by hand).
        tips: PathBuf,
        #[command(flatten)]
        config: ConfigArgs,
        /// Output folder (default: output.dir from the config).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return match e.kind() {
                clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion => {
                    ExitCode::SUCCESS
                }
                _ => ExitCode::from(2),
            };
        }
    };
    init_logging(cli.verbose);
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("treemocap: {e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}

fn init_logging(verbose: u8) {
    let default = match verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Inspect { file, json } => {
            let _ = (file, json);
            Err(Error::Runtime("inspect is not written yet".into()))
        }
        Command::Reconstruct { tips, config, out } => {
            let config = config.load()?;
            let input = treemocap::reconstruct::read_tips(&tips)?;
            let out = out.unwrap_or_else(|| PathBuf::from(&config.output.dir));
            let report =
                treemocap::reconstruct::run_and_write(&input.tips, input.wind, &config, &out)?;
            println!(
                "{} captured + {} random tips, {} nodes, {} steps, {} forced joins, {} triangles, {} leaves",
                report.captured_tips,
                report.random_tips,
                report.nodes,
                report.steps,
                report.forced_joins,
                report.branch_triangles,
                report.leaves
            );
            for f in &report.files {
                println!("wrote {}", f.display());
            }
            Ok(())
        }
    }
}
