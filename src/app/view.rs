//! `treemocap view PATH`: the live page for a finished session, with a
//! timeline to scrub through it.
//!
//! PATH is a recording (any format `replay` reads: the marker stage runs on
//! it) or an output folder (`replay --out`, or the daemon's `out/`): its
//! `tree.glb`, `tree.json`, `tips.json` are served, and its frames come from
//! `session.log.csv` in the folder (the daemon's recording) or from
//! `--recording FILE`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use tokio::sync::watch;

use crate::app::open::open_recording;
use crate::app::replay::estimate_wind;
use crate::config::Config;
use crate::error::{Error, Result};
use crate::model::frame::MarkerFrame;
use crate::serve::http::{self, HttpState};
use crate::serve::live::LiveHub;
use crate::serve::snapshot::TreeSnapshot;
use crate::serve::view::{self, SessionFrames, ViewState};
use crate::track;

/// What `view` serves, gathered before the server starts.
pub struct ViewSession {
    /// The recording the frames came from, if any.
    pub recording: Option<PathBuf>,
    /// The frames and what the marker stage made of them.
    pub frames: Arc<SessionFrames>,
    /// The tree of the output folder, if it has one.
    pub tree: Option<Arc<TreeSnapshot>>,
    /// The `/status` document.
    pub status: serde_json::Value,
    /// `session.json`.
    pub info: serde_json::Value,
}

/// Reads PATH (and `recording`, for a folder) and runs the marker stage.
pub fn load(path: &Path, recording: Option<&Path>, config: &Config) -> Result<ViewSession> {
    let (folder, recording) = if path.is_dir() {
        let log = path.join("session.log.csv");
        let rec = recording
            .map(Path::to_path_buf)
            .or_else(|| log.is_file().then_some(log));
        (Some(path), rec)
    } else {
        (None, Some(path.to_path_buf()))
    };
    let tree = match folder {
        Some(dir) => read_tree(dir)?,
        None => None,
    };
    let (frames, wind, source) = match &recording {
        Some(file) => {
            let frames: Vec<MarkerFrame> =
                open_recording(file, config)?.collect::<Result<Vec<_>>>()?;
            let mut rec = open_recording(file, config)?;
            let (tips, _) = track::process(rec.as_mut(), &config.tracking)?;
            let wind = estimate_wind(&tips, config);
            (
                SessionFrames::new(frames, &tips),
                wind,
                file.display().to_string(),
            )
        }
        None => (SessionFrames::default(), None, path.display().to_string()),
    };
    let info = frames.info(&source, tree.is_some());
    let wind = wind.map(|w| {
        serde_json::json!({
            "source": w.source.name(),
            "azimuth_deg": w.azimuth_deg(),
            "direction": [w.direction.x, w.direction.y, w.direction.z],
            "speed_m_s": w.speed_m_s,
        })
    });
    let status = serde_json::json!({
        "mode": "view",
        "source": source,
        "connection": {"state": "file"},
        "frames": info["frames"],
        "frame_rate_hz": info["frame_rate_hz"],
        "tips": info["tips"],
        "tree": tree.is_some(),
        "tree_version": tree.as_ref().map(|t| t.version),
        "wind": wind,
    });
    Ok(ViewSession {
        recording,
        frames: Arc::new(frames),
        tree,
        status,
        info,
    })
}

/// The tree files of an output folder, `None` when it has no `tree.glb`.
fn read_tree(dir: &Path) -> Result<Option<Arc<TreeSnapshot>>> {
    let glb_path = dir.join("tree.glb");
    if !glb_path.is_file() {
        return Ok(None);
    }
    let read = |name: &str| -> Result<String> {
        let p = dir.join(name);
        if p.is_file() {
            std::fs::read_to_string(&p).map_err(|e| Error::io(&p, e))
        } else {
            Ok(String::new())
        }
    };
    Ok(Some(Arc::new(TreeSnapshot {
        version: 1,
        time_s: 0.0,
        reason: "from the output folder".into(),
        glb: std::fs::read(&glb_path).map_err(|e| Error::io(&glb_path, e))?,
        tree_json: read("tree.json")?,
        tips_json: read("tips.json")?,
        nodes: Vec::new(),
        trees: Vec::new(),
        rig: None,
    })))
}

/// Serves the session on `listener` until `shutdown` turns true or Ctrl-C; `ready`
/// is called with the page's URL once the server listens.
pub fn serve(
    session: ViewSession,
    listener: std::net::TcpListener,
    shutdown: watch::Receiver<bool>,
    ready: impl FnOnce(String),
) -> Result<()> {
    let addr = listener
        .local_addr()
        .map_err(|e| Error::Runtime(format!("view: {e}")))?;
    listener
        .set_nonblocking(true)
        .map_err(|e| Error::Runtime(format!("view: {e}")))?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| Error::Runtime(format!("cannot start the async runtime: {e}")))?;
    let (_tree_tx, tree_rx) = watch::channel(session.tree.clone());
    let status = session.status.clone();
    let state = HttpState {
        tree: tree_rx,
        hub: Arc::new(LiveHub::default()),
        status: Arc::new(move || status.clone()),
        metrics: Arc::new(String::new),
        rebuild: None,
        shutdown: shutdown.clone(),
    };
    let router = http::router(state).merge(view::routes(ViewState {
        frames: session.frames.clone(),
        info: Arc::new(session.info.clone()),
    }));
    ready(format!("http://{addr}/"));
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::from_std(listener)?;
        tokio::select! {
            r = http::serve_router(listener, router, shutdown) => r,
            _ = tokio::signal::ctrl_c() => Ok(()),
        }
    })
    .map_err(|e| Error::Runtime(format!("view: HTTP on {addr}: {e}")))
}
