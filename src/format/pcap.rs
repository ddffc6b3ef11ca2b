//! Wireshark / tcpdump captures (`.pcap`, `.pcapng`) of NatNet traffic as a
//! recording: users capture a session to report a problem or to keep it,
//! and `inspect`, `replay`, `tips` and `serve` read the capture like any
//! other recording.
//!
//! The capture file format is read by `pcap-parser` (both pcap flavours,
//! pcapng, either byte order). What lies inside is read here: the link
//! layer (Ethernet with VLAN tags, Linux cooked v1/v2, BSD loopback, raw
//! IP), IPv4 with fragment reassembly (a NatNet frame above the MTU travels
//! in fragments), and UDP. NatNet is found by its messages, not by fixed
//! ports:
//! - the server is the sender of the first NAT_SERVERINFO, which also gives
//!   the bitstream version (or `--natnet-version` when the capture started
//!   after the client connected); a later SERVERINFO from it (a restart)
//!   changes the version, and so does an accepted `Bitstream,X.Y` request
//!   of the client whose frames are read;
//! - frames are the NAT_FRAMEOFDATA datagrams the server sent, to one
//!   destination (the multicast group, or the first unicast client: several
//!   unicast clients each get a copy of every frame);
//! - the frame rate is the server's answer to a `FrameRate` request in the
//!   capture, else measured from the first frames' numbers and times;
//! - the up axis is the server's answer to `GetProperty,,Up Axis`, else the
//!   configured one.
//!
//! Frames come in capture order. Their time is the frame's own timestamp
//! (2.6+), as the live client takes it; versions without one use the frame
//! number over the rate, else the capture time since the first frame.

use std::collections::{HashMap, VecDeque};
use std::io::Read;
use std::net::{Ipv4Addr, SocketAddrV4};
use std::path::PathBuf;

use pcap_parser::traits::{PcapNGPacketBlock, PcapReaderIterator};
use pcap_parser::{Block, PcapBlockOwned, PcapError};

use crate::error::{Error, Location, Result};
use crate::model::frame::MarkerFrame;
use crate::model::recording::{Format, Recording, RecordingInfo};
use crate::protocol::natnet::select::{
    to_marker_frame, up_axis_from_answer, FrameContext, MarkerSelection, UpAxis, UpAxisSetting,
};
use crate::protocol::natnet::{decode, id, peek_id, FrameOfData, Packet, Response, Version};

/// How a capture is read: the `--natnet-version` and `[natnet]` settings
/// that apply to it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PcapOptions {
    /// The bitstream, when the capture holds no SERVERINFO.
    pub version: Option<Version>,
    /// Which markers of a frame are taken.
    pub markers: MarkerSelection,
    /// The stream's up axis when the capture does not hold the answer.
    pub up_axis: UpAxisSetting,
}

/// True when `head` starts like a pcap or pcapng file.
pub fn looks_like_pcap(head: &[u8]) -> bool {
    const MAGICS: [[u8; 4]; 5] = [
        [0xd4, 0xc3, 0xb2, 0xa1],
        [0xa1, 0xb2, 0xc3, 0xd4],
        [0x4d, 0x3c, 0xb2, 0xa1],
        [0xa1, 0xb2, 0x3c, 0x4d],
        [0x0a, 0x0d, 0x0d, 0x0a],
    ];
    head.get(..4).is_some_and(|m| MAGICS.iter().any(|x| x == m))
}

/// One UDP datagram of the capture.
#[derive(Debug, Clone)]
struct Datagram {
    /// Capture time, seconds since the epoch.
    time_s: f64,
    /// 1-based packet number, as Wireshark shows it (the last fragment's).
    packet: u64,
    src: SocketAddrV4,
    dst: SocketAddrV4,
    payload: Vec<u8>,
}

/// What the capture says about the stream, learnt as it is read.
#[derive(Debug, Clone, Default)]
struct Stream {
    /// The server's command address (sender of SERVERINFO).
    server: Option<SocketAddrV4>,
    server_name: String,
    version: Option<Version>,
    clock_frequency: u64,
    /// Where the frames read go (group or first unicast client).
    frames_to: Option<SocketAddrV4>,
    /// The client whose requests are followed, and what it asked, in order.
    client: Option<SocketAddrV4>,
    pending: VecDeque<String>,
    rate: Option<f64>,
    up: Option<UpAxis>,
}

