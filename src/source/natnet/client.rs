//! The live NatNet client: connects to Motive (or `treemocap serve`), turns
//! every frame into a [`MarkerFrame`] and pushes it into the pipeline's
//! [`FrameSink`].
//!
//! What it does, and why (spec §1, §4, §7):
//! - **Unicast**: CONNECT from the command socket; the server answers
//!   SERVERINFO and then sends frames *to that same socket* from its data
//!   port. A KEEPALIVE goes out every `keepalive_interval`, since servers drop
//!   silent unicast clients.
//! - **Multicast**: the data port is bound with address reuse (several
//!   clients on one machine) and the group joined on the chosen interface;
//!   commands still go to the command port.
//! - Which of the two: what the user says, else what SERVERINFO says (3.0+);
//!   a 2.x server does not say, so the client listens on both.
//! - Frames are decoded with the version from SERVERINFO, or the one a
//!   `Bitstream,X.Y` request switched to (unicast, server 3.0+).
//! - Silence longer than `silence_timeout` means the server went away or
//!   restarted: the client sends CONNECT again until it answers. Frame
//!   numbers that go back are counted as restarts (downstream starts fresh
//!   traces on them). Frame params bit 0x02 (model list changed) makes it
//!   re-request MODELDEF.
//! - Bad datagrams are counted by kind and logged with message, field and
//!   offset; the client carries on. Non-frame messages on the data channel
//!   (Motive 1.x multicasts SERVERINFO there) are counted and skipped.

use std::collections::VecDeque;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use socket2::{Domain, Protocol, Socket, Type};
use tokio::net::UdpSocket;
use tokio::sync::watch;

use super::packet::{
    self, decode, encode, id, peek_id, ConnectionOptions, DecodeErrorKind, Packet, Response,
    Sender, ServerInfo, Version, FRAME_BITSTREAM_CHANGED, FRAME_MODELS_CHANGED,
};
use super::select::{to_marker_frame, MarkerSelection};
use super::Transport;
use crate::config::NatNetConfig;
use crate::error::{Error, Result};
use crate::source::channel::FrameSink;

/// How to reach the server and what to take from it.
#[derive(Debug, Clone)]
pub struct NatNetOptions {
    /// The server's address; None looks for one with DISCOVERY (needs `discovery`).
    pub server: Option<Ipv4Addr>,
    pub command_port: u16,
    /// None: follow SERVERINFO (3.0+); for 2.x servers listen on both.
    pub transport: Option<Transport>,
    /// Local interface address the multicast group is joined on (0.0.0.0
    /// lets the OS choose); also where DISCOVERY is sent from.
    pub local: Ipv4Addr,
    /// None: from SERVERINFO (3.0+), else 239.255.42.99.
    pub multicast_group: Option<Ipv4Addr>,
    /// None: from SERVERINFO (3.0+), else 1511.
    pub data_port: Option<u16>,
    /// Ask the server to stream this bitstream version (unicast, server 3.0+).
    pub bitstream: Option<Version>,
    /// Allow looking for a server with a DISCOVERY broadcast when `server` is None.
    pub discovery: bool,
    /// Where DISCOVERY is sent (a broadcast address, or a host).
    pub discovery_address: Ipv4Addr,
    pub markers: MarkerSelection,
    pub connect_timeout: Duration,
    pub silence_timeout: Duration,
    pub keepalive_interval: Duration,
    /// Counters the caller reads while the client runs.
    pub stats: Arc<NatNetStats>,
}

impl Default for NatNetOptions {
    fn default() -> Self {
        NatNetOptions::from_config(&crate::config::Config::default().natnet)
    }
}

impl NatNetOptions {
    /// Points the client at `ADDRESS` or `ADDRESS:COMMAND_PORT` (IPv4;
    /// without a port the configured command port stays). `key` names the
    /// option in the error (`--natnet`, `daemon.natnet_server`).
    pub fn set_server(&mut self, text: &str, key: &str) -> Result<()> {
        let (ip, port) = match text.parse::<SocketAddrV4>() {
            Ok(a) => (*a.ip(), a.port()),
            Err(_) => (
                text.parse::<Ipv4Addr>().map_err(|_| {
                    Error::config(
                        key,
                        format!("'{text}' is not an IPv4 address or ADDRESS:PORT"),
                    )
                })?,
                self.command_port,
            ),
        };
        self.server = Some(ip);
        self.command_port = port;
        Ok(())
    }

