//! The NatNet client's protocol state, with no socket and no clock: the
//! I/O layer (`source::natnet::client`) hands it each datagram with the time
//! and the sender's address ([`Session::handle`]), wakes it at
//! [`Session::poll_timeout`] ([`Session::on_timeout`]), and carries out the
//! [`Action`]s it queues ([`Session::poll_action`]): send these bytes to that
//! address, join this multicast group, here is a frame, the version changed,
//! give up with this error. The same split as quinn-proto's, so every rule
//! below is unit-tested without a network.
//!
//! What it does, and why:
//! - **Handshake**: CONNECT every 500 ms until the server's SERVERINFO, for
//!   at most `connect_timeout`. SERVERINFO gives the version frames are
//!   decoded with, the server's clock, and (3.0+) unicast or multicast, the
//!   group and the data port. Then it asks for the bitstream it was told to
//!   use (unicast, server 3.0+), the frame rate (`FrameRate`), the up axis
//!   when set to `auto` (`GetProperty,,Up Axis`) and the model definitions.
//! - **Only the server is heard.** Replies (SERVERINFO, RESPONSE, …) count
//!   only from the server's command address; frames only from the server's
//!   address (and its data port once known), or on the multicast socket,
//!   which the I/O layer binds to the group itself. Anything else is counted
//!   as *wrong sender* and does not keep the session alive, so a forged
//!   SERVERINFO can neither change the version nor hide a dead server.
//! - **Unicast keep-alive** every `keepalive_interval`: servers drop silent
//!   unicast clients.
//! - **Silence** longer than `silence_timeout`: the server went away or
//!   restarted; CONNECT again every 500 ms until it answers. A SERVERINFO
//!   with another version is a restarted server: adopt it, ask again for
//!   the bitstream and the models.
//! - **Frames that keep failing to decode** for more than
//!   [`DECODE_FAILURE_LIMIT`]: the version we decode with is wrong. Say so
//!   (state [`State::DecodeFailing`]) and renegotiate: CONNECT again and
//!   take the version from the answer, whatever it is.
//! - **Frame times**: 2.6+ frames carry their timestamp. 2.5 and earlier
//!   carry none: frame number over the frame rate, else the arrival time. So
//!   the first frames are held until the rate is known (at most
//!   [`HOLD_LIMIT`]); held frames keep their arrival time and are flushed
//!   at [`Session::close`].
//! - **Frame rate**: the server's answer to `FrameRate`; where it has none,
//!   the rate measured over the first frames (their numbers and times).
//!   [`FrameRate::source`] says which.
//! - Frame numbers that go back are counted as restarts (and MODELDEF is
//!   asked again); frame params bit 0x02 (models changed) asks again too.
//! - Bad datagrams are counted by kind and logged (rate-limited) with
//!   message, field and offset; the session carries on.

use std::collections::VecDeque;
use std::net::{Ipv4Addr, SocketAddr};
use std::time::{Duration, Instant};

use serde::Serialize;

use super::select::{
    to_marker_frame, up_axis_from_answer, up_axis_name, FrameContext, MarkerSelection, UpAxis,
    UpAxisSetting,
};
use super::{
    decode, encode, id, message_name, peek_id, Connect, ConnectionOptions, DecodeError,
    DecodeErrorKind, FrameOfData, Packet, Response, Sender, ServerInfo, Transport, Version,
    DEFAULT_DATA_PORT, DEFAULT_MULTICAST_GROUP, FRAME_BITSTREAM_CHANGED, FRAME_MODELS_CHANGED,
    OLDEST_VERSION,
};
use crate::model::frame::MarkerFrame;

/// Longest wait for the frame rate (and the up axis) before the first frames
/// go out anyway: untimed frames then fall back to their arrival time.
pub const HOLD_LIMIT: Duration = Duration::from_secs(1);
/// How long frames from the server may keep failing to decode before the
/// session says so and renegotiates.
pub const DECODE_FAILURE_LIMIT: Duration = Duration::from_secs(1);
/// CONNECT is repeated this often while the server does not answer.
const CONNECT_RETRY: Duration = Duration::from_millis(500);
/// Held frames beyond this many are released (a 10 kHz stream for 1 s).
const MAX_HELD: usize = 10_000;
/// Frames over this span measure the frame rate well enough.
const MEASURE_SPAN_S: f64 = 0.5;
/// The bitstream our own commands are encoded with (their layout never
/// depends on it).
const COMMAND_VERSION: Version = Version::new(4, 1);

/// What the session is told; the source's settings make it.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionSettings {
    /// Unicast or multicast; None follows SERVERINFO (3.0+) and, for 2.x
    /// servers, which do not say, listens on both.
    pub transport: Option<Transport>,
    /// The multicast group; None: from SERVERINFO (3.0+), else the default.
    pub multicast_group: Option<Ipv4Addr>,
    /// The server's data port; None: from SERVERINFO (3.0+), else 1511.
    pub data_port: Option<u16>,
    /// Ask the server to stream this bitstream (unicast, server 3.0+).
    pub bitstream: Option<Version>,
    /// Which markers of a frame become the [`MarkerFrame`].
    pub markers: MarkerSelection,
    /// Which axis of the stream points up.
    pub up_axis: UpAxisSetting,
    /// Give up when the server has not answered CONNECT for this long.
    pub connect_timeout: Duration,
    /// Reconnect after this long without a datagram from the server.
    pub silence_timeout: Duration,
    /// Unicast keep-alive period.
    pub keepalive_interval: Duration,
}

impl Default for SessionSettings {
    fn default() -> Self {
        SessionSettings {
            transport: None,
            multicast_group: None,
            data_port: None,
            bitstream: None,
            markers: MarkerSelection::default(),
            up_axis: UpAxisSetting::default(),
            connect_timeout: Duration::from_secs(3),
            silence_timeout: Duration::from_secs(2),
            keepalive_interval: Duration::from_secs(1),
        }
    }
}

