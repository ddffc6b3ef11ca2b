//! OSC packets to `MarkerFrame`s: the pure half of the OSC source (no
//! sockets, no clock; the receive time is an argument).
//!
//! There is no OSC standard for motion capture (`shared/spec/osc.md`), so
//! this accepts what the NatNet→OSC bridges in the wild send, plus our own
//! message:
//!
//! | address | arguments | sent by |
//! |---|---|---|
//! | `/marker` | `i x y z` (index, position) | hku-ect NatNet2OSCbridge, one bundle per tick |
//! | `/marker` | `i "position" x y z` (NatNet id) | NatNetThree2OSC / NatNetFour2OSC `max` mode |
//! | `/marker/<id>/position` | `x y z` | the same bridges in `isadora` / `touch` mode |
//! | `/frame/start`, `/frame/end` | `i` frame number | the same bridges, bracketing a frame |
//! | `/frame/timestamp` | `i` (or `h f d`) milliseconds | the same bridges |
//! | `/treemocap/markers` | `i`/`h` frame, `f`/`d` time (s), then `x y z` per marker (`f` or `d`) | ours |
//! | `/othermarker…` | as `/marker…` | the bridges' legacy other-marker list; only with `othermarkers` on |
//!
//! A **frame** is one OSC bundle (everything in it, nested bundles
//! flattened; a bundle without markers is a frame with none in sight), or
//! the messages between `/frame/start n` and `/frame/end n` when they arrive
//! unbundled, or one `/treemocap/markers` message (its own frame even inside
//! a bundle; a bundle holding only those makes no other).
//! Bundle time tags are ignored: the bridges that set them put milliseconds
//! there, not NTP time. Frame time is the sender's `/frame/timestamp` or
//! `/treemocap/markers` time when there is one, otherwise the receive time
//! (the bridges' timestamp is milliseconds since Motive started, modulo 24 h,
//! so it jumps back once a day).
//! Frames without a sender frame number (the hku bridge) are numbered on from
//! the last frame. Other addresses (rigid bodies, skeletons, `/frame/timecode`)
//! are ignored and counted, not errors.
//!
//! Numbers: coordinates must be `f` or `d` and finite, ids and frame numbers
//! `i` or `h`; anything else is a [`Problem`] naming the address and the
//! argument, and only that message is skipped.

use glam::DVec3;
use rosc::{OscMessage, OscPacket, OscType};

use crate::model::frame::{Marker, MarkerFrame, UpAxis};

/// Bundles nested deeper than this, and arrays (`[` … `]` in the type tags)
/// nested deeper than this, are refused before rosc parses them. rosc
/// recurses once per bundle level, and builds nested arrays whose drop
/// recurses once per level: a 64 KiB datagram goes ~3000 bundles or ~30 000
/// arrays deep, which overflows a 2 MiB task stack and aborts the process.
/// No sender in the wild nests at all beyond a bundle of bundles.
pub const MAX_DEPTH: usize = 8;

/// Largest datagram decoded: the most a UDP datagram over IPv4 can carry.
/// A receive that fills a larger buffer was cut by the kernel and is refused.
pub const MAX_DATAGRAM_BYTES: usize = 65_507;

/// The edge conversions of the OSC source: incoming positions to metres, Y up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodeOptions {
    /// Multiplier from the sender's length unit to metres (1 for m, 0.001 for mm).
    pub scale: f64,
    /// The sender's up axis: Z up (a bridge's `--yup2zup`, Blender, Unreal)
    /// is turned to Y up, the inverse of the bridges' `--yup2zup`.
    pub up_axis: UpAxis,
    /// Also take `/othermarker` messages. Off by default: NatNet 3+ lists
    /// unlabeled markers under `/marker` as well, so a bridge sending both
    /// would double every marker.
    pub othermarkers: bool,
}

impl Default for DecodeOptions {
    fn default() -> Self {
        DecodeOptions {
            scale: 1.0,
            up_axis: UpAxis::Y,
            othermarkers: false,
        }
    }
}

/// What was wrong with an input, by counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ProblemKind {
    /// The datagram is not OSC at all (or is truncated, or nests too deep).
    Garbage,
    /// An address we use with wrong type tags, too few arguments or a
    /// non-finite coordinate: the message is skipped.
    BadArgs,
    /// A `/frame/start` … `/frame/end` bracket that did not close properly
    /// (a lost datagram): the frame is still delivered when it has markers.
    BrokenFrame,
}

impl ProblemKind {
    /// The counter's name in reports.
    pub fn name(self) -> &'static str {
        match self {
            ProblemKind::Garbage => "garbage",
            ProblemKind::BadArgs => "bad_args",
            ProblemKind::BrokenFrame => "broken_frame",
        }
    }
}

/// One rejected input, phrased for the log.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// Which counter it goes to (garbage, bad arguments, broken frame).
    pub kind: ProblemKind,
    /// The OSC address concerned (empty for garbage).
    pub address: String,
    /// What is wrong, naming the argument (`argument 2 (x): expected float, got string`).
    pub msg: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.address.is_empty() {
            write!(f, "{}", self.msg)
        } else {
            write!(f, "{}: {}", self.address, self.msg)
        }
    }
}

