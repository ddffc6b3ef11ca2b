//! The byte-exact NatNet encoder: what [`decode`](super::decode()) reads back
//! unchanged (for what the version can carry, see
//! [`FrameOfData::restricted_to`]). The server and the tests use it; the
//! client uses it for its few commands.

use super::types::*;
use super::Version;

/// Why a packet could not be encoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// The payload exceeds the 65535 bytes `nDataBytes` can state; NatNet
    /// has no fragmentation.
    #[error("{message} of {bytes} bytes does not fit one NatNet datagram (max {MAX_PAYLOAD})")]
    TooLarge {
        /// The message ("NAT_FRAMEOFDATA").
        message: &'static str,
        /// Its payload size.
        bytes: usize,
    },
    /// A list is longer than its i32 count can state.
    #[error("too many entries in {field}")]
    TooMany {
        /// The count that overflowed.
        field: &'static str,
    },
    /// The message cannot be expressed in this version (assets before 4.1).
    #[error("{what} cannot be sent in NatNet {version}")]
    NotInVersion {
        /// What could not be sent.
        what: &'static str,
        /// The version asked for.
        version: Version,
    },
}

type EncodeResult<T> = Result<T, EncodeError>;

/// Appends little-endian fields to one datagram being built.
struct PayloadWriter<'a> {
    /// The datagram, header included.
    out: &'a mut Vec<u8>,
}

impl PayloadWriter<'_> {
    #[inline]
    fn bytes(&mut self, b: &[u8]) {
        self.out.extend_from_slice(b);
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
        self.out.push(0);
    }
    fn count(&mut self, n: usize, field: &'static str) -> EncodeResult<()> {
        let n = i32::try_from(n).map_err(|_| EncodeError::TooMany { field })?;
        self.i32(n);
        Ok(())
    }
    /// 4.1+: a placeholder byte count, patched by `section_end`.
    fn section_start(&mut self, v: Version) -> Option<usize> {
        v.has_section_sizes().then(|| {
            self.u32(0);
            self.out.len()
        })
    }
    fn section_end(&mut self, start: Option<usize>) {
        if let Some(p) = start {
            let n = (self.out.len() - p) as u32;
            self.out[p - 4..p].copy_from_slice(&n.to_le_bytes());
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
pub fn encode_into(packet: &Packet, version: Version, out: &mut Vec<u8>) -> EncodeResult<()> {
    out.clear();
    out.extend_from_slice(&packet.id().to_le_bytes());
    out.extend_from_slice(&[0, 0]);
    let mut w = PayloadWriter { out };
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

fn encode_sender(w: &mut PayloadWriter, s: &Sender) {
    let mut name = [0u8; 256];
    let b = s.name.as_bytes();
    let n = b.len().min(255);
    name[..n].copy_from_slice(&b[..n]);
    w.bytes(&name);
    w.bytes(&s.version);
    w.bytes(&s.natnet_version);
}

fn encode_connect(w: &mut PayloadWriter, c: &Connect) {
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

fn encode_rb_description(
    w: &mut PayloadWriter,
    d: &RigidBodyDescription,
    v: Version,
) -> EncodeResult<()> {
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

fn encode_names(w: &mut PayloadWriter, names: &[String], field: &'static str) -> EncodeResult<()> {
    w.count(names.len(), field)?;
    names.iter().for_each(|n| w.cstr(n));
    Ok(())
}

fn encode_modeldef(w: &mut PayloadWriter, m: &ModelDef, v: Version) -> EncodeResult<()> {
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
        encode_description(w, d, v)?;
        w.section_end(sz);
    }
    Ok(())
}

/// One description's body (after its type and, 4.1+, its size).
fn encode_description(w: &mut PayloadWriter, d: &Description, v: Version) -> EncodeResult<()> {
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
    Ok(())
}

fn encode_rb(w: &mut PayloadWriter, b: &RigidBodyData, v: Version) -> EncodeResult<()> {
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

fn encode_analog(
    w: &mut PayloadWriter,
    list: &[AnalogData],
    v: Version,
    field: &'static str,
) -> EncodeResult<()> {
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

/// A frame: its sections in wire order, each in its own function.
fn encode_frame(w: &mut PayloadWriter, f: &FrameOfData, v: Version) -> EncodeResult<()> {
    w.i32(f.frame_number);
    encode_marker_sets(w, f, v)?;
    encode_rigid_bodies(w, f, v)?;
    if v.at_least(2, 1) {
        encode_skeletons(w, f, v)?;
    }
    if v.has_section_sizes() {
        encode_assets(w, f, v)?;
    }
    if v.at_least(2, 3) {
        encode_labeled_markers(w, f, v)?;
    }
    if v.at_least(2, 9) {
        encode_analog(w, &f.force_plates, v, "force plate count")?;
    }
    if v.at_least(2, 11) {
        encode_analog(w, &f.devices, v, "device count")?;
    }

    encode_frame_trailer(w, f, v);
    Ok(())
}

/// Latency, timecode, timestamps, params and the end-of-data tag.
fn encode_frame_trailer(w: &mut PayloadWriter, f: &FrameOfData, v: Version) {
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
}

/// The named marker sets and the legacy "other markers" list.
fn encode_marker_sets(w: &mut PayloadWriter, f: &FrameOfData, v: Version) -> EncodeResult<()> {
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

    Ok(())
}

/// The rigid bodies.
fn encode_rigid_bodies(w: &mut PayloadWriter, f: &FrameOfData, v: Version) -> EncodeResult<()> {
    w.count(f.rigid_bodies.len(), "rigid body count")?;
    let sz = w.section_start(v);
    for b in &f.rigid_bodies {
        encode_rb(w, b, v)?;
    }
    w.section_end(sz);

    Ok(())
}

/// 2.1+.
fn encode_skeletons(w: &mut PayloadWriter, f: &FrameOfData, v: Version) -> EncodeResult<()> {
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
    Ok(())
}

/// 4.1+.
fn encode_assets(w: &mut PayloadWriter, f: &FrameOfData, v: Version) -> EncodeResult<()> {
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
    Ok(())
}

/// 2.3+.
fn encode_labeled_markers(w: &mut PayloadWriter, f: &FrameOfData, v: Version) -> EncodeResult<()> {
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
    Ok(())
}