/// Which of the server's channels a datagram came by.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    /// Its command port: replies (and frames from servers that send them
    /// from there).
    Command,
    /// Its data port or the multicast group: frames only.
    Data,
}

/// Which socket a datagram arrived on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// The command socket: replies, and unicast frames.
    Command,
    /// The multicast data socket (bound to the group and data port).
    Data,
}

/// Where the frame rate came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RateSource {
    /// The server's answer to the `FrameRate` request.
    Server,
    /// Measured from the frame numbers and times of the first frames.
    Measured,
}

/// A frame rate and where it came from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameRate {
    /// Frames per second.
    pub hz: f64,
    /// The server's answer, or measured.
    pub source: RateSource,
}

impl std::fmt::Display for FrameRate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.source {
            RateSource::Server => write!(f, "{} Hz (the server's FrameRate answer)", self.hz),
            RateSource::Measured => write!(
                f,
                "{:.3} Hz (measured from frame numbers and times; the server gave no FrameRate)",
                self.hz
            ),
        }
    }
}

/// Where the session is, as `/status` shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum State {
    /// Sending CONNECT, waiting for SERVERINFO.
    Connecting,
    /// Frames are coming.
    Streaming,
    /// The server went silent; sending CONNECT until it answers.
    Reconnecting,
    /// Frames from the server keep failing to decode; renegotiating.
    DecodeFailing,
    /// Stopped by [`Session::close`] or a fatal error.
    Closed,
}

impl std::fmt::Display for State {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            State::Connecting => "connecting",
            State::Streaming => "streaming",
            State::Reconnecting => "server silent; reconnecting",
            State::DecodeFailing => "frames fail to decode; renegotiating",
            State::Closed => "closed",
        })
    }
}

/// What the session counts; the daemon shows it on `/status`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Counters {
    /// Frames decoded and handed on.
    pub frames: u64,
    /// Markers in those frames (after selection).
    pub markers: u64,
    /// Frame numbers skipped between consecutive frames.
    pub missed_frames: u64,
    /// Datagrams that ended inside a field.
    pub incomplete: u64,
    /// Datagrams with an impossible field.
    pub invalid: u64,
    /// Datagrams with a message id NatNet does not define.
    pub unknown: u64,
    /// Datagrams from anyone but the server, ignored.
    pub wrong_sender: u64,
    /// Well-formed datagrams not expected where they came (SERVERINFO on
    /// the data channel, requests sent to a client).
    pub skipped: u64,
    /// Times the server answered again after silence.
    pub reconnects: u64,
    /// Times frames kept failing to decode and the session renegotiated.
    pub renegotiations: u64,
    /// Times the frame number went back (server restarted or looped).
    pub restarts: u64,
    /// MODELDEFs received.
    pub modeldefs: u64,
    /// Latest system latency (3.0+), microseconds.
    pub latency_us: u64,
}

impl Counters {
    /// All datagrams that did not decode.
    pub fn bad_packets(&self) -> u64 {
        self.incomplete + self.invalid + self.unknown
    }
}

/// The server as its SERVERINFO names it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ServerIdentity {
    /// Application name ("Motive").
    pub name: String,
    /// Application version.
    pub app_version: [u8; 4],
    /// The bitstream frames are decoded with now.
    pub version: Version,
}

/// Why a session gave up. Each names the server and what to do.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SessionError {
    /// No SERVERINFO within the connect timeout.
    #[error("NatNet server {server}: no answer after {:.1} s", after.as_secs_f64())]
    NoAnswer {
        /// The command address.
        server: SocketAddr,
        /// The connect timeout.
        after: Duration,
    },
    /// The server speaks a NatNet older than [`OLDEST_VERSION`].
    #[error("{server}: the server speaks NatNet {version}; treemocap reads 2.0 and later")]
    Unsupported {
        /// The command address.
        server: SocketAddr,
        /// Its version.
        version: Version,
    },
    /// A bitstream was asked for, but the server multicasts.
    #[error("cannot request bitstream {want}: the server streams multicast, and the bitstream can only be changed in unicast")]
    BitstreamMulticast {
        /// The version asked for.
        want: Version,
    },
    /// A bitstream was asked for, but the server is older than 3.0.
    #[error("cannot request bitstream {want}: the server speaks NatNet {server_version}, which cannot change its bitstream (3.0 or later can)")]
    BitstreamTooOld {
        /// The version asked for.
        want: Version,
        /// The server's.
        server_version: Version,
    },
    /// The server refused the bitstream.
    #[error("the NatNet server at {server} refused bitstream version {want} (it streams {current}; answer: {answer})")]
    BitstreamRefused {
        /// The command address.
        server: SocketAddr,
        /// The version asked for.
        want: Version,
        /// What it streams.
        current: Version,
        /// Its answer, as text.
        answer: String,
    },
}

/// What the I/O layer must do, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Send `datagram` from the command socket to `to`.
    Send {
        /// The server's command address.
        to: SocketAddr,
        /// The encoded message.
        datagram: Vec<u8>,
    },
    /// Bind the data socket to `group:port` and join the group. `required`
    /// is false when the server did not say it multicasts (2.x): then a
    /// failure is a warning and frames are taken by unicast only.
    JoinMulticast {
        /// The multicast group.
        group: Ipv4Addr,
        /// The data port.
        port: u16,
        /// Whether failing to join is fatal.
        required: bool,
    },
    /// The server answered: first contact or again after a restart.
    Connected(ServerIdentity),
    /// Frames are decoded with another bitstream from now on.
    VersionChanged {
        /// The old version.
        from: Version,
        /// The new one.
        to: Version,
    },
    /// The frame rate is known.
    FrameRate(FrameRate),
    /// A frame for the pipeline.
    Frame(MarkerFrame),
    /// The session gave up; the I/O layer stops with this error.
    Fail(SessionError),
}