    /// Defaults with the `[natnet]` settings applied.
    pub fn from_config(c: &NatNetConfig) -> Self {
        NatNetOptions {
            server: Some(Ipv4Addr::LOCALHOST),
            command_port: packet::DEFAULT_COMMAND_PORT,
            transport: None,
            local: Ipv4Addr::UNSPECIFIED,
            multicast_group: None,
            data_port: None,
            bitstream: None,
            discovery: false,
            discovery_address: Ipv4Addr::BROADCAST,
            markers: c.markers,
            connect_timeout: Duration::from_secs_f64(c.connect_timeout_s),
            silence_timeout: Duration::from_secs_f64(c.silence_timeout_s),
            keepalive_interval: Duration::from_secs_f64(c.keepalive_interval_s),
            stats: Arc::default(),
        }
    }
}

/// Live counters of a running client.
#[derive(Debug, Default)]
pub struct NatNetStats {
    /// Frames decoded and pushed.
    pub frames: AtomicU64,
    /// Markers in those frames (after selection).
    pub markers: AtomicU64,
    /// Frame numbers skipped between consecutive frames (network loss or a
    /// server that dropped frames).
    pub missed_frames: AtomicU64,
    /// Datagrams that ended inside a field.
    pub incomplete: AtomicU64,
    /// Datagrams with an impossible field.
    pub invalid: AtomicU64,
    /// Datagrams with an unknown message id.
    pub unknown: AtomicU64,
    /// Well-formed datagrams that were not expected where they came
    /// (SERVERINFO on the data channel, requests sent to a client).
    pub skipped: AtomicU64,
    /// Times the client re-sent CONNECT after silence.
    pub reconnects: AtomicU64,
    /// Times the frame number went back (server restarted or looped).
    pub restarts: AtomicU64,
    /// MODELDEFs received.
    pub modeldefs: AtomicU64,
    /// Latest system latency (3.0+), microseconds.
    pub latency_us: AtomicU64,
    /// The server and version in use, once connected.
    pub server: Mutex<Option<(String, Version)>>,
}

impl NatNetStats {
    /// All datagrams that did not decode.
    pub fn bad_packets(&self) -> u64 {
        self.incomplete.load(Ordering::Relaxed)
            + self.invalid.load(Ordering::Relaxed)
            + self.unknown.load(Ordering::Relaxed)
    }
}

/// What a finished client did.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceReport {
    /// "Motive 2.1.0.0 at 192.168.0.106:1510".
    pub server: String,
    /// The bitstream version frames were last decoded with.
    pub version: Option<Version>,
    pub frames: u64,
    pub markers: u64,
    pub missed_frames: u64,
    pub bad_packets: u64,
    pub reconnects: u64,
    pub restarts: u64,
}

fn socket(bind: SocketAddrV4, reuse: bool) -> std::io::Result<Socket> {
    let s = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
    if reuse {
        s.set_reuse_address(true)?;
        #[cfg(unix)]
        s.set_reuse_port(true)?;
    }
    // 1000 frames/s of 1000 markers is 26 MB/s; the kernel may cap this.
    let _ = s.set_recv_buffer_size(8 << 20);
    s.set_nonblocking(true)?;
    s.bind(&bind.into())?;
    Ok(s)
}

fn tokio_socket(s: Socket) -> std::io::Result<UdpSocket> {
    UdpSocket::from_std(s.into())
}

fn our_sender() -> Sender {
    Sender {
        name: "treemocap".into(),
        version: [0, 1, 0, 0],
        natnet_version: [4, 1, 0, 0],
    }
}

