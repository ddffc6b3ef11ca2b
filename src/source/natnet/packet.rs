//! The NatNet wire format: message types, a strict decoder and a byte-exact
//! encoder for every bitstream version from 2.0 to 4.x. Pure functions, no I/O.
//!
//! The layouts are those of `../shared/spec/natnet.md` (OptiTrack's
//! `PacketClient.cpp` of each SDK, checked against real captures). A frame
//! carries no version number, so every call takes the [`Version`] negotiated
//! with the server.
//!
//! Decoding is strict: every byte of the payload must be accounted for, every
//! count must fit in what is left of the packet, 4.1+ section sizes must agree
//! with their content. Failures are [`DecodeError`]s that name the message, the
//! field and the byte offset in the datagram, split into *incomplete* (the
//! packet ended inside a field) and *invalid* (a field holds an impossible
//! value). Nothing here panics on any input: all reads are bounds-checked and
//! counts are checked against the remaining bytes before anything is allocated.
//!
//! One leniency, because real clients are sloppy (spec §2): a datagram may be
//! longer than its header's `nDataBytes`; the extra bytes are ignored. And
//! payload-less client messages (KEEPALIVE, REQUEST_MODELDEF, …) may carry NUL
//! padding.

use std::fmt;

/// Default command port of a NatNet server (`NATNET_DEFAULT_PORT_COMMAND`).
pub const DEFAULT_COMMAND_PORT: u16 = 1510;
/// Default data port of a NatNet server (`NATNET_DEFAULT_PORT_DATA`).
pub const DEFAULT_DATA_PORT: u16 = 1511;
/// Default multicast group (`NATNET_DEFAULT_MULTICAST_ADDRESS`).
pub const DEFAULT_MULTICAST_GROUP: std::net::Ipv4Addr = std::net::Ipv4Addr::new(239, 255, 42, 99);
/// `nDataBytes` is a u16, so no payload can be longer than this.
pub const MAX_PAYLOAD: usize = u16::MAX as usize;
/// Labeled-marker params bit: an unlabeled point-cloud marker (3.0+).
pub const MARKER_UNLABELED: i16 = 0x10;
/// Frame params bit: the tracked-model list changed; re-request MODELDEF.
pub const FRAME_MODELS_CHANGED: i16 = 0x02;
/// Frame params bit: the bitstream version changed (unicast `Bitstream` request).
pub const FRAME_BITSTREAM_CHANGED: i16 = 0x08;

/// Message ids (spec §3). 2.x names in parentheses in the docs.
pub mod id {
    pub const CONNECT: u16 = 0;
    pub const SERVERINFO: u16 = 1;
    pub const REQUEST: u16 = 2;
    pub const RESPONSE: u16 = 3;
    pub const REQUEST_MODELDEF: u16 = 4;
    pub const MODELDEF: u16 = 5;
    pub const REQUEST_FRAMEOFDATA: u16 = 6;
    pub const FRAMEOFDATA: u16 = 7;
    pub const MESSAGESTRING: u16 = 8;
    pub const DISCONNECT: u16 = 9;
    pub const KEEPALIVE: u16 = 10;
    pub const DISCONNECTBYTIMEOUT: u16 = 11;
    pub const ECHOREQUEST: u16 = 12;
    pub const ECHORESPONSE: u16 = 13;
    pub const DISCOVERY: u16 = 14;
    pub const UNRECOGNIZED_REQUEST: u16 = 100;
}

/// The name of a message id, for error messages and logs.
pub fn message_name(id: u16) -> &'static str {
    match id {
        id::CONNECT => "NAT_CONNECT",
        id::SERVERINFO => "NAT_SERVERINFO",
        id::REQUEST => "NAT_REQUEST",
        id::RESPONSE => "NAT_RESPONSE",
        id::REQUEST_MODELDEF => "NAT_REQUEST_MODELDEF",
        id::MODELDEF => "NAT_MODELDEF",
        id::REQUEST_FRAMEOFDATA => "NAT_REQUEST_FRAMEOFDATA",
        id::FRAMEOFDATA => "NAT_FRAMEOFDATA",
        id::MESSAGESTRING => "NAT_MESSAGESTRING",
        id::DISCONNECT => "NAT_DISCONNECT",
        id::KEEPALIVE => "NAT_KEEPALIVE",
        id::DISCONNECTBYTIMEOUT => "NAT_DISCONNECTBYTIMEOUT",
        id::ECHOREQUEST => "NAT_ECHOREQUEST",
        id::ECHORESPONSE => "NAT_ECHORESPONSE",
        id::DISCOVERY => "NAT_DISCOVERY",
        id::UNRECOGNIZED_REQUEST => "NAT_UNRECOGNIZED_REQUEST",
        _ => "unknown message",
    }
}

/// A NatNet bitstream version (major.minor). Build and revision never change
/// the layout, so they are not part of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Version {
    pub major: u8,
    pub minor: u8,
}

impl Version {
    pub const fn new(major: u8, minor: u8) -> Self {
        Version { major, minor }
    }

    /// `self >= major.minor`.
    pub fn at_least(self, major: u8, minor: u8) -> bool {
        (self.major, self.minor) >= (major, minor)
    }

    /// 4.1 added a u32 byte count after every frame section's count and
    /// after every description's type.
    pub fn has_section_sizes(self) -> bool {
        self.at_least(4, 1)
    }

    /// Parses "3.1" (a third component, "4.1.0", is accepted and ignored).
    pub fn parse(text: &str) -> Option<Version> {
        let mut parts = text.trim().split('.');
        let major = parts.next()?.trim().parse().ok()?;
        let minor = parts.next().map_or(Some(0), |m| m.trim().parse().ok())?;
        Some(Version { major, minor })
    }
}

impl fmt::Display for Version {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.major, self.minor)
    }
}

impl std::str::FromStr for Version {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Version::parse(s).ok_or_else(|| format!("'{s}' is not a NatNet version like 3.1"))
    }
}

/// Every bitstream version whose frame layout differs from its predecessor's,
/// plus the later 4.x versions: what the round-trip tests and the server cover.
pub const SUPPORTED_VERSIONS: &[Version] = &[
    Version::new(2, 5),
    Version::new(2, 6),
    Version::new(2, 7),
    Version::new(2, 9),
    Version::new(2, 11),
    Version::new(3, 0),
    Version::new(3, 1),
    Version::new(4, 0),
    Version::new(4, 1),
    Version::new(4, 2),
    Version::new(4, 3),
];

/// The oldest bitstream this codec decodes (the 2.0 frame layout; 1.x differs).
pub const OLDEST_VERSION: Version = Version::new(2, 0);

// ---------------------------------------------------------------------------
// Message types
// ---------------------------------------------------------------------------

/// One NatNet datagram, decoded.
#[derive(Debug, Clone, PartialEq)]
pub enum Packet {
    Connect(Connect),
    ServerInfo(ServerInfo),
    /// A command string: `FrameRate`, `Bitstream,4.1`, `TimelinePlay`, …
    Request(String),
    Response(Response),
    RequestModelDef,
    ModelDef(ModelDef),
    RequestFrameOfData,
    FrameOfData(Box<FrameOfData>),
    /// A free-text message from the server.
    MessageString(String),
    Disconnect,
    KeepAlive,
    DisconnectByTimeout,
    /// Client's clock in its own ticks.
    EchoRequest(u64),
    /// The echoed client ticks and the server's receive time in its hi-res ticks.
    EchoResponse {
        client_ticks: u64,
        server_ticks: u64,
    },
    /// Broadcast by clients looking for a server; same payload forms as CONNECT.
    Discovery(Connect),
    /// The server's answer to a request it does not know; Motive fills the
    /// payload with junk, kept only for byte-exact re-encoding.
    UnrecognizedRequest(Vec<u8>),
}