/// What one call of the assembler produced.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Output {
    /// Finished frames, in order of completion.
    pub frames: Vec<MarkerFrame>,
    /// Input rejected on the way; each one skips only its own message.
    pub problems: Vec<Problem>,
    /// Well-formed messages at addresses we do not use (rigid bodies, …).
    pub ignored: u64,
    /// Of those, `/othermarker…` messages (taken only with `othermarkers`
    /// on), so the source can tell a user who forgot to turn it on.
    pub ignored_othermarkers: u64,
}

/// A frame being collected (an open bracket or a bundle).
#[derive(Debug, Default)]
struct Partial {
    /// From `/frame/start` (or `/frame/end` when the start was lost).
    number: Option<i64>,
    /// From `/frame/timestamp`, seconds.
    time_s: Option<f64>,
    /// Receive time of the first datagram of the frame.
    received_s: f64,
    markers: Vec<Marker>,
    /// Saw anything that belongs to a marker frame.
    content: bool,
}

/// Turns OSC packets into frames. Stateful only for unbundled
/// `/frame/start` … `/frame/end` brackets, which span datagrams.
#[derive(Debug)]
pub struct Assembler {
    opts: DecodeOptions,
    /// The unbundled bracket currently open.
    open: Option<Partial>,
    /// Number for the next frame that brings none.
    next_number: i64,
}

impl Assembler {
    /// An assembler with no frame open, converting positions by `opts`.
    pub fn new(opts: DecodeOptions) -> Self {
        Assembler {
            opts,
            open: None,
            next_number: 0,
        }
    }

    /// Decodes one UDP datagram received at `now_s` and adds what it completes to `out`.
    pub fn datagram(&mut self, bytes: &[u8], now_s: f64, out: &mut Output) {
        match parse_datagram(bytes) {
            Ok(packet) => self.packet(&packet, now_s, out),
            Err(msg) => out.problems.push(Problem {
                kind: ProblemKind::Garbage,
                address: String::new(),
                msg,
            }),
        }
    }

    /// Takes one decoded OSC packet received at `now_s`.
    pub fn packet(&mut self, packet: &OscPacket, now_s: f64, out: &mut Output) {
        match packet {
            OscPacket::Message(m) => {
                if m.addr == "/treemocap/markers" {
                    // Self-contained, whatever else is going on.
                    self.treemocap_markers(m, out);
                    return;
                }
                if self.open.is_none()
                    && !is_frame_message(&m.addr)
                    && !self.is_marker_address(&m.addr)
                {
                    self.ignore(&m.addr, out);
                    return;
                }
                // A marker outside any bracket is one whose /frame/start was
                // lost: it opens the frame and /frame/end will name it.
                let mut open = self.open.take().unwrap_or_else(|| Partial {
                    received_s: now_s,
                    ..Partial::default()
                });
                let done = self.message(m, &mut open, true, now_s, out);
                if done {
                    self.emit(open, out);
                } else if open.content {
                    self.open = Some(open);
                }
            }
            OscPacket::Bundle(_) => {
                let mut frame = Partial {
                    received_s: now_s,
                    ..Partial::default()
                };
                let mut census = Census::default();
                self.bundle(packet, &mut frame, &mut census, now_s, out);
                // Every bundle is a frame (one with only rigid bodies, or
                // none at all, is a bridge tick with no marker in sight),
                // except one that only carried our self-contained messages.
                if census.others > 0 || census.own == 0 {
                    self.emit(frame, out);
                }
            }
        }
    }

    /// Delivers a bracket left open (at shutdown), counted as broken.
    pub fn finish(&mut self, out: &mut Output) {
        if let Some(open) = self.open.take() {
            out.problems.push(Problem {
                kind: ProblemKind::BrokenFrame,
                address: "/frame/end".into(),
                msg: "source stopped inside a frame; delivering what arrived".into(),
            });
            self.emit(open, out);
        }
    }

    fn bundle(
        &mut self,
        packet: &OscPacket,
        frame: &mut Partial,
        census: &mut Census,
        now_s: f64,
        out: &mut Output,
    ) {
        match packet {
            OscPacket::Bundle(b) => {
                for p in &b.content {
                    self.bundle(p, frame, census, now_s, out);
                }
            }
            OscPacket::Message(m) => {
                if m.addr == "/treemocap/markers" {
                    census.own += 1;
                    self.treemocap_markers(m, out);
                } else {
                    census.others += 1;
                    // A /frame/end inside a bundle ends nothing: the bundle does.
                    self.message(m, frame, false, now_s, out);
                }
            }
        }
    }

    fn ignore(&self, addr: &str, out: &mut Output) {
        out.ignored += 1;
        if addr.starts_with("/othermarker") {
            out.ignored_othermarkers += 1;
        }
    }

    fn is_marker_address(&self, addr: &str) -> bool {
        marker_kind(addr, self.opts.othermarkers).is_some()
    }

