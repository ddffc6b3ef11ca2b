//! `treemocap run`: the wiring of the live daemon.
//!
//! ```text
//! source task ──FrameSink (bounded, drop-oldest)──► pipeline thread
//!   (NatNet, OSC, or a replay player)                 │ every frame: record, window,
//!                                                     │ live tips → WebSocket/OSC, sway PCA
//!                                                     ▼ every analysis_interval_s
//!                                               analysis thread: track::process on the
//!                                               window, triggers ──latest wins──► recon thread:
//!                                               flow, files, TreeSnapshot → HTTP, OSC, WebSocket
//! ```
//!
//! Only the latest reconstruction request is kept; outputs read an
//! `Arc<TreeSnapshot>`; a slow viewer never slows the pipeline. Shutdown is one
//! flag: every thread finishes its item, flushes and exits.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Receiver, Sender};
use glam::DVec3;
use tokio::sync::{broadcast, watch};

use super::follow::TipFollower;
use super::handoff::{track_snapshot, AnalysisHandoff, Job};
use super::rest_estimate::{BestRest, RestEstimate};
use super::status::Status;
use super::triggers::{Reason, TriggerConfig, Triggers};
use super::window::FrameWindow;
use crate::app::files::write_atomic;
use crate::app::open::{self as replay, ReplayOptions};
use crate::config::Config;
use crate::daemon::wind_log::WindLog;
use crate::error::{Error, Result};
use crate::format::log::{LogHeader, LogWriter};
use crate::model::tips::{CapturedTip, Tips};
use crate::model::wind::WindEstimate;
use crate::render::outputs::build_model;
use crate::serve::http;
use crate::serve::osc::{tips_datagram, tree_datagrams, wind_datagram, OscSender};
use crate::serve::snapshot::SnapshotNode;
use crate::serve::snapshot::TreeSnapshot;
use crate::source::channel::{frame_channel, FrameReceiver, FrameSink};
use crate::source::live::LiveSource;
use crate::source::wind_sensor as serial;
use crate::wind::pca::SwayPca;
use crate::wind::{fan, WindSelector};

/// A request to build a tree (only the latest pending one is kept).
struct Build {
    /// When the trigger fired, for the trigger-to-tree time.
    fired: Instant,
    reason: Reason,
    time_s: f64,
    tips: Vec<CapturedTip>,
    tips_json: String,
    wind: DVec3,
}

/// "Latest wins" hand-off from analysis to reconstruction.
#[derive(Default)]
struct Slot {
    pending: Mutex<Option<Build>>,
    ready: Condvar,
}

/// Everything the threads share.
struct Shared {
    config: Config,
    /// The settings reconstruction uses; SIGHUP replaces them.
    recon_config: Mutex<Config>,
    out: PathBuf,
    status: Arc<Status>,
    shutdown: Arc<AtomicBool>,
    wind: Mutex<WindSelector>,
    wind_log: Mutex<Option<WindLog>>,
    rebuild: Arc<AtomicBool>,
    live: broadcast::Sender<Arc<str>>,
    tree_tx: watch::Sender<Option<Arc<TreeSnapshot>>>,
    slot: Slot,
}

/// Reads the configuration again (for SIGHUP).
pub type Reload = Box<dyn Fn() -> Result<Config> + Send + Sync>;

/// Runs the daemon until `shutdown` is set (Ctrl-C and SIGTERM set it when
/// `handle_signals`). Returns once every thread has flushed and stopped.
pub fn run(
    config: Config,
    out: &Path,
    shutdown: Arc<AtomicBool>,
    handle_signals: bool,
) -> Result<()> {
    run_with_reload(config, out, shutdown, handle_signals, None)
}