/// Finds a server with a DISCOVERY datagram; returns its address and info.
pub async fn discover(
    local: Ipv4Addr,
    to: Ipv4Addr,
    command_port: u16,
    timeout: Duration,
) -> Result<(SocketAddr, ServerInfo)> {
    let s = socket(SocketAddrV4::new(local, 0), false)
        .and_then(|s| {
            s.set_broadcast(true)?;
            Ok(s)
        })
        .and_then(tokio_socket)
        .map_err(|e| {
            Error::Runtime(format!(
                "cannot open a socket on {local} for discovery: {e}"
            ))
        })?;
    let msg = encode(
        &Packet::Discovery(packet::Connect::Sender {
            sender: our_sender(),
            options: None,
            spare: Vec::new(),
        }),
        Version::new(4, 1),
    )
    .map_err(|e| Error::Runtime(e.to_string()))?;
    let deadline = Instant::now() + timeout;
    let mut buf = vec![0u8; 2048];
    while Instant::now() < deadline {
        let _ = s.send_to(&msg, (to, command_port)).await;
        let wait = tokio::time::timeout(Duration::from_millis(500), s.recv_from(&mut buf)).await;
        if let Ok(Ok((n, from))) = wait {
            if let Some(Ok(Packet::ServerInfo(info))) =
                buf.get(..n).map(|d| decode(d, Version::new(3, 0)))
            {
                return Ok((from, info));
            }
        }
    }
    Err(Error::Runtime(format!(
        "no NatNet server answered a discovery broadcast to {to}:{command_port} within {:.1} s",
        timeout.as_secs_f64()
    )))
}

/// Tells "nothing listening" (an ICMP port-unreachable) from "no answer":
/// a connected UDP socket sees the ICMP error as ECONNREFUSED.
async fn refused(server: SocketAddr) -> bool {
    let Ok(s) = UdpSocket::bind("0.0.0.0:0").await else {
        return false;
    };
    if s.connect(server).await.is_err() {
        return false;
    }
    let Ok(ka) = encode(&Packet::KeepAlive, Version::new(3, 0)) else {
        return false;
    };
    let mut buf = [0u8; 64];
    for _ in 0..2 {
        if let Err(e) = s.send(&ka).await {
            return e.kind() == std::io::ErrorKind::ConnectionRefused;
        }
        if let Ok(Err(e)) = tokio::time::timeout(Duration::from_millis(200), s.recv(&mut buf)).await
        {
            return e.kind() == std::io::ErrorKind::ConnectionRefused;
        }
    }
    false
}

/// A request waiting for its NAT_RESPONSE (responses come in order).
#[derive(Debug, Clone, PartialEq)]
enum Pending {
    FrameRate,
    Bitstream(Version),
}

/// Everything known about the current connection.
struct Session {
    server: SocketAddr,
    info: Option<ServerInfo>,
    version: Version,
    clock_frequency: u64,
    frame_rate: Option<f64>,
    pending: VecDeque<Pending>,
    last_frame: Option<i64>,
    first_frame: Option<i64>,
    started: Instant,
    /// Rate-limits bad-packet warnings.
    warned: u64,
    /// Frames of a version without timestamps (2.5 and earlier) that came
    /// before the FrameRate answer their time is computed from; replayed
    /// when it comes (or after `HOLD_LIMIT`).
    held: Vec<Vec<u8>>,
    hold_since: Option<Instant>,
    /// Set when held frames are due for replay.
    release: bool,
}

/// Longest wait for a FrameRate answer before untimed frames fall back to
/// their arrival time.
const HOLD_LIMIT: Duration = Duration::from_secs(1);

