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
//! | `GET /live` | WebSocket: a JSON text message per frame of tips, and one per new tree |
//!
//! The server only reads shared state handed to it ([`HttpState`]); it never
//! blocks the pipeline. A WebSocket client too slow for the frame rate skips
//! frames (it is told how many) instead of holding memory; one that stops
//! reading altogether is closed after the idle timeout. Who may connect, how
//! many at once and for how long: [`super::limits`]. `POST /rebuild` from a
//! web page of another site (a browser on the allowed machine visiting it)
//! is refused by its `Origin` header.

use std::sync::Arc;
use std::time::Duration;

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use tokio::sync::{broadcast, watch, Semaphore};

use super::limits::HttpLimits;
use super::snapshot::TreeSnapshot;
use crate::source::bad_input::BadInput;

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
    router_with(
        state,
        LiveGate {
            sessions: Arc::new(Semaphore::new(Semaphore::MAX_PERMITS)),
            send_timeout: Duration::from_secs(60),
        },
    )
}

fn router_with(state: HttpState, gate: LiveGate) -> Router {
    Router::new()
        .route("/tree.glb", get(tree_glb))
        .route("/tree.json", get(tree_json))
        .route("/tips.json", get(tips_json))
        .route("/status", get(status))
        .route("/metrics", get(metrics))
        .route("/rebuild", post(rebuild))
        .route("/live", get(live))
        .with_state(state)
        .layer(axum::Extension(gate))
}

/// The WebSocket sessions that may still open, and how long a send may
/// wait for a client that stopped reading.
#[derive(Clone)]
struct LiveGate {
    sessions: Arc<Semaphore>,
    send_timeout: Duration,
}

/// Serves until `shutdown` turns true, within `limits`; bad input is counted
/// in `bad`.
pub async fn serve(
    listener: tokio::net::TcpListener,
    state: HttpState,
    limits: HttpLimits,
    bad: Arc<BadInput>,
) -> std::io::Result<()> {
    let shutdown = state.shutdown.clone();
    let gate = LiveGate {
        sessions: Arc::new(Semaphore::new(limits.max_websockets)),
        send_timeout: limits.idle_timeout,
    };
    let app = router_with(state, gate);
    super::limits::serve(listener, app, limits, bad, shutdown).await
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

async fn rebuild(State(s): State<HttpState>, headers: HeaderMap) -> Response {
    if !same_origin(&headers) {
        return (
            StatusCode::FORBIDDEN,
            "POST /rebuild from a page of another site is refused\n",
        )
            .into_response();
    }
    (s.rebuild)();
    (StatusCode::ACCEPTED, "rebuild requested\n").into_response()
}

/// False when a browser says the request comes from a page of another site
/// (its `Origin` names another host than the one asked). Scripts, curl and
/// our viewer send no `Origin` or our own.
fn same_origin(headers: &HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN).and_then(|o| o.to_str().ok()) else {
        return true;
    };
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    let origin_host = origin.split_once("://").map_or(origin, |(_, h)| h);
    !host.is_empty() && origin_host.eq_ignore_ascii_case(host)
}

async fn live(
    ws: WebSocketUpgrade,
    State(s): State<HttpState>,
    axum::Extension(gate): axum::Extension<LiveGate>,
) -> Response {
    let Ok(permit) = gate.sessions.clone().try_acquire_owned() else {
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            "too many /live sessions (daemon.http_max_websockets)\n",
        )
            .into_response();
    };
    ws.on_upgrade(move |socket| async move {
        live_session(socket, s, gate.send_timeout).await;
        drop(permit);
    })
}

/// Sends `text`; false when the client is gone or has not taken it within
/// `timeout` (it stopped reading: the session ends rather than wait).
async fn send(socket: &mut WebSocket, text: &str, timeout: Duration) -> bool {
    matches!(
        tokio::time::timeout(timeout, socket.send(Message::Text(text.into()))).await,
        Ok(Ok(()))
    )
}

async fn live_session(mut socket: WebSocket, s: HttpState, timeout: Duration) {
    let mut rx = s.live.subscribe();
    let shutdown = until_true(s.shutdown.clone());
    tokio::pin!(shutdown);
    if let Some(t) = latest(&s) {
        let hello = tree_notice(&t);
        if !send(&mut socket, &hello, timeout).await {
            return;
        }
    }
    loop {
        tokio::select! {
            msg = rx.recv() => match msg {
                Ok(text) => {
                    if !send(&mut socket, &text, timeout).await {
                        return;
                    }
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    let note = format!("{{\"type\":\"skipped\",\"messages\":{n}}}");
                    if !send(&mut socket, &note, timeout).await {
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
