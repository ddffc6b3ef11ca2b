//! Starting the daemon's inputs: the configured frame source, the serial wind
//! sensor and the OSC control port. Each runs until the shutdown signal.

use std::path::PathBuf;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use super::shared::{lock, Shared};
use super::spawn;
use super::status::SourceState;
use crate::app::live::{natnet_source, osc_source};
use crate::app::open::{locate, open_with, ReplayOptions};
use crate::config::DaemonSource;
use crate::error::{Error, Result};
use crate::source::allow::AllowList;
use crate::source::channel::FrameSink;
use crate::source::live::LiveSource;
use crate::source::player::play;
use crate::source::wind_sensor as serial;

/// Starts the configured source: a replay plays on its own thread (returned
/// for joining), a live source runs as a task on `rt`.
pub(crate) fn start_source(
    shared: &Arc<Shared>,
    rt: &tokio::runtime::Handle,
    sink: FrameSink,
) -> Result<Option<JoinHandle<()>>> {
    let c = &shared.config;
    let d = &c.daemon;
    let source: Arc<dyn LiveSource> = match d.source {
        DaemonSource::Replay => return start_replay(shared, sink).map(Some),
        DaemonSource::Natnet => {
            let mut settings = c.natnet.clone();
            settings.transport = d.natnet_transport;
            natnet_source(settings, &d.natnet_server, "daemon.natnet_server")?
        }
        DaemonSource::Osc => osc_source(c, None)?,
    };
    *lock(&shared.status.source) = source.describe();
    let counted = source.clone();
    let name = match d.source {
        DaemonSource::Natnet => "natnet",
        _ => "osc",
    };
    shared
        .status
        .bad_input
        .register(name, Arc::new(move || counted.losses()));
    let probe = source.clone();
    let _ = shared
        .status
        .source_state
        .set(SourceState(Arc::new(move || probe.status())));
    rt.spawn(log_state_changes(
        source.clone(),
        shared.shutdown.receiver(),
    ));
    let s = shared.clone();
    let stop = shared.shutdown.receiver();
    rt.spawn(async move {
        if let Err(e) = source.start(sink, stop).await {
            tracing::error!("{e}");
            *lock(&s.status.source_error) = Some(e.to_string());
        }
    });
    Ok(None)
}

/// Logs each change of the source's state ("connected to …", "frames fail
/// to decode; renegotiating"), as `record` prints them: the operator reads
/// in the log what `/status` shows as `source_state`.
async fn log_state_changes(
    source: Arc<dyn LiveSource>,
    mut stop: tokio::sync::watch::Receiver<bool>,
) {
    let mut last: Option<String> = None;
    let mut tick = tokio::time::interval(Duration::from_millis(250));
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = stop.changed() => return,
        }
        let now = source.status();
        if now != last {
            match &now {
                Some(s) if s.contains("fail") => tracing::warn!("source: {s}"),
                Some(s) => tracing::info!("source: {s}"),
                None => {}
            }
            last = now;
        }
    }
}

/// `daemon.replay_file` played at `daemon.replay_speed`: a stand-in for the
/// rig. The file is opened here so that a missing file fails the start.
fn start_replay(shared: &Arc<Shared>, sink: FrameSink) -> Result<JoinHandle<()>> {
    let d = &shared.config.daemon;
    let path = locate(&PathBuf::from(&d.replay_file), "daemon.replay_file")?;
    let opts = ReplayOptions::from_config(&shared.config);
    let first = open_with(&path, &opts)?;
    *lock(&shared.status.source) = format!("replay {} at {}×", path.display(), d.replay_speed);
    let (speed, repeat) = (d.replay_speed, d.replay_loop);
    let s = shared.clone();
    Ok(spawn("treemocap-replay", move || {
        let reopen = || open_with(&path, &opts);
        let stop = s.shutdown.flag();
        match play(first, &reopen, &sink, speed, repeat, &stop) {
            Ok(r) => tracing::info!("replay finished: {} frames", r.frames),
            Err(e) => {
                tracing::error!("{e}");
                *lock(&s.status.source_error) = Some(e.to_string());
            }
        }
    }))
}

/// The serial wind sensor's reader thread; it reads with a timeout and
/// stops at the next read after the shutdown signal.
pub(crate) fn start_serial(shared: &Arc<Shared>) -> JoinHandle<()> {
    let w = &shared.config.wind;
    let opts = serial::SerialOptions {
        port: w.sensor_port.clone(),
        baud: w.sensor_baud,
        heading_deg: w.sensor_heading_deg,
        backoff_min: Duration::from_millis(200),
        backoff_max: Duration::from_secs(5),
    };
    let s = shared.clone();
    let s2 = shared.clone();
    let clock: Arc<dyn Fn() -> f64 + Send + Sync> = Arc::new(move || s.status.frame_time());
    serial::spawn(
        opts,
        clock,
        Box::new(move |e| s2.new_wind(e)),
        Arc::new(serial::SerialStatus::default()),
        shared.shutdown.flag(),
    )
}

/// Binds `daemon.osc_control` and serves `/treemocap/rebuild` from the
/// senders in `osc.allow` until shutdown.
pub(crate) fn start_osc_control(
    shared: &Arc<Shared>,
    rt: &tokio::runtime::Handle,
    addr: std::net::SocketAddr,
) -> Result<()> {
    // Inside the runtime: tokio registers the socket with its reactor.
    let socket = rt
        .block_on(async { crate::source::osc::bind_buffered(addr) })
        .map_err(|source| Error::Bind {
            what: "OSC control",
            addr,
            source,
        })?;
    let allow = AllowList::parse("osc.allow", &shared.config.osc.allow)?;
    let bad = Arc::new(crate::source::bad_input::BadInput::default());
    let b = bad.clone();
    shared
        .status
        .bad_input
        .register("osc_control", Arc::new(move || b.counts()));
    let (s, stop) = (shared.clone(), shared.shutdown.clone());
    rt.spawn(super::osc_control::run(
        socket,
        allow,
        move || s.ask_rebuild(),
        bad,
        stop,
    ));
    Ok(())
}