/// A NatNet capture read as a stream of frames; see the module docs.
pub struct PcapRecording {
    packets: Packets,
    path: PathBuf,
    options: PcapOptions,
    stream: Stream,
    /// Datagrams read ahead while learning the version and the rate.
    ahead: VecDeque<Datagram>,
    first_frame: Option<(i64, f64)>,
    rate: f64,
    rate_measured: bool,
    bad_frames: u64,
    warnings: Vec<String>,
    /// What the capture says about itself, once read ahead.
    info: RecordingInfo,
    /// The version at the start of the capture.
    start_version: Option<Version>,
}

/// Datagrams read ahead at most while looking for the version and rate.
const LOOKAHEAD: usize = 20_000;
/// Capture seconds of frames enough to measure the rate.
const MEASURE_SPAN_S: f64 = 1.0;

impl PcapRecording {
    /// Reads the capture from `reader`; `path` names it in errors. Reads
    /// ahead until the NatNet version and frame rate are known.
    pub fn new(reader: Box<dyn Read + Send>, path: PathBuf, options: PcapOptions) -> Result<Self> {
        let packets = Packets::new(reader, &path)?;
        let mut r = PcapRecording {
            packets,
            path,
            options,
            stream: Stream::default(),
            ahead: VecDeque::new(),
            first_frame: None,
            rate: 0.0,
            rate_measured: false,
            bad_frames: 0,
            warnings: Vec::new(),
            info: RecordingInfo {
                format: Format::Pcap,
                version: String::new(),
                frame_rate: 0.0,
                units: "m".into(),
                up_axis: "Y".into(),
                source: String::new(),
            },
            start_version: None,
        };
        r.stream.version = options.version;
        r.look_ahead()?;
        r.info.version = r
            .start_version
            .map_or_else(String::new, |v| format!("NatNet {v}"));
        r.info.frame_rate = r.rate;
        r.info.up_axis = crate::protocol::natnet::select::up_axis_name(r.up_axis()).into();
        Ok(r)
    }

    /// The server ("natnet capture of Motive at 10.0.0.5:1510"), for the
    /// recording's header.
    pub fn source(&self) -> &str {
        &self.info.source
    }

    /// The bitstream version frames are decoded with (at the start).
    pub fn version(&self) -> Option<Version> {
        self.start_version
    }

    /// Frames per second: the server's answer, else measured.
    pub fn frame_rate(&self) -> f64 {
        self.rate
    }

    /// The stream's up axis.
    pub fn up_axis(&self) -> UpAxis {
        self.stream.up.unwrap_or(match self.options.up_axis {
            UpAxisSetting::Z => UpAxis::Z,
            _ => UpAxis::Y,
        })
    }

    /// What was odd about the capture (skipped frames, a measured rate).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Reads datagrams into `ahead` until the version, the rate and the up
    /// axis are known or enough frames were seen to measure the rate.
    fn look_ahead(&mut self) -> Result<()> {
        let mut probe = self.stream.clone();
        let mut frames: Vec<(i64, f64)> = Vec::new();
        while self.ahead.len() < LOOKAHEAD {
            let Some(d) = self.packets.next_datagram()? else {
                break;
            };
            learn(&mut probe, &d);
            if let Some(f) = probe_frame(&probe, &d) {
                frames.push(f);
            }
            self.ahead.push_back(d);
            let span = frames.last().map_or(0.0, |l| l.1 - frames[0].1);
            if probe.version.is_some() && probe.rate.is_some() && probe.up.is_some() {
                break;
            }
            if span >= MEASURE_SPAN_S {
                break;
            }
        }
        if probe.version.is_none() {
            return Err(Error::parse(
                &self.path,
                Location::Field("NAT_SERVERINFO".into()),
                "no NatNet server info in the capture (it started after the client connected?); \
                 give the bitstream with --natnet-version X.Y",
            ));
        }
        self.set_rate(probe.rate, &frames);
        self.stream.up = probe.up;
        self.info.source = match probe.server {
            Some(s) if !probe.server_name.is_empty() => {
                format!("natnet capture of {} at {s}", probe.server_name)
            }
            Some(s) => format!("natnet capture of {s}"),
            None => "natnet capture".into(),
        };
        self.start_version = probe.version;
        Ok(())
    }