/// Like [`run`]; with `handle_signals`, SIGHUP calls `reload` and, if the
/// config is good, rebuilds the tree with its `[reconstruct]` and `[wind]`
/// settings (sources and ports need a restart).
pub fn run_with_reload(
    config: Config,
    out: &Path,
    shutdown: Arc<AtomicBool>,
    handle_signals: bool,
    reload: Option<Reload>,
) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let d = config.daemon.clone();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("treemocap-io")
        .enable_all()
        .build()
        .map_err(|e| Error::Runtime(format!("cannot start the async runtime: {e}")))?;
    let (stop_tx, stop_rx) = watch::channel(false);
    {
        let flag = shutdown.clone();
        rt.spawn(async move {
            loop {
                if flag.load(Ordering::Relaxed) {
                    let _ = stop_tx.send(true);
                    return;
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        });
    }
    if handle_signals {
        let flag = shutdown.clone();
        rt.spawn(async move {
            wait_for_signal().await;
            tracing::info!("shutting down");
            flag.store(true, Ordering::Relaxed);
        });
    }

    let status = Arc::new(Status::default());
    let (live_tx, _) = broadcast::channel(1024);
    let (tree_tx, tree_rx) = watch::channel(None);
    let rebuild = Arc::new(AtomicBool::new(false));
    let wind_log = match WindLog::create(&out.join("wind.csv")) {
        Ok(l) => Some(l),
        Err(e) => {
            tracing::warn!("{e}");
            None
        }
    };
    let shared = Arc::new(Shared {
        out: out.to_path_buf(),
        status: status.clone(),
        shutdown: shutdown.clone(),
        wind: Mutex::new(WindSelector::new(
            config.wind.priority(),
            config.wind.max_age_s,
        )),
        wind_log: Mutex::new(wind_log),
        rebuild: rebuild.clone(),
        live: live_tx.clone(),
        tree_tx,
        slot: Slot::default(),
        recon_config: Mutex::new(config.clone()),
        config,
    });
    if handle_signals {
        let s = shared.clone();
        rt.spawn(async move { reload_on_hangup(s, reload).await });
    }
    if !d.osc_control.is_empty() {
        let socket = rt
            .block_on(tokio::net::UdpSocket::bind(&d.osc_control))
            .map_err(|e| Error::Runtime(format!("OSC control on {}: {e}", d.osc_control)))?;
        let allow = crate::source::allow::AllowList::parse("osc.allow", &shared.config.osc.allow)?;
        let s = shared.clone();
        let stop = stop_rx.clone();
        rt.spawn(async move { osc_control(socket, allow, s, stop).await });
    }

    // HTTP first: a busy port is an error the user must see at once.
    if !d.http.is_empty() {
        let listener = rt
            .block_on(tokio::net::TcpListener::bind(&d.http))
            .map_err(|e| Error::Runtime(format!("HTTP on {}: {e}", d.http)))?;
        let st = status.clone();
        let st2 = status.clone();
        let rb = rebuild.clone();
        let state = http::HttpState {
            tree: tree_rx,
            live: live_tx.clone(),
            status: Arc::new(move || st.to_json()),
            metrics: Arc::new(move || st2.to_prometheus()),
            rebuild: Arc::new(move || rb.store(true, Ordering::Relaxed)),
            shutdown: stop_rx.clone(),
        };
        rt.spawn(async move {
            if let Err(e) = http::serve(listener, state).await {
                tracing::error!("HTTP server: {e}");
            }
        });
        tracing::info!("HTTP on http://{}", d.http);
    }

    let (sink, rx) = frame_channel(d.channel_frames as usize);
    let source_thread = start_source(&shared, &rt, sink.clone(), stop_rx.clone())?;

    let mut threads = Vec::new();
    if !shared.config.wind.sensor_port.is_empty() {
        threads.push(start_serial(&shared));
    }
    let handoff = Arc::new(AnalysisHandoff::default());
    let (tips_tx, tips_rx) = bounded::<Vec<(usize, DVec3)>>(4);
    {
        let s = shared.clone();
        let h = handoff.clone();
        threads.push(spawn("treemocap-analysis", move || analysis_loop(&s, &h)));
    }
    {
        let s = shared.clone();
        threads.push(spawn("treemocap-recon", move || recon_loop(&s, tips_tx)));
    }
    let result = pipeline_loop(&shared, rx, &sink, &handoff, tips_rx);
    shutdown.store(true, Ordering::Relaxed);
    shared.slot.ready.notify_all();
    handoff.wake();
    for t in threads {
        let _ = t.join();
    }
    if let Some(t) = source_thread {
        let _ = t.join();
    }
    rt.shutdown_timeout(Duration::from_millis(500));
    result
}

async fn wait_for_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        if let Ok(mut term) = signal(SignalKind::terminate()) {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
            return;
        }
    }
    let _ = tokio::signal::ctrl_c().await;
}