impl Packet {
    /// The message id this packet is sent with.
    pub fn id(&self) -> u16 {
        match self {
            Packet::Connect(_) => id::CONNECT,
            Packet::ServerInfo(_) => id::SERVERINFO,
            Packet::Request(_) => id::REQUEST,
            Packet::Response(_) => id::RESPONSE,
            Packet::RequestModelDef => id::REQUEST_MODELDEF,
            Packet::ModelDef(_) => id::MODELDEF,
            Packet::RequestFrameOfData => id::REQUEST_FRAMEOFDATA,
            Packet::FrameOfData(_) => id::FRAMEOFDATA,
            Packet::MessageString(_) => id::MESSAGESTRING,
            Packet::Disconnect => id::DISCONNECT,
            Packet::KeepAlive => id::KEEPALIVE,
            Packet::DisconnectByTimeout => id::DISCONNECTBYTIMEOUT,
            Packet::EchoRequest(_) => id::ECHOREQUEST,
            Packet::EchoResponse { .. } => id::ECHORESPONSE,
            Packet::Discovery(_) => id::DISCOVERY,
            Packet::UnrecognizedRequest(_) => id::UNRECOGNIZED_REQUEST,
        }
    }
}

/// `sSender`: who is talking, and which versions it speaks.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Sender {
    /// Application name (at most 255 bytes on the wire; NUL-padded to 256).
    pub name: String,
    /// Application version (major, minor, build, revision).
    pub version: [u8; 4],
    /// NatNet version (major, minor, build, revision).
    pub natnet_version: [u8; 4],
}

impl Sender {
    /// The NatNet version as a bitstream [`Version`].
    pub fn natnet(&self) -> Version {
        Version::new(self.natnet_version[0], self.natnet_version[1])
    }
}

/// `sConnectionOptions`, sent by 4.x clients after their `sSender`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ConnectionOptions {
    /// Only send what the client subscribed to (unicast subscriptions).
    pub subscribed_data_only: bool,
    /// The bitstream the client wants; 0.0.0.0 = the server's current one.
    pub bitstream: [u8; 4],
}

/// The payload forms of NAT_CONNECT (and NAT_DISCOVERY) seen in the wild
/// (spec §4); a server must accept all of them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Connect {
    /// No payload: the 2.x "ping".
    Empty,
    /// A short NUL-terminated string instead of an `sSender` (PyPI `natnet`
    /// sends "Ping").
    Text(String),
    /// An `sSender`, optionally followed by `sConnectionOptions` and spare
    /// bytes (SDK 4.x PacketClient adds 4, OptiTrack's Python client 2).
    Sender {
        sender: Sender,
        options: Option<ConnectionOptions>,
        spare: Vec<u8>,
    },
}

impl Connect {
    /// The bitstream version the client asked for in its CONNECT, if any
    /// (0.0 means "the server's own").
    pub fn requested_bitstream(&self) -> Option<Version> {
        match self {
            Connect::Sender {
                options: Some(o), ..
            } if o.bitstream[0] != 0 => Some(Version::new(o.bitstream[0], o.bitstream[1])),
            _ => None,
        }
    }
}

/// `sSender_Server`: the server's answer to CONNECT and DISCOVERY.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ServerInfo {
    pub sender: Sender,
    /// Present from NatNet 3.0 (279-byte form); absent in 2.x (264 bytes).
    pub connection: Option<ServerConnection>,
}

/// The part of SERVERINFO that NatNet 3.0 added.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ServerConnection {
    /// Ticks per second of the server's hi-res clock (frame timestamps).
    pub clock_frequency: u64,
    pub data_port: u16,
    pub multicast: bool,
    pub multicast_group: [u8; 4],
}

/// NAT_RESPONSE: four bytes (an int or a float, the request decides) or a string.
#[derive(Debug, Clone, PartialEq)]
pub enum Response {
    Value([u8; 4]),
    /// A NUL-terminated string.
    Text(String),
    /// A string filling the payload with no NUL. OptiTrack's Python client
    /// parses the `Bitstream` reply up to the end of the datagram, so a NUL
    /// there makes it crash (`int('0\x00')`); our server answers that query so.
    Unterminated(String),
}

impl Response {
    pub fn int(v: i32) -> Self {
        Response::Value(v.to_le_bytes())
    }
    pub fn float(v: f32) -> Self {
        Response::Value(v.to_le_bytes())
    }
    pub fn as_i32(&self) -> Option<i32> {
        match self {
            Response::Value(b) => Some(i32::from_le_bytes(*b)),
            _ => None,
        }
    }
    pub fn as_f32(&self) -> Option<f32> {
        match self {
            Response::Value(b) => Some(f32::from_le_bytes(*b)),
            _ => None,
        }
    }
    /// The text of a string response.
    pub fn as_text(&self) -> Option<&str> {
        match self {
            Response::Text(s) | Response::Unterminated(s) => Some(s),
            Response::Value(_) => None,
        }
    }
}

/// NAT_MODELDEF: the descriptions of everything the server tracks.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelDef {
    pub descriptions: Vec<Description>,
}

/// One dataset of a MODELDEF.
#[derive(Debug, Clone, PartialEq)]
pub enum Description {
    /// Type 0: a named set of markers.
    MarkerSet { name: String, markers: Vec<String> },
    /// Type 1.
    RigidBody(RigidBodyDescription),
    /// Type 2.
    Skeleton {
        name: String,
        id: i32,
        bones: Vec<RigidBodyDescription>,
    },
    /// Type 3 (3.0+ layout).
    ForcePlate(Box<ForcePlateDescription>),
    /// Type 4 (3.0+ layout).
    Device(DeviceDescription),
    /// Type 5.
    Camera {
        name: String,
        position: [f32; 3],
        orientation: [f32; 4],
    },
    /// Type 6 (4.1+).
    Asset(AssetDescription),
}

/// A rigid body (or skeleton bone) description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RigidBodyDescription {
    /// On the wire from 2.0.
    pub name: String,
    pub id: i32,
    pub parent_id: i32,
    pub offset: [f32; 3],
    /// Rotation offset (qx, qy, qz, qw), on the wire from 4.2.
    pub rotation: [f32; 4],
    /// Marker offsets and labels, on the wire from 3.0 (names from 4.0).
    pub markers: Vec<RigidBodyMarkerDescription>,
}

/// One marker of a rigid body description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RigidBodyMarkerDescription {
    pub offset: [f32; 3],
    pub active_label: i32,
    /// On the wire from 4.0.
    pub name: String,
}

/// A force plate description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ForcePlateDescription {
    pub id: i32,
    pub serial: String,
    pub width: f32,
    pub length: f32,
    pub origin: [f32; 3],
    /// 12 × 12 calibration matrix, row-major.
    pub calibration: Vec<f32>,
    pub corners: [[f32; 3]; 4],
    pub plate_type: i32,
    pub channel_data_type: i32,
    pub channels: Vec<String>,
}

/// An analog device description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DeviceDescription {
    pub id: i32,
    pub name: String,
    pub serial: String,
    pub device_type: i32,
    pub channel_data_type: i32,
    pub channels: Vec<String>,
}

/// An asset description (4.1+).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetDescription {
    pub name: String,
    pub asset_type: i32,
    pub id: i32,
    pub rigid_bodies: Vec<RigidBodyDescription>,
    pub markers: Vec<AssetMarkerDescription>,
}

/// One marker of an asset description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetMarkerDescription {
    pub name: String,
    pub id: i32,
    pub position: [f32; 3],
    pub size: f32,
    pub params: i16,
}

