//! A NatNet replay server: streams any recording as NatNet frames at the
//! recorded rate, so any NatNet client can be tested without a rig, and so
//! our own client is tested against a real server on real sockets.
//!
//! It behaves like Motive where clients can tell (spec §1, §4): commands and
//! replies on the command port; in unicast, frames go *from the data port* to
//! the address that sent CONNECT (clients receive them on their command
//! socket); in multicast, to the group on the data port. It answers CONNECT
//! and DISCOVERY with SERVERINFO, REQUEST_MODELDEF, REQUEST_FRAMEOFDATA,
//! ECHO, the `FrameRate` and `Bitstream` requests, and notes keep-alives.
//! A unicast client may change its own bitstream version with
//! `Bitstream,X.Y` (server version 3.0 or later, as in Motive); the first
//! frame in the new version carries frame-params bit 0x08.
//!
//! Markers go into the labeled-marker list as unlabeled point-cloud entries
//! (params 0x10 | 0x02, model id 0) from 2.3 on, and, for 2.x, also into the
//! legacy other-markers list, which is where 2.x clients look for the point
//! cloud. Positions are rounded to f32 (the wire type); the frame timestamp
//! is the recording's time (f64 from 2.7).

use std::collections::HashMap;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use socket2::{Domain, Protocol, Socket, Type};
use tokio::net::UdpSocket;
use tokio::sync::watch;

use super::packet::{
    self, decode, encode_into, Connect, Description, FrameOfData, LabeledMarker, ModelDef, Packet,
    Response, Sender, ServerConnection, ServerInfo, Version, FRAME_BITSTREAM_CHANGED,
    MARKER_UNLABELED,
};
pub use super::Transport;
use crate::error::{Error, Result};
use crate::model::frame::MarkerFrame;
use crate::model::recording::Recording;

/// Ticks per second of the server's hi-res clock (nanoseconds since start).
pub const CLOCK_FREQUENCY: u64 = 1_000_000_000;

/// Everything `treemocap serve` can be told.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// Bitstream version to stream (clients may change theirs in unicast).
    pub version: Version,
    /// Playback speed: 2.0 streams twice as fast as recorded.
    pub speed: f64,
    /// Start again at the end (frame numbers jump back, as in Motive).
    pub looping: bool,
    pub transport: Transport,
    /// Local address for the command and data sockets.
    pub bind: Ipv4Addr,
    /// 0 picks a free port (tests); see [`ServerStats::command_addr`].
    pub command_port: u16,
    pub data_port: u16,
    pub multicast_group: Ipv4Addr,
    /// Interface (its IPv4 address) multicast frames leave by.
    pub multicast_interface: Ipv4Addr,
    /// Start playback only when the first client connects, so it sees the
    /// whole recording; false starts at once.
    pub wait_for_client: bool,
    /// A unicast client silent this long (no keep-alive) gets no more frames.
    pub client_timeout: Duration,
    /// Counters the caller can read while the server runs.
    pub stats: Arc<ServerStats>,
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            version: Version::new(3, 1),
            speed: 1.0,
            looping: false,
            transport: Transport::Unicast,
            bind: Ipv4Addr::UNSPECIFIED,
            command_port: packet::DEFAULT_COMMAND_PORT,
            data_port: packet::DEFAULT_DATA_PORT,
            multicast_group: packet::DEFAULT_MULTICAST_GROUP,
            multicast_interface: Ipv4Addr::LOCALHOST,
            wait_for_client: true,
            client_timeout: Duration::from_secs(10),
            stats: Arc::default(),
        }
    }
}

/// Live counters of a running server.
#[derive(Debug, Default)]
pub struct ServerStats {
    /// The bound command socket (known once the server is listening).
    pub command_addr: OnceLock<SocketAddr>,
    /// The bound data socket.
    pub data_addr: OnceLock<SocketAddr>,
    /// Frames played (each counted once, whatever the number of clients).
    pub frames: AtomicU64,
    /// Frame datagrams sent.
    pub datagrams: AtomicU64,
    /// CONNECTs answered.
    pub connects: AtomicU64,
    /// Requests of any kind answered.
    pub requests: AtomicU64,
    /// Datagrams that did not decode.
    pub bad_packets: AtomicU64,
    /// Frames too large for one datagram in the chosen version, skipped.
    pub oversized_frames: AtomicU64,
}

