//! The daemon: sources → bounded channel → pipeline → analysis and triggers
//! → tree builder → outputs. Wiring only: threads, channels, triggers and
//! shutdown; every stage it runs is the plain library code that
//! `treemocap replay` runs too.
//!
//! ```text
//! source task ──FrameSink (bounded, drop-oldest)──► pipeline thread
//!   (NatNet, OSC, or a replay player)                 │ every frame: record, window,
//!                                                     │ live tips → WebSocket/OSC, sway PCA
//!                                                     ▼ every analysis_interval_s
//!                                               analysis thread: track::process on the
//!                                               window, triggers ──latest wins──► builder
//!                                               thread: flow, TreeSnapshot → HTTP, OSC,
//!                                               WebSocket, files
//! ```
//!
//! Shutdown is the process's one [`Shutdown`] signal: the sources stop, the
//! pipeline finishes its frame and flushes the recording, and the end flows
//! down the channels — the analysis ends when the pipeline's sender goes, the
//! builder when the analysis closes its requests.

mod affinity;
mod analysis;
mod builder;
mod console;
pub mod counters;
pub mod handoff;
mod live_tips;
mod osc_control;
mod pipeline;
mod pose;
mod pose_feed;
pub mod progress;
pub mod rest_estimate;
mod shared;
mod sources;
pub mod status;
pub mod triggers;
pub mod wind_log;
pub mod window;

use std::net::SocketAddr;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use crossbeam_channel::bounded;
use tokio::sync::watch;

use crate::config::Config;
use crate::error::{Error, Result};
use crate::serve::http;
use crate::serve::live::LiveHub;
use crate::serve::osc::OscSender;
use crate::shutdown::Shutdown;
use crate::source::channel::frame_channel;
use crate::wind::WindSelector;
use shared::{lock, LatestRequest, Shared};
use status::Status;
use wind_log::WindLog;

/// Reads the configuration again (for SIGHUP).
pub type Reload = Box<dyn Fn() -> Result<Config> + Send + Sync>;

/// Runs the daemon on `rt` until `shutdown` fires; returns once every thread
/// has flushed and stopped. With `reload`, SIGHUP reads the config again and,
/// if it is good, rebuilds the tree with its `[reconstruct]` settings
/// (sources and ports need a restart).
pub fn run(
    config: Config,
    out: &Path,
    rt: &tokio::runtime::Handle,
    shutdown: &Shutdown,
    reload: Option<Reload>,
) -> Result<()> {
    run_with(config, out, rt, shutdown, reload, false)
}

/// [`run`] for an operator at the rig (`treemocap run`): with the console
/// on stderr (the source and the page's address at start, the source
/// connecting or going silent, the still-phase progress, each new tree).
pub fn run_at_the_rig(
    config: Config,
    out: &Path,
    rt: &tokio::runtime::Handle,
    shutdown: &Shutdown,
    reload: Option<Reload>,
) -> Result<()> {
    run_with(config, out, rt, shutdown, reload, true)
}

