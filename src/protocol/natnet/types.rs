//! The NatNet messages as Rust types (spec: OptiTrack's `NatNetTypes.h` and
//! `PacketClient.cpp`), with what each bitstream version can carry of them
//! ([`FrameOfData::restricted_to`]).

use super::Version;

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
    /// A client says hello (payload: its `sSender`, or less).
    pub const CONNECT: u16 = 0;
    /// The server's answer to CONNECT and DISCOVERY.
    pub const SERVERINFO: u16 = 1;
    /// A command string from a client.
    pub const REQUEST: u16 = 2;
    /// The server's answer to a REQUEST.
    pub const RESPONSE: u16 = 3;
    /// A client asks for the model descriptions.
    pub const REQUEST_MODELDEF: u16 = 4;
    /// The model descriptions.
    pub const MODELDEF: u16 = 5;
    /// A client asks for the latest frame.
    pub const REQUEST_FRAMEOFDATA: u16 = 6;
    /// One frame of data.
    pub const FRAMEOFDATA: u16 = 7;
    /// Free text from the server.
    pub const MESSAGESTRING: u16 = 8;
    /// A client leaves.
    pub const DISCONNECT: u16 = 9;
    /// A unicast client is still there.
    pub const KEEPALIVE: u16 = 10;
    /// The server dropped a silent client.
    pub const DISCONNECTBYTIMEOUT: u16 = 11;
    /// A client's clock, for latency measurement.
    pub const ECHOREQUEST: u16 = 12;
    /// The echoed client clock and the server's.
    pub const ECHORESPONSE: u16 = 13;
    /// A broadcast looking for servers.
    pub const DISCOVERY: u16 = 14;
    /// The server's answer to a request it does not know.
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

/// One NatNet datagram, decoded.
#[derive(Debug, Clone, PartialEq)]
pub enum Packet {
    /// A client says hello.
    Connect(Connect),
    /// The server answers CONNECT or DISCOVERY.
    ServerInfo(ServerInfo),
    /// A command string: `FrameRate`, `Bitstream,4.1`, `TimelinePlay`, …
    Request(String),
    /// The server answers a request.
    Response(Response),
    /// A client asks for the model descriptions.
    RequestModelDef,
    /// The model descriptions.
    ModelDef(ModelDef),
    /// A client asks for the latest frame.
    RequestFrameOfData,
    /// One frame (boxed: it is far larger than the other messages).
    FrameOfData(Box<FrameOfData>),
    /// A free-text message from the server.
    MessageString(String),
    /// A client leaves.
    Disconnect,
    /// A unicast client is still there.
    KeepAlive,
    /// The server dropped a silent client.
    DisconnectByTimeout,
    /// Client's clock in its own ticks.
    EchoRequest(u64),
    /// The echoed client ticks and the server's receive time in its hi-res ticks.
    EchoResponse {
        /// The client's clock, echoed.
        client_ticks: u64,
        /// The server's hi-res clock when it received the request.
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
        /// Who is talking.
        sender: Sender,
        /// 4.x clients: what they ask of the server.
        options: Option<ConnectionOptions>,
        /// Bytes after the options, kept for byte-exact re-encoding.
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
    /// Who is talking.
    pub sender: Sender,
    /// Present from NatNet 3.0 (279-byte form); absent in 2.x (264 bytes).
    pub connection: Option<ServerConnection>,
}

/// The part of SERVERINFO that NatNet 3.0 added.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ServerConnection {
    /// Ticks per second of the server's hi-res clock (frame timestamps).
    pub clock_frequency: u64,
    /// The port frames are sent from (and, in multicast, to).
    pub data_port: u16,
    /// Whether frames go to the multicast group.
    pub multicast: bool,
    /// The multicast group, as four octets.
    pub multicast_group: [u8; 4],
}

/// NAT_RESPONSE: four bytes (an int or a float, the request decides) or a string.
#[derive(Debug, Clone, PartialEq)]
pub enum Response {
    /// Four bytes: an int or a float, the request decides.
    Value([u8; 4]),
    /// A NUL-terminated string.
    Text(String),
    /// A string filling the payload with no NUL. OptiTrack's Python client
    /// parses the `Bitstream` reply up to the end of the datagram, so a NUL
    /// there makes it crash (`int('0\x00')`); our server answers that query so.
    Unterminated(String),
}