/// What a finished server did.
#[derive(Debug, Clone, PartialEq)]
pub struct ServeReport {
    pub frames: u64,
    pub loops: u64,
    pub clients: u64,
    pub elapsed_s: f64,
}

/// One unicast client.
struct Client {
    version: Version,
    last_seen: Instant,
    /// Set after a bitstream change until the next frame announces it.
    announce_change: bool,
}

fn udp_socket(addr: SocketAddrV4, reuse: bool) -> std::io::Result<Socket> {
    let s = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
    if reuse {
        s.set_reuse_address(true)?;
        #[cfg(unix)]
        s.set_reuse_port(true)?;
    }
    s.set_nonblocking(true)?;
    s.bind(&addr.into())?;
    Ok(s)
}

fn to_tokio(s: Socket) -> std::io::Result<UdpSocket> {
    UdpSocket::from_std(s.into())
}

/// The SERVERINFO this server sends for bitstream `version`.
pub fn server_info(
    version: Version,
    transport: Transport,
    data_port: u16,
    group: Ipv4Addr,
) -> ServerInfo {
    let app = env!("CARGO_PKG_VERSION")
        .split('.')
        .map(|p| p.parse::<u8>().unwrap_or(0))
        .chain(std::iter::repeat(0));
    let mut app_version = [0u8; 4];
    app_version.iter_mut().zip(app).for_each(|(a, b)| *a = b);
    ServerInfo {
        sender: Sender {
            name: "treemocap".into(),
            version: app_version,
            natnet_version: [version.major, version.minor, 0, 0],
        },
        connection: (version.major >= 3).then_some(ServerConnection {
            clock_frequency: CLOCK_FREQUENCY,
            data_port,
            multicast: transport == Transport::Multicast,
            multicast_group: group.octets(),
        }),
    }
}

/// A recorded frame as Motive would stream it in `version` (see the module
/// docs for where the markers go). Ticks are the server clock at send time.
pub fn to_natnet_frame(frame: &MarkerFrame, version: Version, ticks: u64) -> FrameOfData {
    let pos = |m: &crate::model::frame::Marker| {
        [
            m.position.x as f32,
            m.position.y as f32,
            m.position.z as f32,
        ]
    };
    let labeled = if version.at_least(2, 3) {
        frame
            .markers
            .iter()
            .enumerate()
            .map(|(i, m)| LabeledMarker {
                // Point-cloud ids live in the low 16 bits (model 0).
                id: m
                    .id
                    .filter(|id| (0..=0xFFFF).contains(id))
                    .map_or((i as i32).wrapping_add(1) & 0xFFFF, |id| id as i32),
                position: pos(m),
                size: 0.014,
                params: MARKER_UNLABELED | 0x02,
                residual: 0.0,
            })
            .collect()
    } else {
        Vec::new()
    };
    let other = if version.major < 3 {
        frame.markers.iter().map(pos).collect()
    } else {
        Vec::new()
    };
    FrameOfData {
        frame_number: frame.frame.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        other_markers: other,
        labeled_markers: labeled,
        timestamp: frame.time_s,
        camera_mid_exposure: ticks,
        camera_data_received: ticks,
        transmit: ticks,
        ..Default::default()
    }
}

/// The MODELDEF of a replay: one empty "all" marker set (no assets; the
/// point cloud is unlabeled).
pub fn model_def() -> ModelDef {
    ModelDef {
        descriptions: vec![Description::MarkerSet {
            name: "all".into(),
            markers: Vec::new(),
        }],
    }
}