fn run_with(
    config: Config,
    out: &Path,
    rt: &tokio::runtime::Handle,
    shutdown: &Shutdown,
    reload: Option<Reload>,
    console: bool,
) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let placement = affinity::Placement::from_setting(config.daemon.pipeline_cpu)?;
    let shared = new_shared(config, out, shutdown.clone(), placement);
    if let Some(reload) = reload {
        let s = shared.clone();
        rt.spawn(async move { reload_on_hangup(s, reload).await });
    }
    let d = shared.config.daemon.clone();
    if let Some(addr) = d.osc_control {
        sources::start_osc_control(&shared, rt, addr)?;
    }
    // HTTP first: a busy port is an error the user must see at once.
    if let Some(addr) = d.http {
        start_http(&shared, rt, addr)?;
    }
    let (sink, rx) = frame_channel(d.channel_frames as usize);
    let mut threads: Vec<JoinHandle<()>> = Vec::new();
    threads.extend(sources::start_source(&shared, rt, sink.clone())?);
    if console {
        let start = console::start_line(&shared.status, d.http);
        threads.push(console::spawn(
            start,
            shared.status.clone(),
            shutdown.flag(),
        ));
    }
    if !shared.config.wind.sensor_port.is_empty() {
        threads.push(sources::start_serial(&shared));
    }
    let handoff = Arc::new(handoff::AnalysisHandoff::default());
    let (tips_tx, tips_rx) = bounded(4);
    let (s, h) = (shared.clone(), handoff.clone());
    threads.push(spawn_background(
        "treemocap-analysis",
        placement,
        shared.config.daemon.background_idle,
        move || analysis::Analysis::new(s).run(&h),
    ));
    let s = shared.clone();
    threads.push(spawn_background(
        "treemocap-builder",
        placement,
        shared.config.daemon.background_idle,
        move || builder::run(&s, tips_tx),
    ));
    let result =
        pipeline::Pipeline::new(shared.clone(), handoff.clone()).map(|p| p.run(rx, &sink, tips_rx));
    // The analysis ends once it has nothing more to read.
    handoff.close();
    // The pipeline stops on shutdown, or on an error at its start: either way
    // everything else stops with it.
    shutdown.trigger();
    shared.requests.close();
    for t in threads {
        let _ = t.join();
    }
    result
}

fn new_shared(
    config: Config,
    out: &Path,
    shutdown: Shutdown,
    placement: affinity::Placement,
) -> Arc<Shared> {
    let wind_log = WindLog::create(&out.join("wind.csv"))
        .map_err(|e| tracing::warn!("{e}"))
        .ok();
    Arc::new(Shared {
        out: out.to_path_buf(),
        status: Arc::new(Status {
            progress: progress::Progress::new(config.daemon.rest_min_s),
            ..Status::default()
        }),
        shutdown,
        wind: Mutex::new(WindSelector::new(
            config.wind.priority.clone(),
            config.wind.max_age_s,
        )),
        wind_log: Mutex::new(wind_log),
        rebuild: Arc::new(AtomicBool::new(false)),
        hub: Arc::new(LiveHub::default()),
        tree_tx: watch::channel(None).0,
        requests: LatestRequest::default(),
        placement,
        recon_config: Mutex::new(config.clone()),
        config,
    })
}

fn start_http(shared: &Arc<Shared>, rt: &tokio::runtime::Handle, addr: SocketAddr) -> Result<()> {
    let listener = rt
        .block_on(tokio::net::TcpListener::bind(addr))
        .map_err(|source| Error::Bind {
            what: "HTTP",
            addr,
            source,
        })?;
    let (st, st2, s) = (shared.status.clone(), shared.status.clone(), shared.clone());
    let state = http::HttpState {
        tree: shared.tree_tx.subscribe(),
        hub: shared.hub.clone(),
        status: Arc::new(move || st.to_json()),
        metrics: Arc::new(move || st2.to_prometheus()),
        rebuild: Some(Arc::new(move || s.ask_rebuild())),
        shutdown: shared.shutdown.receiver(),
    };
    let (limits, bad) = counters::http_limits(&shared.config.daemon, &shared.status.bad_input)?;
    rt.spawn(async move {
        if let Err(e) = http::serve(listener, state, limits, bad).await {
            tracing::error!("HTTP server: {e}");
        }
    });
    tracing::info!("HTTP on http://{addr}");
    Ok(())
}

#[cfg(unix)]
async fn reload_on_hangup(shared: Arc<Shared>, reload: Reload) {
    use tokio::signal::unix::{signal, SignalKind};
    let Ok(mut hup) = signal(SignalKind::hangup()) else {
        return;
    };
    loop {
        tokio::select! {
            got = hup.recv() => if got.is_none() { return },
            _ = shared.shutdown.triggered() => return,
        }
        match reload() {
            Ok(new) => {
                tracing::info!("SIGHUP: config reloaded; rebuilding");
                *lock(&shared.recon_config) = new;
                *lock(&shared.status.config_error) = None;
                shared.ask_rebuild();
            }
            Err(e) => {
                tracing::error!("SIGHUP: {e}; keeping the running config");
                *lock(&shared.status.config_error) = Some(e.to_string());
            }
        }
    }
}