    /// Applies one message to `frame`; true when it closes an unbundled bracket.
    fn message(
        &mut self,
        m: &OscMessage,
        frame: &mut Partial,
        unbundled: bool,
        now_s: f64,
        out: &mut Output,
    ) -> bool {
        let result = match m.addr.as_str() {
            "/frame/start" => int_arg(&m.args, 0, "frame number")
                .map(|n| self.frame_start(n, frame, unbundled, now_s, out)),
            "/frame/end" => {
                int_arg(&m.args, 0, "frame number").map(|n| frame_end(n, frame, unbundled, out))
            }
            "/frame/timestamp" => number_arg(&m.args, 0, "timestamp (ms)").map(|ms| {
                frame.time_s = Some(ms / 1000.0);
                false
            }),
            addr => match marker_kind(addr, self.opts.othermarkers) {
                None => {
                    self.ignore(addr, out);
                    Ok(false)
                }
                Some(kind) => self.marker(m, kind).map(|marker| {
                    frame.markers.push(marker);
                    frame.content = true;
                    false
                }),
            },
        };
        result.unwrap_or_else(|msg| {
            out.problems.push(Problem {
                kind: ProblemKind::BadArgs,
                address: m.addr.clone(),
                msg,
            });
            false
        })
    }

    /// `/frame/start n`: opens frame `n`. An unbundled frame still open
    /// lost its `/frame/end`: it is delivered first, with a problem.
    fn frame_start(
        &mut self,
        n: i64,
        frame: &mut Partial,
        unbundled: bool,
        now_s: f64,
        out: &mut Output,
    ) -> bool {
        if frame.content && unbundled {
            out.problems.push(Problem {
                kind: ProblemKind::BrokenFrame,
                address: "/frame/start".into(),
                msg: format!(
                    "frame {n} started before {} ended (its /frame/end was lost)",
                    describe_number(frame.number)
                ),
            });
            let prev = std::mem::replace(
                frame,
                Partial {
                    received_s: now_s,
                    ..Partial::default()
                },
            );
            self.emit(prev, out);
        }
        frame.number = Some(n);
        frame.content = true;
        false
    }

    fn marker(&self, m: &OscMessage, kind: MarkerAddress) -> Result<Marker, String> {
        let (id, first) = match kind {
            MarkerAddress::Path(id) => (id, 0),
            MarkerAddress::Plain => {
                let id = int_arg(&m.args, 0, "marker id")?;
                match m.args.get(1) {
                    // `max` mode: id "position" x y z.
                    Some(OscType::String(s)) if s == "position" => (id, 2),
                    Some(OscType::String(s)) => {
                        return Err(format!(
                        "argument 2: expected \"position\" or the x coordinate, got string \"{}\"",
                        clip(s)
                    ))
                    }
                    _ => (id, 1),
                }
            }
        };
        let p = self.position(&m.args, first)?;
        if m.args.len() > first + 3 {
            return Err(format!(
                "{} arguments, expected {}",
                m.args.len(),
                first + 3
            ));
        }
        Ok(Marker {
            position: p,
            id: Some(id),
        })
    }

    fn position(&self, args: &[OscType], first: usize) -> Result<DVec3, String> {
        let x = coord_arg(args, first, "x")?;
        let y = coord_arg(args, first + 1, "y")?;
        let z = coord_arg(args, first + 2, "z")?;
        Ok(self.convert(x, y, z))
    }

    fn convert(&self, x: f64, y: f64, z: f64) -> DVec3 {
        self.opts.up_axis.to_y_up(DVec3::new(x, y, z)) * self.opts.scale
    }

    fn treemocap_markers(&mut self, m: &OscMessage, out: &mut Output) {
        let parsed = (|| {
            let frame = int_arg(&m.args, 0, "frame")?;
            let time_s = coord_arg(&m.args, 1, "time (s)")?;
            let coords = m.args.len().saturating_sub(2);
            if !coords.is_multiple_of(3) {
                return Err(format!(
                    "{coords} coordinates after frame and time; expected x y z per marker (a multiple of 3)"
                ));
            }
            let mut markers = Vec::with_capacity(coords / 3);
            let mut i = 2;
            while i + 2 < m.args.len() {
                markers.push(Marker::new(self.position(&m.args, i)?));
                i += 3;
            }
            Ok(MarkerFrame::new(frame, time_s, markers))
        })();
        match parsed {
            Ok(frame) => {
                self.next_number = frame.frame.saturating_add(1);
                out.frames.push(frame);
            }
            Err(msg) => out.problems.push(Problem {
                kind: ProblemKind::BadArgs,
                address: m.addr.clone(),
                msg,
            }),
        }
    }

    fn emit(&mut self, p: Partial, out: &mut Output) {
        let number = p.number.unwrap_or(self.next_number);
        self.next_number = number.saturating_add(1);
        let time_s = p.time_s.unwrap_or(p.received_s);
        out.frames.push(MarkerFrame::new(number, time_s, p.markers));
    }
}

/// The messages of one bundle, by whether they are self-contained frames.
#[derive(Debug, Default)]
struct Census {
    /// `/treemocap/markers` messages (each its own frame).
    own: usize,
    /// Everything else.
    others: usize,
}

