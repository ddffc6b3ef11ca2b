//! The OSC source: marker frames from a NatNet→OSC bridge (or anything that
//! speaks the addresses in [`decode`]) over UDP.
//!
//! This half owns the socket, the sender allow-list, the clock and the
//! counters; [`decode::Assembler`] turns the packets into frames.
//! Everything rejected is counted by kind ([`BadInput`]) and logged with the
//! sender and the offending address and argument, once per kind every 10 s
//! ([`LogThrottle`]), so a flood cannot flood the log.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;
use tokio::net::UdpSocket;
use tokio::sync::watch;

use crate::error::{Error, Result};
use crate::model::frame::{LengthUnit, UpAxis};
use crate::protocol::osc::{Assembler, DecodeOptions, Output, ProblemKind, MAX_DATAGRAM_BYTES};
use crate::source::allow::AllowList;
use crate::source::bad_input::{BadInput, BadInputKind};
use crate::source::channel::FrameSink;
use crate::source::live::{LiveSource, SourceFuture, SourceReport};
use crate::throttle::LogThrottle;
use serde::Deserialize;

/// How often the throttled warnings' counts are written out while the
/// socket is quiet.
const FLUSH_EVERY: Duration = Duration::from_secs(1);
/// Kernel receive buffer asked for: 1000 markers × 1000 frames/s arrive in
/// bursts, and a datagram the kernel cannot queue is lost without a trace.
const RECV_BUFFER_BYTES: usize = 4 << 20;

/// The OSC source's settings (`[osc]` in the config): where it listens,
/// whom it accepts, and how the sender's positions convert to metres, Y up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OscSettings {
    /// Address and port to listen on; loopback unless the user widens it.
    pub bind: SocketAddr,
    /// IP addresses or CIDR ranges accepted as senders.
    pub allow: Vec<String>,
    /// The sender's up axis.
    pub up_axis: UpAxis,
    /// The sender's length unit.
    pub units: LengthUnit,
    /// Also take `/othermarker` messages.
    pub othermarkers: bool,
    /// Nominal frame rate for recording headers (Hz).
    pub frame_rate: f64,
}

/// Everything the OSC source needs to run.
#[derive(Debug, Clone)]
pub struct OscOptions {
    /// Address and port to listen on.
    pub bind: SocketAddr,
    /// Senders accepted; the rest are dropped and counted.
    pub allow: AllowList,
    /// Unit and axis conversion of incoming positions.
    pub decode: DecodeOptions,
    /// Nominal frames per second, for recording headers only.
    pub frame_rate: f64,
    /// The live counters. Clone the `Arc` before calling [`run`] to watch
    /// them while it runs.
    pub stats: Arc<OscStats>,
}

impl OscOptions {
    /// Options from the `[osc]` settings; a bad allow-list entry is named
    /// by its key.
    pub fn from_settings(c: &OscSettings) -> Result<Self> {
        Ok(OscOptions {
            bind: c.bind,
            allow: AllowList::parse("osc.allow", &c.allow)?,
            decode: DecodeOptions {
                scale: c.units.metres(),
                up_axis: c.up_axis,
                othermarkers: c.othermarkers,
            },
            frame_rate: c.frame_rate,
            stats: Arc::default(),
        })
    }
}

/// Live counters of the OSC source.
#[derive(Debug, Default)]
pub struct OscStats {
    /// Datagrams received from allowed senders.
    pub datagrams: AtomicU64,
    /// Frames delivered to the sink.
    pub frames: AtomicU64,
    /// Markers in those frames.
    pub markers: AtomicU64,
    /// Rejected input by kind: senders not in the allow-list
    /// (`not_allowed`), datagrams that are not OSC or nest too deep
    /// (`failed_decode`), messages at our addresses with wrong type tags or
    /// arguments (`invalid`), `/frame/start` … `/frame/end` brackets broken
    /// by a lost datagram (`incomplete`).
    pub bad: BadInput,
    /// Well-formed messages at addresses we do not use (rigid bodies, …).
    pub ignored: AtomicU64,
    /// Frames the sink dropped because its consumer fell behind.
    pub dropped: AtomicU64,
    /// `/othermarker…` messages ignored (part of `ignored`; warned about once).
    pub othermarkers_ignored: AtomicU64,
    /// The address actually bound (port 0 resolved), once listening.
    local_addr: Mutex<Option<SocketAddr>>,
}

