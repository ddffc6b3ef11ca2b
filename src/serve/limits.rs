//! The HTTP server's defences: who may connect, how many at once, and how
//! long a connection may sit without sending a request or moving a byte.
//!
//! axum's own `serve` has no limits (2 000 slowloris requests were held for
//! a minute; 20 000 idle connections used up the file descriptors and
//! `/status` stopped answering), so connections are accepted here and each
//! is served by hyper with:
//! - the **allow-list** checked at accept: others get a `403` line and are
//!   closed before anything is read, and are counted;
//! - a **header timeout** (hyper's): a request head must arrive within it,
//!   counted from the connection or the end of the previous response, so a
//!   silent, a slowloris and an idle keep-alive connection all end there;
//! - an **idle timeout**: a connection that moves no byte either way for that
//!   long (a client that stopped reading a response) is closed;
//! - a **connection cap**: at the cap a new connection evicts the oldest one
//!   that is not in the middle of a request (one still waiting for its
//!   headers or idle), so a flood of idle connections cannot lock out a user
//!   asking for `/status`; only when every connection is busy is the new one
//!   refused with `503`.
//!
//! WebSocket sessions leave hyper once upgraded; `http.rs` caps them apart.

use std::collections::HashMap;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, Notify};

use crate::source::allow::AllowList;
use crate::source::bad_input::{BadInput, BadInputKind};
use crate::throttle::LogThrottle;

use crate::shutdown::until_true;

/// The limits of the HTTP server (`daemon.http_*` settings).
#[derive(Debug, Clone)]
pub struct HttpLimits {
    /// Clients accepted; everyone else gets 403.
    pub allow: AllowList,
    /// Connections open at once (WebSockets not counted).
    pub max_connections: usize,
    /// WebSocket sessions open at once.
    pub max_websockets: usize,
    /// Longest wait for a request's head.
    pub header_timeout: Duration,
    /// Longest time a connection may move no byte.
    pub idle_timeout: Duration,
}

impl Default for HttpLimits {
    /// The `[daemon]` defaults of config/default.toml.
    fn default() -> Self {
        HttpLimits {
            allow: AllowList::loopback(),
            max_connections: 256,
            max_websockets: 64,
            header_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
        }
    }
}

/// One open connection as the accept loop sees it.
#[derive(Debug)]
struct Slot {
    accepted: Instant,
    /// Requests being answered on it right now.
    busy: AtomicU64,
    /// Requests it has sent so far.
    requests: AtomicU64,
    /// Milliseconds since `accepted` of the last byte moved.
    last_io_ms: AtomicU64,
    /// Set to make the connection's task drop it.
    evict: Notify,
}

impl Slot {
    fn touch(&self) {
        let ms = self.accepted.elapsed().as_millis() as u64;
        self.last_io_ms.store(ms, Ordering::Relaxed);
    }

    fn idle_for(&self) -> Duration {
        let last = Duration::from_millis(self.last_io_ms.load(Ordering::Relaxed));
        self.accepted.elapsed().saturating_sub(last)
    }

    /// May be closed to make room: it is not answering a request, and it
    /// either never sent one (silent, slowloris) or has been idle for a
    /// second (a keep-alive connection a browser would reopen).
    fn evictable(&self) -> bool {
        self.busy.load(Ordering::Relaxed) == 0
            && (self.requests.load(Ordering::Relaxed) == 0
                || self.idle_for() >= Duration::from_secs(1))
    }
}

/// The open connections, by id.
#[derive(Debug, Default)]
struct Table {
    slots: Mutex<HashMap<u64, Arc<Slot>>>,
}

impl Table {
    fn len(&self) -> usize {
        self.slots.lock().map(|s| s.len()).unwrap_or(0)
    }

    fn insert(&self, id: u64) -> Arc<Slot> {
        let slot = Arc::new(Slot {
            accepted: Instant::now(),
            busy: AtomicU64::new(0),
            requests: AtomicU64::new(0),
            last_io_ms: AtomicU64::new(0),
            evict: Notify::new(),
        });
        if let Ok(mut s) = self.slots.lock() {
            s.insert(id, slot.clone());
        }
        slot
    }

    fn remove(&self, id: u64) {
        if let Ok(mut s) = self.slots.lock() {
            s.remove(&id);
        }
    }