/// `/frame/end n`: closes frame `n`; true when an unbundled bracket is
/// complete. A number other than the start's keeps the start's; an end
/// without a start delivers the markers seen (or, unbundled and without
/// markers, nothing).
fn frame_end(n: i64, frame: &mut Partial, unbundled: bool, out: &mut Output) -> bool {
    match frame.number {
        Some(s) if s != n => out.problems.push(Problem {
            kind: ProblemKind::BrokenFrame,
            address: "/frame/end".into(),
            msg: format!("frame {n} ended but frame {s} was started; keeping {s}"),
        }),
        Some(_) => {}
        None if frame.markers.is_empty() => {
            out.problems.push(Problem {
                kind: ProblemKind::BrokenFrame,
                address: "/frame/end".into(),
                msg: format!("frame {n} ended but was never started"),
            });
            if unbundled {
                frame.content = false;
                return false;
            }
            frame.number = Some(n);
        }
        None => {
            if unbundled {
                out.problems.push(Problem {
                    kind: ProblemKind::BrokenFrame,
                    address: "/frame/start".into(),
                    msg: format!("frame {n}: /frame/start was lost; delivering its markers"),
                });
            }
            frame.number = Some(n);
        }
    }
    frame.content = true;
    unbundled
}

/// The addresses that only make sense inside a frame bracket.
fn is_frame_message(addr: &str) -> bool {
    matches!(addr, "/frame/start" | "/frame/end" | "/frame/timestamp")
}

#[derive(Debug, Clone, Copy)]
enum MarkerAddress {
    /// `/marker` with the id as the first argument.
    Plain,
    /// `/marker/<id>/position` with the id in the address.
    Path(i64),
}

fn marker_kind(addr: &str, othermarkers: bool) -> Option<MarkerAddress> {
    let rest = addr.strip_prefix("/marker").or_else(|| {
        othermarkers
            .then(|| addr.strip_prefix("/othermarker"))
            .flatten()
    })?;
    if rest.is_empty() {
        return Some(MarkerAddress::Plain);
    }
    let id = rest.strip_prefix('/')?.strip_suffix("/position")?;
    id.parse().ok().map(MarkerAddress::Path)
}

fn describe_number(n: Option<i64>) -> String {
    n.map_or_else(
        || "the previous frame".to_string(),
        |n| format!("frame {n}"),
    )
}

fn type_name(a: &OscType) -> &'static str {
    match a {
        OscType::Int(_) => "int32",
        OscType::Float(_) => "float32",
        OscType::String(_) => "string",
        OscType::Blob(_) => "blob",
        OscType::Time(_) => "timetag",
        OscType::Long(_) => "int64",
        OscType::Double(_) => "float64",
        OscType::Char(_) => "char",
        OscType::Color(_) => "color",
        OscType::Midi(_) => "midi",
        OscType::Bool(_) => "bool",
        OscType::Array(_) => "array",
        OscType::Nil => "nil",
        OscType::Inf => "infinitum",
    }
}

fn missing(args: &[OscType], i: usize, name: &str) -> String {
    format!(
        "argument {} ({name}) is missing: the message has {} argument{}",
        i + 1,
        args.len(),
        if args.len() == 1 { "" } else { "s" }
    )
}

/// An `i` or `h` argument.
fn int_arg(args: &[OscType], i: usize, name: &str) -> Result<i64, String> {
    match args.get(i) {
        Some(OscType::Int(v)) => Ok(i64::from(*v)),
        Some(OscType::Long(v)) => Ok(*v),
        Some(a) => Err(format!(
            "argument {} ({name}): expected int32 or int64, got {}",
            i + 1,
            type_name(a)
        )),
        None => Err(missing(args, i, name)),
    }
}

/// A finite `f` or `d` argument.
fn coord_arg(args: &[OscType], i: usize, name: &str) -> Result<f64, String> {
    let v = match args.get(i) {
        Some(OscType::Float(v)) => f64::from(*v),
        Some(OscType::Double(v)) => *v,
        Some(a) => {
            return Err(format!(
                "argument {} ({name}): expected float32 or float64, got {}",
                i + 1,
                type_name(a)
            ))
        }
        None => return Err(missing(args, i, name)),
    };
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("argument {} ({name}) is {v}", i + 1))
    }
}

/// Any finite number (timestamps come as int or float depending on the bridge).
fn number_arg(args: &[OscType], i: usize, name: &str) -> Result<f64, String> {
    match args.get(i) {
        Some(OscType::Int(v)) => Ok(f64::from(*v)),
        // Milliseconds in an i64 stay exact in f64 for 285 000 years.
        Some(OscType::Long(v)) => Ok(*v as f64),
        _ => coord_arg(args, i, name),
    }
}

fn clip(s: &str) -> String {
    let mut c: String = s.chars().take(32).collect();
    if c.len() < s.len() {
        c.push('…');
    }
    c.chars()
        .map(|c| if c.is_control() { '?' } else { c })
        .collect()
}

/// Decodes a datagram with rosc, refusing what rosc would accept only in part
/// (trailing bytes, a bundle element it stopped at) or could not parse safely
/// (nested deeper than [`MAX_DEPTH`], longer than [`MAX_DATAGRAM_BYTES`]).
/// Every OSC socket of treemocap decodes through this one function.
pub fn parse_datagram(bytes: &[u8]) -> Result<OscPacket, String> {
    if bytes.is_empty() {
        return Err("empty datagram".into());
    }
    if bytes.len() > MAX_DATAGRAM_BYTES {
        return Err(format!(
            "datagram of {} bytes or more is longer than UDP allows ({MAX_DATAGRAM_BYTES}); refused",
            bytes.len()
        ));
    }
    check_nesting(bytes, 0)?;
    match rosc::decoder::decode_udp(bytes) {
        Ok(([], packet)) => Ok(packet),
        Ok((rest, _)) => Err(format!(
            "not OSC: {} bytes at byte {} are not part of a message or bundle element",
            rest.len(),
            bytes.len() - rest.len()
        )),
        Err(e) => Err(format!(
            "not OSC ({} bytes starting \"{}\"): {e}",
            bytes.len(),
            preview(bytes)
        )),
    }
}

