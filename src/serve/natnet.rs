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
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use socket2::{Domain, Protocol, Socket, Type};
use tokio::net::UdpSocket;
use tokio::sync::watch;

use crate::error::{Error, Result};
use crate::model::frame::MarkerFrame;
use crate::model::recording::Recording;
use crate::protocol::natnet::select::{up_axis_name, UpAxis};
pub use crate::protocol::natnet::Transport;
use crate::protocol::natnet::{
    self as packet, decode, encode_into, Connect, Description, FrameOfData, LabeledMarker,
    ModelDef, Packet, Response, Sender, ServerConnection, ServerInfo, Version,
    FRAME_BITSTREAM_CHANGED, MARKER_UNLABELED,
};

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
    /// Unicast to each client, or multicast to the group.
    pub transport: Transport,
    /// Local address for the command and data sockets.
    pub bind: Ipv4Addr,
    /// 0 picks a free port (tests); see [`ServerStats::command_addr`].
    pub command_port: u16,
    /// The port frames are sent from (and, in multicast, to).
    pub data_port: u16,
    /// The multicast group, as four octets.
    pub multicast_group: Ipv4Addr,
    /// Interface (its IPv4 address) multicast frames leave by.
    pub multicast_interface: Ipv4Addr,
    /// Start playback only when the first client connects, so it sees the
    /// whole recording; false starts at once.
    pub wait_for_client: bool,
    /// A unicast client silent this long (no keep-alive) gets no more frames.
    pub client_timeout: Duration,
    /// The up axis of the stream: Y (Motive's default), or Z to stand in
    /// for Motive's "Z up" streaming option. Clients asking
    /// `GetProperty,,Up Axis` are told.
    pub up_axis: UpAxis,
    /// Counters the caller can read while the server runs.
    pub stats: Arc<ServerStats>,
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            version: packet::DEFAULT_SERVE_VERSION,
            up_axis: UpAxis::Y,
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
    /// Frames played.
    pub frames: u64,
    /// Times the recording started again.
    pub loops: u64,
    /// Unicast clients that connected.
    pub clients: u64,
    /// Seconds the server ran.
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

/// A recorded frame as Motive would stream it in `version` with `up` up (see
/// the module docs for where the markers go). Ticks are the server clock at
/// send time.
pub fn to_natnet_frame(
    frame: &MarkerFrame,
    version: Version,
    ticks: u64,
    up: UpAxis,
) -> FrameOfData {
    let pos = |m: &crate::model::frame::Marker| {
        let p = m.position;
        match up {
            UpAxis::Y => [p.x as f32, p.y as f32, p.z as f32],
            // The inverse of the client's (x, y, z) -> (x, z, -y).
            UpAxis::Z => [p.x as f32, -p.z as f32, p.y as f32],
        }
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

/// Streams the recordings `open` gives (called again for each loop) until
/// the last ends (or forever with `looping`) or `shutdown` turns true.
pub async fn serve(
    mut open: impl FnMut() -> Result<Box<dyn Recording>>,
    opts: &ServeOptions,
    mut shutdown: watch::Receiver<bool>,
) -> Result<ServeReport> {
    check_options(opts)?;
    let recording = open()?;
    let (cmd, data, data_port) = open_sockets(opts)?;
    let mut server = Server::new(opts, recording.info().frame_rate, data_port);
    let mut player = Player::new(recording);
    let mut buf = vec![0u8; 65536];
    loop {
        if server.playing && !player.advance(&mut open, opts)? {
            break;
        }
        let due = player.due(opts.speed);
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
                let was_playing = server.playing;
                if let Some((reply, v)) = server.on_command(from, &buf[..n], player.last_sent.as_ref()) {
                    server.send_reply(&cmd, from, &reply, v).await;
                }
                if server.playing && !was_playing {
                    player.start(opts.transport);
                }
            }
            _ = sleep, if due.is_some() => {
                if let Some(frame) = player.pending.take() {
                    server.stream(&data, &frame).await;
                    player.last_sent = Some(frame);
                }
            }
        }
    }
    Ok(ServeReport {
        frames: server.stats.frames.load(Ordering::Relaxed),
        loops: player.loops,
        clients: server.clients_seen,
        elapsed_s: server.started.elapsed().as_secs_f64(),
    })
}

/// Speed and version checks, each naming its option.
fn check_options(opts: &ServeOptions) -> Result<()> {
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
    Ok(())
}

/// Binds the command and data sockets (multicast set up on the data one)
/// and publishes their addresses in the stats.
fn open_sockets(opts: &ServeOptions) -> Result<(UdpSocket, UdpSocket, u16)> {
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
    // A smaller send buffer only risks loss under load: not an error.
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
    Ok((cmd, data, data_port))
}

/// The recording being played: the next frame, when it is due, loops.
struct Player {
    recording: Box<dyn Recording>,
    /// The next frame to send, read ahead.
    pending: Option<MarkerFrame>,
    /// The last frame sent (REQUEST_FRAMEOFDATA answers with it).
    last_sent: Option<MarkerFrame>,
    /// When the first frame of this pass is due.
    play_start: Instant,
    /// The recording time of the first frame of this pass.
    first_time: Option<f64>,
    loops: u64,
}

