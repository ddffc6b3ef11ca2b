//! The live hub between the pipeline and the viewers of `/live`.
//!
//! The pipeline publishes each frame into a latest-wins slot (a `watch`
//! channel: one short lock, never a wait on a viewer) and rare events (a new
//! tree) into a small broadcast. Each WebSocket session takes the latest
//! frame at most 60 times a second, encodes it (once for all viewers: the
//! bytes are cached with the frame) and sends it; a slow viewer simply gets
//! fewer frames. The status document goes out when it changes, at most
//! 4 times a second. The message format is in the README ("/live").

use std::sync::{Arc, OnceLock};
use std::time::Duration;

use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket};
use tokio::sync::{broadcast, watch};
use tokio::time::Instant;

use super::snapshot::TreeSnapshot;
use crate::protocol::live_frame::{self, LiveFrame, TipState};
use crate::shutdown::until_true;

/// Frames a viewer gets per second at most: what a display shows.
pub const MAX_FRAMES_PER_S: f64 = 60.0;
/// How often a session looks at the status document.
const STATUS_EVERY: Duration = Duration::from_millis(250);

/// A published frame with its encoding, made once by the first viewer that
/// sends it (the pipeline never encodes).
#[derive(Debug)]
pub struct Published {
    /// The frame as the pipeline built it.
    pub frame: LiveFrame,
    /// The binary form, cached.
    bytes: OnceLock<Bytes>,
}

impl Published {
    /// The binary frame (see [`live_frame`]).
    pub fn bytes(&self) -> Bytes {
        self.bytes
            .get_or_init(|| Bytes::from(live_frame::encode(&self.frame)))
            .clone()
    }
}

/// What the pipeline publishes and the `/live` sessions read.
#[derive(Debug)]
pub struct LiveHub {
    /// The latest frame; `None` before the first.
    frame: watch::Sender<Option<Arc<Published>>>,
    /// The latest poses of the swaying trees (JSON `pose` messages of one
    /// frame, one per tree): stream data like the frames, so latest-wins
    /// and thinned per viewer, not queued (a replay fed faster than real
    /// time made hundreds a second, and a slow page fell seconds behind).
    pose: watch::Sender<Option<Arc<[Arc<str>]>>>,
    /// New-tree notices and other rare JSON messages.
    events: broadcast::Sender<Arc<str>>,
}

impl Default for LiveHub {
    fn default() -> Self {
        LiveHub {
            frame: watch::Sender::new(None),
            pose: watch::Sender::new(None),
            events: broadcast::Sender::new(64),
        }
    }
}

impl LiveHub {
    /// True while a viewer is connected: the pipeline builds frames only then.
    pub fn has_viewers(&self) -> bool {
        self.frame.receiver_count() > 0
    }

    /// Replaces the latest frame. Never waits for a viewer.
    pub fn publish_frame(&self, frame: LiveFrame) {
        self.frame.send_replace(Some(Arc::new(Published {
            frame,
            bytes: OnceLock::new(),
        })));
    }

    /// Replaces the latest poses (one message per tree, of one frame).
    /// Never waits for a viewer.
    pub fn publish_pose(&self, texts: Arc<[Arc<str>]>) {
        self.pose.send_replace(Some(texts));
    }

    /// Sends a JSON message to every connected viewer (dropped when none).
    pub fn publish_event(&self, text: Arc<str>) {
        let _ = self.events.send(text);
    }

    /// The latest frame, if any.
    pub fn latest(&self) -> Option<Arc<Published>> {
        self.frame.borrow().clone()
    }
}

/// How a session sends frames: binary (the page) or JSON text (scripts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameFormat {
    /// The `TMF1` binary frame.
    Binary,
    /// `{"type":"frame",…}` text.
    Json,
}

/// The JSON form of a frame (`/live?format=json`).
pub fn frame_json(f: &LiveFrame) -> String {
    let state = |s: TipState| match s {
        TipState::Measured => "measured",
        TipState::Filled => "filled",
        TipState::Unseen => "unseen",
    };
    let noise: Vec<usize> = f
        .classes
        .iter()
        .enumerate()
        .filter(|(_, c)| **c == live_frame::MarkerClass::Noise)
        .map(|(i, _)| i)
        .collect();
    serde_json::json!({
        "type": "frame",
        "frame": f.frame,
        "time_s": f.time_s,
        "markers": f.markers,
        "noise": noise,
        "tips": f.tips.iter().map(|t| serde_json::json!({
            "marker": t.marker, "state": state(t.state), "position": t.position,
        })).collect::<Vec<_>>(),
    })
    .to_string()
}