/// NAT_FRAMEOFDATA. Fields a version does not carry decode as zero/empty and
/// are not written by the encoder ([`FrameOfData::restricted_to`] says which).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameOfData {
    pub frame_number: i32,
    pub marker_sets: Vec<MarkerSetData>,
    /// The legacy "other" (unlabeled) marker list.
    pub other_markers: Vec<[f32; 3]>,
    pub rigid_bodies: Vec<RigidBodyData>,
    /// 2.1+.
    pub skeletons: Vec<SkeletonData>,
    /// 4.1+.
    pub assets: Vec<AssetData>,
    /// 2.3+. In 3.0+ this list also holds the unlabeled point-cloud markers
    /// (params bit [`MARKER_UNLABELED`]).
    pub labeled_markers: Vec<LabeledMarker>,
    /// 2.9+.
    pub force_plates: Vec<AnalogData>,
    /// 2.11+.
    pub devices: Vec<AnalogData>,
    /// 2.x only (f32; the SDK calls it software latency).
    pub software_latency: f32,
    /// SMPTE packed: h = tc>>24, m = tc>>16 & 255, s = tc>>8 & 255, f = tc & 255.
    pub timecode: u32,
    pub timecode_subframe: u32,
    /// Seconds since the server started: f32 in 2.6, f64 from 2.7, absent before.
    pub timestamp: f64,
    /// 3.0+: server hi-res ticks at mid-exposure, at data receipt, at transmit.
    pub camera_mid_exposure: u64,
    pub camera_data_received: u64,
    pub transmit: u64,
    /// 4.1+: PTP time (0 when the server has none).
    pub precision_seconds: u32,
    pub precision_fraction: u32,
    /// Frame flags (2.6+): 0x01 recording, 0x02 models changed, 0x04 edit
    /// mode, 0x08 bitstream changed.
    pub params: i16,
}

/// One marker set of a frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MarkerSetData {
    pub name: String,
    pub markers: Vec<[f32; 3]>,
}

/// One rigid body of a frame (also a skeleton bone).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RigidBodyData {
    pub id: i32,
    pub position: [f32; 3],
    /// qx, qy, qz, qw.
    pub orientation: [f32; 4],
    /// Per-marker data, on the wire before 3.0 only.
    pub markers: Vec<RigidBodyMarker>,
    pub mean_error: f32,
    /// 2.6+: bit 0 = tracking valid.
    pub params: i16,
}

/// A rigid body marker in a pre-3.0 frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RigidBodyMarker {
    pub position: [f32; 3],
    pub id: i32,
    pub size: f32,
}

/// One skeleton of a frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SkeletonData {
    pub id: i32,
    pub bones: Vec<RigidBodyData>,
}

/// One asset of a frame (4.1+).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetData {
    pub id: i32,
    pub rigid_bodies: Vec<AssetRigidBody>,
    pub markers: Vec<AssetMarker>,
}

/// A rigid body of an asset.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetRigidBody {
    pub id: i32,
    pub position: [f32; 3],
    pub orientation: [f32; 4],
    pub mean_error: f32,
    pub params: i16,
}

/// A marker of an asset.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetMarker {
    pub id: i32,
    pub position: [f32; 3],
    pub size: f32,
    pub params: i16,
    pub residual: f32,
}

/// One entry of the labeled-marker list.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LabeledMarker {
    /// modelId << 16 | markerId (model 0 = unlabeled point cloud in 3.0+).
    pub id: i32,
    pub position: [f32; 3],
    pub size: f32,
    /// 2.6+: 0x01 occluded, 0x02 point-cloud solved, 0x04 model solved,
    /// 0x08 has model, 0x10 unlabeled, 0x20 active.
    pub params: i16,
    /// 3.0+.
    pub residual: f32,
}

impl LabeledMarker {
    pub fn model_id(&self) -> i32 {
        self.id >> 16
    }
    pub fn marker_id(&self) -> i32 {
        self.id & 0xFFFF
    }
    pub fn is_unlabeled(&self) -> bool {
        self.params & MARKER_UNLABELED != 0
    }
}

/// A force plate or device: channels of sub-frame samples.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AnalogData {
    pub id: i32,
    pub channels: Vec<Vec<f32>>,
}

impl FrameOfData {
    /// This frame with everything `version` cannot carry set to zero/empty
    /// (and the 2.6 timestamp rounded to f32): exactly what a decoder of that
    /// version gets back from the encoded frame.
    pub fn restricted_to(&self, v: Version) -> FrameOfData {
        let mut f = self.clone();
        let rb = |r: &mut RigidBodyData| {
            if v.major >= 3 {
                r.markers.clear();
            }
            if !v.at_least(2, 6) {
                r.params = 0;
            }
        };
        f.rigid_bodies.iter_mut().for_each(rb);
        if !v.at_least(2, 1) {
            f.skeletons.clear();
        }
        for s in &mut f.skeletons {
            s.bones.iter_mut().for_each(rb);
        }
        if !v.has_section_sizes() {
            f.assets.clear();
        }
        if !v.at_least(2, 3) {
            f.labeled_markers.clear();
        }
        for m in &mut f.labeled_markers {
            if !v.at_least(2, 6) {
                m.params = 0;
            }
            if v.major < 3 {
                m.residual = 0.0;
            }
        }
        if !v.at_least(2, 9) {
            f.force_plates.clear();
        }
        if !v.at_least(2, 11) {
            f.devices.clear();
        }
        if v.major >= 3 {
            f.software_latency = 0.0;
        }
        if !v.at_least(2, 6) {
            f.timestamp = 0.0;
            f.params = 0;
        } else if v == Version::new(2, 6) {
            f.timestamp = f.timestamp as f32 as f64;
        }
        if v.major < 3 {
            f.camera_mid_exposure = 0;
            f.camera_data_received = 0;
            f.transmit = 0;
        }
        if !v.has_section_sizes() {
            f.precision_seconds = 0;
            f.precision_fraction = 0;
        }
        f
    }
}

impl RigidBodyDescription {
    /// What `version` can carry of this description.
    pub fn restricted_to(&self, v: Version) -> RigidBodyDescription {
        let mut d = self.clone();
        if v.major < 2 {
            d.name.clear();
        }
        if !v.at_least(4, 2) {
            d.rotation = [0.0; 4];
        }
        if v.major < 3 {
            d.markers.clear();
        }
        if v.major < 4 {
            d.markers.iter_mut().for_each(|m| m.name.clear());
        }
        d
    }
}

impl ModelDef {
    /// What `version` can carry of these descriptions.
    pub fn restricted_to(&self, v: Version) -> ModelDef {
        let descriptions = self
            .descriptions
            .iter()
            .filter(|d| !matches!(d, Description::Asset(_)) || v.has_section_sizes())
            .map(|d| match d {
                Description::RigidBody(r) => Description::RigidBody(r.restricted_to(v)),
                Description::Skeleton { name, id, bones } => Description::Skeleton {
                    name: name.clone(),
                    id: *id,
                    bones: bones.iter().map(|b| b.restricted_to(v)).collect(),
                },
                Description::Asset(a) => {
                    let mut a = a.clone();
                    a.rigid_bodies = a.rigid_bodies.iter().map(|b| b.restricted_to(v)).collect();
                    Description::Asset(a)
                }
                other => other.clone(),
            })
            .collect();
        ModelDef { descriptions }
    }
}

// ---------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------

/// Why a datagram could not be decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DecodeErrorKind {
    /// The packet ended inside a field (truncated datagram, or a header
    /// `nDataBytes` shorter than the content).
    Incomplete,
    /// A field holds an impossible value: a negative count, a count larger
    /// than the packet could hold, a section size that disagrees with its
    /// content, bytes left over, a malformed payload length.
    Invalid,
    /// A message id NatNet does not define.
    UnknownMessage,
}

/// A decoding failure naming the message, the field and the byte offset
/// (from the start of the datagram, header included).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DecodeError {
    pub kind: DecodeErrorKind,
    pub message: &'static str,
    pub field: &'static str,
    pub offset: usize,
    pub detail: String,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.kind {
            DecodeErrorKind::Incomplete => "incomplete",
            DecodeErrorKind::Invalid => "invalid",
            DecodeErrorKind::UnknownMessage => "unknown",
        };
        write!(
            f,
            "{kind} {}: field {} at byte {}: {}",
            self.message, self.field, self.offset, self.detail
        )
    }
}

impl std::error::Error for DecodeError {}

