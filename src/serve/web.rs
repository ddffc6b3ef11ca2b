//! The viewer page, compiled into the binary: `GET /` and `GET /web/…`.
//!
//! No internet at the rig, so every file the page loads is here: the page,
//! its script and style, and three.js (npm `three`, vendored unmodified under
//! `web/three/` with its licence; `web/three/VENDOR.md` names the version and
//! how to update it).

use axum::extract::Path;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;

/// One embedded file.
struct Asset {
    /// Path under `/web/`.
    path: &'static str,
    /// Its `Content-Type`.
    content_type: &'static str,
    /// The bytes, from the source tree at build time.
    body: &'static [u8],
}

const JS: &str = "text/javascript; charset=utf-8";

/// Every file the page loads.
const ASSETS: &[Asset] = &[
    Asset {
        path: "app.js",
        content_type: JS,
        body: include_bytes!("web/app.js"),
    },
    Asset {
        path: "style.css",
        content_type: "text/css; charset=utf-8",
        body: include_bytes!("web/style.css"),
    },
    Asset {
        path: "three/three.module.js",
        content_type: JS,
        body: include_bytes!("web/three/three.module.js"),
    },
    Asset {
        path: "three/three.core.js",
        content_type: JS,
        body: include_bytes!("web/three/three.core.js"),
    },
    Asset {
        path: "three/addons/loaders/GLTFLoader.js",
        content_type: JS,
        body: include_bytes!("web/three/addons/loaders/GLTFLoader.js"),
    },
    Asset {
        path: "three/addons/controls/OrbitControls.js",
        content_type: JS,
        body: include_bytes!("web/three/addons/controls/OrbitControls.js"),
    },
    Asset {
        path: "three/addons/utils/BufferGeometryUtils.js",
        content_type: JS,
        body: include_bytes!("web/three/addons/utils/BufferGeometryUtils.js"),
    },
    Asset {
        path: "three/addons/utils/SkeletonUtils.js",
        content_type: JS,
        body: include_bytes!("web/three/addons/utils/SkeletonUtils.js"),
    },
    Asset {
        path: "three/LICENSE",
        content_type: "text/plain; charset=utf-8",
        body: include_bytes!("web/three/LICENSE"),
    },
];

const INDEX: &[u8] = include_bytes!("web/index.html");

/// The page's routes, for any router state.
pub(crate) fn routes<S: Clone + Send + Sync + 'static>() -> Router<S> {
    Router::new()
        .route("/", get(index))
        .route("/web/{*path}", get(asset))
}

async fn index() -> Response {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        INDEX,
    )
        .into_response()
}

async fn asset(Path(path): Path<String>) -> Response {
    match ASSETS.iter().find(|a| a.path == path) {
        Some(a) => (
            [
                (header::CONTENT_TYPE, a.content_type),
                // Revalidated on every load: a new binary serves a new page.
                (header::CACHE_CONTROL, "no-cache"),
            ],
            a.body,
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, "no such file of the page\n").into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_module_the_page_imports_is_embedded() {
        // Relative imports inside the embedded modules resolve to embedded files.
        for a in ASSETS.iter().filter(|a| a.path.ends_with(".js")) {
            let text = std::str::from_utf8(a.body).unwrap();
            for line in text.lines().filter(|l| l.contains("from '.")) {
                let rel = line
                    .split("from '")
                    .nth(1)
                    .unwrap()
                    .split('\'')
                    .next()
                    .unwrap();
                let dir = a.path.rsplit_once('/').map_or("", |d| d.0);
                let mut parts: Vec<&str> = dir.split('/').filter(|p| !p.is_empty()).collect();
                for seg in rel.split('/') {
                    match seg {
                        "." => {}
                        ".." => {
                            parts.pop();
                        }
                        s => parts.push(s),
                    }
                }
                let target = parts.join("/");
                assert!(
                    ASSETS.iter().any(|b| b.path == target),
                    "{} imports {rel} ({target}), not embedded",
                    a.path
                );
            }
        }
        let index = std::str::from_utf8(INDEX).unwrap();
        assert!(index.contains("./web/three/three.module.js"));
        assert!(!index.contains("http://") && !index.contains("https://"));
    }
}