/// A copy of the counters at one instant.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct OscCounts {
    /// Datagrams received from allowed senders.
    pub datagrams: u64,
    /// Frames delivered.
    pub frames: u64,
    /// Markers in those frames.
    pub markers: u64,
    /// Datagrams from senders outside `osc.allow`, dropped unread.
    pub not_allowed: u64,
    /// Datagrams that are not OSC or nest too deep.
    pub failed_decode: u64,
    /// Messages with wrong type tags or arguments, skipped.
    pub invalid: u64,
    /// Frame brackets broken by a lost datagram.
    pub incomplete: u64,
    /// Well-formed messages at addresses we do not use.
    pub ignored: u64,
    /// Frames dropped because the consumer fell behind.
    pub dropped: u64,
}

impl OscStats {
    /// The counters now, for the progress line and `/status`.
    pub fn snapshot(&self) -> OscCounts {
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        OscCounts {
            datagrams: get(&self.datagrams),
            frames: get(&self.frames),
            markers: get(&self.markers),
            not_allowed: self.bad.get(BadInputKind::NotAllowed),
            failed_decode: self.bad.get(BadInputKind::FailedDecode),
            invalid: self.bad.get(BadInputKind::Invalid),
            incomplete: self.bad.get(BadInputKind::Incomplete),
            ignored: get(&self.ignored),
            dropped: get(&self.dropped),
        }
    }

    /// The bound address once the source listens (useful with port 0).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        *self.local_addr.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn set_local_addr(&self, addr: SocketAddr) {
        *self.local_addr.lock().unwrap_or_else(|p| p.into_inner()) = Some(addr);
    }
}

/// The common kind of a decoder problem.
fn bad_input_kind(kind: ProblemKind) -> BadInputKind {
    match kind {
        ProblemKind::Garbage => BadInputKind::FailedDecode,
        ProblemKind::BadArgs => BadInputKind::Invalid,
        ProblemKind::BrokenFrame => BadInputKind::Incomplete,
    }
}

/// The throttle kind (and log prefix) of a decoder problem.
fn warning_kind(kind: ProblemKind) -> &'static str {
    match kind {
        ProblemKind::Garbage => "osc: datagrams that are not OSC",
        ProblemKind::BadArgs => "osc: messages with wrong arguments",
        ProblemKind::BrokenFrame => "osc: frames broken by a lost datagram",
    }
}

/// Opens the UDP socket with a large receive buffer.
fn bind(addr: SocketAddr) -> Result<UdpSocket> {
    bind_buffered(addr).map_err(|e| {
        Error::Runtime(format!(
            "cannot listen for OSC on udp {addr}: {e} (another program on that port? \
             choose another with --osc ADDR:PORT or osc.bind)"
        ))
    })
}

/// A UDP socket on `addr` with a receive buffer of
/// [`RECV_BUFFER_BYTES`]: the kernel's default holds a few hundred
/// datagrams, which a burst outruns while the runtime is busy elsewhere
/// (the control socket too: a flood of 500 datagrams lost 44 of them on a
/// machine running four jobs on two cores).
pub(crate) fn bind_buffered(addr: SocketAddr) -> std::io::Result<UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let socket = Socket::new(Domain::for_address(addr), Type::DGRAM, Some(Protocol::UDP))?;
    if let Err(e) = socket.set_recv_buffer_size(RECV_BUFFER_BYTES) {
        tracing::debug!("osc: could not enlarge the receive buffer: {e}");
    }
    socket.bind(&addr.into())?;
    socket.set_nonblocking(true)?;
    UdpSocket::from_std(socket.into())
}

