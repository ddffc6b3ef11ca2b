//! The strict NatNet decoder: every byte of the payload must be accounted
//! for, every count must fit in what is left of the packet, 4.1+ section
//! sizes must agree with their content. Failures are [`DecodeError`]s that
//! name the message, the field and the byte offset in the datagram, split
//! into *incomplete* (the packet ended inside a field) and *invalid* (a field
//! holds an impossible value). Nothing here panics on any input: all reads
//! are bounds-checked and counts are checked against the remaining bytes
//! before anything is allocated.
//!
//! One leniency, because real clients are sloppy: a datagram may be longer
//! than its header's `nDataBytes`; the extra bytes are ignored. And
//! payload-less client messages (KEEPALIVE, REQUEST_MODELDEF, …) may carry
//! NUL padding.

use std::fmt;

use super::types::*;
use super::Version;

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

impl fmt::Display for DecodeErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DecodeErrorKind::Incomplete => "incomplete",
            DecodeErrorKind::Invalid => "invalid",
            DecodeErrorKind::UnknownMessage => "unknown",
        })
    }
}

/// A decoding failure naming the message, the field and the byte offset
/// (from the start of the datagram, header included): what a user needs to
/// find the bad byte in a capture.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{kind} {message}: field {field} at byte {offset}: {detail}")]
pub struct DecodeError {
    /// Incomplete, invalid or unknown: counted apart by the client.
    pub kind: DecodeErrorKind,
    /// The message being decoded ("NAT_FRAMEOFDATA").
    pub message: &'static str,
    /// The field that failed ("labeled marker count").
    pub field: &'static str,
    /// Byte offset of that field in the datagram.
    pub offset: usize,
    /// What was wrong, with the numbers.
    pub detail: String,
}

/// What every read returns.
type DecodeResult<T> = Result<T, DecodeError>;

/// A bounds-checked little-endian cursor over one payload.
struct PayloadReader<'a> {
    /// The payload (the datagram after its 4-byte header, or the header).
    bytes: &'a [u8],
    /// The next byte to read.
    pos: usize,
    /// Offset of `bytes[0]` in the datagram, so errors give datagram offsets.
    base: usize,
    /// The message being read, for errors.
    message: &'static str,
}

impl<'a> PayloadReader<'a> {
    fn err(&self, kind: DecodeErrorKind, field: &'static str, detail: String) -> DecodeError {
        DecodeError {
            kind,
            message: self.message,
            field,
            offset: self.base + self.pos,
            detail,
        }
    }

    fn invalid(&self, field: &'static str, detail: String) -> DecodeError {
        self.err(DecodeErrorKind::Invalid, field, detail)
    }

    fn left(&self) -> usize {
        self.bytes.len() - self.pos
    }