    /// Evicts the oldest connection not answering a request; false when all
    /// are busy.
    fn evict_oldest_idle(&self) -> bool {
        let Ok(mut slots) = self.slots.lock() else {
            return false;
        };
        let victim = slots
            .iter()
            .filter(|(_, s)| s.evictable())
            .min_by_key(|(_, s)| s.accepted)
            .map(|(&id, _)| id);
        match victim.and_then(|id| slots.remove(&id)) {
            Some(s) => {
                s.evict.notify_one();
                true
            }
            None => false,
        }
    }
}

/// A TCP stream that notes on its slot every time a byte moves.
struct Tracked {
    tcp: TcpStream,
    slot: Arc<Slot>,
}

impl AsyncRead for Tracked {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        let r = Pin::new(&mut self.tcp).poll_read(cx, buf);
        if buf.filled().len() > before {
            self.slot.touch();
        }
        r
    }
}

impl AsyncWrite for Tracked {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let r = Pin::new(&mut self.tcp).poll_write(cx, buf);
        if matches!(r, Poll::Ready(Ok(n)) if n > 0) {
            self.slot.touch();
        }
        r
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.tcp).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.tcp).poll_shutdown(cx)
    }
}

/// Everything a connection task needs, shared.
struct Shared {
    router: axum::Router,
    limits: HttpLimits,
    bad: Arc<BadInput>,
    throttle: LogThrottle,
    table: Table,
    /// Refusals being written (each holds a socket for a moment).
    refusing: AtomicUsize,
}

/// Refusals written at once at most; beyond, a refused connection is just
/// closed, so that a flood cannot hold sockets through its refusals.
const MAX_REFUSING: usize = 64;

