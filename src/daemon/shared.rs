//! What the daemon's threads share: the settings, the status counters, the
//! wind, the outputs' channels and the latest-wins hand-off of tree requests.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Instant;

use glam::DVec3;
use tokio::sync::watch;

use super::status::Status;
use super::triggers::Reason;
use super::wind_log::WindLog;
use crate::config::Config;
use crate::model::tips::CapturedTip;
use crate::model::wind::WindEstimate;
use crate::serve::live::LiveHub;
use crate::serve::snapshot::TreeSnapshot;
use crate::shutdown::Shutdown;
use crate::wind::WindSelector;

/// Locks a mutex whose holder may have panicked. Every value the daemon
/// keeps behind a lock (status strings, the wind selector, the pending
/// tree request) is whole after any single assignment, so the value a
/// panicking thread left behind is still a valid one: the daemon goes on
/// with it instead of skipping the update or panicking in turn.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A request to build a tree.
pub(crate) struct TreeRequest {
    /// When the trigger fired, for the trigger-to-tree time.
    pub(crate) fired: Instant,
    /// Why the tree is rebuilt.
    pub(crate) reason: Reason,
    /// Session time (s) of the data the tips come from.
    pub(crate) time_s: f64,
    /// The captured tips to build from.
    pub(crate) tips: Vec<CapturedTip>,
    /// tips.json of those tips with the wind used, written beside the tree.
    pub(crate) tips_json: String,
    /// The wind vector of the flow.
    pub(crate) wind: DVec3,
    /// Tips that sway together, which help split several trees
    /// (docs/forest.md); empty without a wind phase.
    pub(crate) links: Vec<crate::reconstruct::forest::SwayLink>,
}

/// The latest-wins hand-off from the analysis to the tree builder: a new
/// request replaces one not yet started, so the builder never works through
/// a backlog of stale trees.
#[derive(Default)]
pub(crate) struct LatestRequest {
    state: Mutex<RequestState>,
    ready: Condvar,
}

#[derive(Default)]
struct RequestState {
    pending: Option<TreeRequest>,
    /// No request will come any more (the analysis has stopped).
    closed: bool,
}

impl LatestRequest {
    /// Replaces the pending request.
    pub(crate) fn put(&self, request: TreeRequest) {
        lock(&self.state).pending = Some(request);
        self.ready.notify_one();
    }

    /// Tells the builder that no request will follow.
    pub(crate) fn close(&self) {
        lock(&self.state).closed = true;
        self.ready.notify_all();
    }

    /// Waits for the next request; `None` once closed and empty.
    pub(crate) fn take(&self) -> Option<TreeRequest> {
        let mut state = lock(&self.state);
        loop {
            if let Some(r) = state.pending.take() {
                return Some(r);
            }
            if state.closed {
                return None;
            }
            state = self
                .ready
                .wait(state)
                .unwrap_or_else(PoisonError::into_inner);
        }
    }
}

/// Everything the threads share.
pub(crate) struct Shared {
    /// The settings the daemon started with.
    pub(crate) config: Config,
    /// The settings reconstruction uses; SIGHUP replaces them.
    pub(crate) recon_config: Mutex<Config>,
    /// The output folder.
    pub(crate) out: PathBuf,
    /// Counters and states for /status and /metrics.
    pub(crate) status: Arc<Status>,
    /// The process's shutdown signal.
    pub(crate) shutdown: Shutdown,
    /// The latest wind estimate of every source, by priority.
    pub(crate) wind: Mutex<WindSelector>,
    /// wind.csv, when it could be created.
    pub(crate) wind_log: Mutex<Option<WindLog>>,
    /// A rebuild was asked for (HTTP, OSC, SIGHUP).
    pub(crate) rebuild: Arc<AtomicBool>,
    /// Frames and JSON events for the live page's WebSocket (`/live`).
    pub(crate) hub: Arc<LiveHub>,
    /// The latest tree for HTTP.
    pub(crate) tree_tx: watch::Sender<Option<Arc<TreeSnapshot>>>,
    /// Tree requests from the analysis to the builder.
    pub(crate) requests: LatestRequest,
    /// Which CPUs the pipeline and the background threads run on
    /// (`daemon.pipeline_cpu`).
    pub(crate) placement: super::affinity::Placement,
}

impl Shared {
    /// A new wind estimate from any source: selector, log, status, viewers.
    pub(crate) fn new_wind(&self, e: WindEstimate) {
        let current = {
            let mut sel = lock(&self.wind);
            sel.update(e);
            sel.current(e.time_s)
        };
        if let Some(log) = lock(&self.wind_log).as_mut() {
            if let Err(err) = log.write(&e) {
                tracing::warn!("{err}");
            }
        }
        *lock(&self.status.wind) = current;
        self.hub.publish_event(
            serde_json::json!({
                "type": "wind", "source": e.source.name(), "azimuth_deg": e.azimuth_deg(),
                "direction": [e.direction.x, e.direction.y, e.direction.z], "speed_m_s": e.speed_m_s,
            })
            .to_string()
            .into(),
        );
    }

    /// Asks for a rebuild at the next analysis.
    pub(crate) fn ask_rebuild(&self) {
        self.rebuild.store(true, Ordering::Relaxed);
    }

    /// Records an output that could not be made (shown on /status).
    pub(crate) fn output_error(&self, e: Option<String>) {
        *lock(&self.status.output_error) = e;
    }
}