impl Player {
    fn new(recording: Box<dyn Recording>) -> Self {
        Player {
            recording,
            pending: None,
            last_sent: None,
            play_start: Instant::now(),
            first_time: None,
            loops: 0,
        }
    }

    /// Playback starts (the first client connected). A multicast client
    /// joins the group only after SERVERINFO told it where; give it that
    /// moment.
    fn start(&mut self, transport: Transport) {
        self.play_start = Instant::now()
            + match transport {
                Transport::Multicast => Duration::from_millis(250),
                Transport::Unicast => Duration::ZERO,
            };
    }

    /// Reads the next frame if none is pending; false at the end.
    fn advance(
        &mut self,
        open: &mut impl FnMut() -> Result<Box<dyn Recording>>,
        opts: &ServeOptions,
    ) -> Result<bool> {
        while self.pending.is_none() {
            match self.recording.next() {
                Some(Ok(f)) => self.pending = Some(f),
                Some(Err(e)) => return Err(e),
                None if opts.looping => {
                    self.recording = open()?;
                    self.loops += 1;
                    self.first_time = None;
                    self.play_start = Instant::now();
                }
                None => return Ok(false),
            }
        }
        Ok(true)
    }

    /// When the pending frame is due, at `speed` times the recorded rate.
    fn due(&mut self, speed: f64) -> Option<Instant> {
        let f = self.pending.as_ref()?;
        let t0 = *self.first_time.get_or_insert(f.time_s);
        let dt = ((f.time_s - t0) / speed).max(0.0);
        Some(
            self.play_start
                + Duration::from_secs_f64(if dt.is_finite() { dt.min(1e9) } else { 0.0 }),
        )
    }
}

/// The server's state apart from the recording: clients, clock, counters.
struct Server<'a> {
    opts: &'a ServeOptions,
    stats: &'a ServerStats,
    frame_rate: f64,
    data_port: u16,
    group: SocketAddr,
    started: Instant,
    clients: HashMap<SocketAddr, Client>,
    clients_seen: u64,
    playing: bool,
    /// Reused encode buffers: one for replies and announcements, and one
    /// per version in use for the frame sent to every client.
    out: Vec<u8>,
    per_version: Vec<(Version, Vec<u8>)>,
}

impl<'a> Server<'a> {
    fn new(opts: &'a ServeOptions, frame_rate: f64, data_port: u16) -> Self {
        Server {
            opts,
            stats: &opts.stats,
            frame_rate,
            data_port,
            group: SocketAddr::V4(SocketAddrV4::new(opts.multicast_group, data_port)),
            started: Instant::now(),
            clients: HashMap::new(),
            clients_seen: 0,
            playing: !opts.wait_for_client,
            out: Vec::with_capacity(65536),
            per_version: Vec::new(),
        }
    }

    /// The server clock: nanoseconds since start.
    fn ticks(&self) -> u64 {
        self.started.elapsed().as_nanos() as u64
    }

    fn server_info(&self, version: Version) -> Packet {
        Packet::ServerInfo(server_info(
            version,
            self.opts.transport,
            self.data_port,
            self.opts.multicast_group,
        ))
    }

    /// Handles one command datagram; returns the reply and the version to
    /// encode it in.
    fn on_command(
        &mut self,
        from: SocketAddr,
        datagram: &[u8],
        last_sent: Option<&MarkerFrame>,
    ) -> Option<(Packet, Version)> {
        let packet = match decode(datagram, self.opts.version) {
            Ok(p) => p,
            Err(e) => {
                self.stats.bad_packets.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("bad datagram from {from}: {e}");
                return None;
            }
        };
        let now = Instant::now();
        if let Some(c) = self.clients.get_mut(&from) {
            c.last_seen = now;
        }
        let client_version = self
            .clients
            .get(&from)
            .map_or(self.opts.version, |c| c.version);
        let reply = match packet {
            Packet::Connect(c) => Some(self.on_connect(from, &c, now)),
            Packet::Discovery(_) => Some(self.server_info(self.opts.version)),
            Packet::KeepAlive => None,
            Packet::Disconnect => {
                self.clients.remove(&from);
                None
            }
            Packet::RequestModelDef => Some(Packet::ModelDef(model_def())),
            Packet::RequestFrameOfData => last_sent
                .map(|f| Packet::FrameOfData(Box::new(self.natnet_frame(f, client_version)))),
            Packet::EchoRequest(t) => Some(Packet::EchoResponse {
                client_ticks: t,
                server_ticks: self.ticks(),
            }),
            Packet::Request(text) => Some(answer_request(
                &text,
                self.opts,
                self.frame_rate,
                self.clients.get_mut(&from),
            )),
            other => {
                tracing::debug!("ignoring {} from {from}", packet::message_name(other.id()));
                None
            }
        }?;
        self.stats.requests.fetch_add(1, Ordering::Relaxed);
        let v = self
            .clients
            .get(&from)
            .map_or(self.opts.version, |c| c.version);
        Some((reply, v))
    }