/// A request waiting for its NAT_RESPONSE (responses come in order).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Pending {
    FrameRate,
    UpAxis,
    Bitstream(Version),
}

/// Where the frame rate stands.
#[derive(Debug, Clone, Copy, PartialEq)]
enum RateState {
    /// `FrameRate` asked, no answer yet.
    Asking,
    /// The server had none: measuring over the first frames.
    Measuring,
    /// Known.
    Known(FrameRate),
    /// Nothing to measure it with; untimed frames use arrival times.
    Unknown,
}

/// A frame held until the frame rate (or up axis) is known.
struct HeldFrame {
    arrived: Instant,
    frame: Box<FrameOfData>,
    version: Version,
}

/// The client's protocol state for one server; see the module docs.
pub struct Session {
    settings: SessionSettings,
    /// The server's command address.
    server: SocketAddr,
    state: State,
    started: Instant,
    connect_deadline: Instant,
    next_connect: Option<Instant>,
    next_keepalive: Option<Instant>,
    last_heard: Instant,
    info: Option<ServerInfo>,
    version: Version,
    clock_frequency: u64,
    /// Chosen from the settings and SERVERINFO; None listens on both.
    transport: Option<Transport>,
    /// The server's data port, when known (frames come from it in unicast).
    data_port: Option<u16>,
    rate: RateState,
    up: Option<UpAxis>,
    pending: VecDeque<Pending>,
    held: Vec<HeldFrame>,
    last_frame: Option<i64>,
    first_frame: Option<i64>,
    /// First decode failure of a frame since the last good one.
    failing_since: Option<Instant>,
    last_decode_error: Option<DecodeError>,
    /// Adopt the next SERVERINFO whatever its version (after a renegotiation).
    renegotiating: bool,
    /// Rate-limits warnings.
    warned: u64,
    counters: Counters,
    actions: VecDeque<Action>,
}

impl Session {
    /// A session with the server at `server` (its command address), started
    /// at `now`: its first action sends CONNECT.
    pub fn new(settings: SessionSettings, server: SocketAddr, now: Instant) -> Session {
        let up = match settings.up_axis {
            UpAxisSetting::Auto => None,
            UpAxisSetting::Y => Some(UpAxis::Y),
            UpAxisSetting::Z => Some(UpAxis::Z),
        };
        let mut s = Session {
            connect_deadline: now + settings.connect_timeout,
            transport: settings.transport,
            data_port: settings.data_port,
            settings,
            server,
            state: State::Connecting,
            started: now,
            next_connect: None,
            next_keepalive: None,
            last_heard: now,
            info: None,
            version: Version::new(3, 0),
            clock_frequency: 0,
            rate: RateState::Asking,
            up,
            pending: VecDeque::new(),
            held: Vec::new(),
            last_frame: None,
            first_frame: None,
            failing_since: None,
            last_decode_error: None,
            renegotiating: false,
            warned: 0,
            counters: Counters::default(),
            actions: VecDeque::new(),
        };
        s.send_connect(now);
        s
    }

    /// The next thing the I/O layer must do.
    pub fn poll_action(&mut self) -> Option<Action> {
        self.actions.pop_front()
    }

    /// Where the session is.
    pub fn state(&self) -> State {
        self.state
    }

    /// What it counted so far.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// The server, once it answered.
    pub fn server(&self) -> Option<ServerIdentity> {
        self.info.as_ref().map(|i| ServerIdentity {
            name: i.sender.name.clone(),
            app_version: i.sender.version,
            version: self.version,
        })
    }

    /// The server's command address.
    pub fn server_addr(&self) -> SocketAddr {
        self.server
    }

    /// The frame rate, once known.
    pub fn frame_rate(&self) -> Option<FrameRate> {
        match self.rate {
            RateState::Known(r) => Some(r),
            _ => None,
        }
    }

    /// The stream's up axis, once known.
    pub fn up_axis(&self) -> Option<UpAxis> {
        self.up
    }

    /// Whether frames travel by unicast to the command socket (so
    /// keep-alives and DISCONNECT are due).
    fn unicast(&self) -> bool {
        self.transport != Some(Transport::Multicast)
    }