/// Receives OSC on `opts.bind` and pushes frames into `sink` until
/// `shutdown` turns true (or its sender is dropped, or the sink's receiver
/// is gone). Fails only when the socket cannot be opened; bad input is
/// counted in `opts.stats` and skipped.
pub async fn run(
    opts: &OscOptions,
    sink: FrameSink,
    mut shutdown: watch::Receiver<bool>,
) -> Result<SourceReport> {
    let socket = bind(opts.bind)?;
    let local = socket.local_addr().unwrap_or(opts.bind);
    opts.stats.set_local_addr(local);
    tracing::info!(
        "osc: listening on udp {local}, accepting {:?}",
        opts.allow.0
    );
    let started = Instant::now();
    let stats = &opts.stats;
    let mut assembler = Assembler::new(opts.decode);
    let throttle = LogThrottle::default();
    // One byte more than the largest datagram taken, so that a datagram the
    // kernel cut to fit is seen as too long rather than decoded in part.
    let mut buf = vec![0u8; MAX_DATAGRAM_BYTES + 1];
    let mut out = Output::default();
    let mut sender = local;
    let mut open = true;
    let mut flush = tokio::time::interval(FLUSH_EVERY);
    while open && !*shutdown.borrow() {
        tokio::select! {
            changed = shutdown.changed() => {
                if changed.is_err() {
                    break;
                }
            }
            _ = flush.tick() => throttle.flush(),
            received = socket.recv_from(&mut buf) => {
                let (n, from) = match received {
                    Ok(r) => r,
                    Err(e) => {
                        // An ICMP error from an earlier send, an interrupted
                        // call: nothing to do with the next datagram.
                        tracing::debug!("osc: receive error: {e}");
                        tokio::task::yield_now().await;
                        continue;
                    }
                };
                if !opts.allow.allows(from.ip()) {
                    stats.bad.add(BadInputKind::NotAllowed);
                    throttle.warn("osc: senders not in osc.allow", || {
                        format!(
                            "osc: dropping datagrams from {from}: not in osc.allow {:?} \
                             (to accept it: --set 'osc.allow=[\"{}\"]')",
                            opts.allow.0.iter().map(|r| r.to_string()).collect::<Vec<_>>(),
                            from.ip()
                        )
                    });
                    continue;
                }
                stats.datagrams.fetch_add(1, Ordering::Relaxed);
                sender = from;
                let now_s = started.elapsed().as_secs_f64();
                assembler.datagram(buf.get(..n).unwrap_or(&[]), now_s, &mut out);
                open = deliver(&mut out, &sink, stats, &throttle, from);
            }
        }
    }
    assembler.finish(&mut out);
    deliver(&mut out, &sink, stats, &throttle, sender);
    throttle.finish();
    stats.dropped.store(sink.dropped(), Ordering::Relaxed);
    let counts = stats.snapshot();
    Ok(SourceReport {
        source: format!("osc udp {local}"),
        duration_s: started.elapsed().as_secs_f64(),
        frames: counts.frames,
        markers: counts.markers,
        dropped: counts.dropped,
        rejected: stats.bad.counts(),
    })
}

/// Pushes finished frames and accounts for problems; false when the
/// consumer is gone.
fn deliver(
    out: &mut Output,
    sink: &FrameSink,
    stats: &OscStats,
    throttle: &LogThrottle,
    from: SocketAddr,
) -> bool {
    stats
        .ignored
        .fetch_add(std::mem::take(&mut out.ignored), Ordering::Relaxed);
    let others = std::mem::take(&mut out.ignored_othermarkers);
    if others > 0
        && stats
            .othermarkers_ignored
            .fetch_add(others, Ordering::Relaxed)
            == 0
    {
        tracing::warn!(
            "osc: {from} sends /othermarker messages, which are ignored; \
             set osc.othermarkers = true to track them (and turn off /marker in the \
             bridge, or markers are doubled)"
        );
    }
    for p in out.problems.drain(..) {
        stats.bad.add(bad_input_kind(p.kind));
        throttle.warn(warning_kind(p.kind), || {
            format!("osc: {} from {from}: {p}", p.kind.name())
        });
    }
    let mut open = true;
    for frame in out.frames.drain(..) {
        stats.frames.fetch_add(1, Ordering::Relaxed);
        stats
            .markers
            .fetch_add(frame.markers.len() as u64, Ordering::Relaxed);
        open &= sink.push(frame);
    }
    stats.dropped.store(sink.dropped(), Ordering::Relaxed);
    open
}

/// The OSC source as a [`LiveSource`], for `record` and the daemon.
#[derive(Debug, Clone)]
pub struct OscSource(pub OscOptions);

impl LiveSource for OscSource {
    fn describe(&self) -> String {
        let addr = self.0.stats.local_addr().unwrap_or(self.0.bind);
        format!("osc udp {addr}")
    }

    fn status(&self) -> Option<String> {
        let addr = self.0.stats.local_addr()?;
        Some(format!("listening for OSC on udp {addr}"))
    }

    fn frame_rate(&self) -> Option<f64> {
        Some(self.0.frame_rate)
    }

    fn losses(&self) -> Vec<(String, u64)> {
        self.0.stats.bad.counts()
    }

    fn start(&self, sink: FrameSink, shutdown: watch::Receiver<bool>) -> SourceFuture {
        let opts = self.0.clone();
        Box::pin(async move { run(&opts, sink, shutdown).await })
    }
}