    #[inline]
    fn take(&mut self, n: usize, field: &'static str) -> DecodeResult<&'a [u8]> {
        match self.bytes.get(self.pos..self.pos.saturating_add(n)) {
            Some(s) if n <= self.left() => {
                self.pos += n;
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
    fn arr<const N: usize>(&mut self, field: &'static str) -> DecodeResult<[u8; N]> {
        let s = self.take(N, field)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    #[inline]
    fn u8(&mut self, field: &'static str) -> DecodeResult<u8> {
        Ok(self.arr::<1>(field)?[0])
    }
    #[inline]
    fn i16(&mut self, field: &'static str) -> DecodeResult<i16> {
        Ok(i16::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn u16(&mut self, field: &'static str) -> DecodeResult<u16> {
        Ok(u16::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn i32(&mut self, field: &'static str) -> DecodeResult<i32> {
        Ok(i32::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn u32(&mut self, field: &'static str) -> DecodeResult<u32> {
        Ok(u32::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn u64(&mut self, field: &'static str) -> DecodeResult<u64> {
        Ok(u64::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn f32(&mut self, field: &'static str) -> DecodeResult<f32> {
        Ok(f32::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn f64(&mut self, field: &'static str) -> DecodeResult<f64> {
        Ok(f64::from_le_bytes(self.arr(field)?))
    }
    #[inline]
    fn vec3(&mut self, field: &'static str) -> DecodeResult<[f32; 3]> {
        let b: [u8; 12] = self.arr(field)?;
        Ok([
            f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            f32::from_le_bytes([b[4], b[5], b[6], b[7]]),
            f32::from_le_bytes([b[8], b[9], b[10], b[11]]),
        ])
    }
    #[inline]
    fn quat(&mut self, field: &'static str) -> DecodeResult<[f32; 4]> {
        Ok([
            self.f32(field)?,
            self.f32(field)?,
            self.f32(field)?,
            self.f32(field)?,
        ])
    }

    /// A NUL-terminated string (lossy UTF-8: names are for people).
    fn cstr(&mut self, field: &'static str) -> DecodeResult<String> {
        let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
        match rest.iter().position(|&c| c == 0) {
            Some(n) => {
                let s = String::from_utf8_lossy(&rest[..n]).into_owned();
                self.pos += n + 1;
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
    fn count(&mut self, field: &'static str, min_size: usize) -> DecodeResult<usize> {
        let n = self.i32(field)?;
        self.pos -= 4; // report the count's own offset
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
        self.pos += 4;
        Ok(n as usize)
    }

    /// Only NUL padding may remain.
    fn padding(&mut self, field: &'static str) -> DecodeResult<()> {
        let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
        if let Some(i) = rest.iter().position(|&c| c != 0) {
            self.pos += i;
            return Err(self.invalid(field, format!("{} unexpected bytes", rest.len() - i)));
        }
        self.pos = self.bytes.len();
        Ok(())
    }

    fn end(&self) -> DecodeResult<()> {
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
    fn section_start(
        &mut self,
        v: Version,
        field: &'static str,
    ) -> DecodeResult<Option<(usize, u32)>> {
        if !v.has_section_sizes() {
            return Ok(None);
        }
        let sz = self.u32(field)?;
        if sz as usize > self.left() {
            self.pos -= 4;
            return Err(self.invalid(
                field,
                format!(
                    "section size {sz} exceeds the {} bytes left",
                    self.left() - 4
                ),
            ));
        }
        Ok(Some((self.pos, sz)))
    }

    fn section_end(&self, start: Option<(usize, u32)>, field: &'static str) -> DecodeResult<()> {
        if let Some((p0, sz)) = start {
            let used = self.pos - p0;
            if used != sz as usize {
                return Err(DecodeError {
                    kind: DecodeErrorKind::Invalid,
                    message: self.message,
                    field,
                    offset: self.base + p0 - 4,
                    detail: format!("section size says {sz} bytes, its content is {used}"),
                });
            }
        }
        Ok(())
    }
}

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
    let mut h = PayloadReader {
        bytes: datagram,
        pos: 0,
        base: 0,
        message: "packet header",
    };
    let mid = h.u16("iMessage")?;
    let msg = message_name(mid);
    h.message = msg;
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
    let mut r = PayloadReader {
        bytes: payload,
        pos: 0,
        base: 4,
        message: msg,
    };
    let packet = match mid {
        id::CONNECT => Packet::Connect(decode_connect(&mut r)?),
        id::DISCOVERY => Packet::Discovery(decode_connect(&mut r)?),
        id::SERVERINFO => Packet::ServerInfo(decode_server_info(&mut r)?),
        id::REQUEST => {
            // Anything after the command's NUL is ignored: NatNetLib sends
            // binary after some commands (`service20,-1,…`).
            let s = r.cstr("command")?;
            r.pos = r.bytes.len();
            Packet::Request(s)
        }
        id::RESPONSE => Packet::Response(decode_response(&mut r)?),
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

/// Four bytes (an int or a float), a NUL-terminated string, or a string
/// filling the payload.
fn decode_response(r: &mut PayloadReader) -> DecodeResult<Response> {
    let n = r.bytes.len();
    Ok(if n == 4 {
        Response::Value(r.arr("value")?)
    } else if !r.bytes.contains(&0) {
        Response::Unterminated(String::from_utf8_lossy(r.take(n, "text")?).into_owned())
    } else {
        let s = r.cstr("text")?;
        r.padding("text")?;
        Response::Text(s)
    })
}

fn empty(r: &mut PayloadReader, p: Packet) -> DecodeResult<Packet> {
    r.padding("payload")?;
    Ok(p)
}

fn decode_sender(r: &mut PayloadReader) -> DecodeResult<Sender> {
    let name = r.take(256, "szName")?;
    let end = name.iter().position(|&c| c == 0).unwrap_or(name.len());
    Ok(Sender {
        name: String::from_utf8_lossy(&name[..end]).into_owned(),
        version: r.arr("Version")?,
        natnet_version: r.arr("NatNetVersion")?,
    })
}

fn decode_connect(r: &mut PayloadReader) -> DecodeResult<Connect> {
    let n = r.bytes.len();
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

fn decode_server_info(r: &mut PayloadReader) -> DecodeResult<ServerInfo> {
    let n = r.bytes.len();
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

fn decode_rb_description(r: &mut PayloadReader, v: Version) -> DecodeResult<RigidBodyDescription> {
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
    r: &mut PayloadReader,
    field: &'static str,
    count_field: &'static str,
) -> DecodeResult<Vec<String>> {
    let n = r.count(count_field, 1)?;
    let mut names = Vec::with_capacity(n);
    for _ in 0..n {
        names.push(r.cstr(field)?);
    }
    Ok(names)
}

fn decode_description(r: &mut PayloadReader, v: Version, kind: i32) -> DecodeResult<Description> {
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
        3 => Description::ForcePlate(Box::new(decode_force_plate(r)?)),
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
        6 => Description::Asset(decode_asset_description(r, v)?),
        other => {
            r.pos -= if v.has_section_sizes() { 8 } else { 4 };
            return Err(r.invalid(
                "description type",
                format!("unknown description type {other}"),
            ));
        }
    })
}

/// Type 3 (3.0+ layout).
fn decode_force_plate(r: &mut PayloadReader) -> DecodeResult<ForcePlateDescription> {
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
    Ok(d)
}

/// Type 6 (4.1+).
fn decode_asset_description(r: &mut PayloadReader, v: Version) -> DecodeResult<AssetDescription> {
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
    Ok(AssetDescription {
        name,
        asset_type,
        id,
        rigid_bodies,
        markers,
    })
}

fn decode_modeldef(r: &mut PayloadReader, v: Version) -> DecodeResult<ModelDef> {
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

fn decode_rb(r: &mut PayloadReader, v: Version) -> DecodeResult<RigidBodyData> {
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
fn decode_analog(
    r: &mut PayloadReader,
    v: Version,
    fields: [&'static str; 5],
) -> DecodeResult<Vec<AnalogData>> {
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

/// A frame: its sections in wire order, each in its own function.
fn decode_frame(r: &mut PayloadReader, v: Version) -> DecodeResult<FrameOfData> {
    let mut f = FrameOfData {
        frame_number: r.i32("frame number")?,
        ..Default::default()
    };
    decode_marker_sets(r, v, &mut f)?;
    decode_rigid_bodies(r, v, &mut f)?;
    if v.at_least(2, 1) {
        decode_skeletons(r, v, &mut f)?;
    }
    if v.has_section_sizes() {
        decode_assets(r, v, &mut f)?;
    }
    if v.at_least(2, 3) {
        decode_labeled_markers(r, v, &mut f)?;
    }
    if v.at_least(2, 9) {
        f.force_plates = decode_analog(r, v, FORCE_PLATE_FIELDS)?;
    }
    if v.at_least(2, 11) {
        f.devices = decode_analog(r, v, DEVICE_FIELDS)?;
    }
    decode_frame_trailer(r, v, &mut f)?;
    Ok(f)
}

/// Field names of the force plate and device sections, for errors.
const FORCE_PLATE_FIELDS: [&str; 5] = [
    "force plate count",
    "force plate section size",
    "force plate id",
    "force plate channel count",
    "force plate sample count",
];
const DEVICE_FIELDS: [&str; 5] = [
    "device count",
    "device section size",
    "device id",
    "device channel count",
    "device sample count",
];

/// Positions packed as f32 triples in a block already bounds-checked.
fn positions(block: &[u8]) -> Vec<[f32; 3]> {
    block
        .chunks_exact(12)
        .map(|c| [le_f32(c, 0), le_f32(c, 4), le_f32(c, 8)])
        .collect()
}

/// The named marker sets and the legacy "other markers" list.
fn decode_marker_sets(r: &mut PayloadReader, v: Version, f: &mut FrameOfData) -> DecodeResult<()> {
    let n = r.count("marker set count", 5)?;
    let sz = r.section_start(v, "marker set section size")?;
    f.marker_sets.reserve_exact(n);
    for _ in 0..n {
        let name = r.cstr("marker set name")?;
        let m = r.count("marker set marker count", 12)?;
        let markers = positions(r.take(m * 12, "marker set marker positions")?);
        f.marker_sets.push(MarkerSetData { name, markers });
    }
    r.section_end(sz, "marker set section size")?;

    let n = r.count("other marker count", 12)?;
    let sz = r.section_start(v, "other marker section size")?;
    f.other_markers = positions(r.take(n * 12, "other marker positions")?);
    r.section_end(sz, "other marker section size")
}

fn decode_rigid_bodies(r: &mut PayloadReader, v: Version, f: &mut FrameOfData) -> DecodeResult<()> {
    let n = r.count("rigid body count", rb_min_size(v))?;
    let sz = r.section_start(v, "rigid body section size")?;
    f.rigid_bodies.reserve_exact(n);
    for _ in 0..n {
        f.rigid_bodies.push(decode_rb(r, v)?);
    }
    r.section_end(sz, "rigid body section size")
}

/// 2.1+.
fn decode_skeletons(r: &mut PayloadReader, v: Version, f: &mut FrameOfData) -> DecodeResult<()> {
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
    r.section_end(sz, "skeleton section size")
}

/// 4.1+.
fn decode_assets(r: &mut PayloadReader, v: Version, f: &mut FrameOfData) -> DecodeResult<()> {
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
    r.section_end(sz, "asset section size")
}

/// 2.3+: the list a tree rig reads (the point cloud from 3.0).
fn decode_labeled_markers(
    r: &mut PayloadReader,
    v: Version,
    f: &mut FrameOfData,
) -> DecodeResult<()> {
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
    r.section_end(sz, "labeled marker section size")
}

/// Latency, timecode, timestamps, params and the end-of-data tag.
fn decode_frame_trailer(
    r: &mut PayloadReader,
    v: Version,
    f: &mut FrameOfData,
) -> DecodeResult<()> {
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
        r.pos -= 4;
        return Err(r.invalid("end of data tag", format!("{eod}, expected 0")));
    }
    Ok(())
}
