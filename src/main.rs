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
    /// Stream a recording as a NatNet server (a stand-in for Motive), so any
    /// NatNet client can be tested without a rig.
    Serve {
        /// A Motive CSV export or a treemocap log (detected by content).
        file: PathBuf,
        /// NatNet bitstream version to stream (2.5 … 4.x); unicast clients
        /// may switch theirs with a `Bitstream,X.Y` request.
        #[arg(long, value_name = "X.Y", default_value = "3.1")]
        natnet_version: treemocap::source::natnet::packet::Version,
        /// Playback speed (2 = twice as fast as recorded).
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
        /// Start again at the end (frame numbers jump back, as in Motive).
        #[arg(long = "loop")]
        looping: bool,
        /// Send frames to the multicast group (default: unicast to each
        /// client that connects).
        #[arg(long, conflicts_with = "unicast")]
        multicast: bool,
        /// Send frames to each client that connects (the default).
        #[arg(long)]
        unicast: bool,
        /// Local address to listen on.
        #[arg(long, default_value = "0.0.0.0")]
        bind: std::net::Ipv4Addr,
        /// Command port (clients send CONNECT here).
        #[arg(long, default_value_t = 1510)]
        command_port: u16,
        /// Data port (frames are sent from / to it).
        #[arg(long, default_value_t = 1511)]
        data_port: u16,
        /// Multicast group.
        #[arg(long, default_value = "239.255.42.99")]
        group: std::net::Ipv4Addr,
        /// Address of the interface multicast frames leave by.
        #[arg(long, default_value = "127.0.0.1")]
        interface: std::net::Ipv4Addr,
        /// Start streaming at once instead of when the first client connects.
        #[arg(long)]
        now: bool,
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
        Command::Serve {
            file,
            natnet_version,
            speed,
            looping,
            multicast,
            unicast: _,
            bind,
            command_port,
            data_port,
            group,
            interface,
            now,
        } => {
            use treemocap::source::natnet::server;
            let opts = server::ServeOptions {
                version: natnet_version,
                speed,
                looping,
                transport: if multicast {
                    server::Transport::Multicast
                } else {
                    server::Transport::Unicast
                },
                bind,
                command_port,
                data_port,
                multicast_group: group,
                multicast_interface: interface,
                wait_for_client: !now,
                ..Default::default()
            };
            let report =
                with_ctrl_c(|shutdown| async move { server::serve(&file, &opts, shutdown).await })?;
            eprintln!(
                "served {} frames ({} loops) to {} clients in {:.1} s",
                report.frames, report.loops, report.clients, report.elapsed_s
            );
            Ok(())
        }
    }
}

/// Runs an async library call on a tokio runtime until it returns or Ctrl-C
/// (which it sees as its shutdown signal turning true).
fn with_ctrl_c<T, F, Fut>(f: F) -> Result<T>
where
    F: FnOnce(tokio::sync::watch::Receiver<bool>) -> Fut,
    Fut: std::future::Future<Output = Result<T>>,
{
    let rt = tokio::runtime::Runtime::new()
        .map_err(|e| Error::Runtime(format!("cannot start the async runtime: {e}")))?;
    rt.block_on(async move {
        let (tx, rx) = tokio::sync::watch::channel(false);
        tokio::spawn(async move {
            if tokio::signal::ctrl_c().await.is_ok() {
                let _ = tx.send(true);
            }
        });
        f(rx).await
    })
}
