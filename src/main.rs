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
    /// Run the whole job on a recorded session: read it, and report what was
    /// found. Results go to --out (default: output.dir of the config).
    Replay {
        /// A Motive CSV export or a treemocap log (detected by content).
        file: PathBuf,
        #[command(flatten)]
        config: ConfigArgs,
        /// Output folder (overrides output.dir).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Describe a recording: format, rate, units, frames, markers, gaps.
    Inspect {
        /// A Motive CSV export or a treemocap log (detected by content).
        file: PathBuf,
        /// Print one JSON object instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Record a live source (OSC or NatNet) to a treemocap log until Ctrl-C
    /// or --seconds, printing frames, markers and losses once a second.
    #[command(group(clap::ArgGroup::new("live").required(true).args(["osc", "natnet"])))]
    Record {
        /// Listen for OSC on ADDR:PORT (UDP; overrides osc.bind), e.g.
        /// 127.0.0.1:9000. Senders must be in osc.allow (default: loopback).
        #[arg(long, value_name = "ADDR:PORT")]
        osc: Option<String>,
        /// Receive from a NatNet server (Motive) at ADDRESS or
        /// ADDRESS:COMMAND_PORT (default port 1510).
        #[arg(long, value_name = "SERVER")]
        natnet: Option<String>,
        /// NatNet: frames sent to this client only (default: what the
        /// server says it does).
        #[arg(long, requires = "natnet", conflicts_with = "multicast")]
        unicast: bool,
        /// NatNet: frames multicast to the group.
        #[arg(long, requires = "natnet")]
        multicast: bool,
        /// NatNet: ask the server for this bitstream version (e.g. 3.1).
        #[arg(long, value_name = "X.Y", requires = "natnet")]
        natnet_version: Option<String>,
        /// The log file to write (truncated if it exists).
        out: PathBuf,
        /// Stop after N seconds (default: run until Ctrl-C).
        #[arg(long, value_name = "N")]
        seconds: Option<f64>,
        #[command(flatten)]
        config: ConfigArgs,
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

fn to_json(value: &impl serde::Serialize) -> Result<String> {
    serde_json::to_string_pretty(value).map_err(|e| Error::Runtime(format!("JSON output: {e}")))
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Replay { file, config, out } => {
            let config = config.load()?;
            let _out = out.unwrap_or_else(|| PathBuf::from(&config.output.dir));
            let mut rec = treemocap::source::replay::open_with(&file, &config.replay)?;
            let report = treemocap::inspect::inspect_recording(&file, rec.as_mut())?;
            print!("{report}");
            Ok(())
        }
        Command::Inspect { file, json } => {
            let report = treemocap::inspect::inspect(&file)?;
            if json {
                println!("{}", to_json(&report)?);
            } else {
                print!("{report}");
            }
            Ok(())
        }
        Command::Record {
            osc,
            natnet,
            unicast,
            multicast,
            natnet_version,
            out,
            seconds,
            config,
        } => {
            use std::sync::Arc;
            use treemocap::source::live::LiveSource;
            use treemocap::source::record::{self, RecordEvent, RecordOptions};
            let config = config.load()?;
            if let Some(s) = seconds {
                if !(s.is_finite() && s > 0.0) {
                    return Err(Error::config(
                        "--seconds",
                        format!("{s}: must be a positive number"),
                    ));
                }
            }
            let source: Arc<dyn LiveSource> = match (osc, natnet) {
                (Some(addr), _) => {
                    let mut opts = treemocap::source::osc::OscOptions::from_config(&config.osc)?;
                    opts.bind = addr.parse().map_err(|_| {
                        Error::config(
                            "--osc",
                            format!("'{addr}' is not ADDR:PORT (e.g. 127.0.0.1:9000)"),
                        )
                    })?;
                    Arc::new(treemocap::source::osc::OscSource(opts))
                }
                (None, Some(server)) => {
                    use treemocap::source::natnet::{client::NatNetOptions, live::NatNetSource};
                    let mut opts = NatNetOptions::from_config(&config.natnet);
                    let (ip, port) = match server.parse::<std::net::SocketAddrV4>() {
                        Ok(a) => (*a.ip(), a.port()),
                        Err(_) => (
                            server.parse().map_err(|_| {
                                Error::config(
                                    "--natnet",
                                    format!("'{server}' is not an IPv4 address or ADDRESS:PORT"),
                                )
                            })?,
                            opts.command_port,
                        ),
                    };
                    opts.server = Some(ip);
                    opts.command_port = port;
                    opts.transport = match (unicast, multicast) {
                        (true, _) => Some(treemocap::source::natnet::Transport::Unicast),
                        (_, true) => Some(treemocap::source::natnet::Transport::Multicast),
                        _ => None,
                    };
                    if let Some(v) = natnet_version {
                        opts.bitstream = Some(
                            v.parse()
                                .map_err(|e| Error::config("--natnet-version", e))?,
                        );
                    }
                    Arc::new(NatNetSource(opts))
                }
                (None, None) => return Err(Error::config("record", "give --osc or --natnet")),
            };
            let opts = RecordOptions::from_config(out, seconds, &config);
            println!("recording to {}", opts.out.display());
            let summary = record::record_until_ctrl_c(source, &opts, |event| match event {
                RecordEvent::Status(s) => println!("{s}"),
                RecordEvent::Progress(p) => println!("{}", record::progress_line(&p)),
            })?;
            println!("{}", record::progress_line(&summary.progress));
            println!("{}", summary.source);
            println!("wrote {}", summary.out.display());
            Ok(())
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