/// Why a packet could not be encoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum EncodeError {
    /// The payload exceeds the 65535 bytes `nDataBytes` can state; NatNet
    /// has no fragmentation.
    TooLarge { message: &'static str, bytes: usize },
    /// A list is longer than its i32 count can state.
    TooMany { field: &'static str },
    /// The message cannot be expressed in this version (assets before 4.1).
    NotInVersion {
        what: &'static str,
        version: Version,
    },
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::TooLarge { message, bytes } => write!(
                f,
                "{message} of {bytes} bytes does not fit one NatNet datagram (max {MAX_PAYLOAD})"
            ),
            EncodeError::TooMany { field } => write!(f, "too many entries in {field}"),
            EncodeError::NotInVersion { what, version } => {
                write!(f, "{what} cannot be sent in NatNet {version}")
            }
        }
    }
}

impl std::error::Error for EncodeError {}

// ---------------------------------------------------------------------------
// Reader
// ---------------------------------------------------------------------------

type DResult<T> = Result<T, DecodeError>;

/// A bounds-checked little-endian cursor over one payload.
struct Rd<'a> {
    b: &'a [u8],
    p: usize,
    /// Offset of `b[0]` in the datagram (the 4-byte header).
    base: usize,
    msg: &'static str,
}

impl<'a> Rd<'a> {
    fn err(&self, kind: DecodeErrorKind, field: &'static str, detail: String) -> DecodeError {
        DecodeError {
            kind,
            message: self.msg,
            field,
            offset: self.base + self.p,
            detail,
        }
    }

    fn invalid(&self, field: &'static str, detail: String) -> DecodeError {
        self.err(DecodeErrorKind::Invalid, field, detail)
    }

    fn left(&self) -> usize {
        self.b.len() - self.p
    }

