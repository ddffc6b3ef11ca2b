//! The `treemocap` command: argument parsing and printing only; the work is
//! in the library. Every failure becomes one line naming the file and what is
//! wrong, with exit code 2 for bad usage or config and 1 for everything else.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use treemocap::app::record::RecordOptions;
use treemocap::config::{Config, TransportSetting};
use treemocap::protocol::natnet;
use treemocap::shutdown::Shutdown;
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
    /// Refuse a recording that can be read only in part (a C3D file holding
    /// fewer frames than it declares) instead of reading its complete frames
    /// with a warning; the same as --set replay.strict=true.
    #[arg(long)]
    strict: bool,
}

impl ConfigArgs {
    fn load(&self) -> Result<treemocap::config::Config> {
        let mut sets = self.set.clone();
        if self.strict {
            sets.push("replay.strict=true".into());
        }
        treemocap::config::Config::load(self.config.as_deref(), &sets)
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
    /// tips.json, tree.glb (the tree swaying as captured: a skin and an
    /// animation), tree.json and tree.png to --out (default: output.dir of
    /// the config, "out").
    Replay {
        /// A Motive CSV export, a C3D file, a NatNet capture (pcap/pcapng)
        /// or a treemocap log (detected by content).
        file: PathBuf,
        /// The NatNet bitstream of a capture (.pcap/.pcapng) that holds
        /// no SERVERINFO (overrides replay.natnet_version).
        #[arg(long, value_name = "X.Y")]
        natnet_version: Option<natnet::Version>,
        #[command(flatten)]
        config: ConfigArgs,
        /// Output folder (overrides output.dir).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Write the still tree.glb (no skin, no animation).
        #[arg(long)]
        still: bool,
    },
    /// Find the branch tips in a recording: track the markers, fill gaps,
    /// drop noise, average each marker over the still phase. Prints a table
    /// of tips and a summary.
    Tips {
        /// A Motive CSV export, a C3D file, a NatNet capture (pcap/pcapng)
        /// or a treemocap log (detected by content).
        file: PathBuf,
        /// The NatNet bitstream of a capture (.pcap/.pcapng) that holds
        /// no SERVERINFO (overrides replay.natnet_version).
        #[arg(long, value_name = "X.Y")]
        natnet_version: Option<natnet::Version>,
        #[command(flatten)]
        config: ConfigArgs,
        /// Write the tips as JSON (tips.json, what reconstruction reads).
        #[arg(long, value_name = "OUT")]
        json: Option<PathBuf>,
        /// With --json: include each tip's cleaned trajectory (one position
        /// or null per frame, filled frames listed; see docs/tracking.md).
        #[arg(long, requires = "json")]
        traces: bool,
        /// Draw each marker's x, y, z over time, with gaps and fills, as PNG.
        #[arg(long, value_name = "OUT.png")]
        plot: Option<PathBuf>,
    },
    /// Write the cleaned, labelled tip trajectories (tip_01, … with their
    /// marker ids; filled samples flagged) as C3D, CSV or TRC, chosen by the
    /// extension of --out.
    Export {
        /// A Motive CSV export, a C3D file, a NatNet capture (pcap/pcapng)
        /// or a treemocap log (detected by content).
        session: PathBuf,
        /// Output file: .c3d, .csv (pandas reads it as is) or .trc (OpenSim).
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
        #[command(flatten)]
        config: ConfigArgs,
    },
    /// Describe a recording: format, rate, units, frames, markers, gaps.
    Inspect {
        /// A Motive CSV export, a C3D file, a NatNet capture (pcap/pcapng)
        /// or a treemocap log (detected by content).
        file: PathBuf,
        /// The NatNet bitstream of a capture (.pcap/.pcapng) that holds
        /// no SERVERINFO (overrides replay.natnet_version).
        #[arg(long, value_name = "X.Y")]
        natnet_version: Option<natnet::Version>,
        /// Print one JSON object instead of the table.
        #[arg(long)]
        json: bool,
        /// Refuse a file that can be read only in part (a C3D file holding
        /// fewer frames than it declares).
        #[arg(long)]
        strict: bool,
    },
    /// Record a live source (OSC or NatNet) to a treemocap log until Ctrl-C
    /// or --seconds, printing frames, markers and losses once a second.
    Record(RecordArgs),
    /// Stream a recording as a NatNet server (a stand-in for Motive), so any
    /// NatNet client can be tested without a rig.
    Serve(ServeArgs),
    /// Re-run the particle flow on saved tips (tips.json) and write
    /// tree.glb, tree.json and tree.png. When the tips file carries the tips'
    /// trajectories (`tips --json --traces`), tree.glb is animated with them.
    Reconstruct {
        /// A tips.json written by `treemocap replay` (or by hand).
        tips: PathBuf,
        #[command(flatten)]
        config: ConfigArgs,
        /// Output folder (default: output.dir from the config).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Write the still tree.glb even when the tips have trajectories.
        #[arg(long)]
        still: bool,
    },
    /// Show a finished session in the live page, with a timeline to scrub:
    /// a recording (the marker stage runs on it) or an output folder
    /// (`replay --out`, or the daemon's out/ with its session.log.csv).
    /// Serves until Ctrl-C.
    View {
        /// A recording (Motive CSV, C3D, treemocap log) or an output folder.
        path: PathBuf,
        /// For an output folder without session.log.csv: the recording its
        /// tips came from, for the timeline.
        #[arg(long, value_name = "FILE")]
        recording: Option<PathBuf>,
        /// Where to serve the page (0.0.0.0:8080 for the lab network; port 0
        /// picks a free one).
        #[arg(long, value_name = "ADDR:PORT", default_value = "127.0.0.1:8080")]
        http: String,
        #[command(flatten)]
        config: ConfigArgs,
    },
    /// Make a synthetic capture session of a simulated tree: a Motive 1.23
    /// CSV of unlabeled markers plus NAME.truth.json beside it (the true tree,
    /// rest positions, wind and every gap), for testing without a mocap lab.
    ///
    /// Example (how replays/maple-24.csv was made):
    /// treemocap synth --seed 24 --tips 24 --shape maple --out replays/maple-24.csv
    Synth(SynthArgs),
}

/// Options of `treemocap record`.
#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("live").required(true).args(["osc", "natnet"])))]
struct RecordArgs {
    /// Listen for OSC on ADDR:PORT (UDP; overrides osc.bind), e.g.
    /// 127.0.0.1:9000. Senders must be in osc.allow (default: loopback).
    #[arg(long, value_name = "ADDR:PORT")]
    osc: Option<String>,
    /// Receive from a NatNet server (Motive) at ADDRESS or
    /// ADDRESS:COMMAND_PORT (default port 1510).
    #[arg(long, value_name = "SERVER")]
    natnet: Option<String>,
    #[command(flatten)]
    natnet_options: NatNetArgs,
    /// The log file to write (truncated if it exists).
    out: PathBuf,
    /// Stop after N seconds (default: run until Ctrl-C).
    #[arg(long, value_name = "N")]
    seconds: Option<f64>,
    #[command(flatten)]
    config: ConfigArgs,
}

/// `record`'s NatNet options; each overrides its `[natnet]` key.
#[derive(clap::Args, Debug)]
struct NatNetArgs {
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
    /// NatNet: the network interface multicast is joined on, an address
    /// or a name such as eth1 (overrides natnet.interface).
    #[arg(long, value_name = "ADDRESS|NAME", requires = "natnet")]
    interface: Option<String>,
    /// NatNet: the multicast group (overrides natnet.multicast_group).
    #[arg(long, value_name = "GROUP", requires = "natnet")]
    group: Option<std::net::Ipv4Addr>,
    /// NatNet: the server's command port (overrides natnet.command_port;
    /// so does --natnet ADDRESS:PORT).
    #[arg(long, value_name = "PORT", requires = "natnet")]
    command_port: Option<u16>,
    /// NatNet: the server's data port (overrides natnet.data_port).
    #[arg(long, value_name = "PORT", requires = "natnet")]
    data_port: Option<u16>,
    /// NatNet: which axis of the stream points up: auto, y or z
    /// (overrides natnet.up_axis).
    #[arg(long, value_name = "AXIS", requires = "natnet")]
    up_axis: Option<String>,
}

/// Options of `treemocap serve`.
#[derive(clap::Args, Debug)]
struct ServeArgs {
    /// A recording: Motive CSV, C3D, a NatNet capture (pcap/pcapng) or a
    /// treemocap log (detected by content).
    file: PathBuf,
    /// NatNet bitstream version to stream (2.5 … 4.x); unicast clients
    /// may switch theirs with a `Bitstream,X.Y` request.
    #[arg(long, value_name = "X.Y", default_value_t = natnet::DEFAULT_SERVE_VERSION)]
    natnet_version: natnet::Version,
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
    /// Local address to listen on: loopback, so that only clients on this
    /// machine can connect; 0.0.0.0 (or the lab interface's address) to
    /// serve the lab network.
    #[arg(long, default_value = "127.0.0.1")]
    bind: std::net::Ipv4Addr,
    /// Command port (clients send CONNECT here).
    #[arg(long, default_value_t = natnet::DEFAULT_COMMAND_PORT)]
    command_port: u16,
    /// Data port (frames are sent from / to it).
    #[arg(long, default_value_t = natnet::DEFAULT_DATA_PORT)]
    data_port: u16,
    /// Multicast group.
    #[arg(long, default_value_t = natnet::DEFAULT_MULTICAST_GROUP)]
    group: std::net::Ipv4Addr,
    /// Address of the interface multicast frames leave by.
    #[arg(long, default_value = "127.0.0.1")]
    interface: std::net::Ipv4Addr,
    /// Start streaming at once instead of when the first client connects.
    #[arg(long)]
    now: bool,
    /// Stream Z up, as Motive's "Z up" option does (default: y).
    #[arg(long, value_name = "AXIS", default_value = "y", value_parser = parse_up_axis)]
    up_axis: natnet::select::UpAxis,
}

/// `y` or `z`.
fn parse_up_axis(text: &str) -> std::result::Result<natnet::select::UpAxis, String> {
    match text.to_ascii_lowercase().as_str() {
        "y" => Ok(natnet::select::UpAxis::Y),
        "z" => Ok(natnet::select::UpAxis::Z),
        _ => Err(format!("'{text}' is not an up axis; use y or z")),
    }
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
    /// Trees in the capture, 1-5, each with --tips markers (docs/forest.md).
    #[arg(long, default_value_t = 1)]
    trees: usize,
    /// How far neighbouring crowns overlap, as a fraction of the narrower
    /// crown's width; negative leaves a gap [default: 0].
    #[arg(long, value_name = "F", allow_hyphen_values = true)]
    overlap: Option<f64>,
    /// How the trees stand: row or cluster [default: row].
    #[arg(long)]
    layout: Option<treemocap::sim::Layout>,
    /// The first crown leans towards its neighbour by this many metres per
    /// metre of height [default: 0].
    #[arg(long, value_name = "M_PER_M", allow_hyphen_values = true)]
    lean: Option<f64>,
    /// Each tree maple or pine at random instead of --shape.
    #[arg(long)]
    mixed: bool,
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
            trees: self.trees,
            overlap: self.overlap.unwrap_or(d.overlap),
            layout: self.layout.unwrap_or(d.layout),
            lean: self.lean.unwrap_or(d.lean),
            mixed: self.mixed,
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
            // One line whatever the error holds; a closed stderr is no
            // reason to panic either.
            use std::io::Write;
            let line = treemocap::error::one_line(&e.to_string());
            let _ = writeln!(std::io::stderr(), "treemocap: {line}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}

/// `print!` that ends quietly on a closed pipe (see `app::stdout`).
macro_rules! say {
    ($($arg:tt)*) => { treemocap::app::stdout::print(format_args!($($arg)*)) };
}

/// The process's one async runtime and one shutdown signal, with the one
/// Ctrl-C/SIGTERM handler, for the commands that run until stopped.
fn runtime() -> Result<(tokio::runtime::Runtime, Shutdown)> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("treemocap-io")
        .enable_all()
        .build()
        .map_err(|e| Error::Runtime(format!("cannot start the async runtime: {e}")))?;
    let shutdown = Shutdown::new();
    shutdown.trigger_on_signals(rt.handle());
    Ok((rt, shutdown))
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
        // No colour codes in a file or a pipe: only on a terminal.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .try_init();
}

fn to_json(value: &impl serde::Serialize) -> Result<String> {
    serde_json::to_string_pretty(value).map_err(|e| Error::Runtime(format!("JSON output: {e}")))
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Run { config, out } => run_daemon(config, out),
        Command::View {
            path,
            recording,
            http,
            config,
        } => view(&path, recording.as_deref(), &http, config),
        Command::Replay {
            file,
            config,
            out,
            natnet_version,
            still,
        } => {
            let mut config = config.load()?;
            config.replay.natnet_version = natnet_version.or(config.replay.natnet_version);
            let out = out.unwrap_or_else(|| PathBuf::from(&config.output.dir));
            let report = treemocap::app::replay::run_with(&file, &config, still, &out)?;
            say!("{report}")?;
            Ok(())
        }
        Command::Tips {
            file,
            config,
            json,
            traces,
            plot,
            natnet_version,
        } => {
            let mut config = config.load()?;
            config.replay.natnet_version = natnet_version.or(config.replay.natnet_version);
            tips(&file, &config, json.as_deref(), traces, plot.as_deref())
        }
        Command::Export {
            session,
            out,
            config,
        } => {
            let config = config.load()?;
            let summary = treemocap::app::export::export_command(&session, &out, &config)?;
            say!("{summary}\n")?;
            say!("wrote {} ({} tips)\n", out.display(), summary.tips)?;
            Ok(())
        }
        Command::Inspect {
            file,
            json,
            natnet_version,
            strict,
        } => inspect(&file, json, natnet_version, strict),
        Command::Record(args) => record(args),
        Command::Serve(args) => serve(args),
        Command::Synth(args) => {
            let summary = treemocap::app::synth::write_session(&args.options(), &args.out)?;
            say!("{summary}")?;
            Ok(())
        }
        Command::Reconstruct {
            tips,
            config,
            out,
            still,
        } => {
            let config = config.load()?;
            let out = out.unwrap_or_else(|| PathBuf::from(&config.output.dir));
            let report = treemocap::app::reconstruct::command(&tips, &config, still, &out)?;
            say!("{report}")?;
            Ok(())
        }
    }
}

/// `treemocap view`: a finished session served to the live page until Ctrl-C.
fn view(path: &Path, recording: Option<&Path>, http: &str, config: ConfigArgs) -> Result<()> {
    let config = config.load()?;
    let session = treemocap::app::view::load(path, recording, &config)?;
    let listener = std::net::TcpListener::bind(http)
        .map_err(|e| Error::Runtime(format!("view: HTTP on {http}: {e}")))?;
    let frames = session.frames.len();
    let (_stop, shutdown) = tokio::sync::watch::channel(false);
    treemocap::app::view::serve(session, listener, shutdown, |url| {
        let _ = say!(
            "{}: {frames} frames; the page is at {url} (Ctrl-C stops)\n",
            path.display()
        );
    })
}

/// `treemocap tips`: the marker stage's table, and the files asked for.
fn tips(
    file: &Path,
    config: &Config,
    json: Option<&Path>,
    traces: bool,
    plot: Option<&Path>,
) -> Result<()> {
    let (_, _, text) = treemocap::app::tips::tips_command(file, config, json, traces, plot)?;
    say!("{text}")?;
    Ok(())
}

/// `treemocap inspect`: what a recording holds, as a table or JSON.
fn inspect(
    file: &Path,
    json: bool,
    natnet_version: Option<natnet::Version>,
    strict: bool,
) -> Result<()> {
    let mut options = treemocap::app::open::ReplayOptions::default();
    options.pcap.version = natnet_version;
    options.c3d.strict = strict;
    let report = treemocap::app::inspect::inspect_with(file, &options)?;
    if json {
        say!("{}\n", to_json(&report)?)?;
    } else {
        say!("{report}")?;
    }
    Ok(())
}

/// `treemocap run`: the daemon until Ctrl-C or SIGTERM; SIGHUP reloads.
fn run_daemon(args: ConfigArgs, out: Option<PathBuf>) -> Result<()> {
    let config = args.load()?;
    let out = out.unwrap_or_else(|| PathBuf::from(&config.output.dir));
    let (rt, shutdown) = runtime()?;
    let reload: treemocap::daemon::Reload = Box::new(move || args.load());
    let result =
        treemocap::daemon::run_at_the_rig(config, &out, rt.handle(), &shutdown, Some(reload));
    rt.shutdown_timeout(std::time::Duration::from_millis(500));
    result
}

/// `treemocap record`: a live source into our log format.
fn record(args: RecordArgs) -> Result<()> {
    let config = args.config.load()?;
    if let Some(s) = args.seconds {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::config(
                "--seconds",
                format!("{s}: must be a positive number"),
            ));
        }
    }
    let source = match (args.osc, args.natnet) {
        (Some(addr), _) => {
            let bind = addr.parse().map_err(|_| {
                Error::config(
                    "--osc",
                    format!("'{addr}' is not ADDR:PORT (e.g. 127.0.0.1:9000)"),
                )
            })?;
            treemocap::app::live::osc_source(&config, Some(bind))?
        }
        (None, Some(server)) => {
            let settings = natnet_options(&args.natnet_options, config.natnet.clone())?;
            treemocap::app::live::natnet_source(settings, &server, "--natnet")?
        }
        (None, None) => return Err(Error::config("record", "give --osc or --natnet")),
    };
    let opts = RecordOptions::from_config(args.out, args.seconds, &config);
    let (rt, shutdown) = runtime()?;
    treemocap::app::record::command(rt.handle(), &shutdown, source, &opts)?;
    Ok(())
}

