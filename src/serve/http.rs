//! HTTP and WebSocket for viewers, on 127.0.0.1 unless the config says
//! otherwise.
//!
//! | route | what |
//! |---|---|
//! | `GET /` | the live view: a page showing markers, tips, noise, tree, wind, status |
//! | `GET /tree.glb` | the latest tree, binary glTF (404 until the first tree); `X-Tree-Version` names it |
//! | `GET /trees` | the trees of the latest snapshot: id, name, base, tips, nodes, rebuilt (docs/forest.md) |
//! | `GET /trees/{id}.json` | one tree as a version-1 tree.json |
//! | `GET /tree.json`, `GET /tips.json` | the latest skeleton and tips |
//! | `GET /status` | JSON: sources, rates, markers, tips, drops, last tree, wind |
//! | `GET /metrics` | the same counters in Prometheus text format |
//! | `POST /rebuild` | ask for a new tree now (202 Accepted) |
//! | `GET /live` | WebSocket: binary marker frames (at most 60/s), JSON status, tree and wind messages ([`super::live`]) |
//!
//! The server only reads shared state handed to it ([`HttpState`]); it never
//! blocks the pipeline. GET responses carry `Access-Control-Allow-Origin: *`
//! so that other web tools can fetch the tree and the JSON.

use std::sync::Arc;

use axum::extract::ws::WebSocketUpgrade;
use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode, Uri};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use tokio::sync::{watch, Semaphore};

use super::limits::HttpLimits;
use super::live::{self, FrameFormat};
use super::snapshot::TreeSnapshot;
pub use crate::shutdown::until_true;
use crate::source::bad_input::BadInput;

pub use super::live::{tree_notice, HttpState};

/// The router, for tests and for [`serve`].
pub fn router(state: HttpState) -> Router {
    let rebuild_route = if state.rebuild.is_some() {
        post(rebuild)
    } else {
        axum::routing::MethodRouter::new()
    };
    Router::new()
        .route("/tree.glb", get(tree_glb))
        .route("/tree.json", get(tree_json))
        .route("/tips.json", get(tips_json))
        .route("/trees", get(trees))
        .route("/trees/{file}", get(one_tree))
        .route("/status", get(status))
        .route("/metrics", get(metrics))
        .route("/rebuild", rebuild_route)
        .route("/live", get(live))
        .with_state(state)
        .merge(super::web::routes())
        .layer(axum::middleware::from_fn(cors))
}

/// `Access-Control-Allow-Origin: *` on GET (and HEAD) responses: the tree and
/// the JSON are for any web tool on the lab network; POST gets none.
async fn cors(req: Request, next: Next) -> Response {
    let read = matches!(*req.method(), Method::GET | Method::HEAD);
    let mut res = next.run(req).await;
    if read {
        res.headers_mut().insert(
            header::ACCESS_CONTROL_ALLOW_ORIGIN,
            HeaderValue::from_static("*"),
        );
    }
    res
}

/// Serves until `shutdown` turns true.
pub async fn serve(
    listener: tokio::net::TcpListener,
    state: HttpState,
    limits: HttpLimits,
    bad: Arc<BadInput>,
) -> std::io::Result<()> {
    let shutdown = state.shutdown.clone();
    let gate = LiveGate(Arc::new(Semaphore::new(limits.max_websockets)));
    let app = router(state).layer(axum::Extension(gate));
    super::limits::serve(listener, app, limits, bad, shutdown).await
}

/// The `/live` sessions that may still open (`daemon.http_max_websockets`);
/// without one (`treemocap view`) there is no cap.
#[derive(Clone)]
struct LiveGate(Arc<Semaphore>);