/// Streams the recording at `path` (any format [`replay::open`] reads) until
/// it ends (or forever with `looping`) or `shutdown` turns true.
pub async fn serve(
    path: &Path,
    opts: &ServeOptions,
    shutdown: watch::Receiver<bool>,
) -> Result<ServeReport> {
    let p = path.to_path_buf();
    serve_with(move || crate::app::open::open(&p), opts, shutdown).await
}

/// [`serve`] over any source of recordings; `open` is called again for each loop.
pub async fn serve_with(
    mut open: impl FnMut() -> Result<Box<dyn Recording>>,
    opts: &ServeOptions,
    mut shutdown: watch::Receiver<bool>,
) -> Result<ServeReport> {
    if !(opts.speed > 0.0 && opts.speed.is_finite()) {
        return Err(Error::config(
            "--speed",
            format!("{} must be above 0", opts.speed),
        ));
    }
    if opts.version < packet::OLDEST_VERSION || opts.version.major > 4 {
        return Err(Error::config(
            "--natnet-version",
            format!(
                "{} is not a version treemocap can stream (2.0 to 4.x)",
                opts.version
            ),
        ));
    }
    let mut recording = open()?;
    let frame_rate = recording.info().frame_rate;
    let cmd_addr = SocketAddrV4::new(opts.bind, opts.command_port);
    let cmd = udp_socket(cmd_addr, false)
        .and_then(to_tokio)
        .map_err(|e| {
            Error::Runtime(format!(
                "cannot listen for NatNet commands on {cmd_addr}: {e}"
            ))
        })?;
    let data_addr = SocketAddrV4::new(opts.bind, opts.data_port);
    let data = udp_socket(data_addr, opts.transport == Transport::Multicast).map_err(|e| {
        Error::Runtime(format!("cannot bind the NatNet data port {data_addr}: {e}"))
    })?;
    if opts.transport == Transport::Multicast {
        data.set_multicast_if_v4(&opts.multicast_interface)
            .and_then(|_| data.set_multicast_loop_v4(true))
            .and_then(|_| data.set_multicast_ttl_v4(1))
            .map_err(|e| {
                Error::Runtime(format!(
                    "cannot send multicast on interface {}: {e}",
                    opts.multicast_interface
                ))
            })?;
    }
    let _ = data.set_send_buffer_size(4 << 20);
    let data = to_tokio(data).map_err(|e| Error::Runtime(format!("data socket: {e}")))?;
    let stats = &opts.stats;
    let data_port = data
        .local_addr()
        .map(|a| a.port())
        .unwrap_or(opts.data_port);
    if let Ok(a) = cmd.local_addr() {
        let _ = stats.command_addr.set(a);
    }
    if let Ok(a) = data.local_addr() {
        let _ = stats.data_addr.set(a);
    }
    tracing::info!(
        "serving NatNet {} ({:?}) on command {:?}, data {:?}",
        opts.version,
        opts.transport,
        stats.command_addr.get(),
        stats.data_addr.get()
    );

    let started = Instant::now();
    let ticks = move || started.elapsed().as_nanos() as u64;
    let group = SocketAddr::V4(SocketAddrV4::new(opts.multicast_group, data_port));
    let mut clients: HashMap<SocketAddr, Client> = HashMap::new();
    let mut clients_seen = 0u64;
    let mut playing = !opts.wait_for_client;
    let mut play_start = Instant::now();
    let mut first_time: Option<f64> = None;
    let mut pending: Option<MarkerFrame> = None;
    let mut last_sent: Option<MarkerFrame> = None;
    let mut loops = 0u64;
    let mut buf = vec![0u8; 65536];
    let mut out = Vec::with_capacity(65536);
    let mut per_version: Vec<(Version, Vec<u8>)> = Vec::new();

    loop {
        // The next frame and when it is due.
        if playing && pending.is_none() {
            match recording.next() {
                Some(Ok(f)) => pending = Some(f),
                Some(Err(e)) => return Err(e),
                None if opts.looping => {
                    recording = open()?;
                    loops += 1;
                    first_time = None;
                    play_start = Instant::now();
                    continue;
                }
                None => break,
            }
        }
        let due = pending.as_ref().map(|f| {
            let t0 = *first_time.get_or_insert(f.time_s);
            let dt = ((f.time_s - t0) / opts.speed).max(0.0);
            play_start + Duration::from_secs_f64(if dt.is_finite() { dt.min(1e9) } else { 0.0 })
        });
        let sleep = tokio::time::sleep_until(
            due.unwrap_or_else(|| Instant::now() + Duration::from_secs(3600))
                .into(),
        );
        tokio::select! {
            _ = shutdown.changed() => {
                if *shutdown.borrow() { break; }
            }
            r = cmd.recv_from(&mut buf) => {
                let (n, from) = match r {
                    Ok(x) => x,
                    // ICMP errors from a departed client surface here on some
                    // systems; they are not the server's problem.
                    Err(e) => { tracing::debug!("command socket: {e}"); continue; }
                };
                let Some(datagram) = buf.get(..n) else { continue };
                let packet = match decode(datagram, opts.version) {
                    Ok(p) => p,
                    Err(e) => {
                        stats.bad_packets.fetch_add(1, Ordering::Relaxed);
                        tracing::warn!("bad datagram from {from}: {e}");
                        continue;
                    }
                };
                let now = Instant::now();
                if let Some(c) = clients.get_mut(&from) {
                    c.last_seen = now;
                }
                let client_version = clients.get(&from).map_or(opts.version, |c| c.version);
                let reply = match packet {
                    Packet::Connect(c) => {
                        stats.connects.fetch_add(1, Ordering::Relaxed);
                        if let Connect::Sender { sender, .. } = &c {
                            tracing::info!("client {from} connected: {:?} NatNet {}", sender.name, sender.natnet());
                        } else {
                            tracing::info!("client {from} connected");
                        }
                        if !clients.contains_key(&from) {
                            clients_seen += 1;
                        }
                        // The bitstream in a 4.x CONNECT is not honoured:
                        // clients decode with SERVERINFO's version (spec §4).
                        let entry = clients.entry(from).or_insert(Client {
                            version: opts.version,
                            last_seen: now,
                            announce_change: false,
                        });
                        entry.last_seen = now;
                        if !playing && opts.wait_for_client {
                            playing = true;
                            // A multicast client joins the group only after
                            // SERVERINFO told it where; give it that moment.
                            play_start = Instant::now() + match opts.transport {
                                Transport::Multicast => Duration::from_millis(250),
                                Transport::Unicast => Duration::ZERO,
                            };
                        }
                        Some(Packet::ServerInfo(server_info(entry.version, opts.transport, data_port, opts.multicast_group)))
                    }
                    Packet::Discovery(_) => Some(Packet::ServerInfo(server_info(opts.version, opts.transport, data_port, opts.multicast_group))),
                    Packet::KeepAlive => None,
                    Packet::Disconnect => {
                        clients.remove(&from);
                        None
                    }
                    Packet::RequestModelDef => Some(Packet::ModelDef(model_def())),
                    Packet::RequestFrameOfData => last_sent
                        .as_ref()
                        .map(|f| Packet::FrameOfData(Box::new(to_natnet_frame(f, client_version, ticks())))),
                    Packet::EchoRequest(t) => Some(Packet::EchoResponse { client_ticks: t, server_ticks: ticks() }),
                    Packet::Request(cmd_text) => Some(answer_request(
                        &cmd_text,
                        opts,
                        frame_rate,
                        clients.get_mut(&from),
                    )),
                    other => {
                        tracing::debug!("ignoring {} from {from}", packet::message_name(other.id()));
                        None
                    }
                };
                if let Some(reply) = reply {
                    stats.requests.fetch_add(1, Ordering::Relaxed);
                    let v = clients.get(&from).map_or(opts.version, |c| c.version);
                    match encode_into(&reply, v, &mut out) {
                        Ok(()) => { let _ = cmd.send_to(&out, from).await; }
                        Err(e) => tracing::warn!("cannot answer {from}: {e}"),
                    }
                }
            }
            _ = sleep, if due.is_some() => {
                let Some(frame) = pending.take() else { continue };
                stats.frames.fetch_add(1, Ordering::Relaxed);
                let now_ticks = ticks();
                match opts.transport {
                    Transport::Multicast => {
                        let nf = Packet::FrameOfData(Box::new(to_natnet_frame(&frame, opts.version, now_ticks)));
                        match encode_into(&nf, opts.version, &mut out) {
                            Ok(()) => {
                                if data.send_to(&out, group).await.is_ok() {
                                    stats.datagrams.fetch_add(1, Ordering::Relaxed);
                                }
                            }
                            Err(e) => oversized(stats, &frame, e),
                        }
                    }
                    Transport::Unicast => {
                        let now = Instant::now();
                        clients.retain(|a, c| {
                            let keep = now.duration_since(c.last_seen) < opts.client_timeout;
                            if !keep { tracing::info!("client {a} timed out"); }
                            keep
                        });
                        per_version.clear();
                        for (addr, c) in clients.iter_mut() {
                            let mut nf = to_natnet_frame(&frame, c.version, now_ticks);
                            let bytes: &[u8] = if c.announce_change {
                                c.announce_change = false;
                                nf.params |= FRAME_BITSTREAM_CHANGED;
                                match encode_into(&Packet::FrameOfData(Box::new(nf)), c.version, &mut out) {
                                    Ok(()) => &out,
                                    Err(e) => { oversized(stats, &frame, e); continue; }
                                }
                            } else if let Some(i) = per_version.iter().position(|(v, _)| *v == c.version) {
                                &per_version[i].1
                            } else {
                                let mut b = Vec::new();
                                match encode_into(&Packet::FrameOfData(Box::new(nf)), c.version, &mut b) {
                                    Ok(()) => {
                                        per_version.push((c.version, b));
                                        &per_version[per_version.len() - 1].1
                                    }
                                    Err(e) => { oversized(stats, &frame, e); continue; }
                                }
                            };
                            if data.send_to(bytes, *addr).await.is_ok() {
                                stats.datagrams.fetch_add(1, Ordering::Relaxed);
                            }
                        }
                    }
                }
                last_sent = Some(frame);
            }
        }
    }
    Ok(ServeReport {
        frames: stats.frames.load(Ordering::Relaxed),
        loops,
        clients: clients_seen,
        elapsed_s: started.elapsed().as_secs_f64(),
    })
}