    #[inline]
    fn take(&mut self, n: usize, field: &'static str) -> DResult<&'a [u8]> {
        match self.b.get(self.p..self.p.saturating_add(n)) {
            Some(s) if n <= self.left() => {
                self.p += n;
                Ok(s)
            }
            _ => Err(self.err(
                DecodeErrorKind::Incomplete,
                field,
                format!("needs {n} bytes, {} left", self.left()),
            )),
        }
    }

    #[inline]
    fn arr<const N: usize>(&mut self, field: &'static str) -> DResult<[u8; N]> {
        let s = self.take(N, field)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    #[inline]
    fn u8(&mut self, field: &'static str) -> DResult<u8> {
        Ok(self.arr::<1>(field)?[0])
    }
    #[inline]
    fn i16(&mut self, field: &'static str) -> DResult<i16> {
        Ok(i16::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn u16(&mut self, field: &'static str) -> DResult<u16> {
        Ok(u16::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn i32(&mut self, field: &'static str) -> DResult<i32> {
        Ok(i32::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn u32(&mut self, field: &'static str) -> DResult<u32> {
        Ok(u32::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn u64(&mut self, field: &'static str) -> DResult<u64> {
        Ok(u64::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn f32(&mut self, field: &'static str) -> DResult<f32> {
        Ok(f32::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn f64(&mut self, field: &'static str) -> DResult<f64> {
        Ok(f64::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn vec3(&mut self, field: &'static str) -> DResult<[f32; 3]> {
        let b: [u8; 12] = self.arr(field)?;
        Ok([
            f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            f32::from_le_bytes([b[4], b[5], b[6], b[7]]),
            f32::from_le_bytes([b[8], b[9], b[10], b[11]]),
        ])
    }
    #[inline]
    fn quat(&mut self, field: &'static str) -> DResult<[f32; 4]> {
        Ok([
            self.f32(field)?,
            self.f32(field)?,
            self.f32(field)?,
            self.f32(field)?,
        ])
    }

    /// A NUL-terminated string (lossy UTF-8: names are for people).
    fn cstr(&mut self, field: &'static str) -> DResult<String> {
        let rest = self.b.get(self.p..).unwrap_or(&[]);
        match rest.iter().position(|&c| c == 0) {
            Some(n) => {
                let s = String::from_utf8_lossy(&rest[..n]).into_owned();
                self.p += n + 1;
                Ok(s)
            }
            None => Err(self.err(
                DecodeErrorKind::Incomplete,
                field,
                format!(
                    "string not NUL-terminated within the {} bytes left",
                    rest.len()
                ),
            )),
        }
    }

    /// An i32 element count, checked against what is left: each element
    /// takes at least `min_size` bytes, so a count the packet cannot hold is
    /// rejected before anything is allocated.
    fn count(&mut self, field: &'static str, min_size: usize) -> DResult<usize> {
        let n = self.i32(field)?;
        self.p -= 4; // report the count's own offset
        let err = if n < 0 {
            Some(format!("negative count {n}"))
        } else if (n as u64).saturating_mul(min_size as u64) > (self.left() - 4) as u64 {
            Some(format!(
                "count {n} needs at least {} bytes, only {} left in the packet",
                (n as u64).saturating_mul(min_size as u64),
                self.left() - 4
            ))
        } else {
            None
        };
        if let Some(detail) = err {
            return Err(self.invalid(field, detail));
        }
        self.p += 4;
        Ok(n as usize)
    }

    /// Only NUL padding may remain.
    fn padding(&mut self, field: &'static str) -> DResult<()> {
        let rest = self.b.get(self.p..).unwrap_or(&[]);
        if let Some(i) = rest.iter().position(|&c| c != 0) {
            self.p += i;
            return Err(self.invalid(field, format!("{} unexpected bytes", rest.len() - i)));
        }
        self.p = self.b.len();
        Ok(())
    }

    fn end(&self) -> DResult<()> {
        if self.left() != 0 {
            return Err(self.invalid(
                "end of payload",
                format!("{} bytes left over after the last field", self.left()),
            ));
        }
        Ok(())
    }

    /// 4.1+: reads a section's byte count and returns a checker to call after
    /// the section.
    fn section_start(&mut self, v: Version, field: &'static str) -> DResult<Option<(usize, u32)>> {
        if !v.has_section_sizes() {
            return Ok(None);
        }
        let sz = self.u32(field)?;
        if sz as usize > self.left() {
            self.p -= 4;
            return Err(self.invalid(
                field,
                format!(
                    "section size {sz} exceeds the {} bytes left",
                    self.left() - 4
                ),
            ));
        }
        Ok(Some((self.p, sz)))
    }

    fn section_end(&self, start: Option<(usize, u32)>, field: &'static str) -> DResult<()> {
        if let Some((p0, sz)) = start {
            let used = self.p - p0;
            if used != sz as usize {
                return Err(DecodeError {
                    kind: DecodeErrorKind::Invalid,
                    message: self.msg,
                    field,
                    offset: self.base + p0 - 4,
                    detail: format!("section size says {sz} bytes, its content is {used}"),
                });
            }
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------
// Decoding
// ---------------------------------------------------------------------------

/// Little-endian reads inside a block whose length was already checked
/// (`chunks_exact` of the element size), so the indexing cannot fail.
#[inline(always)]
fn le_f32(c: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([c[at], c[at + 1], c[at + 2], c[at + 3]])
}

#[inline(always)]
fn le_i32(c: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([c[at], c[at + 1], c[at + 2], c[at + 3]])
}

/// The message id of a datagram, if it has a header.
pub fn peek_id(datagram: &[u8]) -> Option<u16> {
    datagram.get(..2).map(|b| u16::from_le_bytes([b[0], b[1]]))
}

/// Decodes one datagram with the bitstream `version` negotiated with the server.
pub fn decode(datagram: &[u8], version: Version) -> Result<Packet, DecodeError> {
    let mut h = Rd {
        b: datagram,
        p: 0,
        base: 0,
        msg: "packet header",
    };
    let mid = h.u16("iMessage")?;
    let msg = message_name(mid);
    h.msg = msg;
    let n = h.u16("nDataBytes")? as usize;
    let payload = h.take(n, "payload").map_err(|mut e| {
        e.field = "nDataBytes";
        e.offset = 2;
        e.detail = format!(
            "header says {n} payload bytes, the datagram has {}",
            datagram.len() - 4
        );
        e
    })?;
    let mut r = Rd {
        b: payload,
        p: 0,
        base: 4,
        msg,
    };
    let packet = match mid {
        id::CONNECT => Packet::Connect(decode_connect(&mut r)?),
        id::DISCOVERY => Packet::Discovery(decode_connect(&mut r)?),
        id::SERVERINFO => Packet::ServerInfo(decode_server_info(&mut r)?),
        id::REQUEST => {
            // Anything after the command's NUL is ignored: NatNetLib sends
            // binary after some commands (`service20,-1,…`).
            let s = r.cstr("command")?;
            r.p = r.b.len();
            Packet::Request(s)
        }
        id::RESPONSE => {
            if n == 4 {
                Packet::Response(Response::Value(r.arr("value")?))
            } else if !payload.contains(&0) {
                let s = String::from_utf8_lossy(r.take(n, "text")?).into_owned();
                Packet::Response(Response::Unterminated(s))
            } else {
                let s = r.cstr("text")?;
                r.padding("text")?;
                Packet::Response(Response::Text(s))
            }
        }
        id::MESSAGESTRING => {
            let s = r.cstr("text")?;
            r.padding("text")?;
            Packet::MessageString(s)
        }
        id::REQUEST_MODELDEF => empty(&mut r, Packet::RequestModelDef)?,
        id::REQUEST_FRAMEOFDATA => empty(&mut r, Packet::RequestFrameOfData)?,
        id::DISCONNECT => empty(&mut r, Packet::Disconnect)?,
        id::KEEPALIVE => empty(&mut r, Packet::KeepAlive)?,
        id::DISCONNECTBYTIMEOUT => empty(&mut r, Packet::DisconnectByTimeout)?,
        id::ECHOREQUEST => Packet::EchoRequest(r.u64("client timestamp")?),
        id::ECHORESPONSE => Packet::EchoResponse {
            client_ticks: r.u64("client timestamp")?,
            server_ticks: r.u64("server timestamp")?,
        },
        id::UNRECOGNIZED_REQUEST => {
            let rest = r.take(n, "payload")?;
            Packet::UnrecognizedRequest(rest.to_vec())
        }
        id::MODELDEF => Packet::ModelDef(decode_modeldef(&mut r, version)?),
        id::FRAMEOFDATA => Packet::FrameOfData(Box::new(decode_frame(&mut r, version)?)),
        other => {
            return Err(DecodeError {
                kind: DecodeErrorKind::UnknownMessage,
                message: msg,
                field: "iMessage",
                offset: 0,
                detail: format!("message id {other} is not a NatNet message"),
            })
        }
    };
    r.end()?;
    Ok(packet)
}

fn empty(r: &mut Rd, p: Packet) -> DResult<Packet> {
    r.padding("payload")?;
    Ok(p)
}

fn decode_sender(r: &mut Rd) -> DResult<Sender> {
    let name = r.take(256, "szName")?;
    let end = name.iter().position(|&c| c == 0).unwrap_or(name.len());
    Ok(Sender {
        name: String::from_utf8_lossy(&name[..end]).into_owned(),
        version: r.arr("Version")?,
        natnet_version: r.arr("NatNetVersion")?,
    })
}

fn decode_connect(r: &mut Rd) -> DResult<Connect> {
    let n = r.b.len();
    if n == 0 {
        return Ok(Connect::Empty);
    }
    if n < 264 {
        let s = r.cstr("text")?;
        r.padding("text")?;
        return Ok(Connect::Text(s));
    }
    let sender = decode_sender(r)?;
    let options = match n {
        264 => None,
        265..=268 => {
            return Err(r.invalid(
                "sConnectionOptions",
                format!(
                    "{} bytes cannot hold connection options (5 needed)",
                    n - 264
                ),
            ))
        }
        _ => Some(ConnectionOptions {
            subscribed_data_only: r.u8("subscribedDataOnly")? != 0,
            bitstream: r.arr("BitstreamVersion")?,
        }),
    };
    let spare = r.take(r.left(), "spare")?.to_vec();
    Ok(Connect::Sender {
        sender,
        options,
        spare,
    })
}

fn decode_server_info(r: &mut Rd) -> DResult<ServerInfo> {
    let n = r.b.len();
    if n != 264 && n != 279 {
        return Err(r.invalid(
            "nDataBytes",
            format!("{n} bytes; a server info is 264 (2.x) or 279 (3.0+) bytes"),
        ));
    }
    let sender = decode_sender(r)?;
    let connection = if n == 279 {
        Some(ServerConnection {
            clock_frequency: r.u64("HighResClockFrequency")?,
            data_port: r.u16("DataPort")?,
            multicast: r.u8("IsMulticast")? != 0,
            multicast_group: r.arr("MulticastGroupAddress")?,
        })
    } else {
        None
    };
    Ok(ServerInfo { sender, connection })
}

fn decode_rb_description(r: &mut Rd, v: Version) -> DResult<RigidBodyDescription> {
    let mut d = RigidBodyDescription {
        name: if v.major >= 2 {
            r.cstr("rigid body name")?
        } else {
            String::new()
        },
        id: r.i32("rigid body id")?,
        parent_id: r.i32("rigid body parent id")?,
        offset: r.vec3("rigid body offset")?,
        ..Default::default()
    };
    if v.at_least(4, 2) {
        d.rotation = r.quat("rigid body rotation offset")?;
    }
    if v.major >= 3 {
        let min = if v.major >= 4 { 17 } else { 16 };
        let n = r.count("rigid body marker count", min)?;
        let mut markers = Vec::with_capacity(n);
        for _ in 0..n {
            markers.push(RigidBodyMarkerDescription {
                offset: r.vec3("rigid body marker offset")?,
                ..Default::default()
            });
        }
        for m in &mut markers {
            m.active_label = r.i32("rigid body marker active label")?;
        }
        if v.major >= 4 {
            for m in &mut markers {
                m.name = r.cstr("rigid body marker name")?;
            }
        }
        d.markers = markers;
    }
    Ok(d)
}

fn decode_names(
    r: &mut Rd,
    field: &'static str,
    count_field: &'static str,
) -> DResult<Vec<String>> {
    let n = r.count(count_field, 1)?;
    let mut names = Vec::with_capacity(n);
    for _ in 0..n {
        names.push(r.cstr(field)?);
    }
    Ok(names)
}

fn decode_description(r: &mut Rd, v: Version, kind: i32) -> DResult<Description> {
    Ok(match kind {
        0 => Description::MarkerSet {
            name: r.cstr("marker set name")?,
            markers: decode_names(r, "marker name", "marker set marker count")?,
        },
        1 => Description::RigidBody(decode_rb_description(r, v)?),
        2 => {
            let name = r.cstr("skeleton name")?;
            let id = r.i32("skeleton id")?;
            let n = r.count("skeleton bone count", 20)?;
            let mut bones = Vec::with_capacity(n);
            for _ in 0..n {
                bones.push(decode_rb_description(r, v)?);
            }
            Description::Skeleton { name, id, bones }
        }
        3 => {
            let mut d = ForcePlateDescription {
                id: r.i32("force plate id")?,
                serial: r.cstr("force plate serial")?,
                width: r.f32("force plate width")?,
                length: r.f32("force plate length")?,
                origin: r.vec3("force plate origin")?,
                ..Default::default()
            };
            let mut cal = Vec::with_capacity(144);
            for _ in 0..144 {
                cal.push(r.f32("force plate calibration matrix")?);
            }
            d.calibration = cal;
            for c in &mut d.corners {
                *c = r.vec3("force plate corners")?;
            }
            d.plate_type = r.i32("force plate type")?;
            d.channel_data_type = r.i32("force plate channel data type")?;
            d.channels = decode_names(r, "force plate channel name", "force plate channel count")?;
            Description::ForcePlate(Box::new(d))
        }
        4 => Description::Device(DeviceDescription {
            id: r.i32("device id")?,
            name: r.cstr("device name")?,
            serial: r.cstr("device serial")?,
            device_type: r.i32("device type")?,
            channel_data_type: r.i32("device channel data type")?,
            channels: decode_names(r, "device channel name", "device channel count")?,
        }),
        5 => Description::Camera {
            name: r.cstr("camera name")?,
            position: r.vec3("camera position")?,
            orientation: r.quat("camera orientation")?,
        },
        6 => {
            let name = r.cstr("asset name")?;
            let asset_type = r.i32("asset type")?;
            let id = r.i32("asset id")?;
            let n = r.count("asset rigid body count", 20)?;
            let mut rigid_bodies = Vec::with_capacity(n);
            for _ in 0..n {
                rigid_bodies.push(decode_rb_description(r, v)?);
            }
            let n = r.count("asset marker count", 23)?;
            let mut markers = Vec::with_capacity(n);
            for _ in 0..n {
                markers.push(AssetMarkerDescription {
                    name: r.cstr("asset marker name")?,
                    id: r.i32("asset marker id")?,
                    position: r.vec3("asset marker position")?,
                    size: r.f32("asset marker size")?,
                    params: r.i16("asset marker params")?,
                });
            }
            Description::Asset(AssetDescription {
                name,
                asset_type,
                id,
                rigid_bodies,
                markers,
            })
        }
        other => {
            r.p -= if v.has_section_sizes() { 8 } else { 4 };
            return Err(r.invalid(
                "description type",
                format!("unknown description type {other}"),
            ));
        }
    })
}

fn decode_modeldef(r: &mut Rd, v: Version) -> DResult<ModelDef> {
    let n = r.count("dataset count", 4)?;
    let mut descriptions = Vec::with_capacity(n);
    for _ in 0..n {
        let kind = r.i32("description type")?;
        let size = r.section_start(v, "description size")?;
        descriptions.push(decode_description(r, v, kind)?);
        r.section_end(size, "description size")?;
    }
    Ok(ModelDef { descriptions })
}

/// The smallest encoding of one rigid body in a frame of version `v`.
fn rb_min_size(v: Version) -> usize {
    let mut n = 32;
    if v.major < 3 {
        n += 4;
    }
    n += 4;
    if v.at_least(2, 6) {
        n += 2;
    }
    n
}

fn decode_rb(r: &mut Rd, v: Version) -> DResult<RigidBodyData> {
    let mut b = RigidBodyData {
        id: r.i32("rigid body id")?,
        position: r.vec3("rigid body position")?,
        orientation: r.quat("rigid body orientation")?,
        ..Default::default()
    };
    if v.major < 3 {
        let n = r.count("rigid body marker count", 20)?;
        let mut markers = Vec::with_capacity(n);
        for _ in 0..n {
            markers.push(RigidBodyMarker {
                position: r.vec3("rigid body marker position")?,
                ..Default::default()
            });
        }
        for m in &mut markers {
            m.id = r.i32("rigid body marker id")?;
        }
        for m in &mut markers {
            m.size = r.f32("rigid body marker size")?;
        }
        b.markers = markers;
    }
    b.mean_error = r.f32("rigid body mean error")?;
    if v.at_least(2, 6) {
        b.params = r.i16("rigid body params")?;
    }
    Ok(b)
}

/// Force plates and devices: count, (4.1+) section size, then per element
/// an id and channels of sub-frame samples.
fn decode_analog(r: &mut Rd, v: Version, fields: [&'static str; 5]) -> DResult<Vec<AnalogData>> {
    let [count_f, size_f, id_f, chan_f, frames_f] = fields;
    let n = r.count(count_f, 8)?;
    let sz = r.section_start(v, size_f)?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let id = r.i32(id_f)?;
        let nc = r.count(chan_f, 4)?;
        let mut channels = Vec::with_capacity(nc);
        for _ in 0..nc {
            let nf = r.count(frames_f, 4)?;
            let mut vals = Vec::with_capacity(nf);
            for _ in 0..nf {
                vals.push(r.f32("analog sample")?);
            }
            channels.push(vals);
        }
        out.push(AnalogData { id, channels });
    }
    r.section_end(sz, size_f)?;
    Ok(out)
}

fn decode_frame(r: &mut Rd, v: Version) -> DResult<FrameOfData> {
    let mut f = FrameOfData {
        frame_number: r.i32("frame number")?,
        ..Default::default()
    };

    let n = r.count("marker set count", 5)?;
    let sz = r.section_start(v, "marker set section size")?;
    f.marker_sets.reserve_exact(n);
    for _ in 0..n {
        let name = r.cstr("marker set name")?;
        let m = r.count("marker set marker count", 12)?;
        let block = r.take(m * 12, "marker set marker positions")?;
        let markers = block
            .chunks_exact(12)
            .map(|c| [le_f32(c, 0), le_f32(c, 4), le_f32(c, 8)])
            .collect();
        f.marker_sets.push(MarkerSetData { name, markers });
    }
    r.section_end(sz, "marker set section size")?;

    let n = r.count("other marker count", 12)?;
    let sz = r.section_start(v, "other marker section size")?;
    let block = r.take(n * 12, "other marker positions")?;
    f.other_markers = block
        .chunks_exact(12)
        .map(|c| [le_f32(c, 0), le_f32(c, 4), le_f32(c, 8)])
        .collect();
    r.section_end(sz, "other marker section size")?;

    let n = r.count("rigid body count", rb_min_size(v))?;
    let sz = r.section_start(v, "rigid body section size")?;
    f.rigid_bodies.reserve_exact(n);
    for _ in 0..n {
        f.rigid_bodies.push(decode_rb(r, v)?);
    }
    r.section_end(sz, "rigid body section size")?;

    if v.at_least(2, 1) {
        let n = r.count("skeleton count", 8)?;
        let sz = r.section_start(v, "skeleton section size")?;
        f.skeletons.reserve_exact(n);
        for _ in 0..n {
            let id = r.i32("skeleton id")?;
            let nb = r.count("skeleton bone count", rb_min_size(v))?;
            let mut bones = Vec::with_capacity(nb);
            for _ in 0..nb {
                bones.push(decode_rb(r, v)?);
            }
            f.skeletons.push(SkeletonData { id, bones });
        }
        r.section_end(sz, "skeleton section size")?;
    }

    if v.has_section_sizes() {
        let n = r.count("asset count", 12)?;
        let sz = r.section_start(v, "asset section size")?;
        f.assets.reserve_exact(n);
        for _ in 0..n {
            let id = r.i32("asset id")?;
            let nb = r.count("asset rigid body count", 38)?;
            let mut rigid_bodies = Vec::with_capacity(nb);
            for _ in 0..nb {
                rigid_bodies.push(AssetRigidBody {
                    id: r.i32("asset rigid body id")?,
                    position: r.vec3("asset rigid body position")?,
                    orientation: r.quat("asset rigid body orientation")?,
                    mean_error: r.f32("asset rigid body mean error")?,
                    params: r.i16("asset rigid body params")?,
                });
            }
            let nm = r.count("asset marker count", 26)?;
            let mut markers = Vec::with_capacity(nm);
            for _ in 0..nm {
                markers.push(AssetMarker {
                    id: r.i32("asset marker id")?,
                    position: r.vec3("asset marker position")?,
                    size: r.f32("asset marker size")?,
                    params: r.i16("asset marker params")?,
                    residual: r.f32("asset marker residual")?,
                });
            }
            f.assets.push(AssetData {
                id,
                rigid_bodies,
                markers,
            });
        }
        r.section_end(sz, "asset section size")?;
    }

    if v.at_least(2, 3) {
        let with_params = v.at_least(2, 6);
        let with_residual = v.major >= 3;
        let size = 20 + if with_params { 2 } else { 0 } + if with_residual { 4 } else { 0 };
        let n = r.count("labeled marker count", size)?;
        let sz = r.section_start(v, "labeled marker section size")?;
        // The count was checked against the bytes left, so the whole list
        // is one block: one bounds check instead of six per marker.
        let block = r.take(n * size, "labeled markers")?;
        f.labeled_markers.reserve_exact(n);
        f.labeled_markers.extend(block.chunks_exact(size).map(|c| {
            let mut m = LabeledMarker {
                id: le_i32(c, 0),
                position: [le_f32(c, 4), le_f32(c, 8), le_f32(c, 12)],
                size: le_f32(c, 16),
                ..Default::default()
            };
            if with_params {
                m.params = i16::from_le_bytes([c[20], c[21]]);
            }
            if with_residual {
                m.residual = le_f32(c, 22);
            }
            m
        }));
        r.section_end(sz, "labeled marker section size")?;
    }

    if v.at_least(2, 9) {
        f.force_plates = decode_analog(
            r,
            v,
            [
                "force plate count",
                "force plate section size",
                "force plate id",
                "force plate channel count",
                "force plate sample count",
            ],
        )?;
    }
    if v.at_least(2, 11) {
        f.devices = decode_analog(
            r,
            v,
            [
                "device count",
                "device section size",
                "device id",
                "device channel count",
                "device sample count",
            ],
        )?;
    }

    if v.major < 3 {
        f.software_latency = r.f32("software latency")?;
    }
    f.timecode = r.u32("timecode")?;
    f.timecode_subframe = r.u32("timecode subframe")?;
    if v == Version::new(2, 6) {
        f.timestamp = r.f32("timestamp")? as f64;
    } else if v.at_least(2, 7) {
        f.timestamp = r.f64("timestamp")?;
    }
    if v.major >= 3 {
        f.camera_mid_exposure = r.u64("camera mid-exposure timestamp")?;
        f.camera_data_received = r.u64("camera data received timestamp")?;
        f.transmit = r.u64("transmit timestamp")?;
    }
    if v.has_section_sizes() {
        f.precision_seconds = r.u32("precision timestamp seconds")?;
        f.precision_fraction = r.u32("precision timestamp fraction")?;
    }
    if v.at_least(2, 6) {
        f.params = r.i16("frame params")?;
    }
    let eod = r.i32("end of data tag")?;
    if eod != 0 {
        r.p -= 4;
        return Err(r.invalid("end of data tag", format!("{eod}, expected 0")));
    }
    Ok(f)
}

// ---------------------------------------------------------------------------
// Encoding
// ---------------------------------------------------------------------------

type EResult<T> = Result<T, EncodeError>;

struct Wr<'a> {
    v: &'a mut Vec<u8>,
}

impl Wr<'_> {
    #[inline]
    fn bytes(&mut self, b: &[u8]) {
        self.v.extend_from_slice(b);
    }
    #[inline]
    fn i16(&mut self, x: i16) {
        self.bytes(&x.to_le_bytes())
    }
    #[inline]
    fn i32(&mut self, x: i32) {
        self.bytes(&x.to_le_bytes())
    }
    #[inline]
    fn u32(&mut self, x: u32) {
        self.bytes(&x.to_le_bytes())
    }
    #[inline]
    fn u64(&mut self, x: u64) {
        self.bytes(&x.to_le_bytes())
    }
    #[inline]
    fn f32(&mut self, x: f32) {
        self.bytes(&x.to_le_bytes())
    }
    #[inline]
    fn vec3(&mut self, p: &[f32; 3]) {
        p.iter().for_each(|&x| self.f32(x))
    }
    #[inline]
    fn quat(&mut self, q: &[f32; 4]) {
        q.iter().for_each(|&x| self.f32(x))
    }
    /// A string up to its first NUL, then a NUL.
    fn cstr(&mut self, s: &str) {
        let b = s.as_bytes();
        let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
        self.bytes(&b[..end]);
        self.v.push(0);
    }
    fn count(&mut self, n: usize, field: &'static str) -> EResult<()> {
        let n = i32::try_from(n).map_err(|_| EncodeError::TooMany { field })?;
        self.i32(n);
        Ok(())
    }
    /// 4.1+: a placeholder byte count, patched by `section_end`.
    fn section_start(&mut self, v: Version) -> Option<usize> {
        v.has_section_sizes().then(|| {
            self.u32(0);
            self.v.len()
        })
    }
    fn section_end(&mut self, start: Option<usize>) {
        if let Some(p) = start {
            let n = (self.v.len() - p) as u32;
            self.v[p - 4..p].copy_from_slice(&n.to_le_bytes());
        }
    }
}

/// Encodes `packet` for bitstream `version`.
pub fn encode(packet: &Packet, version: Version) -> Result<Vec<u8>, EncodeError> {
    let mut out = Vec::new();
    encode_into(packet, version, &mut out)?;
    Ok(out)
}

/// Encodes `packet` for bitstream `version`, replacing the contents of `out`
/// (so a server can reuse one buffer).
pub fn encode_into(packet: &Packet, version: Version, out: &mut Vec<u8>) -> EResult<()> {
    out.clear();
    out.extend_from_slice(&packet.id().to_le_bytes());
    out.extend_from_slice(&[0, 0]);
    let mut w = Wr { v: out };
    match packet {
        Packet::Connect(c) | Packet::Discovery(c) => encode_connect(&mut w, c),
        Packet::ServerInfo(s) => {
            encode_sender(&mut w, &s.sender);
            if let Some(c) = &s.connection {
                w.u64(c.clock_frequency);
                w.bytes(&c.data_port.to_le_bytes());
                w.bytes(&[c.multicast as u8]);
                w.bytes(&c.multicast_group);
            }
        }
        Packet::Request(s) | Packet::MessageString(s) | Packet::Response(Response::Text(s)) => {
            w.cstr(s)
        }
        Packet::Response(Response::Value(b)) => w.bytes(b),
        Packet::Response(Response::Unterminated(s)) => {
            let b = s.as_bytes();
            let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
            w.bytes(&b[..end]);
        }
        Packet::RequestModelDef
        | Packet::RequestFrameOfData
        | Packet::Disconnect
        | Packet::KeepAlive
        | Packet::DisconnectByTimeout => {}
        Packet::EchoRequest(t) => w.u64(*t),
        Packet::EchoResponse {
            client_ticks,
            server_ticks,
        } => {
            w.u64(*client_ticks);
            w.u64(*server_ticks);
        }
        Packet::UnrecognizedRequest(b) => w.bytes(b),
        Packet::ModelDef(m) => encode_modeldef(&mut w, m, version)?,
        Packet::FrameOfData(f) => encode_frame(&mut w, f, version)?,
    }
    let n = out.len() - 4;
    if n > MAX_PAYLOAD {
        return Err(EncodeError::TooLarge {
            message: message_name(packet.id()),
            bytes: n,
        });
    }
    out[2..4].copy_from_slice(&(n as u16).to_le_bytes());
    Ok(())
}

fn encode_sender(w: &mut Wr, s: &Sender) {
    let mut name = [0u8; 256];
    let b = s.name.as_bytes();
    let n = b.len().min(255);
    name[..n].copy_from_slice(&b[..n]);
    w.bytes(&name);
    w.bytes(&s.version);
    w.bytes(&s.natnet_version);
}

fn encode_connect(w: &mut Wr, c: &Connect) {
    match c {
        Connect::Empty => {}
        Connect::Text(s) => w.cstr(s),
        Connect::Sender {
            sender,
            options,
            spare,
        } => {
            encode_sender(w, sender);
            if let Some(o) = options {
                w.bytes(&[o.subscribed_data_only as u8]);
                w.bytes(&o.bitstream);
            }
            w.bytes(spare);
        }
    }
}

fn encode_rb_description(w: &mut Wr, d: &RigidBodyDescription, v: Version) -> EResult<()> {
    if v.major >= 2 {
        w.cstr(&d.name);
    }
    w.i32(d.id);
    w.i32(d.parent_id);
    w.vec3(&d.offset);
    if v.at_least(4, 2) {
        w.quat(&d.rotation);
    }
    if v.major >= 3 {
        w.count(d.markers.len(), "rigid body marker count")?;
        d.markers.iter().for_each(|m| w.vec3(&m.offset));
        d.markers.iter().for_each(|m| w.i32(m.active_label));
        if v.major >= 4 {
            d.markers.iter().for_each(|m| w.cstr(&m.name));
        }
    }
    Ok(())
}

fn encode_names(w: &mut Wr, names: &[String], field: &'static str) -> EResult<()> {
    w.count(names.len(), field)?;
    names.iter().for_each(|n| w.cstr(n));
    Ok(())
}

fn encode_modeldef(w: &mut Wr, m: &ModelDef, v: Version) -> EResult<()> {
    w.count(m.descriptions.len(), "dataset count")?;
    for d in &m.descriptions {
        let kind = match d {
            Description::MarkerSet { .. } => 0,
            Description::RigidBody(_) => 1,
            Description::Skeleton { .. } => 2,
            Description::ForcePlate(_) => 3,
            Description::Device(_) => 4,
            Description::Camera { .. } => 5,
            Description::Asset(_) => 6,
        };
        if kind == 6 && !v.has_section_sizes() {
            return Err(EncodeError::NotInVersion {
                what: "an asset description",
                version: v,
            });
        }
        w.i32(kind);
        let sz = w.section_start(v);
        match d {
            Description::MarkerSet { name, markers } => {
                w.cstr(name);
                encode_names(w, markers, "marker set marker count")?;
            }
            Description::RigidBody(r) => encode_rb_description(w, r, v)?,
            Description::Skeleton { name, id, bones } => {
                w.cstr(name);
                w.i32(*id);
                w.count(bones.len(), "skeleton bone count")?;
                for b in bones {
                    encode_rb_description(w, b, v)?;
                }
            }
            Description::ForcePlate(p) => {
                w.i32(p.id);
                w.cstr(&p.serial);
                w.f32(p.width);
                w.f32(p.length);
                w.vec3(&p.origin);
                for i in 0..144 {
                    w.f32(p.calibration.get(i).copied().unwrap_or(0.0));
                }
                p.corners.iter().for_each(|c| w.vec3(c));
                w.i32(p.plate_type);
                w.i32(p.channel_data_type);
                encode_names(w, &p.channels, "force plate channel count")?;
            }
            Description::Device(d) => {
                w.i32(d.id);
                w.cstr(&d.name);
                w.cstr(&d.serial);
                w.i32(d.device_type);
                w.i32(d.channel_data_type);
                encode_names(w, &d.channels, "device channel count")?;
            }
            Description::Camera {
                name,
                position,
                orientation,
            } => {
                w.cstr(name);
                w.vec3(position);
                w.quat(orientation);
            }
            Description::Asset(a) => {
                w.cstr(&a.name);
                w.i32(a.asset_type);
                w.i32(a.id);
                w.count(a.rigid_bodies.len(), "asset rigid body count")?;
                for b in &a.rigid_bodies {
                    encode_rb_description(w, b, v)?;
                }
                w.count(a.markers.len(), "asset marker count")?;
                for m in &a.markers {
                    w.cstr(&m.name);
                    w.i32(m.id);
                    w.vec3(&m.position);
                    w.f32(m.size);
                    w.i16(m.params);
                }
            }
        }
        w.section_end(sz);
    }
    Ok(())
}

fn encode_rb(w: &mut Wr, b: &RigidBodyData, v: Version) -> EResult<()> {
    w.i32(b.id);
    w.vec3(&b.position);
    w.quat(&b.orientation);
    if v.major < 3 {
        w.count(b.markers.len(), "rigid body marker count")?;
        b.markers.iter().for_each(|m| w.vec3(&m.position));
        b.markers.iter().for_each(|m| w.i32(m.id));
        b.markers.iter().for_each(|m| w.f32(m.size));
    }
    w.f32(b.mean_error);
    if v.at_least(2, 6) {
        w.i16(b.params);
    }
    Ok(())
}

fn encode_analog(w: &mut Wr, list: &[AnalogData], v: Version, field: &'static str) -> EResult<()> {
    w.count(list.len(), field)?;
    let sz = w.section_start(v);
    for a in list {
        w.i32(a.id);
        w.count(a.channels.len(), "analog channel count")?;
        for c in &a.channels {
            w.count(c.len(), "analog sample count")?;
            c.iter().for_each(|&x| w.f32(x));
        }
    }
    w.section_end(sz);
    Ok(())
}

fn encode_frame(w: &mut Wr, f: &FrameOfData, v: Version) -> EResult<()> {
    w.i32(f.frame_number);

    w.count(f.marker_sets.len(), "marker set count")?;
    let sz = w.section_start(v);
    for s in &f.marker_sets {
        w.cstr(&s.name);
        w.count(s.markers.len(), "marker set marker count")?;
        s.markers.iter().for_each(|p| w.vec3(p));
    }
    w.section_end(sz);

    w.count(f.other_markers.len(), "other marker count")?;
    let sz = w.section_start(v);
    f.other_markers.iter().for_each(|p| w.vec3(p));
    w.section_end(sz);

    w.count(f.rigid_bodies.len(), "rigid body count")?;
    let sz = w.section_start(v);
    for b in &f.rigid_bodies {
        encode_rb(w, b, v)?;
    }
    w.section_end(sz);

    if v.at_least(2, 1) {
        w.count(f.skeletons.len(), "skeleton count")?;
        let sz = w.section_start(v);
        for s in &f.skeletons {
            w.i32(s.id);
            w.count(s.bones.len(), "skeleton bone count")?;
            for b in &s.bones {
                encode_rb(w, b, v)?;
            }
        }
        w.section_end(sz);
    }

    if v.has_section_sizes() {
        w.count(f.assets.len(), "asset count")?;
        let sz = w.section_start(v);
        for a in &f.assets {
            w.i32(a.id);
            w.count(a.rigid_bodies.len(), "asset rigid body count")?;
            for b in &a.rigid_bodies {
                w.i32(b.id);
                w.vec3(&b.position);
                w.quat(&b.orientation);
                w.f32(b.mean_error);
                w.i16(b.params);
            }
            w.count(a.markers.len(), "asset marker count")?;
            for m in &a.markers {
                w.i32(m.id);
                w.vec3(&m.position);
                w.f32(m.size);
                w.i16(m.params);
                w.f32(m.residual);
            }
        }
        w.section_end(sz);
    }

    if v.at_least(2, 3) {
        w.count(f.labeled_markers.len(), "labeled marker count")?;
        let sz = w.section_start(v);
        let with_params = v.at_least(2, 6);
        let with_residual = v.major >= 3;
        for m in &f.labeled_markers {
            w.i32(m.id);
            w.vec3(&m.position);
            w.f32(m.size);
            if with_params {
                w.i16(m.params);
            }
            if with_residual {
                w.f32(m.residual);
            }
        }
        w.section_end(sz);
    }

    if v.at_least(2, 9) {
        encode_analog(w, &f.force_plates, v, "force plate count")?;
    }
    if v.at_least(2, 11) {
        encode_analog(w, &f.devices, v, "device count")?;
    }

    if v.major < 3 {
        w.f32(f.software_latency);
    }
    w.u32(f.timecode);
    w.u32(f.timecode_subframe);
    if v == Version::new(2, 6) {
        w.f32(f.timestamp as f32);
    } else if v.at_least(2, 7) {
        w.bytes(&f.timestamp.to_le_bytes());
    }
    if v.major >= 3 {
        w.u64(f.camera_mid_exposure);
        w.u64(f.camera_data_received);
        w.u64(f.transmit);
    }
    if v.has_section_sizes() {
        w.u32(f.precision_seconds);
        w.u32(f.precision_fraction);
    }
    if v.at_least(2, 6) {
        w.i16(f.params);
    }
    w.i32(0);
    Ok(())
}