#[cfg(unix)]
async fn reload_on_hangup(shared: Arc<Shared>, reload: Option<Reload>) {
    use tokio::signal::unix::{signal, SignalKind};
    let Ok(mut hup) = signal(SignalKind::hangup()) else {
        return;
    };
    while hup.recv().await.is_some() {
        let Some(reload) = &reload else {
            shared.rebuild.store(true, Ordering::Relaxed);
            continue;
        };
        match reload() {
            Ok(new) => {
                tracing::info!("SIGHUP: config reloaded; rebuilding");
                if let Ok(mut c) = shared.recon_config.lock() {
                    *c = new;
                }
                if let Ok(mut e) = shared.status.config_error.lock() {
                    *e = None;
                }
                shared.rebuild.store(true, Ordering::Relaxed);
            }
            Err(e) => {
                tracing::error!("SIGHUP: {e}; keeping the running config");
                if let Ok(mut g) = shared.status.config_error.lock() {
                    *g = Some(e.to_string());
                }
            }
        }
    }
}

#[cfg(not(unix))]
async fn reload_on_hangup(_shared: Arc<Shared>, _reload: Option<Reload>) {}

/// `/treemocap/rebuild` over OSC, from allowed senders only.
async fn osc_control(
    socket: tokio::net::UdpSocket,
    allow: crate::source::allow::AllowList,
    shared: Arc<Shared>,
    stop: watch::Receiver<bool>,
) {
    fn asks_rebuild(p: &rosc::OscPacket) -> bool {
        match p {
            rosc::OscPacket::Message(m) => m.addr == "/treemocap/rebuild",
            rosc::OscPacket::Bundle(b) => b.content.iter().any(asks_rebuild),
        }
    }
    let mut buf = vec![0u8; 65536];
    let stopped = http::until_true(stop);
    tokio::pin!(stopped);
    loop {
        tokio::select! {
            r = socket.recv_from(&mut buf) => {
                let Ok((n, from)) = r else { continue };
                if !allow.allows(from.ip()) {
                    tracing::warn!("OSC control: {from} is not in osc.allow; ignored");
                    continue;
                }
                match rosc::decoder::decode_udp(&buf[..n]) {
                    Ok((_, p)) if asks_rebuild(&p) => shared.rebuild.store(true, Ordering::Relaxed),
                    Ok(_) => {}
                    Err(e) => tracing::warn!("OSC control from {from}: {e:?}"),
                }
            }
            _ = &mut stopped => return,
        }
    }
}

fn spawn(name: &str, f: impl FnOnce() + Send + 'static) -> std::thread::JoinHandle<()> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(f)
        .expect("spawn a daemon thread")
}

/// Starts the configured source; a replay runs on its own thread.
fn start_source(
    shared: &Arc<Shared>,
    rt: &tokio::runtime::Runtime,
    sink: FrameSink,
    stop: watch::Receiver<bool>,
) -> Result<Option<std::thread::JoinHandle<()>>> {
    let c = &shared.config;
    let d = &c.daemon;
    let set_source = |s: String| {
        if let Ok(mut g) = shared.status.source.lock() {
            *g = s;
        }
    };
    match d.source.as_str() {
        "replay" => {
            let path = replay::locate(Path::new(&d.replay_file), "daemon.replay_file")?;
            let opts = ReplayOptions::from_config(c);
            let first = replay::open_with(&path, &opts)?;
            set_source(format!("replay {} at {}×", path.display(), d.replay_speed));
            let (speed, repeat) = (d.replay_speed, d.replay_loop);
            let s = shared.clone();
            Ok(Some(spawn("treemocap-replay", move || {
                let reopen = || replay::open_with(&path, &opts);
                match crate::source::player::play(first, &reopen, &sink, speed, repeat, &s.shutdown)
                {
                    Ok(r) => tracing::info!("replay finished: {} frames", r.frames),
                    Err(e) => {
                        tracing::error!("{e}");
                        if let Ok(mut g) = s.status.source_error.lock() {
                            *g = Some(e.to_string());
                        }
                    }
                }
            })))
        }
        kind => {
            let source: Arc<dyn LiveSource> = if kind == "natnet" {
                use crate::source::natnet::{client::NatNetOptions, live::NatNetSource, Transport};
                let mut opts = NatNetOptions::from_config(&c.natnet);
                opts.set_server(&d.natnet_server, "daemon.natnet_server")?;
                opts.transport = match d.natnet_transport.as_str() {
                    "unicast" => Some(Transport::Unicast),
                    "multicast" => Some(Transport::Multicast),
                    _ => None,
                };
                Arc::new(NatNetSource(opts))
            } else {
                let opts = crate::source::osc::OscOptions::from_config(&c.osc)?;
                Arc::new(crate::source::osc::OscSource(opts))
            };
            set_source(source.describe());
            let s = shared.clone();
            rt.spawn(async move {
                if let Err(e) = source.start(sink, stop).await {
                    tracing::error!("{e}");
                    if let Ok(mut g) = s.status.source_error.lock() {
                        *g = Some(e.to_string());
                    }
                }
            });
            Ok(None)
        }
    }
}