/// Serves `router` on `listener` within `limits` until `shutdown` turns
/// true. Bad input (clients outside the allow-list, requests that never
/// came whole, malformed requests) is counted in `bad`.
pub async fn serve(
    listener: TcpListener,
    router: axum::Router,
    limits: HttpLimits,
    bad: Arc<BadInput>,
    shutdown: watch::Receiver<bool>,
) -> io::Result<()> {
    let shared = Arc::new(Shared {
        router,
        limits,
        bad,
        throttle: LogThrottle::default(),
        table: Table::default(),
        refusing: AtomicUsize::new(0),
    });
    let stopped = until_true(shutdown.clone());
    tokio::pin!(stopped);
    let mut flush = tokio::time::interval(Duration::from_secs(1));
    let mut next_id = 0u64;
    loop {
        let (tcp, peer) = tokio::select! {
            r = listener.accept() => match r {
                Ok(c) => c,
                Err(e) => {
                    // Out of file descriptors, most likely: wait for some
                    // to close rather than spin.
                    shared.throttle.warn("http: accept failed", || {
                        format!("http: cannot accept a connection: {e}")
                    });
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            _ = flush.tick() => {
                shared.throttle.flush();
                continue;
            }
            _ = &mut stopped => break,
        };
        if let Some((status, body)) = refusal(&shared, peer) {
            refuse(&shared, tcp, status, body);
            continue;
        }
        next_id += 1;
        let slot = shared.table.insert(next_id);
        tokio::spawn(connection(
            shared.clone(),
            tcp,
            peer,
            next_id,
            slot,
            shutdown.clone(),
        ));
    }
    shared.throttle.finish();
    Ok(())
}

/// Why a new connection from `peer` is refused, as the status line and body
/// to answer with, or `None` to serve it: a peer outside
/// `daemon.http_allow` (counted as bad input), or a full table with no idle
/// connection to evict. Each reason is logged, throttled.
fn refusal(shared: &Shared, peer: SocketAddr) -> Option<(&'static str, &'static str)> {
    if !shared.limits.allow.allows(peer.ip()) {
        shared.bad.add(BadInputKind::NotAllowed);
        shared
            .throttle
            .warn("http: clients not in daemon.http_allow", || {
                format!(
                    "http: refused {peer}: not in daemon.http_allow {:?} \
                     (to allow it: --set 'daemon.http_allow=[\"{}\"]')",
                    shared
                        .limits
                        .allow
                        .0
                        .iter()
                        .map(|r| r.to_string())
                        .collect::<Vec<_>>(),
                    peer.ip()
                )
            });
        return Some(("403 Forbidden", "not in daemon.http_allow\n"));
    }
    if shared.table.len() >= shared.limits.max_connections && !shared.table.evict_oldest_idle() {
        shared.throttle.warn("http: connection cap reached", || {
            format!(
                "http: refused {peer}: {} connections are open and all busy \
                 (daemon.http_max_connections)",
                shared.limits.max_connections
            )
        });
        return Some(("503 Service Unavailable", "too many connections\n"));
    }
    None
}

/// Answers `status` and closes, without reading the request: cheap enough
/// for a flood, clear enough for a user with curl.
fn refuse(shared: &Arc<Shared>, tcp: TcpStream, status: &str, body: &str) {
    if shared.refusing.fetch_add(1, Ordering::Relaxed) >= MAX_REFUSING {
        shared.refusing.fetch_sub(1, Ordering::Relaxed);
        return;
    }
    let response = format!(
        "HTTP/1.1 {status}\r\nContent-Type: text/plain\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    let shared = shared.clone();
    tokio::spawn(async move {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let mut tcp = tcp;
        let _ = tokio::time::timeout(Duration::from_secs(1), async {
            tcp.write_all(response.as_bytes()).await?;
            tcp.shutdown().await?;
            // Read what the client sent, so that closing does not reset
            // the connection before it reads the answer.
            let mut sink = [0u8; 1024];
            while tcp.read(&mut sink).await? > 0 {}
            io::Result::Ok(())
        })
        .await;
        shared.refusing.fetch_sub(1, Ordering::Relaxed);
    });
}

/// Serves one connection until it closes, times out, is evicted or the
/// server shuts down.
async fn connection(
    shared: Arc<Shared>,
    tcp: TcpStream,
    peer: SocketAddr,
    id: u64,
    slot: Arc<Slot>,
    shutdown: watch::Receiver<bool>,
) {
    let _ = tcp.set_nodelay(true);
    let io = TokioIo::new(Tracked {
        tcp,
        slot: slot.clone(),
    });
    let service = {
        let (router, slot) = (shared.router.clone(), slot.clone());
        hyper::service::service_fn(move |request: hyper::Request<hyper::body::Incoming>| {
            use tower_service::Service;
            let mut router = router.clone();
            let slot = slot.clone();
            slot.requests.fetch_add(1, Ordering::Relaxed);
            slot.busy.fetch_add(1, Ordering::Relaxed);
            async move {
                let response = router.call(request).await;
                slot.busy.fetch_sub(1, Ordering::Relaxed);
                slot.touch();
                response
            }
        })
    };
    let conn = hyper::server::conn::http1::Builder::new()
        .timer(TokioTimer::new())
        .header_read_timeout(shared.limits.header_timeout)
        .serve_connection(io, service)
        .with_upgrades();
    tokio::pin!(conn);
    let stopped = until_true(shutdown);
    tokio::pin!(stopped);
    let mut shutting_down = false;
    let idle = shared.limits.idle_timeout;
    loop {
        let idle_left = idle.saturating_sub(slot.idle_for());
        tokio::select! {
            r = conn.as_mut() => {
                if let Err(e) = r {
                    note_error(&shared, peer, &e);
                }
                break;
            }
            _ = slot.evict.notified() => {
                shared.bad.add(BadInputKind::Incomplete);
                shared.throttle.warn("http: connections closed to make room", || {
                    format!(
                        "http: closed {peer} to make room: {} connections open \
                         (daemon.http_max_connections), it was idle or had sent no request",
                        shared.limits.max_connections
                    )
                });
                break;
            }
            _ = tokio::time::sleep(idle_left) => {
                if slot.idle_for() >= idle {
                    shared.throttle.warn("http: idle connections closed", || {
                        format!("http: closed {peer}: no byte moved for {} s", idle.as_secs())
                    });
                    break;
                }
            }
            _ = &mut stopped, if !shutting_down => {
                shutting_down = true;
                conn.as_mut().graceful_shutdown();
            }
        }
    }
    shared.table.remove(id);
}

/// Counts and (throttled) logs why hyper closed a connection.
fn note_error(shared: &Shared, peer: SocketAddr, e: &hyper::Error) {
    if e.is_timeout() {
        shared.bad.add(BadInputKind::Incomplete);
        shared.throttle.warn("http: requests not sent in time", || {
            format!(
                "http: closed {peer}: no complete request within {} s (daemon.http_header_timeout_s)",
                shared.limits.header_timeout.as_secs_f64()
            )
        });
    } else if e.is_parse() || e.is_parse_too_large() {
        shared.bad.add(BadInputKind::Invalid);
        shared.throttle.warn("http: malformed requests", || {
            format!("http: closed {peer}: {e}")
        });
    }
}