    fn set_rate(&mut self, answered: Option<f64>, frames: &[(i64, f64)]) {
        if let Some(r) = answered {
            self.rate = r;
            return;
        }
        let measured = match (frames.first(), frames.last()) {
            (Some(a), Some(b)) if b.1 > a.1 => (b.0 - a.0) as f64 / (b.1 - a.1),
            _ => 0.0,
        };
        if measured.is_finite() && measured > 0.0 {
            self.rate = measured;
            self.rate_measured = true;
            self.warnings.push(format!(
                "frame rate {measured:.3} Hz measured from frame numbers and times: \
                 the capture holds no FrameRate answer"
            ));
        } else {
            self.rate = 120.0;
            self.warnings.push(
                "frame rate unknown (no FrameRate answer, too few frames to measure); 120 Hz assumed"
                    .into(),
            );
        }
    }

    /// The next datagram, read ahead or from the file.
    fn next_datagram(&mut self) -> Result<Option<Datagram>> {
        match self.ahead.pop_front() {
            Some(d) => Ok(Some(d)),
            None => self.packets.next_datagram(),
        }
    }

    /// Turns a frame datagram into a [`MarkerFrame`], or None (with a
    /// warning naming the packet) when it does not decode.
    fn frame(&mut self, d: &Datagram, version: Version) -> Option<MarkerFrame> {
        let f: Box<FrameOfData> = match decode(&d.payload, version) {
            Ok(Packet::FrameOfData(f)) => f,
            Ok(_) => return None,
            Err(e) => {
                self.bad_frames += 1;
                if self.bad_frames <= 10 {
                    self.warnings.push(format!("packet {}: {e}", d.packet));
                }
                return None;
            }
        };
        let n = i64::from(f.frame_number);
        let (n0, t0) = *self.first_frame.get_or_insert((n, d.time_s));
        let fallback = if self.rate_measured || self.rate <= 0.0 {
            d.time_s - t0
        } else {
            (n - n0) as f64 / self.rate
        };
        let cx = FrameContext {
            version,
            selection: self.options.markers,
            up: self.up_axis(),
            clock_frequency: self.stream.clock_frequency,
        };
        Some(to_marker_frame(&f, &cx, fallback))
    }
}

impl Recording for PcapRecording {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }

    fn warnings(&self) -> &[String] {
        &self.warnings
    }
}

impl Iterator for PcapRecording {
    type Item = Result<MarkerFrame>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            let d = match self.next_datagram() {
                Ok(Some(d)) => d,
                Ok(None) => return None,
                Err(e) => return Some(Err(e)),
            };
            learn(&mut self.stream, &d);
            let Some(version) = self.stream.version else {
                continue;
            };
            if is_frame_for(&self.stream, &d) {
                if let Some(f) = self.frame(&d, version) {
                    return Some(Ok(f));
                }
            }
        }
    }
}

/// Whether `d` is a frame of the stream being read (and picks the
/// destination from the first one).
fn is_frame_for(s: &Stream, d: &Datagram) -> bool {
    peek_id(&d.payload) == Some(id::FRAMEOFDATA)
        && s.server.is_none_or(|srv| srv.ip() == d.src.ip())
        && s.frames_to.is_none_or(|to| to == d.dst)
}

/// The frame number and time of `d` if it is a decodable frame, for
/// measuring the rate while reading ahead.
fn probe_frame(s: &Stream, d: &Datagram) -> Option<(i64, f64)> {
    let v = s.version?;
    if !is_frame_for(s, d) {
        return None;
    }
    match decode(&d.payload, v) {
        Ok(Packet::FrameOfData(f)) => {
            let t = if v.at_least(2, 6) {
                f.timestamp
            } else {
                d.time_s
            };
            Some((i64::from(f.frame_number), t))
        }
        _ => None,
    }
}