fn start_serial(shared: &Arc<Shared>) -> std::thread::JoinHandle<()> {
    let w = &shared.config.wind;
    let opts = serial::SerialOptions {
        port: w.sensor_port.clone(),
        baud: w.sensor_baud,
        heading_deg: w.sensor_heading_deg,
        backoff_min: Duration::from_millis(200),
        backoff_max: Duration::from_secs(5),
    };
    let status = Arc::new(serial::SerialStatus::default());
    let stop = Arc::new(AtomicBool::new(false));
    let s = shared.clone();
    let s2 = shared.clone();
    let clock: Arc<dyn Fn() -> f64 + Send + Sync> = Arc::new(move || s.status.frame_time());
    let stop2 = stop.clone();
    let watcher_shared = shared.clone();
    let handle = serial::spawn(
        opts,
        clock,
        Box::new(move |e| new_wind(&s2, e)),
        status,
        stop,
    );
    spawn("treemocap-serial-stop", move || {
        while !watcher_shared.shutdown.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(50));
        }
        stop2.store(true, Ordering::Relaxed);
        let _ = handle.join();
    })
}

/// A new wind estimate from any source: selector, log, status, outputs.
fn new_wind(shared: &Shared, e: WindEstimate) {
    if let Ok(mut sel) = shared.wind.lock() {
        sel.update(e);
    }
    if let Ok(mut log) = shared.wind_log.lock() {
        if let Some(l) = log.as_mut() {
            if let Err(err) = l.write(&e) {
                tracing::warn!("{err}");
            }
        }
    }
    let current = shared.wind.lock().ok().and_then(|s| s.current(e.time_s));
    if let Ok(mut w) = shared.status.wind.lock() {
        *w = current;
    }
    let _ = shared.live.send(
        serde_json::json!({
            "type": "wind", "source": e.source.name(), "azimuth_deg": e.azimuth_deg(),
            "direction": [e.direction.x, e.direction.y, e.direction.z], "speed_m_s": e.speed_m_s,
        })
        .to_string()
        .into(),
    );
}

/// A sender to `daemon.osc_targets` (validated by the config), or `None`
/// when there are none.
fn osc_sender(targets: &[String]) -> Result<Option<OscSender>> {
    if targets.is_empty() {
        return Ok(None);
    }
    OscSender::new(targets.iter().filter_map(|t| t.parse().ok()).collect()).map(Some)
}

