//! HTTP and WebSocket for viewers, on 127.0.0.1 unless the config says
//! otherwise.
//!
//! | route | what |
//! |---|---|
//! | `GET /tree.glb` | the latest tree, binary glTF (404 until the first tree) |
//! | `GET /tree.json`, `GET /tips.json` | the latest skeleton and tips |
//! | `GET /status` | JSON: sources, rates, markers, tips, drops, last tree, wind |
//! | `GET /metrics` | the same counters in Prometheus text format |
//! | `POST /rebuild` | ask for a new tree now (202 Accepted) |
//! | `GET /live` | WebSocket: a JSON text message per frame of tips, one per new tree, and the tree's sway (`pose`, `super::pose`) |
//!
//! The server only reads shared state handed to it ([`HttpState`]); it never
//! blocks the pipeline. A WebSocket client too slow for the frame rate skips
//! frames (it is told how many) instead of holding memory.

use std::sync::Arc;

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use tokio::sync::{broadcast, watch};

use super::snapshot::TreeSnapshot;

/// What the HTTP server reads. Cheap to clone.
#[derive(Clone)]
pub struct HttpState {
    /// The latest tree, `None` before the first.
    pub tree: watch::Receiver<Option<Arc<TreeSnapshot>>>,
    /// Live messages for `/live` (JSON text), sent by the pipeline.
    pub live: broadcast::Sender<Arc<str>>,
    /// The `/status` document, computed on request.
    pub status: Arc<dyn Fn() -> serde_json::Value + Send + Sync>,
    /// The `/metrics` text, computed on request.
    pub metrics: Arc<dyn Fn() -> String + Send + Sync>,
    /// Called by `POST /rebuild`.
    pub rebuild: Arc<dyn Fn() + Send + Sync>,
    /// Turns true at shutdown; open WebSockets close on it.
    pub shutdown: watch::Receiver<bool>,
}

/// The router, for tests and for [`serve`].
pub fn router(state: HttpState) -> Router {
    Router::new()
        .route("/tree.glb", get(tree_glb))
        .route("/tree.json", get(tree_json))
        .route("/tips.json", get(tips_json))
        .route("/status", get(status))
        .route("/metrics", get(metrics))
        .route("/rebuild", post(rebuild))
        .route("/live", get(live))
        .with_state(state)
}

/// Serves until `shutdown` turns true.
pub async fn serve(listener: tokio::net::TcpListener, state: HttpState) -> std::io::Result<()> {
    let shutdown = state.shutdown.clone();
    axum::serve(listener, router(state))
        .with_graceful_shutdown(until_true(shutdown))
        .await
}

/// Resolves when the flag turns true (or its sender is gone).
pub async fn until_true(mut flag: watch::Receiver<bool>) {
    loop {
        if *flag.borrow_and_update() {
            return;
        }
        if flag.changed().await.is_err() {
            return;
        }
    }
}

fn latest(state: &HttpState) -> Option<Arc<TreeSnapshot>> {
    state.tree.borrow().clone()
}

fn no_tree() -> Response {
    (
        StatusCode::NOT_FOUND,
        "no tree yet: waiting for a still phase of the markers\n",
    )
        .into_response()
}

/// One file of the latest tree, or 404 before the first.
fn tree_file(
    s: &HttpState,
    content_type: &'static str,
    body: fn(&TreeSnapshot) -> Vec<u8>,
) -> Response {
    match latest(s) {
        Some(t) => ([(header::CONTENT_TYPE, content_type)], body(&t)).into_response(),
        None => no_tree(),
    }
}

async fn tree_glb(State(s): State<HttpState>) -> Response {
    tree_file(&s, "model/gltf-binary", |t| t.glb.clone())
}

async fn tree_json(State(s): State<HttpState>) -> Response {
    tree_file(&s, "application/json", |t| t.tree_json.clone().into_bytes())
}

async fn tips_json(State(s): State<HttpState>) -> Response {
    tree_file(&s, "application/json", |t| t.tips_json.clone().into_bytes())
}

async fn status(State(s): State<HttpState>) -> Response {
    let body = serde_json::to_string_pretty(&(s.status)()).unwrap_or_default();
    ([(header::CONTENT_TYPE, "application/json")], body).into_response()
}

async fn metrics(State(s): State<HttpState>) -> Response {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        (s.metrics)(),
    )
        .into_response()
}

async fn rebuild(State(s): State<HttpState>) -> Response {
    (s.rebuild)();
    (StatusCode::ACCEPTED, "rebuild requested\n").into_response()
}

async fn live(ws: WebSocketUpgrade, State(s): State<HttpState>) -> Response {
    ws.on_upgrade(move |socket| live_session(socket, s))
}

async fn live_session(mut socket: WebSocket, s: HttpState) {
    let mut rx = s.live.subscribe();
    let shutdown = until_true(s.shutdown.clone());
    tokio::pin!(shutdown);
    if let Some(t) = latest(&s) {
        let hello = tree_notice(&t);
        if socket
            .send(Message::Text(hello.as_ref().into()))
            .await
            .is_err()
        {
            return;
        }
    }
    loop {
        tokio::select! {
            msg = rx.recv() => match msg {
                Ok(text) => {
                    if socket.send(Message::Text(text.as_ref().into())).await.is_err() {
                        return;
                    }
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    let note = format!("{{\"type\":\"skipped\",\"messages\":{n}}}");
                    if socket.send(Message::Text(note.into())).await.is_err() {
                        return;
                    }
                }
                Err(broadcast::error::RecvError::Closed) => break,
            },
            incoming = socket.recv() => match incoming {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return,
                Some(Ok(_)) => {}
            },
            _ = &mut shutdown => break,
        }
    }
    let _ = socket.send(Message::Close(None)).await;
}

/// The `/live` message announcing a new tree.
pub fn tree_notice(t: &TreeSnapshot) -> Arc<str> {
    serde_json::json!({
        "type": "tree",
        "version": t.version,
        "time_s": t.time_s,
        "reason": t.reason,
        "nodes": t.nodes.len(),
    })
    .to_string()
    .into()
}

/// The `/live` message for one frame of tips: `[marker, x, y, z]` each.
pub fn tips_message(frame: i64, time_s: f64, tips: &[(usize, glam::DVec3)]) -> Arc<str> {
    let list: Vec<serde_json::Value> = tips
        .iter()
        .map(|(i, p)| serde_json::json!([i, p.x, p.y, p.z]))
        .collect();
    serde_json::json!({"type": "tips", "frame": frame, "time_s": time_s, "tips": list})
        .to_string()
        .into()
}