/// Learns what `d` says about the stream: the server, its version and
/// clock, the client's requests and the server's answers, where frames go.
fn learn(s: &mut Stream, d: &Datagram) {
    let from_server = s.server.is_some_and(|srv| srv == d.src);
    match peek_id(&d.payload) {
        Some(id::SERVERINFO) if s.server.is_none() || from_server => {
            // SERVERINFO's layout does not depend on the version.
            if let Ok(Packet::ServerInfo(info)) = decode(&d.payload, Version::new(3, 0)) {
                s.server = Some(d.src);
                s.server_name = info.sender.name.clone();
                s.version = Some(info.sender.natnet());
                s.clock_frequency = info.connection.map_or(0, |c| c.clock_frequency);
                s.client.get_or_insert(d.dst);
            }
        }
        Some(id::FRAMEOFDATA)
            if s.frames_to.is_none() && s.server.is_none_or(|srv| srv.ip() == d.src.ip()) =>
        {
            s.frames_to = Some(d.dst);
            s.server.get_or_insert(d.src);
        }
        Some(id::REQUEST) if Some(d.src) == s.client && Some(d.dst) == s.server => {
            if let Ok(Packet::Request(text)) = decode(&d.payload, Version::new(3, 0)) {
                s.pending.push_back(text);
            }
        }
        Some(id::RESPONSE | id::UNRECOGNIZED_REQUEST) if from_server && Some(d.dst) == s.client => {
            let answer = match decode(&d.payload, Version::new(3, 0)) {
                Ok(Packet::Response(r)) => Some(r),
                _ => None,
            };
            if let Some(asked) = s.pending.pop_front() {
                answered(s, &asked, answer.as_ref());
            }
        }
        _ => {}
    }
}

/// The server answered the client's request `asked` with `r`.
fn answered(s: &mut Stream, asked: &str, r: Option<&Response>) {
    if asked == "FrameRate" {
        s.rate = r
            .and_then(Response::as_f32)
            .map(f64::from)
            .filter(|x| x.is_finite() && *x > 0.0);
    } else if asked.ends_with(",Up Axis") {
        s.up = r.and_then(Response::as_text).and_then(up_axis_from_answer);
    } else if let Some(v) = asked.strip_prefix("Bitstream,").and_then(Version::parse) {
        if r.and_then(Response::as_i32) == Some(0) {
            s.version = Some(v);
        }
    }
}

/// UDP datagrams out of the capture's packets.
struct Packets {
    reader: Box<dyn PcapReaderIterator + Send>,
    path: PathBuf,
    links: Links,
    fragments: Fragments,
    done: bool,
}

/// What the capture's headers say about the packets that follow.
#[derive(Default)]
struct Links {
    /// Link type of a legacy pcap file.
    legacy_link: Option<i32>,
    /// Legacy timestamps in nanoseconds (else microseconds).
    nanos: bool,
    /// The pcapng interfaces of the current section.
    interfaces: Vec<Interface>,
    /// Packets seen (1-based numbers, as Wireshark shows them).
    packet: u64,
    /// The last packet's time (simple packet blocks have none).
    last_time: f64,
}

/// A pcapng interface: its link type and clock.
struct Interface {
    link: i32,
    resolution: u64,
    offset: i64,
}

impl Packets {
    fn new(reader: Box<dyn Read + Send>, path: &std::path::Path) -> Result<Self> {
        let reader = pcap_parser::create_reader(1 << 20, reader).map_err(|e| {
            Error::parse(
                path,
                Location::Offset(0),
                format!("not a pcap or pcapng capture: {e:?}"),
            )
        })?;
        Ok(Packets {
            reader,
            path: path.to_path_buf(),
            links: Links::default(),
            fragments: Fragments::default(),
            done: false,
        })
    }

    fn error(&self, msg: String) -> Error {
        Error::parse(
            &self.path,
            Location::Offset(self.reader.consumed() as u64),
            msg,
        )
    }