/// The `[natnet]` settings with `record`'s NatNet options applied.
fn natnet_options(
    args: &NatNetArgs,
    mut s: treemocap::source::natnet::settings::NatNetSettings,
) -> Result<treemocap::source::natnet::settings::NatNetSettings> {
    s.transport = match (args.unicast, args.multicast) {
        (true, _) => TransportSetting::Unicast,
        (_, true) => TransportSetting::Multicast,
        _ => TransportSetting::Auto,
    };
    if let Some(v) = &args.natnet_version {
        s.bitstream = Some(
            v.parse()
                .map_err(|e| Error::config("--natnet-version", e))?,
        );
    }
    if let Some(i) = &args.interface {
        s.interface = i.parse().map_err(|e| Error::config("--interface", e))?;
    }
    if let Some(a) = &args.up_axis {
        s.up_axis = a.parse().map_err(|e| Error::config("--up-axis", e))?;
    }
    s.multicast_group = args.group.or(s.multicast_group);
    s.command_port = args.command_port.unwrap_or(s.command_port);
    s.data_port = args.data_port.or(s.data_port);
    Ok(s)
}

/// `treemocap serve`: a recording streamed as a NatNet server.
fn serve(args: ServeArgs) -> Result<()> {
    use treemocap::serve::natnet as server;
    let opts = server::ServeOptions {
        version: args.natnet_version,
        speed: args.speed,
        looping: args.looping,
        transport: if args.multicast {
            server::Transport::Multicast
        } else {
            server::Transport::Unicast
        },
        bind: args.bind,
        command_port: args.command_port,
        data_port: args.data_port,
        multicast_group: args.group,
        multicast_interface: args.interface,
        wait_for_client: !args.now,
        up_axis: args.up_axis,
        ..Default::default()
    };
    let (rt, shutdown) = runtime()?;
    // A capture without SERVERINFO is read in the bitstream it is served in.
    let mut options = treemocap::app::open::ReplayOptions::default();
    options.pcap.version = Some(args.natnet_version);
    let open = || treemocap::app::open::open_with(&args.file, &options);
    let report = rt.block_on(server::serve(open, &opts, shutdown.receiver()))?;
    use std::io::Write;
    let _ = writeln!(
        std::io::stderr(),
        "served {} frames ({} loops) to {} clients in {:.1} s",
        report.frames,
        report.loops,
        report.clients,
        report.elapsed_s
    );
    Ok(())
}