/// The first bytes of a datagram, printable ASCII kept and the rest escaped.
fn preview(bytes: &[u8]) -> String {
    let head = bytes.get(..16).unwrap_or(bytes);
    let mut s: String = head.escape_ascii().to_string();
    if head.len() < bytes.len() {
        s.push('…');
    }
    s
}

/// Walks the bundle structure (`#bundle\0`, 8-byte time tag, then
/// size-prefixed elements) without recursing deeper than [`MAX_DEPTH`], and
/// checks the array nesting of every message in it.
fn check_nesting(bytes: &[u8], depth: usize) -> Result<(), String> {
    const TAG: &[u8] = b"#bundle\0";
    if !bytes.starts_with(TAG) {
        return check_arrays(bytes);
    }
    if depth >= MAX_DEPTH {
        return Err(format!(
            "OSC bundles nested more than {MAX_DEPTH} deep; refused"
        ));
    }
    let mut at = 16usize;
    while let Some(size) = bytes.get(at..at + 4) {
        let size = u32::from_be_bytes([size[0], size[1], size[2], size[3]]) as usize;
        let start = at + 4;
        let Some(element) = start
            .checked_add(size)
            .and_then(|end| bytes.get(start..end))
        else {
            // Truncated: rosc reports it.
            return Ok(());
        };
        check_nesting(element, depth + 1)?;
        at = start + size;
    }
    Ok(())
}