    /// The next UDP datagram over IPv4, or None at the end of the file.
    fn next_datagram(&mut self) -> Result<Option<Datagram>> {
        while !self.done {
            let got = match self.reader.next() {
                Ok((offset, block)) => {
                    let link_packet = self.links.block(block);
                    self.reader.consume(offset);
                    link_packet
                }
                Err(PcapError::Eof) => {
                    self.done = true;
                    None
                }
                Err(PcapError::Incomplete(_)) => {
                    if self.reader.reader_exhausted() {
                        // A capture cut short (tcpdump killed): the last
                        // packet is partial; what came before stands.
                        self.done = true;
                    } else if let Err(e) = self.reader.refill() {
                        let msg = format!("cannot read the capture: {e:?}");
                        return Err(self.error(msg));
                    }
                    None
                }
                Err(e) => {
                    let msg = format!("malformed capture block: {e:?}");
                    return Err(self.error(msg));
                }
            };
            if let Some((link, time_s, data)) = got {
                if let Some(d) = self.udp(link, time_s, &data) {
                    return Ok(Some(d));
                }
            }
        }
        Ok(None)
    }

    /// The UDP datagram in a link-layer packet, reassembled if fragmented.
    fn udp(&mut self, link: i32, time_s: f64, data: &[u8]) -> Option<Datagram> {
        let ip = ipv4_payload(link, data)?;
        let whole = self.fragments.add(ip)?;
        let (src, dst, payload) = udp_in_ipv4(&whole)?;
        Some(Datagram {
            time_s,
            packet: self.links.packet,
            src,
            dst,
            payload,
        })
    }
}

impl Links {
    /// A block's packet with its link type and time; headers update state.
    fn block(&mut self, block: PcapBlockOwned<'_>) -> Option<(i32, f64, Vec<u8>)> {
        match block {
            PcapBlockOwned::LegacyHeader(h) => {
                self.legacy_link = Some(h.network.0);
                self.nanos = h.is_nanosecond_precision();
                None
            }
            PcapBlockOwned::Legacy(b) => {
                self.packet += 1;
                let frac = if self.nanos { 1e-9 } else { 1e-6 };
                let t = f64::from(b.ts_sec) + f64::from(b.ts_usec) * frac;
                self.last_time = t;
                Some((self.legacy_link.unwrap_or(1), t, b.data.to_vec()))
            }
            PcapBlockOwned::NG(Block::SectionHeader(_)) => {
                self.interfaces.clear();
                None
            }
            PcapBlockOwned::NG(Block::InterfaceDescription(i)) => {
                self.interfaces.push(Interface {
                    link: i.linktype.0,
                    resolution: i.ts_resolution().unwrap_or(1_000_000),
                    offset: i.ts_offset(),
                });
                None
            }
            PcapBlockOwned::NG(Block::EnhancedPacket(p)) => {
                self.packet += 1;
                let i = self.interfaces.get(p.if_id as usize)?;
                let t = p.decode_ts_f64(i.offset.max(0) as u64, i.resolution.max(1));
                self.last_time = t;
                Some((i.link, t, p.packet_data().to_vec()))
            }
            PcapBlockOwned::NG(Block::SimplePacket(p)) => {
                self.packet += 1;
                let link = self.interfaces.first()?.link;
                Some((link, self.last_time, p.packet_data().to_vec()))
            }
            PcapBlockOwned::NG(_) => None,
        }
    }
}