/// One `/live` WebSocket: hello, the current tree, the status, then frames,
/// status changes and events until the viewer leaves or the server stops.
pub async fn session(mut socket: WebSocket, s: HttpState, format: FrameFormat) {
    let mut frames = s.hub.frame.subscribe();
    frames.mark_changed(); // the frame of now, at once, if there is one
                           // Not marked changed: a pose from before the viewer came may belong to
                           // a tree it has not loaded; the next comes within 1/60 s of capture.
    let mut poses = s.hub.pose.subscribe();
    let mut events = s.hub.events.subscribe();
    let shutdown = until_true(s.shutdown.clone());
    tokio::pin!(shutdown);
    if greet(&mut socket, &s).await.is_err() {
        return;
    }
    let gap = Duration::from_secs_f64(1.0 / MAX_FRAMES_PER_S);
    let mut next_frame = Instant::now();
    let mut next_pose = Instant::now();
    let mut status_tick = tokio::time::interval(STATUS_EVERY);
    status_tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut last_status = String::new();
    loop {
        let sent = tokio::select! {
            changed = frames.changed() => {
                if changed.is_err() {
                    break;
                }
                match latest_after_gap(&mut frames, &mut next_frame, gap).await {
                    Some(p) => send_frame(&mut socket, &p, format).await,
                    None => Ok(()),
                }
            }
            changed = poses.changed() => {
                if changed.is_err() {
                    break;
                }
                match latest_after_gap(&mut poses, &mut next_pose, gap).await {
                    Some(texts) => send_texts(&mut socket, &texts).await,
                    None => Ok(()),
                }
            }
            event = events.recv() => match event {
                Ok(text) => send_text(&mut socket, &text).await,
                // Events are rare and repeated in the status (tree_version).
                Err(broadcast::error::RecvError::Lagged(_)) => Ok(()),
                Err(broadcast::error::RecvError::Closed) => break,
            },
            _ = status_tick.tick() => {
                let doc = (s.status)();
                let text = serde_json::json!({"type": "status", "status": doc}).to_string();
                if text == last_status {
                    Ok(())
                } else {
                    let r = send_text(&mut socket, &text).await;
                    last_status = text;
                    r
                }
            }
            incoming = socket.recv() => match incoming {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return,
                Some(Ok(_)) => Ok(()),
            },
            _ = &mut shutdown => break,
        };
        if sent.is_err() {
            return;
        }
    }
    let _ = socket.send(Message::Close(None)).await;
}

/// Thinning, for frames and poses alike: waits out the gap since the last
/// one sent, then takes whatever is latest (the ones in between are never
/// sent: a viewer gets at most one per gap).
async fn latest_after_gap<T: Clone>(
    rx: &mut watch::Receiver<Option<T>>,
    next: &mut Instant,
    gap: Duration,
) -> Option<T> {
    tokio::time::sleep_until(*next).await;
    *next = Instant::now() + gap;
    rx.borrow_and_update().clone()
}

/// The session's first messages: hello, and the current tree if there is one.
async fn greet(socket: &mut WebSocket, s: &HttpState) -> Result<(), axum::Error> {
    let hello = serde_json::json!({"type": "hello", "protocol": 1}).to_string();
    send_text(socket, &hello).await?;
    let current = s.tree.borrow().clone();
    if let Some(t) = current {
        send_text(socket, &tree_notice(&t)).await?;
    }
    Ok(())
}

async fn send_text(socket: &mut WebSocket, text: &str) -> Result<(), axum::Error> {
    socket.send(Message::Text(text.into())).await
}

/// Several messages in a row (the poses of one frame, a tree each).
async fn send_texts(socket: &mut WebSocket, texts: &[Arc<str>]) -> Result<(), axum::Error> {
    for text in texts {
        send_text(socket, text).await?;
    }
    Ok(())
}

async fn send_frame(
    socket: &mut WebSocket,
    p: &Published,
    format: FrameFormat,
) -> Result<(), axum::Error> {
    match format {
        FrameFormat::Binary => socket.send(Message::Binary(p.bytes())).await,
        FrameFormat::Json => send_text(socket, &frame_json(&p.frame)).await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latest_wins_and_viewers_are_counted() {
        let hub = LiveHub::default();
        assert!(!hub.has_viewers());
        let rx = hub.frame.subscribe();
        assert!(hub.has_viewers());
        for f in 0..100 {
            hub.publish_frame(LiveFrame {
                frame: f,
                ..LiveFrame::default()
            });
        }
        // A viewer that looks now sees only the last frame: nothing queued.
        assert_eq!(rx.borrow().as_ref().unwrap().frame.frame, 99);
        let p = hub.latest().unwrap();
        assert_eq!(
            live_frame::decode(&p.bytes()).unwrap(),
            p.frame,
            "cached bytes are the frame"
        );
        drop(rx);
        assert!(!hub.has_viewers());
    }
}

/// What the HTTP server reads. Cheap to clone.
#[derive(Clone)]
pub struct HttpState {
    /// The latest tree, `None` before the first.
    pub tree: watch::Receiver<Option<Arc<TreeSnapshot>>>,
    /// What the pipeline publishes for `/live`: frames and events.
    pub hub: Arc<LiveHub>,
    /// The `/status` document, computed on request.
    pub status: Arc<dyn Fn() -> serde_json::Value + Send + Sync>,
    /// The `/metrics` text, computed on request.
    pub metrics: Arc<dyn Fn() -> String + Send + Sync>,
    /// Called by `POST /rebuild`; `None` where nothing can be rebuilt
    /// (`treemocap view`), and the route answers 405.
    pub rebuild: Option<Arc<dyn Fn() + Send + Sync>>,
    /// Turns true at shutdown; open WebSockets close on it.
    pub shutdown: watch::Receiver<bool>,
}

/// The `/live` message announcing a new tree.
pub fn tree_notice(t: &TreeSnapshot) -> Arc<str> {
    let mut notice = serde_json::json!({
        "type": "tree",
        "version": t.version,
        "time_s": t.time_s,
        "reason": t.reason,
        "nodes": t.nodes.len(),
    });
    // With several trees the notice also lists them (docs/forest.md).
    if !t.trees.is_empty() {
        notice["trees"] = t
            .trees
            .iter()
            .map(|x| serde_json::json!({"id": x.id, "name": x.name, "nodes": x.nodes.len(), "rebuilt": x.rebuilt}))
            .collect();
    }
    notice.to_string().into()
}