/// Per frame: record, window, live tips, PCA; hands the window to analysis.
fn pipeline_loop(
    shared: &Arc<Shared>,
    rx: FrameReceiver,
    sink: &FrameSink,
    handoff: &AnalysisHandoff,
    tips_rx: Receiver<Vec<(usize, DVec3)>>,
) -> Result<()> {
    let c = &shared.config;
    let d = &c.daemon;
    let status = &shared.status;
    let mut window = FrameWindow::new(d.window_s);
    let mut follower = TipFollower::new(d.follow_gate_mm / 1000.0);
    let mut pca = SwayPca::new(c.wind.pca_window_s, c.wind.pca_min_sway_mm / 1000.0);
    let mut next_pca = f64::NEG_INFINITY;
    let mut next_analysis = f64::NEG_INFINITY;
    // Until two frames have been seen the rate is unknown; 100 Hz is only
    // the placeholder for the recording's header.
    let mut frame_rate = 100.0;
    let mut rate_known = false;
    let mut last_time: Option<f64> = None;
    let mut osc = osc_sender(&d.osc_targets)?;
    let mut recorder = if d.record {
        let path = shared.out.join("session.log.csv");
        let header = LogHeader {
            source: status.source.lock().map(|s| s.clone()).unwrap_or_default(),
            frame_rate,
        };
        Some(LogWriter::create(
            &path,
            &header,
            Duration::from_secs_f64(c.record.flush_interval_s),
        )?)
    } else {
        None
    };
    let mut record_error_logged = false;
    while !shared.shutdown.load(Ordering::Relaxed) {
        if let Some(w) = recorder.as_mut() {
            if let Err(e) = w.tick() {
                record_failed(status, &e, &mut record_error_logged);
            }
        }
        while let Ok(tips) = tips_rx.try_recv() {
            follower.set_tips(&tips);
            status.tips.store(tips.len() as u64, Ordering::Relaxed);
        }
        let (frame, arrived) = match rx.recv_timeout_arrived(Duration::from_millis(50)) {
            Ok(f) => f,
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => {
                // A quiet source (a finished replay, a paused rig) must not
                // leave a requested rebuild waiting for the next frame.
                if shared.rebuild.load(Ordering::Relaxed) && !window.is_empty() {
                    offer_window(handoff, &mut window, frame_rate);
                }
                continue;
            }
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => break,
        };
        status.record_backlog(rx.len(), arrived.elapsed());
        status.frames.fetch_add(1, Ordering::Relaxed);
        status
            .samples
            .fetch_add(frame.markers.len() as u64, Ordering::Relaxed);
        status
            .markers
            .store(frame.markers.len() as u64, Ordering::Relaxed);
        status
            .last_frame
            .store(frame.frame as u64, Ordering::Relaxed);
        status
            .last_frame_time_bits
            .store(frame.time_s.to_bits(), Ordering::Relaxed);
        status.dropped.store(sink.dropped(), Ordering::Relaxed);
        if let Some(prev) = last_time {
            let dt = frame.time_s - prev;
            if dt > 0.0 {
                // A smoothed estimate of the source's rate for the analysis.
                frame_rate = if rate_known {
                    0.99 * frame_rate + 0.01 / dt
                } else {
                    1.0 / dt
                };
                rate_known = true;
                status
                    .frame_rate_bits
                    .store(frame_rate.to_bits(), Ordering::Relaxed);
            }
        }
        last_time = Some(frame.time_s);
        if let Some(w) = recorder.as_mut() {
            if let Err(e) = w.write_frame(&frame) {
                record_failed(status, &e, &mut record_error_logged);
            }
        }

        let now = frame.time_s;
        let positions: Vec<DVec3> = frame.positions().collect();
        if !follower.is_empty() {
            let seen = follower.update(&positions);
            status.tips_live.store(seen.len() as u64, Ordering::Relaxed);
            pca.push(now, follower.displacements(&seen));
            if shared.live.receiver_count() > 0 {
                let _ = shared
                    .live
                    .send(http::tips_message(frame.frame, now, &seen));
            }
            if let Some(o) = osc.as_mut() {
                o.send(&tips_datagram(frame.frame, now, &seen));
            }
            if now >= next_pca {
                next_pca = now + c.wind.pca_window_s;
                if let Some(e) = pca.estimate() {
                    new_wind(shared, e);
                    if let Some(o) = osc.as_mut() {
                        o.send(&wind_datagram(&e));
                    }
                }
            }
        }
        window.push(&frame);
        drop(frame);
        let due = now >= next_analysis || now < next_analysis - 2.0 * d.analysis_interval_s;
        // Analysis still busy: asked again next frame (two atomic loads).
        if due && offer_window(handoff, &mut window, frame_rate) {
            next_analysis = now + d.analysis_interval_s;
        }
        let us = arrived.elapsed().as_micros() as u64;
        status.latency_us_last.store(us, Ordering::Relaxed);
        status.latency_us_max.fetch_max(us, Ordering::Relaxed);
        status.latency_hist.record(us);
    }
    if let Some(w) = recorder.take() {
        if let Err(e) = w.finish() {
            record_failed(status, &e, &mut record_error_logged);
        }
    }
    Ok(())
}