/// Runs the client until `shutdown` turns true; see the module docs.
pub async fn run(
    opts: &NatNetOptions,
    sink: FrameSink,
    mut shutdown: watch::Receiver<bool>,
) -> Result<SourceReport> {
    let stats = opts.stats.clone();
    let server = match opts.server {
        Some(ip) => SocketAddr::V4(SocketAddrV4::new(ip, opts.command_port)),
        None if opts.discovery => {
            let (from, info) = discover(
                opts.local,
                opts.discovery_address,
                opts.command_port,
                opts.connect_timeout,
            )
            .await?;
            tracing::info!("discovered {} at {from}", info.sender.name);
            SocketAddr::new(from.ip(), opts.command_port)
        }
        None => {
            return Err(Error::config(
                "natnet server",
                "no server address given and discovery not enabled",
            ))
        }
    };
    // The OS picks the route to the server; `local` names the multicast interface.
    let cmd = socket(SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, 0), false)
        .and_then(tokio_socket)
        .map_err(|e| Error::Runtime(format!("cannot open a NatNet command socket: {e}")))?;
    let mut s = Session {
        server,
        info: None,
        version: Version::new(3, 0),
        clock_frequency: 0,
        frame_rate: None,
        pending: VecDeque::new(),
        last_frame: None,
        first_frame: None,
        started: Instant::now(),
        warned: 0,
        held: Vec::new(),
        hold_since: None,
        release: false,
    };
    let mut buf = vec![0u8; 65536];

    // Handshake: CONNECT until SERVERINFO.
    let connect = encode(
        &Packet::Connect(packet::Connect::Sender {
            sender: our_sender(),
            options: Some(ConnectionOptions {
                subscribed_data_only: false,
                bitstream: [0; 4],
            }),
            spare: Vec::new(),
        }),
        Version::new(4, 1),
    )
    .map_err(|e| Error::Runtime(e.to_string()))?;
    let deadline = Instant::now() + opts.connect_timeout;
    let info = loop {
        if Instant::now() >= deadline {
            let why = if refused(server).await {
                "nothing is listening there (connection refused)"
            } else {
                "no answer (is Motive streaming, and is the address right?)"
            };
            return Err(Error::Runtime(format!(
                "NatNet server {server}: {why} after {:.1} s",
                opts.connect_timeout.as_secs_f64()
            )));
        }
        cmd.send_to(&connect, server)
            .await
            .map_err(|e| Error::Runtime(format!("cannot send CONNECT to {server}: {e}")))?;
        let wait =
            Duration::from_millis(500).min(deadline.saturating_duration_since(Instant::now()));
        tokio::select! {
            _ = shutdown.changed() => if *shutdown.borrow() { return Ok(report(&s, &stats)); },
            r = tokio::time::timeout(wait, cmd.recv_from(&mut buf)) => {
                if let Ok(Ok((n, _))) = r {
                    match buf.get(..n).map(|d| decode(d, Version::new(3, 0))) {
                        Some(Ok(Packet::ServerInfo(info))) => break info,
                        Some(_) => { stats.skipped.fetch_add(1, Ordering::Relaxed); }
                        None => {}
                    }
                }
            }
        }
    };
    adopt(&mut s, info, &stats);
    let server_version = s.version;
    if server_version < packet::OLDEST_VERSION {
        return Err(Error::Unsupported {
            path: server.to_string().into(),
            msg: format!(
                "the server speaks NatNet {server_version}; treemocap reads 2.0 and later"
            ),
        });
    }

    // Where frames come from.
    let conn = s.info.as_ref().and_then(|i| i.connection);
    let transport = opts.transport.or(conn.map(|c| {
        if c.multicast {
            Transport::Multicast
        } else {
            Transport::Unicast
        }
    }));
    let group = opts
        .multicast_group
        .or(conn
            .map(|c| Ipv4Addr::from(c.multicast_group))
            .filter(|g| g.is_multicast()))
        .unwrap_or(packet::DEFAULT_MULTICAST_GROUP);
    let data_port = opts
        .data_port
        .or(conn.map(|c| c.data_port).filter(|&p| p != 0))
        .unwrap_or(packet::DEFAULT_DATA_PORT);
    let data = if transport != Some(Transport::Unicast) {
        match join(opts.local, group, data_port) {
            Ok(d) => Some(d),
            Err(e) if transport.is_none() => {
                tracing::warn!("{e}; listening for unicast frames only");
                None
            }
            Err(e) => return Err(e),
        }
    } else {
        None
    };
    let unicast = transport != Some(Transport::Multicast);

    if let Some(want) = opts.bitstream.filter(|&v| v != s.version) {
        if transport == Some(Transport::Multicast) {
            return Err(Error::Runtime(format!(
                "cannot request bitstream {want}: the server streams multicast, and the bitstream can only be changed in unicast"
            )));
        }
        if server_version.major < 3 {
            return Err(Error::Runtime(format!(
                "cannot request bitstream {want}: the server speaks NatNet {server_version}, which cannot change its bitstream (3.0 or later can)"
            )));
        }
        send(&cmd, server, &Packet::Request(format!("Bitstream,{want}"))).await;
        s.pending.push_back(Pending::Bitstream(want));
    }
    send(&cmd, server, &Packet::Request("FrameRate".into())).await;
    s.pending.push_back(Pending::FrameRate);
    send(&cmd, server, &Packet::RequestModelDef).await;

    let mut last_heard = Instant::now();
    let mut connected = true;
    let mut keepalive = tokio::time::interval(opts.keepalive_interval);
    keepalive.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut watchdog =
        tokio::time::interval((opts.silence_timeout / 4).max(Duration::from_millis(20)));
    let mut dbuf = vec![0u8; 65536];
    loop {
        tokio::select! {
            _ = shutdown.changed() => {
                if *shutdown.borrow() {
                    if unicast { send(&cmd, server, &Packet::Disconnect).await; }
                    break;
                }
            }
            r = cmd.recv_from(&mut buf) => {
                let Ok((n, _)) = r else { continue };
                last_heard = Instant::now();
                if let Some(d) = buf.get(..n) {
                    on_datagram(d, true, &mut s, &mut connected, opts, &sink, &cmd).await?;
                }
                if s.release {
                    s.release = false;
                    for d in std::mem::take(&mut s.held) {
                        on_datagram(&d, true, &mut s, &mut connected, opts, &sink, &cmd).await?;
                    }
                }
            }
            r = async { match &data { Some(d) => d.recv_from(&mut dbuf).await, None => std::future::pending().await } } => {
                let Ok((n, _)) = r else { continue };
                last_heard = Instant::now();
                if let Some(d) = dbuf.get(..n) {
                    on_datagram(d, false, &mut s, &mut connected, opts, &sink, &cmd).await?;
                }
                if s.release {
                    s.release = false;
                    for d in std::mem::take(&mut s.held) {
                        on_datagram(&d, true, &mut s, &mut connected, opts, &sink, &cmd).await?;
                    }
                }
            }
            _ = keepalive.tick(), if unicast && connected => {
                send(&cmd, server, &Packet::KeepAlive).await;
            }
            _ = watchdog.tick() => {
                if last_heard.elapsed() >= opts.silence_timeout {
                    if connected {
                        tracing::warn!("NatNet server {server} silent for {:.1} s; reconnecting", opts.silence_timeout.as_secs_f64());
                        connected = false;
                    }
                    let _ = cmd.send_to(&connect, server).await;
                    last_heard = Instant::now() - opts.silence_timeout + Duration::from_millis(500).min(opts.silence_timeout);
                }
            }
        }
    }
    Ok(report(&s, &stats))
}