fn oversized(stats: &ServerStats, frame: &MarkerFrame, e: packet::EncodeError) {
    stats.oversized_frames.fetch_add(1, Ordering::Relaxed);
    tracing::warn!("frame {} skipped: {e}", frame.frame);
}

/// Answers a NAT_REQUEST command string.
fn answer_request(
    text: &str,
    opts: &ServeOptions,
    frame_rate: f64,
    client: Option<&mut Client>,
) -> Packet {
    let mut parts = text.split(',');
    let name = parts.next().unwrap_or("").trim();
    match name {
        "FrameRate" => Packet::Response(Response::float(frame_rate as f32)),
        "Bitstream" => {
            let current = client.as_ref().map_or(opts.version, |c| c.version);
            let Some(wanted) = parts.next() else {
                return Packet::Response(Response::Unterminated(format!(
                    "Bitstream,{}.{}.0",
                    current.major, current.minor
                )));
            };
            let wanted = Version::parse(wanted);
            let allowed = opts.transport == Transport::Unicast && opts.version.major >= 3;
            match (wanted, client) {
                (Some(v), Some(c)) if allowed && v >= Version::new(2, 0) && v.major <= 4 => {
                    if c.version != v {
                        c.version = v;
                        c.announce_change = true;
                    }
                    tracing::info!("client switched to bitstream {v}");
                    Packet::Response(Response::int(0))
                }
                _ => {
                    tracing::info!("refused bitstream request '{text}'");
                    Packet::Response(Response::int(-1))
                }
            }
        }
        _ => Packet::UnrecognizedRequest(Vec::new()),
    }
}