    /// A client connects: remember it, start playing, answer SERVERINFO.
    fn on_connect(&mut self, from: SocketAddr, c: &Connect, now: Instant) -> Packet {
        self.stats.connects.fetch_add(1, Ordering::Relaxed);
        if let Connect::Sender { sender, .. } = c {
            tracing::info!(
                "client {from} connected: {:?} NatNet {}",
                sender.name,
                sender.natnet()
            );
        } else {
            tracing::info!("client {from} connected");
        }
        if !self.clients.contains_key(&from) {
            self.clients_seen += 1;
        }
        // The bitstream in a 4.x CONNECT is not honoured: clients decode
        // with SERVERINFO's version (spec §4).
        let version = self.opts.version;
        let entry = self.clients.entry(from).or_insert(Client {
            version,
            last_seen: now,
            announce_change: false,
        });
        entry.last_seen = now;
        let v = entry.version;
        self.playing = true;
        self.server_info(v)
    }

    async fn send_reply(&mut self, cmd: &UdpSocket, to: SocketAddr, reply: &Packet, v: Version) {
        match encode_into(reply, v, &mut self.out) {
            Ok(()) => {
                // A client gone away is not the server's problem.
                let _ = cmd.send_to(&self.out, to).await;
            }
            Err(e) => tracing::warn!("cannot answer {to}: {e}"),
        }
    }

    /// A recorded frame as this server streams it in `version`.
    fn natnet_frame(&self, f: &MarkerFrame, version: Version) -> FrameOfData {
        to_natnet_frame(f, version, self.ticks(), self.opts.up_axis)
    }

    /// Sends one frame: to the group, or to every unicast client in its
    /// own version.
    async fn stream(&mut self, data: &UdpSocket, frame: &MarkerFrame) {
        self.stats.frames.fetch_add(1, Ordering::Relaxed);
        match self.opts.transport {
            Transport::Multicast => {
                let nf = Packet::FrameOfData(Box::new(self.natnet_frame(frame, self.opts.version)));
                match encode_into(&nf, self.opts.version, &mut self.out) {
                    Ok(()) => {
                        if data.send_to(&self.out, self.group).await.is_ok() {
                            self.stats.datagrams.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    Err(e) => oversized(self.stats, frame, e),
                }
            }
            Transport::Unicast => self.stream_unicast(data, frame).await,
        }
    }

    async fn stream_unicast(&mut self, data: &UdpSocket, frame: &MarkerFrame) {
        let now = Instant::now();
        let timeout = self.opts.client_timeout;
        self.clients.retain(|a, c| {
            let keep = now.duration_since(c.last_seen) < timeout;
            if !keep {
                tracing::info!("client {a} timed out");
            }
            keep
        });
        self.per_version.clear();
        let addrs: Vec<SocketAddr> = self.clients.keys().copied().collect();
        for addr in addrs {
            let bytes = match self.frame_for(addr, frame) {
                Some(Encoded::Shared(i)) => &self.per_version[i].1,
                Some(Encoded::Own) => &self.out,
                None => continue,
            };
            if data.send_to(bytes, addr).await.is_ok() {
                self.stats.datagrams.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Encodes the frame for the client at `addr`: once per version, shared
    /// by every client of it, except the first frame after a bitstream
    /// change, which carries the frame-params bit 0x08 (into `out`).
    fn frame_for(&mut self, addr: SocketAddr, frame: &MarkerFrame) -> Option<Encoded> {
        let c = self.clients.get_mut(&addr)?;
        let version = c.version;
        let announce = std::mem::take(&mut c.announce_change);
        if !announce {
            if let Some(i) = self.per_version.iter().position(|(v, _)| *v == version) {
                return Some(Encoded::Shared(i));
            }
        }
        let mut nf = self.natnet_frame(frame, version);
        if announce {
            nf.params |= FRAME_BITSTREAM_CHANGED;
        }
        let nf = Packet::FrameOfData(Box::new(nf));
        if announce {
            return match encode_into(&nf, version, &mut self.out) {
                Ok(()) => Some(Encoded::Own),
                Err(e) => {
                    oversized(self.stats, frame, e);
                    None
                }
            };
        }
        let mut b = Vec::new();
        if let Err(e) = encode_into(&nf, version, &mut b) {
            oversized(self.stats, frame, e);
            return None;
        }
        self.per_version.push((version, b));
        Some(Encoded::Shared(self.per_version.len() - 1))
    }
}

/// Where [`Server::frame_for`] put the encoded frame.
enum Encoded {
    /// `per_version[i]`.
    Shared(usize),
    /// `out`.
    Own,
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
        // Motive's property query; only the up axis is known here.
        "GetProperty" if text.ends_with(",Up Axis") => {
            Packet::Response(Response::Text(up_axis_name(opts.up_axis).into()))
        }
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