#[cfg(not(unix))]
async fn reload_on_hangup(_shared: Arc<Shared>, _reload: Reload) {}

/// A sender to `daemon.osc_targets`, or `None` when there are none.
fn osc_sender(targets: &[SocketAddr]) -> Result<Option<OscSender>> {
    if targets.is_empty() {
        return Ok(None);
    }
    OscSender::new(targets.to_vec()).map(Some)
}

/// Like [`spawn`], for work off the latency path (the analysis of the
/// window, the tree builder, the sway deformation): the thread runs at a
/// lower priority (nice +[`BACKGROUND_NICE`]), so that on a machine with
/// few cores the pipeline thread, which stamps every frame's latency, gets
/// the CPU first whenever both want it. The background work still gets
/// every cycle the pipeline leaves; it is only ever late, never lost. With
/// `daemon.pipeline_cpu` set it also runs off the pipeline's CPU; with
/// `idle` (`daemon.background_idle`) only when a CPU is otherwise idle.
fn spawn_background(
    name: &str,
    placement: affinity::Placement,
    idle: bool,
    f: impl FnOnce() + Send + 'static,
) -> JoinHandle<()> {
    spawn(name, move || {
        lower_priority();
        if idle {
            run_when_idle();
        }
        placement.keep_off_pipeline();
        f()
    })
}

/// How much nicer than the pipeline the background threads are: at +10 the
/// kernel gives a CPU-bound background thread about a tenth of a core the
/// pipeline also wants (CFS weights 1024 against 110).
const BACKGROUND_NICE: i32 = 10;

#[cfg(target_os = "linux")]
fn lower_priority() {
    // On Linux a thread's nice value is its own: PRIO_PROCESS with a thread
    // id sets it for this thread only. Raising one's own nice needs no
    // privilege; a failure (a sandbox refusing it) only costs the priority.
    // Relative to the daemon's own nice value (a daemon started under
    // `nice -n 7` keeps its background 10 steps below its pipeline), at
    // most 19. getpriority's -1 is also its error value; read as a nice
    // of -1 it only makes the thread one step less nice.
    // SAFETY: plain system calls with no pointers.
    let r = unsafe {
        let tid = libc::gettid() as libc::id_t;
        let base = libc::getpriority(libc::PRIO_PROCESS, tid);
        libc::setpriority(libc::PRIO_PROCESS, tid, (base + BACKGROUND_NICE).min(19))
    };
    if r != 0 {
        tracing::debug!("could not lower a background thread's priority");
    }
}

/// `daemon.background_idle`: this thread runs only when a CPU is otherwise
/// idle. A nice value only weighs the threads' shares; a pipeline waking
/// beside a nice +10 analysis could still wait for the analysis's slice
/// (the 360 Hz x 1 000 daemon's p99 of 1.9 ms); beside a `SCHED_IDLE` one
/// it runs at once (0.78 ms).
#[cfg(target_os = "linux")]
fn run_when_idle() {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: a plain system call on this thread (pid 0) with a valid
    // pointer to a parameter that outlives it. Moving to SCHED_IDLE needs
    // no privilege; a refusal only costs the latency.
    let r = unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) };
    if r != 0 {
        tracing::debug!("could not move a background thread to SCHED_IDLE");
    }
}

#[cfg(not(target_os = "linux"))]
fn run_when_idle() {}

#[cfg(not(target_os = "linux"))]
fn lower_priority() {}

fn spawn(name: &str, f: impl FnOnce() + Send + 'static) -> JoinHandle<()> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(f)
        // Failing to start a thread at start-up is a machine out of
        // resources, not bad input: nothing sensible is left to do.
        .expect("spawn a daemon thread")
}