/// Refuses a message whose type tags nest arrays deeper than [`MAX_DEPTH`].
/// A message is its address (NUL-terminated, padded to 4 bytes), then its
/// type tags (`,` then one character per argument); anything malformed is
/// left for rosc to report.
fn check_arrays(message: &[u8]) -> Result<(), String> {
    let Some(nul) = message.iter().position(|&b| b == 0) else {
        return Ok(());
    };
    let Some(tags) = message.get((nul + 4) & !3..) else {
        return Ok(());
    };
    let tags = &tags[..tags.iter().position(|&b| b == 0).unwrap_or(tags.len())];
    let mut depth = 0usize;
    for &t in tags {
        match t {
            b'[' => {
                depth += 1;
                if depth > MAX_DEPTH {
                    return Err(format!(
                        "OSC arrays nested more than {MAX_DEPTH} deep in the type tags of \"{}\"; refused",
                        crate::error::excerpt_bytes(&message[..nul])
                    ));
                }
            }
            b']' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rosc::{encoder, OscBundle, OscTime};

    fn msg(addr: &str, args: Vec<OscType>) -> OscPacket {
        OscPacket::Message(OscMessage {
            addr: addr.into(),
            args,
        })
    }

    fn bundle(content: Vec<OscPacket>) -> OscPacket {
        OscPacket::Bundle(OscBundle {
            timetag: OscTime {
                seconds: 0,
                fractional: 1,
            },
            content,
        })
    }

    fn feed(a: &mut Assembler, p: &OscPacket, now: f64) -> Output {
        let bytes = encoder::encode(p).unwrap();
        let mut out = Output::default();
        a.datagram(&bytes, now, &mut out);
        out
    }

    use OscType::{Float as F, Int as I};

    fn s(v: &str) -> OscType {
        OscType::String(v.into())
    }

    #[test]
    fn hku_bundle_is_one_frame_numbered_on() {
        let mut a = Assembler::new(DecodeOptions::default());
        let b = bundle(vec![
            msg("/marker", vec![I(0), F(0.5), F(1.25), F(-2.0)]),
            msg(
                "/rigidBody",
                vec![
                    I(1),
                    s("rb"),
                    F(0.),
                    F(0.),
                    F(0.),
                    F(0.),
                    F(0.),
                    F(0.),
                    F(1.),
                    I(1),
                ],
            ),
            msg("/marker", vec![I(1), F(1.0), F(2.0), F(3.0)]),
        ]);
        let out = feed(&mut a, &b, 0.25);
        assert_eq!(out.problems, vec![]);
        assert_eq!(out.ignored, 1);
        assert_eq!(out.frames.len(), 1);
        let f = &out.frames[0];
        assert_eq!((f.frame, f.time_s), (0, 0.25));
        assert_eq!(f.markers[0].position, DVec3::new(0.5, 1.25, -2.0));
        assert_eq!(f.markers[0].id, Some(0));
        assert_eq!(f.markers[1].position, DVec3::new(1.0, 2.0, 3.0));
        let out = feed(&mut a, &bundle(vec![]), 0.5);
        assert_eq!(out.frames[0].frame, 1, "next bundle is the next frame");
        assert!(
            out.frames[0].markers.is_empty(),
            "an empty bundle is an empty frame"
        );
        let out = feed(&mut a, &bundle(vec![msg("/rigidBody", vec![I(1)])]), 0.75);
        assert_eq!(
            out.frames.len(),
            1,
            "a tick with only rigid bodies has no markers"
        );
        assert!(out.frames[0].markers.is_empty());
    }

    #[test]
    fn unbundled_bracket_spans_datagrams() {
        let mut a = Assembler::new(DecodeOptions::default());
        let mut frames = Vec::new();
        let seq = [
            msg("/frame/start", vec![I(1200)]),
            msg("/frame/timestamp", vec![I(10_000)]),
            msg("/frame/timecode", vec![OscType::Long(1), OscType::Long(0)]),
            msg(
                "/marker",
                vec![I(65537), s("position"), F(0.25), F(1.5), F(0.0)],
            ),
            msg("/marker/7/position", vec![F(1.0), F(2.0), F(4.0)]),
            msg("/rigidbody", vec![I(1), s("tracked"), I(1)]),
        ];
        for p in &seq {
            let out = feed(&mut a, p, 3.0);
            assert!(out.frames.is_empty() && out.problems.is_empty(), "{out:?}");
        }
        let out = feed(&mut a, &msg("/frame/end", vec![I(1200)]), 3.1);
        frames.extend(out.frames);
        assert_eq!(frames.len(), 1);
        let f = &frames[0];
        assert_eq!(f.frame, 1200);
        assert_eq!(f.time_s, 10.0, "time is the sender's timestamp in ms");
        assert_eq!(f.markers.len(), 2);
        assert_eq!(f.markers[0].id, Some(65537));
        assert_eq!(f.markers[0].position, DVec3::new(0.25, 1.5, 0.0));
        assert_eq!(f.markers[1].id, Some(7));
        assert_eq!(f.markers[1].position, DVec3::new(1.0, 2.0, 4.0));
    }

    #[test]
    fn bundled_bracket_and_treemocap_message() {
        let mut a = Assembler::new(DecodeOptions::default());
        let b = bundle(vec![
            msg("/frame/start", vec![I(5)]),
            msg("/marker", vec![I(3), s("position"), F(1.0), F(2.0), F(3.0)]),
            msg("/frame/end", vec![I(5)]),
        ]);
        let out = feed(&mut a, &b, 1.0);
        assert_eq!(out.frames.len(), 1);
        assert_eq!((out.frames[0].frame, out.frames[0].time_s), (5, 1.0));

        let m = msg(
            "/treemocap/markers",
            vec![
                OscType::Long(42),
                OscType::Double(0.35),
                F(1.0),
                F(2.0),
                F(3.0),
                OscType::Double(-0.1),
                OscType::Double(0.2),
                OscType::Double(0.3),
            ],
        );
        let out = feed(&mut a, &m, 9.0);
        assert_eq!(out.problems, vec![]);
        let f = &out.frames[0];
        assert_eq!((f.frame, f.time_s), (42, 0.35));
        assert_eq!(
            f.positions().collect::<Vec<_>>(),
            vec![DVec3::new(1.0, 2.0, 3.0), DVec3::new(-0.1, 0.2, 0.3)]
        );
        assert_eq!(f.markers[0].id, None);
        // Inside a bundle it is still its own frame, and the bundle adds none.
        let out = feed(&mut a, &bundle(vec![m.clone()]), 9.5);
        assert_eq!(out.frames.len(), 1);
        // Frames without numbers continue after the last one.
        let out = feed(
            &mut a,
            &bundle(vec![msg("/marker", vec![I(0), F(0.), F(0.), F(0.)])]),
            10.0,
        );
        assert_eq!(out.frames[0].frame, 43);
    }

    #[test]
    fn z_up_and_millimetres_convert_to_metres_y_up() {
        let mut a = Assembler::new(DecodeOptions {
            scale: 0.001,
            up_axis: UpAxis::Z,
            othermarkers: false,
        });
        // Z up (x right, y forward, z up): a point 2 m up and 1 m forward.
        let out = feed(
            &mut a,
            &bundle(vec![msg(
                "/marker",
                vec![I(0), F(500.0), F(1000.0), F(2000.0)],
            )]),
            0.0,
        );
        // Y up: up is +y, and forward (+y in Z up) becomes −z.
        assert_eq!(
            out.frames[0].markers[0].position,
            DVec3::new(0.5, 2.0, -1.0)
        );
    }

    #[test]
    fn othermarkers_only_when_asked() {
        let m = bundle(vec![
            msg(
                "/othermarker",
                vec![I(3), s("position"), F(1.0), F(2.0), F(3.0)],
            ),
            msg("/othermarker/4/position", vec![F(1.0), F(2.0), F(3.0)]),
        ]);
        let mut a = Assembler::new(DecodeOptions::default());
        let out = feed(&mut a, &m, 0.0);
        assert!(out.frames[0].markers.is_empty());
        assert_eq!((out.ignored, out.ignored_othermarkers), (2, 2));
        let mut a = Assembler::new(DecodeOptions {
            othermarkers: true,
            ..DecodeOptions::default()
        });
        let out = feed(&mut a, &m, 0.0);
        assert_eq!(out.frames[0].markers.len(), 2);
    }

    #[test]
    fn wrong_type_tags_name_the_argument_and_skip_only_that_message() {
        let mut a = Assembler::new(DecodeOptions::default());
        let b = bundle(vec![
            msg("/marker", vec![s("seven"), F(1.0), F(2.0), F(3.0)]),
            msg("/marker", vec![I(1), F(1.0), I(2), F(3.0)]),
            msg("/marker", vec![I(2), F(1.0), F(2.0)]),
            msg("/marker", vec![I(3), s("quat"), F(1.0), F(2.0), F(3.0)]),
            msg("/marker", vec![I(4), F(f32::NAN), F(2.0), F(3.0)]),
            msg("/marker", vec![I(5), F(1.0), F(2.0), F(3.0), F(4.0)]),
            msg("/marker", vec![I(6), F(1.0), F(2.0), F(3.0)]),
        ]);
        let out = feed(&mut a, &b, 0.0);
        let msgs: Vec<String> = out.problems.iter().map(|p| p.to_string()).collect();
        assert_eq!(msgs.len(), 6, "{msgs:#?}");
        assert!(out.problems.iter().all(|p| p.kind == ProblemKind::BadArgs));
        assert!(
            msgs[0].contains("argument 1 (marker id): expected int32 or int64, got string"),
            "{}",
            msgs[0]
        );
        assert!(
            msgs[1].contains("argument 3 (y): expected float32 or float64, got int32"),
            "{}",
            msgs[1]
        );
        assert!(msgs[2].contains("argument 4 (z) is missing"), "{}", msgs[2]);
        assert!(msgs[3].contains("\"quat\""), "{}", msgs[3]);
        assert!(msgs[4].contains("argument 2 (x) is NaN"), "{}", msgs[4]);
        assert!(msgs[5].contains("5 arguments, expected 4"), "{}", msgs[5]);
        assert_eq!(out.frames[0].markers.len(), 1);
        assert_eq!(out.frames[0].markers[0].id, Some(6));

        let out = feed(
            &mut a,
            &msg("/treemocap/markers", vec![I(1), F(0.0), F(1.0), F(2.0)]),
            0.0,
        );
        assert!(out.frames.is_empty());
        assert!(
            out.problems[0].msg.contains("multiple of 3"),
            "{:?}",
            out.problems
        );
        let out = feed(&mut a, &msg("/frame/start", vec![F(1.0)]), 0.0);
        assert!(out.problems[0]
            .to_string()
            .starts_with("/frame/start: argument 1 (frame number)"));
    }

    #[test]
    fn lost_datagrams_in_brackets_keep_what_arrived() {
        let mut a = Assembler::new(DecodeOptions::default());
        let mk = |id| {
            msg(
                "/marker",
                vec![I(id), s("position"), F(1.0), F(2.0), F(3.0)],
            )
        };
        // /frame/end of frame 1 lost: frame 1 is delivered when frame 2 starts.
        for p in [
            msg("/frame/start", vec![I(1)]),
            mk(1),
            msg("/frame/start", vec![I(2)]),
            mk(2),
        ] {
            let out = feed(&mut a, &p, 0.0);
            if p == msg("/frame/start", vec![I(2)]) {
                assert_eq!(out.frames.len(), 1);
                assert_eq!(out.frames[0].frame, 1);
                assert_eq!(out.problems[0].kind, ProblemKind::BrokenFrame);
            }
        }
        let out = feed(&mut a, &msg("/frame/end", vec![I(2)]), 0.0);
        assert_eq!(out.frames[0].frame, 2);
        assert_eq!(out.frames[0].markers.len(), 1);
        // /frame/start of frame 3 lost: the markers wait for /frame/end 3.
        let out = feed(&mut a, &mk(3), 0.0);
        assert!(out.frames.is_empty());
        let out = feed(&mut a, &msg("/frame/end", vec![I(3)]), 0.0);
        assert_eq!(out.frames[0].frame, 3);
        assert_eq!(out.frames[0].markers[0].id, Some(3));
        assert_eq!(out.problems[0].kind, ProblemKind::BrokenFrame);
        // A stray /frame/end is counted and opens nothing.
        let out = feed(&mut a, &msg("/frame/end", vec![I(4)]), 0.0);
        assert!(out.frames.is_empty());
        assert_eq!(out.problems.len(), 1);
        // A bracket still open at shutdown is delivered.
        feed(&mut a, &msg("/frame/start", vec![I(5)]), 0.0);
        feed(&mut a, &mk(5), 0.0);
        let mut out = Output::default();
        a.finish(&mut out);
        assert_eq!(out.frames[0].frame, 5);
    }

    #[test]
    fn garbage_is_refused_with_a_reason() {
        let mut a = Assembler::new(DecodeOptions::default());
        for bytes in [
            &b""[..],
            b"hello world",
            b"/marker\0",
            b"#bundle\0\0\0\0\0\0\0\0\x01\0\0\0\x10",
            b"\xff\xfe\xfd\xfc",
        ] {
            let mut out = Output::default();
            a.datagram(bytes, 0.0, &mut out);
            assert!(out.frames.is_empty(), "{bytes:?}");
            assert_eq!(out.problems.len(), 1, "{bytes:?}");
            assert_eq!(out.problems[0].kind, ProblemKind::Garbage);
        }
        // A valid message followed by junk is refused, not half-read.
        let mut bytes = encoder::encode(&msg("/marker", vec![I(0), F(1.), F(2.), F(3.)])).unwrap();
        bytes.extend_from_slice(b"junk");
        let mut out = Output::default();
        a.datagram(&bytes, 0.0, &mut out);
        assert!(
            out.problems[0].msg.contains("4 bytes at byte"),
            "{:?}",
            out.problems
        );
    }

    #[test]
    fn deep_bundle_nesting_is_refused_without_recursing() {
        // 3000 nested empty bundles, as an attacker would send.
        let mut inner: Vec<u8> = Vec::new();
        for _ in 0..3000 {
            let mut b = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
            if !inner.is_empty() {
                b.extend_from_slice(&(inner.len() as u32).to_be_bytes());
                b.extend_from_slice(&inner);
            }
            inner = b;
        }
        let err = parse_datagram(&inner).unwrap_err();
        assert!(err.contains("nested more than 8"), "{err}");
        // Nesting within the limit is read, and flattened into one frame.
        let mut p = bundle(vec![msg("/marker", vec![I(0), F(1.), F(2.), F(3.)])]);
        for _ in 0..3 {
            p = bundle(vec![p, msg("/marker", vec![I(1), F(1.), F(2.), F(3.)])]);
        }
        let mut a = Assembler::new(DecodeOptions::default());
        let out = feed(&mut a, &p, 0.0);
        assert_eq!(out.frames.len(), 1);
        assert_eq!(out.frames[0].markers.len(), 4);
    }

    #[test]
    fn deep_array_nesting_and_oversized_datagrams_are_refused() {
        // `,[[[…]]]`: rosc parses it without recursing, but dropping the
        // nested arrays recurses once per level.
        let arrays = |depth: usize| {
            let mut b = b"/marker\0,".to_vec();
            b.extend(std::iter::repeat_n(b'[', depth));
            b.extend(std::iter::repeat_n(b']', depth));
            b.push(0);
            while !b.len().is_multiple_of(4) {
                b.push(0);
            }
            b
        };
        for depth in [9, 10_000, 32_000] {
            let err = parse_datagram(&arrays(depth)).unwrap_err();
            assert!(err.contains("arrays nested more than 8"), "{err}");
            assert!(err.contains("\"/marker\""), "{err}");
        }
        // Inside a bundle too.
        let mut b = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
        let inner = arrays(100);
        b.extend_from_slice(&(inner.len() as u32).to_be_bytes());
        b.extend_from_slice(&inner);
        assert!(parse_datagram(&b).unwrap_err().contains("arrays nested"));
        // Within the limit the message is read (and its arrays are not
        // coordinates: a bad-argument problem, not garbage).
        assert!(parse_datagram(&arrays(8)).is_ok());
        let big = vec![0u8; MAX_DATAGRAM_BYTES + 1];
        assert!(parse_datagram(&big)
            .unwrap_err()
            .contains("longer than UDP allows"));
    }

    /// Seeded random mutations of valid datagrams of every family: nothing
    /// panics, and every frame that comes out has finite positions. This runs
    /// in every `cargo test`; `fuzz/` has the coverage-guided target.
    #[test]
    fn random_mutations_never_panic() {
        let seeds = [
            bundle(vec![
                msg("/marker", vec![I(0), F(0.5), F(1.25), F(-2.0)]),
                msg("/marker", vec![I(1), s("position"), F(1.0), F(2.0), F(3.0)]),
            ]),
            msg("/frame/start", vec![I(1)]),
            msg("/marker/12/position", vec![F(1.0), F(2.0), F(4.0)]),
            msg("/frame/end", vec![I(1)]),
            msg(
                "/treemocap/markers",
                vec![I(1), F(0.5), F(1.0), F(2.0), F(3.0)],
            ),
            bundle(vec![bundle(vec![msg("/frame/start", vec![I(9)])])]),
        ];
        let seeds: Vec<Vec<u8>> = seeds.iter().map(|p| encoder::encode(p).unwrap()).collect();
        let mut rng = crate::rng::Rng::new(0x05C);
        let mut a = Assembler::new(DecodeOptions {
            scale: 0.001,
            up_axis: UpAxis::Z,
            othermarkers: true,
        });
        let mut frames = 0;
        for _ in 0..20_000 {
            let mut d = seeds[rng.int(0, seeds.len() as i64 - 1) as usize].clone();
            for _ in 0..rng.int(1, 4) {
                let i = rng.int(0, d.len() as i64 - 1) as usize;
                match rng.int(0, 3) {
                    0 => d[i] = rng.int(0, 255) as u8,
                    1 => d[i] ^= 1 << rng.int(0, 7),
                    2 => d.truncate(i),
                    _ => d.insert(i, rng.int(0, 255) as u8),
                }
                if d.is_empty() {
                    break;
                }
            }
            let mut out = Output::default();
            a.datagram(&d, 0.0, &mut out);
            for f in &out.frames {
                assert!(f.markers.iter().all(|m| m.position.is_finite()));
            }
            frames += out.frames.len();
        }
        assert!(
            frames > 1000,
            "mutations should often stay valid ({frames})"
        );
    }
}