/// Hands a snapshot of the window to the analysis if it is free; true if it
/// was handed over. No frame is copied either way.
fn offer_window(handoff: &AnalysisHandoff, window: &mut FrameWindow, frame_rate: f64) -> bool {
    if !handoff.wants() {
        return false;
    }
    handoff.offer(Job {
        snapshot: window.snapshot(),
        frame_rate: frame_rate.round().max(1.0),
    });
    true
}

fn record_failed(status: &Status, e: &Error, logged: &mut bool) {
    if !*logged {
        tracing::error!("recording: {e}");
        *logged = true;
    }
    if let Ok(mut g) = status.output_error.lock() {
        *g = Some(format!("recording: {e}"));
    }
}

/// Tracks the window, finds tips and decides whether a new tree is due.
fn analysis_loop(shared: &Arc<Shared>, handoff: &AnalysisHandoff) {
    let c = &shared.config;
    let d = &c.daemon;
    let mut triggers = Triggers::new(TriggerConfig {
        rest_min_s: d.rest_min_s,
        tip_change_s: d.tip_change_s,
        moved_m: d.moved_mm / 1000.0,
        wind_turn_deg: d.wind_turn_deg,
        period_s: d.period_s,
    });
    // The best rest positions seen so far, from a still phase; every tree is
    // built from them (issue 17: they improve while the still phase goes on,
    // and a rebuild uses the latest).
    let mut best = BestRest::new(d.moved_mm / 1000.0);
    let mut fan_set = false;
    while !shared.shutdown.load(Ordering::Relaxed) {
        let Some(job) = handoff.take(Duration::from_millis(100)) else {
            continue;
        };
        let now = job.snapshot.now_s;
        let (tips, summary) = track_snapshot(&job, &c.tracking);
        drop(job);
        handoff.done();
        shared.status.analyses.fetch_add(1, Ordering::Relaxed);
        // Rest positions come only from a still phase. In a window of
        // continuous wind the tracker falls back to the mean of the sway,
        // which is bent downwind: that is not a tip moving, so the best
        // rest positions stand and only wind, request and period can fire.
        if summary.rest_source != crate::track::RestSource::WholeRecording && !tips.tips.is_empty()
        {
            offer_rest(&mut best, tips);
        }
        let Some(rest) = best.get() else {
            continue;
        };
        if !fan_set {
            if let Some(e) = fan::configured_fan_wind(&c.wind, &rest.positions, now) {
                new_wind(shared, e);
            }
            fan_set = true;
        }
        let wind = shared.wind.lock().ok().and_then(|s| s.current(now));
        if shared.rebuild.swap(false, Ordering::Relaxed) {
            triggers.request();
        }
        let Some(reason) = triggers.check(
            now,
            &rest.positions,
            rest.len_s(),
            wind.map(|w| w.direction),
        ) else {
            continue;
        };
        let mut built = rest.payload.clone();
        built.wind = wind;
        let captured = built.captured();
        triggers.built(now, &rest.positions, wind.map(|w| w.direction));
        let tips_json = built.to_json();
        let wv = wind.map_or(DVec3::ZERO, |w| w.flow_vector());
        tracing::info!("new tree: {reason}");
        if let Ok(mut p) = shared.slot.pending.lock() {
            *p = Some(Build {
                fired: Instant::now(),
                reason,
                time_s: now,
                tips: captured,
                tips_json,
                wind: wv,
            });
        }
        shared.slot.ready.notify_one();
    }
}

/// Offers an analysis's rest positions to the best estimate, without the
/// traces (they are the window's size; only the rest positions are kept).
fn offer_rest(best: &mut BestRest<Tips>, mut tips: Tips) {
    for t in &mut tips.tips {
        t.trace = crate::model::trace::Trace::new(t.trace.id, 0, t.rest, None);
    }
    tips.timeline = Default::default();
    best.offer(RestEstimate {
        positions: tips.tips.iter().map(|t| t.rest).collect(),
        window_s: tips.rest_window_s,
        payload: tips,
    });
}