fn report(s: &Session, stats: &NatNetStats) -> SourceReport {
    let server = match &s.info {
        Some(i) => {
            let v = i.sender.version;
            format!(
                "{} {}.{}.{}.{} at {}",
                i.sender.name, v[0], v[1], v[2], v[3], s.server
            )
        }
        None => s.server.to_string(),
    };
    SourceReport {
        server,
        version: s.info.as_ref().map(|_| s.version),
        frames: stats.frames.load(Ordering::Relaxed),
        markers: stats.markers.load(Ordering::Relaxed),
        missed_frames: stats.missed_frames.load(Ordering::Relaxed),
        bad_packets: stats.bad_packets(),
        reconnects: stats.reconnects.load(Ordering::Relaxed),
        restarts: stats.restarts.load(Ordering::Relaxed),
    }
}

/// Takes the version and clock from a SERVERINFO.
fn adopt(s: &mut Session, info: ServerInfo, stats: &NatNetStats) {
    s.version = info.sender.natnet();
    s.clock_frequency = info.connection.map_or(0, |c| c.clock_frequency);
    tracing::info!(
        "connected to {} (NatNet {}) at {}",
        info.sender.name,
        s.version,
        s.server
    );
    if let Ok(mut g) = stats.server.lock() {
        *g = Some((info.sender.name.clone(), s.version));
    }
    s.info = Some(info);
}

