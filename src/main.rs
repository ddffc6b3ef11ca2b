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
    /// Run the daemon beside the rig: ingest the live markers (or a replay
    /// at recorded speed), rebuild the tree on the triggers, stream it out
    /// (files in --out, HTTP/WebSocket, OSC). With no config it plays
    /// replays/maple-24.csv and serves http://127.0.0.1:8080. Ctrl-C stops it.
    Run {
        #[command(flatten)]
        config: ConfigArgs,
        /// Output folder (overrides output.dir).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Run the whole job on a recorded session: track the markers, find the
    /// tips' rest positions, estimate the wind, reconstruct the tree. Writes
    /// tips.json, tree.glb, tree.json and tree.png to --out (default:
    /// output.dir of the config, "out").
    Replay {
        /// A Motive CSV export, a C3D file or a treemocap log (detected by content).
        file: PathBuf,
        #[command(flatten)]
        config: ConfigArgs,
        /// Output folder (overrides output.dir).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Find the branch tips in a recording: track the markers, fill gaps,
    /// drop noise, average each marker over the still phase. Prints a table
    /// of tips and a summary.
    Tips {
        /// A Motive CSV export, a C3D file or a treemocap log (detected by content).
        file: PathBuf,
        #[command(flatten)]
        config: ConfigArgs,
        /// Write the tips as JSON (tips.json, what reconstruction reads).
        #[arg(long, value_name = "OUT")]
        json: Option<PathBuf>,
        /// Draw each marker's x, y, z over time, with gaps and fills, as PNG.
        #[arg(long, value_name = "OUT.png")]
        plot: Option<PathBuf>,
    },
    /// Describe a recording: format, rate, units, frames, markers, gaps.
    Inspect {
        /// A Motive CSV export, a C3D file or a treemocap log (detected by content).
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
        /// A Motive CSV export, a C3D file or a treemocap log (detected by content).
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
    /// Make a synthetic capture session of a simulated tree: a Motive 1.23
    /// CSV of unlabeled markers plus NAME.truth.json beside it (the true tree,
    /// rest positions, wind and every gap), for testing without a mocap lab.
    ///
    /// Example (how replays/maple-24.csv was made):
    /// treemocap synth --seed 24 --tips 24 --shape maple --out replays/maple-24.csv
    Synth(SynthArgs),
}

/// Options of `treemocap synth`; every one left out takes the default shown.
#[derive(clap::Args, Debug)]
struct SynthArgs {
    /// Seed of every random draw: the same options give the same bytes.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Markers on the tree, placed on its outermost branch tips (1-70).
    #[arg(long, default_value_t = 24)]
    tips: usize,
    /// Crown habit: maple (round) or pine (conical).
    #[arg(long, default_value = "maple")]
    shape: treemocap::sim::CrownShape,
    /// The CSV to write; the truth goes to the same name with .truth.json.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Frames per second [default: 100].
    #[arg(long, value_name = "HZ")]
    rate: Option<f64>,
    /// Seconds of still tree at the start [default: 20].
    #[arg(long, value_name = "S")]
    still: Option<f64>,
    /// Seconds of wind after the still phase [default: 20].
    #[arg(long, value_name = "S")]
    wind: Option<f64>,
    /// Measurement noise, standard deviation per axis in mm [default: 0.2].
    #[arg(long, value_name = "MM")]
    noise_mm: Option<f64>,
    /// Scale of the wind sway (1 = up to a few cm) [default: 1].
    #[arg(long, value_name = "X")]
    sway_scale: Option<f64>,
    /// Fraction of tip samples lost to occlusion, 0-0.3 [default: 0.05].
    #[arg(long, value_name = "F")]
    gap_fraction: Option<f64>,
    /// Longest short occlusion burst in frames [default: 50].
    #[arg(long, value_name = "FRAMES")]
    max_burst: Option<u32>,
    /// Markers hidden for seconds (1-4 s each) [default: one per 12 tips].
    #[arg(long, value_name = "N")]
    long_gaps: Option<usize>,
    /// Spurious reflections appearing per second, each living 1-50 frames
    /// [default: 0.5].
    #[arg(long, value_name = "RATE")]
    spurious: Option<f64>,
    /// Least distance between marked tips in mm [default: 60].
    #[arg(long, value_name = "MM")]
    min_spacing_mm: Option<f64>,
    /// Take Name written in the CSV [default: the output file's stem].
    #[arg(long, value_name = "NAME")]
    take_name: Option<String>,
}

impl SynthArgs {
    fn options(&self) -> treemocap::sim::SynthOptions {
        let d = treemocap::sim::SynthOptions::default();
        treemocap::sim::SynthOptions {
            seed: self.seed,
            tips: self.tips,
            shape: self.shape,
            frame_rate: self.rate.unwrap_or(d.frame_rate),
            still_s: self.still.unwrap_or(d.still_s),
            wind_s: self.wind.unwrap_or(d.wind_s),
            noise_mm: self.noise_mm.unwrap_or(d.noise_mm),
            sway_scale: self.sway_scale.unwrap_or(d.sway_scale),
            gap_fraction: self.gap_fraction.unwrap_or(d.gap_fraction),
            max_burst_frames: self.max_burst.unwrap_or(d.max_burst_frames),
            long_gaps: self.long_gaps.or(d.long_gaps),
            spurious_per_s: self.spurious.unwrap_or(d.spurious_per_s),
            min_spacing_mm: self.min_spacing_mm.unwrap_or(d.min_spacing_mm),
            take_name: self.take_name.clone().unwrap_or(d.take_name),
            ..d
        }
    }
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
        Command::Run { config: args, out } => {
            let config = args.load()?;
            let out = out.unwrap_or_else(|| PathBuf::from(&config.output.dir));
            let shutdown = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
            let reload: treemocap::daemon::run::Reload = Box::new(move || args.load());
            treemocap::daemon::run::run_with_reload(config, &out, shutdown, true, Some(reload))
        }
        Command::Replay { file, config, out } => {
            let config = config.load()?;
            let out = out.unwrap_or_else(|| PathBuf::from(&config.output.dir));
            let report = treemocap::app::replay::run(&file, &config, &out)?;
            print!("{report}");
            Ok(())
        }
        Command::Tips {
            file,
            config,
            json,
            plot,
        } => {
            let config = config.load()?;
            let (_, _, text) = treemocap::app::tips::tips_command(
                &file,
                &config,
                json.as_deref(),
                plot.as_deref(),
            )?;
            print!("{text}");
            Ok(())
        }
        Command::Inspect { file, json } => {
            let report = treemocap::app::inspect::inspect(&file)?;
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
            use treemocap::app::record::{self, RecordEvent, RecordOptions};
            use treemocap::source::live::LiveSource;
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
                    opts.set_server(&server, "--natnet")?;
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
        Command::Synth(args) => {
            let summary = treemocap::sim::write_session(&args.options(), &args.out)?;
            print!("{summary}");
            Ok(())
        }
        Command::Reconstruct { tips, config, out } => {
            let config = config.load()?;
            let out = out.unwrap_or_else(|| PathBuf::from(&config.output.dir));
            let report = treemocap::app::reconstruct::command(&tips, &config, &out)?;
            // A closed pipe (`| head`) is not an error worth a panic.
            use std::io::Write;
            let mut stdout = std::io::stdout().lock();
            let _ = writeln!(
                stdout,
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
                let _ = writeln!(stdout, "wrote {}", f.display());
            }
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