impl Response {
    /// An integer answer.
    pub fn int(v: i32) -> Self {
        Response::Value(v.to_le_bytes())
    }
    /// A float answer (`FrameRate`).
    pub fn float(v: f32) -> Self {
        Response::Value(v.to_le_bytes())
    }
    /// The answer as an integer, if it is four bytes.
    pub fn as_i32(&self) -> Option<i32> {
        match self {
            Response::Value(b) => Some(i32::from_le_bytes(*b)),
            _ => None,
        }
    }
    /// The answer as a float, if it is four bytes.
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
    /// One per tracked dataset.
    pub descriptions: Vec<Description>,
}

/// One dataset of a MODELDEF.
#[derive(Debug, Clone, PartialEq)]
pub enum Description {
    /// Type 0: a named set of markers.
    MarkerSet {
        /// Its name.
        name: String,
        /// Its markers' names.
        markers: Vec<String>,
    },
    /// Type 1.
    RigidBody(RigidBodyDescription),
    /// Type 2.
    Skeleton {
        /// Its name.
        name: String,
        /// The id the server gives it.
        id: i32,
        /// Its bones.
        bones: Vec<RigidBodyDescription>,
    },
    /// Type 3 (3.0+ layout).
    ForcePlate(Box<ForcePlateDescription>),
    /// Type 4 (3.0+ layout).
    Device(DeviceDescription),
    /// Type 5.
    Camera {
        /// Its name.
        name: String,
        /// Position (m).
        position: [f32; 3],
        /// Rotation (qx, qy, qz, qw).
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
    /// The id the server gives it.
    pub id: i32,
    /// The parent rigid body id (-1 for none).
    pub parent_id: i32,
    /// Offset from the parent (m).
    pub offset: [f32; 3],
    /// Rotation offset (qx, qy, qz, qw), on the wire from 4.2.
    pub rotation: [f32; 4],
    /// Marker offsets and labels, on the wire from 3.0 (names from 4.0).
    pub markers: Vec<RigidBodyMarkerDescription>,
}

/// One marker of a rigid body description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RigidBodyMarkerDescription {
    /// Offset from the parent (m).
    pub offset: [f32; 3],
    /// The active marker label (0 for passive markers).
    pub active_label: i32,
    /// On the wire from 4.0.
    pub name: String,
}

/// A force plate description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ForcePlateDescription {
    /// The id the server gives it.
    pub id: i32,
    /// The serial number.
    pub serial: String,
    /// Width (m).
    pub width: f32,
    /// Length (m).
    pub length: f32,
    /// Electrical centre offset (m).
    pub origin: [f32; 3],
    /// 12 × 12 calibration matrix, row-major.
    pub calibration: Vec<f32>,
    /// The four corners (m).
    pub corners: [[f32; 3]; 4],
    /// The plate type code.
    pub plate_type: i32,
    /// The sample data type code.
    pub channel_data_type: i32,
    /// Channel names.
    pub channels: Vec<String>,
}

/// An analog device description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DeviceDescription {
    /// The id the server gives it.
    pub id: i32,
    /// Its name.
    pub name: String,
    /// The serial number.
    pub serial: String,
    /// The device type code.
    pub device_type: i32,
    /// The sample data type code.
    pub channel_data_type: i32,
    /// Channel names.
    pub channels: Vec<String>,
}

/// An asset description (4.1+).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetDescription {
    /// Its name.
    pub name: String,
    /// The asset type code.
    pub asset_type: i32,
    /// The id the server gives it.
    pub id: i32,
    /// Its rigid bodies.
    pub rigid_bodies: Vec<RigidBodyDescription>,
    /// Its markers.
    pub markers: Vec<AssetMarkerDescription>,
}

/// One marker of an asset description.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetMarkerDescription {
    /// Its name.
    pub name: String,
    /// The id the server gives it.
    pub id: i32,
    /// Position (m).
    pub position: [f32; 3],
    /// Marker diameter (m).
    pub size: f32,
    /// Status flags.
    pub params: i16,
}