/// Binds the data port with address reuse and joins the group.
fn join(local: Ipv4Addr, group: Ipv4Addr, port: u16) -> Result<UdpSocket> {
    let iface = if local.is_unspecified() {
        "0.0.0.0 (any)".to_string()
    } else {
        local.to_string()
    };
    let s = socket(SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, port), true)
        .map_err(|e| Error::Runtime(format!("cannot bind the NatNet data port {port}: {e}")))?;
    s.join_multicast_v4(&group, &local).map_err(|e| {
        Error::Runtime(format!(
            "cannot join multicast group {group} on interface {iface}: {e} (is the interface up, \
             with a multicast route? try --unicast)"
        ))
    })?;
    tokio_socket(s).map_err(|e| Error::Runtime(format!("data socket: {e}")))
}

async fn send(cmd: &UdpSocket, to: SocketAddr, p: &Packet) {
    match encode(p, Version::new(4, 1)) {
        Ok(b) => {
            if let Err(e) = cmd.send_to(&b, to).await {
                tracing::debug!("cannot send {} to {to}: {e}", packet::message_name(p.id()));
            }
        }
        Err(e) => tracing::warn!("{e}"),
    }
}

/// Handles one datagram from the command socket (`command`) or the data socket.
async fn on_datagram(
    d: &[u8],
    command: bool,
    s: &mut Session,
    connected: &mut bool,
    opts: &NatNetOptions,
    sink: &FrameSink,
    cmd: &UdpSocket,
) -> Result<()> {
    let stats = &opts.stats;
    let mid = peek_id(d);
    if !command
        && mid != Some(id::FRAMEOFDATA)
        && mid.is_some_and(|m| packet::message_name(m) != "unknown message")
    {
        stats.skipped.fetch_add(1, Ordering::Relaxed);
        tracing::debug!(
            "skipped {} on the data channel",
            packet::message_name(mid.unwrap_or(0))
        );
        return Ok(());
    }
    let packet = match decode(d, s.version) {
        Ok(p) => p,
        Err(e) => {
            let counter = match e.kind {
                DecodeErrorKind::Incomplete => &stats.incomplete,
                DecodeErrorKind::Invalid => &stats.invalid,
                DecodeErrorKind::UnknownMessage => &stats.unknown,
            };
            counter.fetch_add(1, Ordering::Relaxed);
            s.warned += 1;
            if s.warned <= 20 || s.warned.is_power_of_two() {
                tracing::warn!(
                    "NatNet {} from {}: {e} (bad datagram #{})",
                    s.version,
                    s.server,
                    s.warned
                );
            }
            return Ok(());
        }
    };
    match packet {
        Packet::FrameOfData(_)
            if !s.version.at_least(2, 6)
                && s.frame_rate.is_none()
                && s.pending.contains(&Pending::FrameRate)
                && s.hold_since.is_none_or(|t| t.elapsed() < HOLD_LIMIT)
                && s.held.len() < 10_000 =>
        {
            s.hold_since.get_or_insert_with(Instant::now);
            s.held.push(d.to_vec());
        }
        Packet::FrameOfData(_) if !s.held.is_empty() => {
            // The FrameRate answer never came: release the held frames
            // first, in order, on arrival time.
            s.held.push(d.to_vec());
            s.release = true;
        }
        Packet::FrameOfData(f) => {
            if !*connected {
                stats.reconnects.fetch_add(1, Ordering::Relaxed);
                *connected = true;
            }
            let n = f.frame_number as i64;
            if let Some(last) = s.last_frame {
                if n <= last {
                    stats.restarts.fetch_add(1, Ordering::Relaxed);
                    tracing::info!(
                        "frame number went back from {last} to {n}: server restarted or looped"
                    );
                    s.first_frame = None;
                    send(cmd, s.server, &Packet::RequestModelDef).await;
                } else if n > last + 1 {
                    stats
                        .missed_frames
                        .fetch_add((n - last - 1) as u64, Ordering::Relaxed);
                }
            }
            s.last_frame = Some(n);
            let first = *s.first_frame.get_or_insert(n);
            if f.params & FRAME_MODELS_CHANGED != 0 {
                send(cmd, s.server, &Packet::RequestModelDef).await;
            }
            if f.params & FRAME_BITSTREAM_CHANGED != 0 {
                tracing::debug!("frame {n} announces a bitstream change (now {})", s.version);
            }
            // 2.5 and earlier frames carry no timestamp.
            let fallback = match s.frame_rate {
                Some(r) if r > 0.0 => (n - first) as f64 / r,
                _ => s.started.elapsed().as_secs_f64(),
            };
            let mf = to_marker_frame(&f, s.version, opts.markers, s.clock_frequency, fallback);
            if let Some(l) = mf.latency_s {
                stats.latency_us.store((l * 1e6) as u64, Ordering::Relaxed);
            }
            stats.frames.fetch_add(1, Ordering::Relaxed);
            stats
                .markers
                .fetch_add(mf.markers.len() as u64, Ordering::Relaxed);
            sink.push(mf);
        }
        Packet::ServerInfo(info) => {
            let was = *connected;
            if !was {
                stats.reconnects.fetch_add(1, Ordering::Relaxed);
                *connected = true;
            }
            if !was || info.sender.natnet() != s.version {
                // A restarted server: it may speak another version now, and
                // a requested bitstream must be asked for again.
                adopt(s, info, stats);
                send(cmd, s.server, &Packet::RequestModelDef).await;
                if let Some(want) = opts.bitstream.filter(|&v| v != s.version) {
                    send(cmd, s.server, &Packet::Request(format!("Bitstream,{want}"))).await;
                    s.pending.push_back(Pending::Bitstream(want));
                }
            }
        }
        Packet::Response(r) => match s.pending.pop_front() {
            Some(Pending::FrameRate) => {
                s.release = true;
                s.frame_rate = r
                    .as_f32()
                    .map(|x| x as f64)
                    .filter(|x| x.is_finite() && *x > 0.0);
                tracing::info!("server frame rate: {:?}", s.frame_rate);
            }
            Some(Pending::Bitstream(want)) => bitstream_answer(s, want, Some(&r))?,
            None => tracing::debug!("unrequested response {r:?}"),
        },
        Packet::UnrecognizedRequest(_) => match s.pending.pop_front() {
            Some(Pending::Bitstream(want)) => bitstream_answer(s, want, None)?,
            Some(Pending::FrameRate) => {
                s.release = true;
                tracing::debug!("server does not know FrameRate");
            }
            None => {}
        },
        Packet::ModelDef(m) => {
            stats.modeldefs.fetch_add(1, Ordering::Relaxed);
            tracing::info!("model definitions: {} datasets", m.descriptions.len());
        }
        Packet::MessageString(text) => tracing::info!("NatNet server says: {text}"),
        Packet::EchoResponse { .. } => {}
        other => {
            stats.skipped.fetch_add(1, Ordering::Relaxed);
            tracing::debug!(
                "ignored {} from the server",
                packet::message_name(other.id())
            );
        }
    }
    Ok(())
}

/// The server's answer to `Bitstream,X.Y`: 0 or a "Bitstream,X.Y…" string
/// accepts; anything else (an error code, an unrecognized request) refuses.
fn bitstream_answer(s: &mut Session, want: Version, r: Option<&Response>) -> Result<()> {
    let accepted = match r {
        Some(Response::Value(_)) => r.and_then(Response::as_i32) == Some(0),
        Some(r) => {
            r.as_text()
                .and_then(|t| t.strip_prefix("Bitstream,"))
                .and_then(Version::parse)
                == Some(want)
        }
        None => false,
    };
    if !accepted {
        return Err(Error::Runtime(format!(
            "the NatNet server at {} refused bitstream version {want} (it streams {}; answer: {})",
            s.server,
            s.version,
            match r {
                Some(r) => format!("{r:?}"),
                None => "unrecognized request".into(),
            }
        )));
    }
    tracing::info!("bitstream switched from {} to {want}", s.version);
    s.version = want;
    Ok(())
}