/// Serves `router` (e.g. [`router`] merged with `treemocap view`'s routes)
/// until `shutdown` turns true.
pub async fn serve_router(
    listener: tokio::net::TcpListener,
    router: Router,
    shutdown: watch::Receiver<bool>,
) -> std::io::Result<()> {
    axum::serve(listener, router)
        .with_graceful_shutdown(until_true(shutdown))
        .await
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
    let mut res = tree_file(&s, "model/gltf-binary", |t| t.glb.clone());
    if let Some(t) = latest(&s) {
        res.headers_mut()
            .insert("x-tree-version", HeaderValue::from(t.version));
        // The page reads the version of what it loaded.
        res.headers_mut().insert(
            header::ACCESS_CONTROL_EXPOSE_HEADERS,
            HeaderValue::from_static("x-tree-version"),
        );
    }
    res
}

async fn tree_json(State(s): State<HttpState>) -> Response {
    tree_file(&s, "application/json", |t| t.tree_json.clone().into_bytes())
}

async fn tips_json(State(s): State<HttpState>) -> Response {
    tree_file(&s, "application/json", |t| t.tips_json.clone().into_bytes())
}

/// `GET /trees`: the trees of the latest snapshot (one entry for a tree
/// alone: id 0, its tips and nodes).
async fn trees(State(s): State<HttpState>) -> Response {
    let Some(t) = latest(&s) else {
        return no_tree();
    };
    let list = if t.trees.is_empty() {
        serde_json::json!([{"id": 0, "name": crate::reconstruct::forest::settings::default_name(0),
            "nodes": t.nodes.len(), "rebuilt": true}])
    } else {
        serde_json::Value::Array(
            t.trees
                .iter()
                .map(|x| {
                    serde_json::json!({"id": x.id, "name": x.name, "base": x.base,
                        "tips": x.tips, "nodes": x.nodes.len(), "rebuilt": x.rebuilt})
                })
                .collect(),
        )
    };
    let body = serde_json::to_string_pretty(&list).unwrap_or_default();
    ([(header::CONTENT_TYPE, "application/json")], body).into_response()
}

/// `GET /trees/{id}.json`: one tree as a version-1 tree.json (the whole
/// tree.json for a tree alone).
async fn one_tree(
    State(s): State<HttpState>,
    axum::extract::Path(file): axum::extract::Path<String>,
) -> Response {
    let Some(t) = latest(&s) else {
        return no_tree();
    };
    let id = file
        .strip_suffix(".json")
        .unwrap_or(&file)
        .parse::<usize>()
        .ok();
    let body = match id {
        Some(0) if t.trees.is_empty() => Some(t.tree_json.clone()),
        Some(id) => t
            .trees
            .iter()
            .find(|x| x.id == id)
            .map(|x| x.tree_json.clone()),
        None => None,
    };
    match body {
        Some(b) => ([(header::CONTENT_TYPE, "application/json")], b).into_response(),
        None => (
            StatusCode::NOT_FOUND,
            format!("no tree '{file}'; GET /trees lists them\n"),
        )
            .into_response(),
    }
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
    if let Some(r) = &s.rebuild {
        r();
    }
    (StatusCode::ACCEPTED, "rebuild requested\n").into_response()
}

/// False when a browser says the request comes from a page of another site
/// (its `Origin` names another host than the one asked): a page visited on
/// the rig's machine must not trigger rebuilds. Scripts, curl and our own
/// page send no `Origin` or our own.
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
    uri: Uri,
    State(s): State<HttpState>,
    gate: Option<axum::Extension<LiveGate>>,
) -> Response {
    let permit = match gate {
        Some(axum::Extension(LiveGate(g))) => match g.try_acquire_owned() {
            Ok(p) => Some(p),
            Err(_) => {
                return (
                    StatusCode::SERVICE_UNAVAILABLE,
                    "too many /live sessions (daemon.http_max_websockets)\n",
                )
                    .into_response()
            }
        },
        None => None,
    };
    // `/live?format=json`: frames as JSON text, for scripts.
    let json = uri
        .query()
        .is_some_and(|q| q.split('&').any(|kv| kv == "format=json"));
    let format = if json {
        FrameFormat::Json
    } else {
        FrameFormat::Binary
    };
    ws.on_upgrade(move |socket| async move {
        live::session(socket, s, format).await;
        drop(permit);
    })
}