/// NAT_FRAMEOFDATA. Fields a version does not carry decode as zero/empty and
/// are not written by the encoder ([`FrameOfData::restricted_to`] says which).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameOfData {
    /// The server's frame number.
    pub frame_number: i32,
    /// Named marker sets.
    pub marker_sets: Vec<MarkerSetData>,
    /// The legacy "other" (unlabeled) marker list.
    pub other_markers: Vec<[f32; 3]>,
    /// Its rigid bodies.
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
    /// SMPTE subframe.
    pub timecode_subframe: u32,
    /// Seconds since the server started: f32 in 2.6, f64 from 2.7, absent before.
    pub timestamp: f64,
    /// 3.0+: server hi-res ticks at mid-exposure, at data receipt, at transmit.
    pub camera_mid_exposure: u64,
    /// Server ticks when the camera data arrived (3.0+).
    pub camera_data_received: u64,
    /// Server ticks when the frame was sent (3.0+).
    pub transmit: u64,
    /// 4.1+: PTP time (0 when the server has none).
    pub precision_seconds: u32,
    /// PTP fraction of a second (4.1+).
    pub precision_fraction: u32,
    /// Frame flags (2.6+): 0x01 recording, 0x02 models changed, 0x04 edit
    /// mode, 0x08 bitstream changed.
    pub params: i16,
}

/// One marker set of a frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MarkerSetData {
    /// Its name.
    pub name: String,
    /// Its markers.
    pub markers: Vec<[f32; 3]>,
}

/// One rigid body of a frame (also a skeleton bone).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RigidBodyData {
    /// The id the server gives it.
    pub id: i32,
    /// Position (m).
    pub position: [f32; 3],
    /// qx, qy, qz, qw.
    pub orientation: [f32; 4],
    /// Per-marker data, on the wire before 3.0 only.
    pub markers: Vec<RigidBodyMarker>,
    /// Mean marker error (m).
    pub mean_error: f32,
    /// 2.6+: bit 0 = tracking valid.
    pub params: i16,
}

/// A rigid body marker in a pre-3.0 frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RigidBodyMarker {
    /// Position (m).
    pub position: [f32; 3],
    /// The id the server gives it.
    pub id: i32,
    /// Marker diameter (m).
    pub size: f32,
}

/// One skeleton of a frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SkeletonData {
    /// The id the server gives it.
    pub id: i32,
    /// Its bones.
    pub bones: Vec<RigidBodyData>,
}

/// One asset of a frame (4.1+).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetData {
    /// The id the server gives it.
    pub id: i32,
    /// Its rigid bodies.
    pub rigid_bodies: Vec<AssetRigidBody>,
    /// Its markers.
    pub markers: Vec<AssetMarker>,
}

/// A rigid body of an asset.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetRigidBody {
    /// The id the server gives it.
    pub id: i32,
    /// Position (m).
    pub position: [f32; 3],
    /// Rotation (qx, qy, qz, qw).
    pub orientation: [f32; 4],
    /// Mean marker error (m).
    pub mean_error: f32,
    /// Status flags.
    pub params: i16,
}

/// A marker of an asset.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AssetMarker {
    /// The id the server gives it.
    pub id: i32,
    /// Position (m).
    pub position: [f32; 3],
    /// Marker diameter (m).
    pub size: f32,
    /// Status flags.
    pub params: i16,
    /// Marker residual (m).
    pub residual: f32,
}

/// One entry of the labeled-marker list.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LabeledMarker {
    /// modelId << 16 | markerId (model 0 = unlabeled point cloud in 3.0+).
    pub id: i32,
    /// Position (m).
    pub position: [f32; 3],
    /// Marker diameter (m).
    pub size: f32,
    /// 2.6+: 0x01 occluded, 0x02 point-cloud solved, 0x04 model solved,
    /// 0x08 has model, 0x10 unlabeled, 0x20 active.
    pub params: i16,
    /// 3.0+.
    pub residual: f32,
}

impl LabeledMarker {
    /// The model the marker belongs to (0: point cloud).
    pub fn model_id(&self) -> i32 {
        self.id >> 16
    }
    /// The marker within its model.
    pub fn marker_id(&self) -> i32 {
        self.id & 0xFFFF
    }
    /// Whether it is an unlabeled point-cloud marker (3.0+).
    pub fn is_unlabeled(&self) -> bool {
        self.params & MARKER_UNLABELED != 0
    }
}

/// A force plate or device: channels of sub-frame samples.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AnalogData {
    /// The id the server gives it.
    pub id: i32,
    /// Channel names.
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