/// Builds trees on request and hands them to every output.
fn recon_loop(shared: &Arc<Shared>, tips_tx: Sender<Vec<(usize, DVec3)>>) {
    let c = &shared.config;
    let version = AtomicU64::new(0);
    let mut osc = osc_sender(&c.daemon.osc_targets).ok().flatten();
    loop {
        let build = {
            let Ok(mut pending) = shared.slot.pending.lock() else {
                return;
            };
            while pending.is_none() && !shared.shutdown.load(Ordering::Relaxed) {
                pending = match shared
                    .slot
                    .ready
                    .wait_timeout(pending, Duration::from_millis(100))
                {
                    Ok((g, _)) => g,
                    Err(_) => return,
                };
            }
            match pending.take() {
                Some(b) => b,
                None => return, // shutdown
            }
        };
        let started = Instant::now();
        let config = match shared.recon_config.lock() {
            Ok(g) => g.clone(),
            Err(_) => return,
        };
        let outputs = match build_model(&build.tips, build.wind, &config) {
            Ok(o) => o,
            Err(e) => {
                tracing::error!("reconstruction: {e}");
                continue;
            }
        };
        let v = version.fetch_add(1, Ordering::Relaxed) + 1;
        let snapshot = Arc::new(TreeSnapshot {
            version: v,
            time_s: build.time_s,
            reason: build.reason.to_string(),
            nodes: SnapshotNode::of_tree(&outputs.tree),
            glb: outputs.glb,
            tree_json: outputs.tree_json,
            tips_json: build.tips_json,
        });
        // Viewers first (memory, sockets), then the picture and the disk.
        let _ = shared.tree_tx.send(Some(snapshot.clone()));
        let _ = tips_tx.try_send(build.tips.iter().map(|t| (t.marker, t.position)).collect());
        let _ = shared.live.send(http::tree_notice(&snapshot));
        let published_ms = build.fired.elapsed().as_secs_f64() * 1000.0;
        if let Some(o) = osc.as_mut() {
            o.send_paced(&tree_datagrams(&snapshot));
        }
        // A picture that cannot be drawn is reported, and no empty
        // tree.png is written in its place.
        let png = crate::render::picture::tree_png(&outputs.tree)
            .map_err(|e| tracing::error!("tree.png: {e}"))
            .ok();
        write_files(shared, &snapshot, png.as_deref(), v);
        let st = &shared.status;
        st.trees.fetch_add(1, Ordering::Relaxed);
        st.tree_version.store(v, Ordering::Relaxed);
        if let Ok(mut t) = st.last_tree.lock() {
            *t = Some(serde_json::json!({
                "version": v,
                "reason": build.reason,
                "time_s": build.time_s,
                "nodes": snapshot.nodes.len(),
                "tips": build.tips.len(),
                "forced_joins": outputs.report.forced_joins,
                "trigger_to_outputs_ms": published_ms,
                "build_ms": started.elapsed().as_secs_f64() * 1000.0,
            }));
        }
    }
}

/// Rewrites tree.glb, tree.json, tips.json, tree.png (and the numbered
/// history). A failing disk is reported on /status; the daemon goes on.
fn write_files(shared: &Shared, t: &TreeSnapshot, png: Option<&[u8]>, version: u64) {
    let mut files: Vec<(String, &[u8])> = vec![
        ("tree.glb".into(), &t.glb),
        ("tree.json".into(), t.tree_json.as_bytes()),
        ("tips.json".into(), t.tips_json.as_bytes()),
    ];
    let mut error = None;
    match png {
        Some(png) => files.push(("tree.png".into(), png)),
        None => error = Some("tree.png: the picture could not be drawn".to_string()),
    }
    if shared.config.daemon.history {
        files.push((format!("tree-{version:04}.glb"), &t.glb));
        files.push((format!("tree-{version:04}.json"), t.tree_json.as_bytes()));
    }
    for (name, bytes) in files {
        if let Err(e) = write_atomic(&shared.out.join(&name), bytes) {
            tracing::error!("{e}");
            error = Some(e.to_string());
        }
    }
    if let Ok(mut g) = shared.status.output_error.lock() {
        *g = error;
    }
}