/// The IPv4 packet inside a link-layer frame (None for anything else).
fn ipv4_payload(link: i32, data: &[u8]) -> Option<&[u8]> {
    let be16 = |at: usize| {
        data.get(at..at + 2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
    };
    let (mut ethertype, mut at) = match link {
        // DLT_NULL / DLT_LOOP: a 4-byte address family (2 = IPv4) in host
        // or network order.
        0 | 108 => {
            let af = data.get(..4)?;
            let v4 = af == [2, 0, 0, 0] || af == [0, 0, 0, 2];
            return v4.then(|| &data[4..]);
        }
        // Ethernet.
        1 => (be16(12)?, 14),
        // Raw IP (LINKTYPE_RAW, DLT_RAW variants, LINKTYPE_IPV4).
        101 | 12 | 14 | 228 => return (data.first()? >> 4 == 4).then_some(data),
        // Linux cooked v1: protocol at 14, payload at 16.
        113 => (be16(14)?, 16),
        // Linux cooked v2: protocol at 0, payload at 20.
        276 => (be16(0)?, 20),
        _ => return None,
    };
    // 802.1Q / 802.1ad tags.
    while ethertype == 0x8100 || ethertype == 0x88a8 {
        ethertype = be16(at + 2)?;
        at += 4;
    }
    (ethertype == 0x0800).then(|| data.get(at..)).flatten()
}

/// Source, destination and payload of a whole IPv4 UDP packet.
fn udp_in_ipv4(ip: &[u8]) -> Option<(SocketAddrV4, SocketAddrV4, Vec<u8>)> {
    let ihl = usize::from(ip.first()? & 0x0f) * 4;
    if ip.get(9) != Some(&17) || ihl < 20 {
        return None;
    }
    let total = usize::from(u16::from_be_bytes([*ip.get(2)?, *ip.get(3)?])).min(ip.len());
    let addr = |at: usize| {
        Some(Ipv4Addr::new(
            *ip.get(at)?,
            ip[at + 1],
            ip[at + 2],
            ip[at + 3],
        ))
    };
    let (src_ip, dst_ip) = (addr(12)?, addr(16)?);
    let udp = ip.get(ihl..total)?;
    let port = |at: usize| Some(u16::from_be_bytes([*udp.get(at)?, *udp.get(at + 1)?]));
    let len = usize::from(port(4)?).clamp(8, udp.len());
    Some((
        SocketAddrV4::new(src_ip, port(0)?),
        SocketAddrV4::new(dst_ip, port(2)?),
        udp.get(8..len)?.to_vec(),
    ))
}

/// IPv4 fragments waiting for the rest of their packet.
#[derive(Default)]
struct Fragments {
    /// (source, destination, id) -> header, pieces (offset, bytes), total
    /// length once the last piece came.
    waiting: HashMap<(u32, u32, u16), Pending>,
    order: VecDeque<(u32, u32, u16)>,
}

#[derive(Default)]
struct Pending {
    header: Vec<u8>,
    pieces: Vec<(usize, Vec<u8>)>,
    total: Option<usize>,
}

/// Reassemblies in flight at most (a lossy capture must not grow memory).
const MAX_REASSEMBLIES: usize = 64;

impl Fragments {
    /// Takes an IPv4 packet; returns a whole one (itself when it was not a
    /// fragment) once complete.
    fn add(&mut self, ip: &[u8]) -> Option<Vec<u8>> {
        let ihl = usize::from(ip.first()? & 0x0f) * 4;
        let flags = u16::from_be_bytes([*ip.get(6)?, *ip.get(7)?]);
        let more = flags & 0x2000 != 0;
        let offset = usize::from(flags & 0x1fff) * 8;
        let total = usize::from(u16::from_be_bytes([*ip.get(2)?, *ip.get(3)?])).min(ip.len());
        let body = ip.get(ihl..total)?;
        if !more && offset == 0 {
            return Some(ip[..total].to_vec());
        }
        let be32 = |at: usize| Some(u32::from_be_bytes(ip.get(at..at + 4)?.try_into().ok()?));
        let key = (be32(12)?, be32(16)?, u16::from_be_bytes([ip[4], ip[5]]));
        if !self.waiting.contains_key(&key) {
            if self.order.len() >= MAX_REASSEMBLIES {
                if let Some(old) = self.order.pop_front() {
                    self.waiting.remove(&old);
                }
            }
            self.order.push_back(key);
        }
        let p = self.waiting.entry(key).or_default();
        if offset == 0 {
            p.header = ip[..ihl].to_vec();
        }
        if !more {
            p.total = Some(offset + body.len());
        }
        p.pieces.push((offset, body.to_vec()));
        let whole = p.assemble()?;
        self.waiting.remove(&key);
        self.order.retain(|k| *k != key);
        Some(whole)
    }
}

impl Pending {
    /// The packet, once the first and last pieces came and nothing is
    /// missing between them.
    fn assemble(&mut self) -> Option<Vec<u8>> {
        let total = self.total?;
        if self.header.is_empty() {
            return None;
        }
        self.pieces.sort_by_key(|p| p.0);
        let mut body = Vec::with_capacity(total);
        for (off, bytes) in &self.pieces {
            if *off > body.len() {
                return None;
            }
            let skip = body.len() - off;
            body.extend_from_slice(bytes.get(skip..).unwrap_or(&[]));
        }
        if body.len() < total {
            return None;
        }
        body.truncate(total);
        let mut ip = self.header.clone();
        let len = u16::try_from(ip.len() + body.len()).ok()?;
        ip[2..4].copy_from_slice(&len.to_be_bytes());
        ip[6..8].copy_from_slice(&[0, 0]);
        ip.extend_from_slice(&body);
        Some(ip)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An IPv4/UDP packet from `src` to `dst` carrying `payload`.
    fn ipv4_udp(src: SocketAddrV4, dst: SocketAddrV4, payload: &[u8]) -> Vec<u8> {
        let total = 20 + 8 + payload.len();
        let mut p = vec![0x45, 0, 0, 0, 0, 7, 0, 0, 64, 17, 0, 0];
        p[2..4].copy_from_slice(&(total as u16).to_be_bytes());
        p.extend_from_slice(&src.ip().octets());
        p.extend_from_slice(&dst.ip().octets());
        p.extend_from_slice(&src.port().to_be_bytes());
        p.extend_from_slice(&dst.port().to_be_bytes());
        p.extend_from_slice(&((8 + payload.len()) as u16).to_be_bytes());
        p.extend_from_slice(&[0, 0]);
        p.extend_from_slice(payload);
        p
    }

    /// Splits an IPv4 packet into fragments of `size` body bytes.
    fn fragment(ip: &[u8], size: usize) -> Vec<Vec<u8>> {
        let body = &ip[20..];
        body.chunks(size)
            .enumerate()
            .map(|(i, c)| {
                let mut f = ip[..20].to_vec();
                f[2..4].copy_from_slice(&((20 + c.len()) as u16).to_be_bytes());
                let more = if (i + 1) * size < body.len() {
                    0x2000
                } else {
                    0
                };
                f[6..8].copy_from_slice(&((more | (i * size / 8)) as u16).to_be_bytes());
                f.extend_from_slice(c);
                f
            })
            .collect()
    }

    #[test]
    fn udp_is_found_under_every_link_layer_and_fragments_are_joined() {
        let a: SocketAddrV4 = "10.0.0.5:1511".parse().unwrap();
        let b: SocketAddrV4 = "239.255.42.99:1511".parse().unwrap();
        let payload: Vec<u8> = (0..3000u32).map(|i| i as u8).collect();
        let ip = ipv4_udp(a, b, &payload);
        let mut eth = vec![0u8; 12];
        eth.extend_from_slice(&[0x81, 0x00, 0, 5, 0x08, 0x00]);
        eth.extend_from_slice(&ip);
        let mut sll2 = vec![0x08, 0x00];
        sll2.extend_from_slice(&[0u8; 18]);
        sll2.extend_from_slice(&ip);
        let mut null = vec![2, 0, 0, 0];
        null.extend_from_slice(&ip);
        for (link, frame) in [(1, &eth), (276, &sll2), (0, &null), (101, &ip)] {
            let got = ipv4_payload(link, frame).unwrap();
            let (s, d, p) = udp_in_ipv4(got).unwrap();
            assert_eq!((s, d, p.len()), (a, b, 3000), "link type {link}");
        }
        // Out of order fragments come back whole, once.
        let mut parts = fragment(&ip, 1480);
        parts.swap(0, 2);
        let mut f = Fragments::default();
        let got: Vec<Vec<u8>> = parts.iter().filter_map(|p| f.add(p)).collect();
        assert_eq!(got.len(), 1);
        assert_eq!(udp_in_ipv4(&got[0]).unwrap().2, payload);
        // A lost fragment never completes, and is forgotten in time.
        let parts = fragment(&ip, 1480);
        for k in 0..(MAX_REASSEMBLIES as u16 + 5) {
            let mut p = parts[0].clone();
            p[4..6].copy_from_slice(&k.to_be_bytes());
            assert!(f.add(&p).is_none());
        }
        assert_eq!(f.waiting.len(), MAX_REASSEMBLIES);
        assert!(looks_like_pcap(&[0xd4, 0xc3, 0xb2, 0xa1, 2, 0]));
        assert!(!looks_like_pcap(b"Format Version"));
    }
}