    /// When [`Session::on_timeout`] is due next.
    pub fn poll_timeout(&self) -> Option<Instant> {
        if self.state == State::Closed {
            return None;
        }
        let silence = (self.state != State::Connecting && self.next_connect.is_none())
            .then(|| self.last_heard + self.settings.silence_timeout);
        let hold = self.held.first().map(|h| h.arrived + HOLD_LIMIT);
        let failing = self.failing_since.map(|t| t + DECODE_FAILURE_LIMIT);
        let deadline = (self.state == State::Connecting).then_some(self.connect_deadline);
        [
            deadline,
            self.next_connect,
            self.next_keepalive,
            silence,
            hold,
            failing,
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// Does what is due at `now`: CONNECT again, a keep-alive, notice
    /// silence or a run of undecodable frames, release held frames.
    pub fn on_timeout(&mut self, now: Instant) {
        if self.state == State::Closed {
            return;
        }
        if self.state == State::Connecting && now >= self.connect_deadline {
            self.fail(SessionError::NoAnswer {
                server: self.server,
                after: self.settings.connect_timeout,
            });
            return;
        }
        if self.next_connect.is_some_and(|t| now >= t) {
            self.send_connect(now);
        }
        if self.next_keepalive.is_some_and(|t| now >= t) {
            self.send(&Packet::KeepAlive);
            self.next_keepalive = Some(now + self.settings.keepalive_interval);
        }
        if self.state != State::Connecting
            && self.next_connect.is_none()
            && now >= self.last_heard + self.settings.silence_timeout
        {
            tracing::warn!(
                "NatNet server {} silent for {:.1} s; reconnecting",
                self.server,
                self.settings.silence_timeout.as_secs_f64()
            );
            self.state = State::Reconnecting;
            self.next_keepalive = None;
            self.send_connect(now);
        }
        if self
            .held
            .first()
            .is_some_and(|h| now >= h.arrived + HOLD_LIMIT)
        {
            self.give_up_waiting();
        }
        if self
            .failing_since
            .is_some_and(|t| now >= t + DECODE_FAILURE_LIMIT)
        {
            self.renegotiate(now);
        }
    }

    /// Ends the session: held frames go out (with their arrival times), a
    /// unicast server is told DISCONNECT.
    pub fn close(&mut self, _now: Instant) {
        if self.state == State::Closed {
            return;
        }
        self.give_up_waiting();
        if self.info.is_some() && self.unicast() {
            self.send(&Packet::Disconnect);
        }
        self.state = State::Closed;
    }

    /// Takes one datagram that arrived at `now` from `from` on `channel`.
    pub fn handle(&mut self, now: Instant, from: SocketAddr, channel: Channel, datagram: &[u8]) {
        if self.state == State::Closed {
            return;
        }
        let mid = peek_id(datagram);
        let Some(source) = self.source_of(from, channel) else {
            self.counters.wrong_sender += 1;
            if self.should_warn() {
                tracing::warn!(
                    "NatNet datagram ({}) from {from}, not from the server {}: ignored",
                    mid.map_or("empty", message_name),
                    self.server
                );
            }
            return;
        };
        self.last_heard = now;
        if source == Source::Data
            && mid != Some(id::FRAMEOFDATA)
            && mid.is_some_and(|m| message_name(m) != "unknown message")
        {
            // Motive 1.x multicasts SERVERINFO on the data channel; only
            // the command port's replies count (a version change above all).
            self.counters.skipped += 1;
            tracing::debug!(
                "skipped {} from the data channel",
                message_name(mid.unwrap_or(0))
            );
            return;
        }
        // Before SERVERINFO the version is unknown; only SERVERINFO matters
        // then, and its layout does not depend on the version.
        match decode(datagram, self.version) {
            Ok(packet) => self.on_packet(now, packet),
            Err(e) => self.on_bad_datagram(now, mid, e),
        }
    }

    /// The sender rule of the module docs: which of the server's channels
    /// a datagram came by, or None when it is not from the server.
    fn source_of(&self, from: SocketAddr, channel: Channel) -> Option<Source> {
        if from.ip() != self.server.ip() {
            return None;
        }
        match channel {
            // The data socket is bound to the group: only the source matters.
            Channel::Data => Some(Source::Data),
            Channel::Command if from.port() == self.server.port() => Some(Source::Command),
            // Unicast frames come from the data port (any port of the
            // server's address while it is unknown: 2.x does not say).
            Channel::Command => self
                .data_port
                .is_none_or(|p| p == from.port())
                .then_some(Source::Data),
        }
    }

    fn on_bad_datagram(&mut self, now: Instant, mid: Option<u16>, e: DecodeError) {
        match e.kind {
            DecodeErrorKind::Incomplete => self.counters.incomplete += 1,
            DecodeErrorKind::Invalid => self.counters.invalid += 1,
            DecodeErrorKind::UnknownMessage => self.counters.unknown += 1,
        }
        let n = self.counters.bad_packets();
        if self.should_warn() {
            tracing::warn!(
                "NatNet {} from {}: {e} (bad datagram #{n})",
                self.version,
                self.server
            );
        }
        if mid == Some(id::FRAMEOFDATA) && self.info.is_some() {
            self.failing_since.get_or_insert(now);
            self.last_decode_error = Some(e);
        }
    }

    fn on_packet(&mut self, now: Instant, packet: Packet) {
        if self.info.is_none() && !matches!(packet, Packet::ServerInfo(_)) {
            // Not connected yet: nothing else can be read right.
            self.counters.skipped += 1;
            return;
        }
        match packet {
            Packet::FrameOfData(f) => self.on_frame(now, f),
            Packet::ServerInfo(info) => self.on_server_info(now, info),
            Packet::Response(r) => self.on_response(Some(r)),
            Packet::UnrecognizedRequest(_) => self.on_response(None),
            Packet::ModelDef(m) => {
                self.counters.modeldefs += 1;
                tracing::info!("model definitions: {} datasets", m.descriptions.len());
            }
            Packet::MessageString(text) => tracing::info!("NatNet server says: {text}"),
            Packet::EchoResponse { .. } => {}
            other => {
                self.counters.skipped += 1;
                tracing::debug!("ignored {} from the server", message_name(other.id()));
            }
        }
    }

    fn on_server_info(&mut self, now: Instant, info: ServerInfo) {
        let first = self.info.is_none();
        let again = matches!(self.state, State::Reconnecting | State::DecodeFailing);
        let version_changed = info.sender.natnet() != self.version;
        if !first && !again && !version_changed && !self.renegotiating {
            return;
        }
        if !first && self.state == State::Reconnecting {
            self.counters.reconnects += 1;
        }
        self.next_connect = None;
        self.renegotiating = false;
        // Still failing until a frame decodes again.
        if self.state != State::DecodeFailing {
            self.state = State::Streaming;
        }
        let old = self.version;
        self.adopt(info);
        if first {
            self.start_streaming(now);
            return;
        }
        if self.version != old {
            self.actions.push_back(Action::VersionChanged {
                from: old,
                to: self.version,
            });
        }
        // A restarted server may speak another version now, and a requested
        // bitstream must be asked for again.
        self.send(&Packet::RequestModelDef);
        if let Some(want) = self.settings.bitstream.filter(|&v| v != self.version) {
            self.request(&format!("Bitstream,{want}"), Pending::Bitstream(want));
        }
        if self.unicast() {
            self.next_keepalive = Some(now + self.settings.keepalive_interval);
        }
    }

    /// Takes the version, clock and data port from a SERVERINFO (a restarted
    /// server may have another data port).
    fn adopt(&mut self, info: ServerInfo) {
        self.version = info.sender.natnet();
        self.clock_frequency = info.connection.map_or(0, |c| c.clock_frequency);
        self.data_port = self
            .settings
            .data_port
            .or(info.connection.map(|c| c.data_port).filter(|&p| p != 0));
        tracing::info!(
            "connected to {} (NatNet {}) at {}",
            info.sender.name,
            self.version,
            self.server
        );
        self.info = Some(info);
        if let Some(id) = self.server() {
            self.actions.push_back(Action::Connected(id));
        }
    }

    /// After the first SERVERINFO: where frames come from, and the requests.
    fn start_streaming(&mut self, now: Instant) {
        if self.version < OLDEST_VERSION {
            self.fail(SessionError::Unsupported {
                server: self.server,
                version: self.version,
            });
            return;
        }
        let conn = self.info.as_ref().and_then(|i| i.connection);
        self.transport = self.settings.transport.or(conn.map(|c| {
            if c.multicast {
                Transport::Multicast
            } else {
                Transport::Unicast
            }
        }));
        if self.transport != Some(Transport::Unicast) {
            let group = self
                .settings
                .multicast_group
                .or(conn
                    .map(|c| Ipv4Addr::from(c.multicast_group))
                    .filter(|g| g.is_multicast()))
                .unwrap_or(DEFAULT_MULTICAST_GROUP);
            self.actions.push_back(Action::JoinMulticast {
                group,
                port: self.data_port.unwrap_or(DEFAULT_DATA_PORT),
                required: self.transport.is_some(),
            });
        }
        if let Some(want) = self.settings.bitstream.filter(|&v| v != self.version) {
            if self.transport == Some(Transport::Multicast) {
                return self.fail(SessionError::BitstreamMulticast { want });
            }
            if self.version.major < 3 {
                return self.fail(SessionError::BitstreamTooOld {
                    want,
                    server_version: self.version,
                });
            }
            self.request(&format!("Bitstream,{want}"), Pending::Bitstream(want));
        }
        self.request("FrameRate", Pending::FrameRate);
        if self.up.is_none() {
            self.request("GetProperty,,Up Axis", Pending::UpAxis);
        }
        self.send(&Packet::RequestModelDef);
        if self.unicast() {
            self.next_keepalive = Some(now + self.settings.keepalive_interval);
        }
    }

    fn on_response(&mut self, r: Option<Response>) {
        match self.pending.pop_front() {
            Some(Pending::FrameRate) => {
                let hz = r
                    .as_ref()
                    .and_then(Response::as_f32)
                    .map(f64::from)
                    .filter(|x| x.is_finite() && *x > 0.0);
                match hz {
                    Some(hz) => self.set_rate(FrameRate {
                        hz,
                        source: RateSource::Server,
                    }),
                    None => {
                        tracing::info!("the server gave no frame rate ({r:?}); measuring it");
                        self.rate = RateState::Measuring;
                        self.try_measure(false);
                    }
                }
            }
            Some(Pending::UpAxis) => {
                let up = r
                    .as_ref()
                    .and_then(Response::as_text)
                    .and_then(up_axis_from_answer);
                match up {
                    Some(up) => tracing::info!("the server streams {} up", up_axis_name(up)),
                    None => tracing::info!(
                        "the server does not say its up axis ({r:?}); taking Y up \
                         (set natnet.up_axis = \"z\" for a Z-up stream)"
                    ),
                }
                self.up = Some(up.unwrap_or(UpAxis::Y));
            }
            Some(Pending::Bitstream(want)) => self.bitstream_answer(want, r.as_ref()),
            None => tracing::debug!("unrequested response {r:?}"),
        }
        self.release_if_ready();
    }

    /// The server's answer to `Bitstream,X.Y`: 0 or a "Bitstream,X.Y…"
    /// string accepts; anything else (an error code, an unrecognized
    /// request) refuses.
    fn bitstream_answer(&mut self, want: Version, r: Option<&Response>) {
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
            return self.fail(SessionError::BitstreamRefused {
                server: self.server,
                want,
                current: self.version,
                answer: match r {
                    Some(r) => format!("{r:?}"),
                    None => "unrecognized request".into(),
                },
            });
        }
        tracing::info!("bitstream switched from {} to {want}", self.version);
        let from = self.version;
        self.version = want;
        self.actions
            .push_back(Action::VersionChanged { from, to: want });
    }

    fn on_frame(&mut self, now: Instant, frame: Box<FrameOfData>) {
        if self.failing_since.take().is_some() && self.counters.renegotiations > 0 {
            tracing::info!("frames decode again with NatNet {}", self.version);
        }
        if matches!(self.state, State::Reconnecting | State::DecodeFailing) {
            if self.state == State::Reconnecting {
                self.counters.reconnects += 1;
            }
            self.state = State::Streaming;
            self.next_connect = None;
            if self.unicast() {
                self.next_keepalive = Some(now + self.settings.keepalive_interval);
            }
        }
        let waiting =
            matches!(self.rate, RateState::Asking | RateState::Measuring) || self.up.is_none();
        if waiting || !self.held.is_empty() {
            self.held.push(HeldFrame {
                arrived: now,
                frame,
                version: self.version,
            });
            if self.held.len() >= MAX_HELD {
                self.give_up_waiting();
            } else {
                self.try_measure(false);
                self.release_if_ready();
            }
            return;
        }
        self.emit(now, &frame, self.version);
    }

    /// Sets the rate and says which one it is.
    fn set_rate(&mut self, rate: FrameRate) {
        tracing::info!("frame rate {rate}");
        self.rate = RateState::Known(rate);
        self.actions.push_back(Action::FrameRate(rate));
    }

    /// While measuring: once the held frames span enough time (or, with
    /// `force`, any time at all), the rate is their frame-number span over
    /// their time span (timestamps from 2.6, arrival times before).
    fn try_measure(&mut self, force: bool) {
        if self.rate != RateState::Measuring {
            return;
        }
        let (Some(a), Some(b)) = (self.held.first(), self.held.last()) else {
            return;
        };
        let time = |h: &HeldFrame| {
            if h.version.at_least(2, 6) {
                h.frame.timestamp
            } else {
                h.arrived.duration_since(self.started).as_secs_f64()
            }
        };
        let frames = f64::from(b.frame.frame_number) - f64::from(a.frame.frame_number);
        let span = time(b) - time(a);
        if span < MEASURE_SPAN_S && !force {
            return;
        }
        let hz = frames / span;
        if hz.is_finite() && hz > 0.0 {
            self.set_rate(FrameRate {
                hz,
                source: RateSource::Measured,
            });
        } else if force {
            tracing::warn!("the frame rate is unknown: the server gave none and too few frames came to measure it");
            self.rate = RateState::Unknown;
        }
    }

    /// The hold limit passed (or the session ends): measure what can be,
    /// stop waiting for answers, and release the held frames.
    fn give_up_waiting(&mut self) {
        if self.rate == RateState::Asking {
            self.rate = RateState::Measuring;
        }
        self.try_measure(true);
        if self.rate == RateState::Measuring {
            self.rate = RateState::Unknown;
        }
        if self.up.is_none() {
            tracing::info!("no up-axis answer from the server; taking Y up");
            self.up = Some(UpAxis::Y);
        }
        self.release_if_ready();
    }

    /// Releases held frames, in order, with their arrival times, once the
    /// rate and the up axis are settled.
    fn release_if_ready(&mut self) {
        let settled = matches!(self.rate, RateState::Known(_) | RateState::Unknown);
        if !settled || self.up.is_none() {
            return;
        }
        for h in std::mem::take(&mut self.held) {
            self.emit(h.arrived, &h.frame, h.version);
        }
    }

    /// Turns a frame that arrived at `arrived` into a [`MarkerFrame`] action.
    fn emit(&mut self, arrived: Instant, f: &FrameOfData, version: Version) {
        let n = i64::from(f.frame_number);
        if let Some(last) = self.last_frame {
            if n <= last {
                self.counters.restarts += 1;
                tracing::info!(
                    "frame number went back from {last} to {n}: server restarted or looped"
                );
                self.first_frame = None;
                self.send(&Packet::RequestModelDef);
            } else if n > last + 1 {
                self.counters.missed_frames += (n - last - 1) as u64;
            }
        }
        self.last_frame = Some(n);
        let first = *self.first_frame.get_or_insert(n);
        if f.params & FRAME_MODELS_CHANGED != 0 {
            self.send(&Packet::RequestModelDef);
        }
        if f.params & FRAME_BITSTREAM_CHANGED != 0 {
            tracing::debug!("frame {n} announces a bitstream change (now {version})");
        }
        // 2.5 and earlier frames carry no timestamp.
        let fallback = match self.rate {
            RateState::Known(r) => (n - first) as f64 / r.hz,
            _ => arrived.duration_since(self.started).as_secs_f64(),
        };
        let cx = FrameContext {
            version,
            selection: self.settings.markers,
            up: self.up.unwrap_or(UpAxis::Y),
            clock_frequency: self.clock_frequency,
        };
        let mf = to_marker_frame(f, &cx, fallback);
        if let Some(l) = mf.latency_s {
            self.counters.latency_us = (l * 1e6) as u64;
        }
        self.counters.frames += 1;
        self.counters.markers += mf.markers.len() as u64;
        self.actions.push_back(Action::Frame(mf));
    }

    /// Frames failed to decode for [`DECODE_FAILURE_LIMIT`]: say so and ask
    /// the server for its version again.
    fn renegotiate(&mut self, now: Instant) {
        if self.state != State::DecodeFailing {
            self.counters.renegotiations += 1;
            tracing::warn!(
                "NatNet frames from {} have failed to decode with NatNet {} for over {:.1} s \
                 (last: {}); renegotiating",
                self.server,
                self.version,
                DECODE_FAILURE_LIMIT.as_secs_f64(),
                self.last_decode_error
                    .as_ref()
                    .map_or_else(String::new, |e| e.to_string()),
            );
        }
        self.state = State::DecodeFailing;
        self.renegotiating = true;
        self.failing_since = Some(now);
        self.send_connect(now);
    }

    fn fail(&mut self, e: SessionError) {
        self.state = State::Closed;
        self.actions.push_back(Action::Fail(e));
    }

    fn send_connect(&mut self, now: Instant) {
        self.send(&connect_packet());
        self.next_connect = Some(now + CONNECT_RETRY);
    }

    fn request(&mut self, text: &str, pending: Pending) {
        self.send(&Packet::Request(text.into()));
        self.pending.push_back(pending);
    }

    fn send(&mut self, p: &Packet) {
        match encode(p, COMMAND_VERSION) {
            Ok(datagram) => self.actions.push_back(Action::Send {
                to: self.server,
                datagram,
            }),
            // Our own commands are a few bytes: this cannot fail.
            Err(e) => tracing::error!("cannot encode {}: {e}", message_name(p.id())),
        }
    }

    /// Rate-limits warnings about bad datagrams: the first 20, then every
    /// power of two, so a flood costs a few dozen lines.
    fn should_warn(&mut self) -> bool {
        self.warned += 1;
        self.warned <= 20 || self.warned.is_power_of_two()
    }
}

/// Who we are in CONNECT and DISCOVERY.
pub fn our_sender() -> Sender {
    Sender {
        name: "treemocap".into(),
        version: [0, 1, 0, 0],
        natnet_version: [4, 1, 0, 0],
    }
}

/// Our CONNECT: an `sSender` with connection options asking for the
/// server's own bitstream (0.0.0.0), as NatNet 4.x clients send it.
pub fn connect_packet() -> Packet {
    Packet::Connect(Connect::Sender {
        sender: our_sender(),
        options: Some(ConnectionOptions {
            subscribed_data_only: false,
            bitstream: [0; 4],
        }),
        spare: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::natnet::{LabeledMarker, ServerConnection, MARKER_UNLABELED};

    const V31: Version = Version::new(3, 1);

    fn server() -> SocketAddr {
        "10.0.0.5:1510".parse().unwrap()
    }

    fn info(v: Version, data_port: u16) -> Vec<u8> {
        let info = ServerInfo {
            sender: Sender {
                name: "Motive".into(),
                version: [3, 0, 1, 0],
                natnet_version: [v.major, v.minor, 0, 0],
            },
            connection: (v.major >= 3).then_some(ServerConnection {
                clock_frequency: 1_000_000,
                data_port,
                multicast: false,
                multicast_group: [239, 255, 42, 99],
            }),
        };
        encode(&Packet::ServerInfo(info), v).unwrap()
    }

    fn frame(n: i32, v: Version) -> Vec<u8> {
        let f = FrameOfData {
            frame_number: n,
            labeled_markers: vec![LabeledMarker {
                id: 1,
                position: [1.0, 2.0, 3.0],
                params: MARKER_UNLABELED,
                ..Default::default()
            }],
            timestamp: f64::from(n) / 100.0,
            ..Default::default()
        };
        encode(&Packet::FrameOfData(Box::new(f)), v).unwrap()
    }

    fn reply(p: Packet) -> Vec<u8> {
        encode(&p, V31).unwrap()
    }

    fn actions(s: &mut Session) -> Vec<Action> {
        std::iter::from_fn(|| s.poll_action()).collect()
    }

    /// The packets a list of actions sends.
    fn sent(a: &[Action]) -> Vec<Packet> {
        a.iter()
            .filter_map(|a| match a {
                Action::Send { datagram, .. } => Some(decode(datagram, V31).unwrap()),
                _ => None,
            })
            .collect()
    }

    fn frames(a: &[Action]) -> Vec<MarkerFrame> {
        a.iter()
            .filter_map(|a| match a {
                Action::Frame(f) => Some(f.clone()),
                _ => None,
            })
            .collect()
    }

    fn settings() -> SessionSettings {
        SessionSettings {
            up_axis: UpAxisSetting::Y,
            ..Default::default()
        }
    }

    /// A session that had SERVERINFO (3.1, data port 1511) and the
    /// server's 100 Hz FrameRate answer.
    fn streaming(t0: Instant) -> Session {
        let mut s = Session::new(settings(), server(), t0);
        s.handle(t0, server(), Channel::Command, &info(V31, 1511));
        s.handle(
            t0,
            server(),
            Channel::Command,
            &reply(Packet::Response(Response::float(100.0))),
        );
        actions(&mut s);
        s
    }

    #[test]
    fn connect_is_repeated_until_the_server_answers_then_given_up() {
        let t0 = Instant::now();
        let mut s = Session::new(settings(), server(), t0);
        assert!(matches!(sent(&actions(&mut s))[..], [Packet::Connect(_)]));
        assert_eq!(s.poll_timeout(), Some(t0 + CONNECT_RETRY));
        s.on_timeout(t0 + CONNECT_RETRY);
        assert!(matches!(sent(&actions(&mut s))[..], [Packet::Connect(_)]));
        s.on_timeout(t0 + Duration::from_secs(3));
        let a = actions(&mut s);
        assert!(
            matches!(a.last(), Some(Action::Fail(SessionError::NoAnswer { .. }))),
            "{a:?}"
        );
        assert_eq!(s.state(), State::Closed);
    }

    #[test]
    fn server_info_sets_the_version_and_asks_for_rate_axis_and_models() {
        let t0 = Instant::now();
        let mut s = Session::new(SessionSettings::default(), server(), t0);
        actions(&mut s);
        s.handle(
            t0,
            server(),
            Channel::Command,
            &info(Version::new(4, 1), 1511),
        );
        let a = actions(&mut s);
        assert!(matches!(&a[0], Action::Connected(id) if id.version == Version::new(4, 1)));
        let requests: Vec<Packet> = sent(&a);
        assert_eq!(
            requests,
            vec![
                Packet::Request("FrameRate".into()),
                Packet::Request("GetProperty,,Up Axis".into()),
                Packet::RequestModelDef,
            ]
        );
        // Frames wait for both answers, then go out Z-up-corrected.
        let t1 = t0 + Duration::from_millis(5);
        s.handle(
            t1,
            server(),
            Channel::Command,
            &frame(7, Version::new(4, 1)),
        );
        assert!(frames(&actions(&mut s)).is_empty());
        s.handle(
            t1,
            server(),
            Channel::Command,
            &reply(Packet::Response(Response::float(100.0))),
        );
        let a = actions(&mut s);
        assert!(a.contains(&Action::FrameRate(FrameRate {
            hz: 100.0,
            source: RateSource::Server
        })));
        assert!(frames(&a).is_empty(), "the up axis is still unknown");
        s.handle(
            t1,
            server(),
            Channel::Command,
            &reply(Packet::Response(Response::Text("Z".into()))),
        );
        let f = frames(&actions(&mut s));
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].markers[0].position, glam::DVec3::new(1.0, 3.0, -2.0));
        assert_eq!(s.up_axis(), Some(UpAxis::Z));
    }

    #[test]
    fn only_the_servers_own_datagrams_count() {
        let t0 = Instant::now();
        let mut s = streaming(t0);
        let stranger: SocketAddr = "10.0.0.6:1510".parse().unwrap();
        let other_port: SocketAddr = "10.0.0.5:4000".parse().unwrap();
        let data_port: SocketAddr = "10.0.0.5:1511".parse().unwrap();
        for from in [stranger, other_port, data_port] {
            s.handle(t0, from, Channel::Command, &info(Version::new(4, 1), 1511));
        }
        s.handle(t0, stranger, Channel::Command, &frame(1, V31));
        s.handle(t0, other_port, Channel::Command, &frame(2, V31));
        s.handle(t0, stranger, Channel::Data, &frame(3, V31));
        // The data port is the server's, but only frames count from there.
        assert_eq!(s.counters().wrong_sender, 5);
        assert_eq!(s.counters().skipped, 1);
        assert!(actions(&mut s).is_empty());
        assert_eq!(s.server().unwrap().version, V31);
        // Frames come from the data port (unicast) or to the group (data).
        s.handle(t0, data_port, Channel::Command, &frame(4, V31));
        s.handle(t0, server(), Channel::Data, &frame(5, V31));
        let f = frames(&actions(&mut s));
        assert_eq!(f.iter().map(|f| f.frame).collect::<Vec<_>>(), vec![4, 5]);
        // Strangers do not keep a dead server alive.
        let t1 = t0 + Duration::from_millis(1900);
        s.handle(t1, stranger, Channel::Command, &frame(6, V31));
        s.on_timeout(t0 + Duration::from_secs(2));
        assert_eq!(s.state(), State::Reconnecting);
    }

    #[test]
    fn silence_reconnects_and_a_restarted_server_is_adopted() {
        let t0 = Instant::now();
        let mut s = streaming(t0);
        let t1 = t0 + Duration::from_secs(2);
        assert_eq!(
            s.poll_timeout(),
            Some(t0 + Duration::from_secs(1)),
            "keep-alive first"
        );
        s.on_timeout(t0 + Duration::from_secs(1));
        assert_eq!(sent(&actions(&mut s)), vec![Packet::KeepAlive]);
        s.on_timeout(t1);
        assert_eq!(s.state(), State::Reconnecting);
        assert!(matches!(
            sent(&actions(&mut s)).last(),
            Some(Packet::Connect(_))
        ));
        s.handle(
            t1,
            server(),
            Channel::Command,
            &info(Version::new(4, 0), 1511),
        );
        let a = actions(&mut s);
        assert!(a.contains(&Action::VersionChanged {
            from: V31,
            to: Version::new(4, 0)
        }));
        assert!(sent(&a).contains(&Packet::RequestModelDef));
        assert_eq!((s.state(), s.counters().reconnects), (State::Streaming, 1));
    }

    #[test]
    fn undecodable_frames_for_a_second_renegotiate() {
        let t0 = Instant::now();
        let mut s = streaming(t0);
        let v41 = Version::new(4, 1);
        for ms in (0..=1000).step_by(100) {
            let t = t0 + Duration::from_millis(ms);
            s.handle(t, server(), Channel::Command, &frame(ms as i32, v41));
            s.on_timeout(t);
        }
        assert_eq!(s.state(), State::DecodeFailing);
        assert_eq!(s.counters().renegotiations, 1);
        assert!(sent(&actions(&mut s))
            .iter()
            .any(|p| matches!(p, Packet::Connect(_))));
        // The same version again is adopted too: the server says so.
        let t = t0 + Duration::from_millis(1100);
        s.handle(t, server(), Channel::Command, &info(v41, 1511));
        s.handle(t, server(), Channel::Command, &frame(2000, v41));
        assert_eq!(frames(&actions(&mut s)).len(), 1);
        assert_eq!(s.state(), State::Streaming);
    }

    #[test]
    fn a_refused_bitstream_is_an_error_naming_it() {
        let t0 = Instant::now();
        let mut s = Session::new(
            SessionSettings {
                bitstream: Some(Version::new(4, 1)),
                ..settings()
            },
            server(),
            t0,
        );
        s.handle(t0, server(), Channel::Command, &info(V31, 1511));
        let a = actions(&mut s);
        assert_eq!(sent(&a)[1], Packet::Request("Bitstream,4.1".into()));
        s.handle(
            t0,
            server(),
            Channel::Command,
            &reply(Packet::Response(Response::int(-1))),
        );
        let a = actions(&mut s);
        let Some(Action::Fail(e)) = a.last() else {
            panic!("{a:?}")
        };
        assert!(
            e.to_string().contains("refused bitstream version 4.1"),
            "{e}"
        );
    }

    #[test]
    fn without_a_frame_rate_answer_it_is_measured_and_held_frames_keep_arrival_times() {
        let t0 = Instant::now();
        let v25 = Version::new(2, 5);
        let mut s = Session::new(settings(), server(), t0);
        s.handle(t0, server(), Channel::Command, &info(v25, 0));
        actions(&mut s);
        // 2.5 frames carry no time: 10 ms apart on arrival, numbered 1 apart.
        for k in 0..3 {
            let t = t0 + Duration::from_millis(10 * k);
            s.handle(t, server(), Channel::Command, &frame(k as i32, v25));
        }
        // Stopped before any answer: delivered at once, arrival times.
        s.close(t0 + Duration::from_millis(500));
        let a = actions(&mut s);
        let f = frames(&a);
        assert_eq!(f.len(), 3);
        assert!((f[2].time_s - f[0].time_s - 0.02).abs() < 1e-9, "{f:?}");
        let rate = s.frame_rate().unwrap();
        assert_eq!(rate.source, RateSource::Measured);
        assert!((rate.hz - 100.0).abs() < 1e-6, "{rate:?}");
        assert!(sent(&a).contains(&Packet::Disconnect));
    }
}
