//! The NatNet codec: round trips for every message and version, packets
//! built by hand from the byte layouts in `shared/spec/natnet.md` (not with
//! our encoder), and bad input.

use treemocap::protocol::natnet::*;
use treemocap::rng::Rng;

// ---------------------------------------------------------------------------
// Random content
// ---------------------------------------------------------------------------

fn f(r: &mut Rng) -> f32 {
    r.range(-5.0, 5.0) as f32
}
fn v3(r: &mut Rng) -> [f32; 3] {
    [f(r), f(r), f(r)]
}
fn q(r: &mut Rng) -> [f32; 4] {
    [f(r), f(r), f(r), f(r)]
}
fn i(r: &mut Rng) -> i32 {
    r.int(-100_000, 100_000) as i32
}
fn name(r: &mut Rng) -> String {
    let n = r.int(0, 12) as usize;
    (0..n)
        .map(|_| (b'a' + r.int(0, 25) as u8) as char)
        .collect()
}
fn list<T>(r: &mut Rng, max: i64, mut g: impl FnMut(&mut Rng) -> T) -> Vec<T> {
    let n = r.int(0, max) as usize;
    (0..n).map(|_| g(r)).collect()
}

fn rb(r: &mut Rng) -> RigidBodyData {
    RigidBodyData {
        id: i(r),
        position: v3(r),
        orientation: q(r),
        markers: list(r, 4, |r| RigidBodyMarker {
            position: v3(r),
            id: i(r),
            size: f(r),
        }),
        mean_error: f(r),
        params: r.int(0, 1) as i16,
    }
}

fn analog(r: &mut Rng) -> AnalogData {
    AnalogData {
        id: i(r),
        channels: list(r, 3, |r| list(r, 4, f)),
    }
}

/// A frame with every section filled.
fn frame(r: &mut Rng) -> FrameOfData {
    FrameOfData {
        frame_number: i(r),
        marker_sets: list(r, 3, |r| MarkerSetData {
            name: name(r),
            markers: list(r, 5, v3),
        }),
        other_markers: list(r, 6, v3),
        rigid_bodies: list(r, 3, rb),
        skeletons: list(r, 2, |r| SkeletonData {
            id: i(r),
            bones: list(r, 3, rb),
        }),
        assets: list(r, 2, |r| AssetData {
            id: i(r),
            rigid_bodies: list(r, 2, |r| AssetRigidBody {
                id: i(r),
                position: v3(r),
                orientation: q(r),
                mean_error: f(r),
                params: 1,
            }),
            markers: list(r, 3, |r| AssetMarker {
                id: i(r),
                position: v3(r),
                size: f(r),
                params: 3,
                residual: f(r),
            }),
        }),
        labeled_markers: list(r, 10, |r| LabeledMarker {
            id: i(r),
            position: v3(r),
            size: f(r),
            params: r.int(0, 0xFF) as i16,
            residual: f(r),
        }),
        force_plates: list(r, 2, analog),
        devices: list(r, 2, analog),
        software_latency: f(r),
        timecode: r.next_u64() as u32,
        timecode_subframe: r.next_u64() as u32,
        timestamp: r.range(0.0, 1e5),
        camera_mid_exposure: r.next_u64(),
        camera_data_received: r.next_u64(),
        transmit: r.next_u64(),
        precision_seconds: r.next_u64() as u32,
        precision_fraction: r.next_u64() as u32,
        params: r.int(0, 15) as i16,
    }
}

fn rb_desc(r: &mut Rng) -> RigidBodyDescription {
    RigidBodyDescription {
        name: name(r),
        id: i(r),
        parent_id: i(r),
        offset: v3(r),
        rotation: q(r),
        markers: list(r, 4, |r| RigidBodyMarkerDescription {
            offset: v3(r),
            active_label: i(r),
            name: name(r),
        }),
    }
}

fn modeldef(r: &mut Rng) -> ModelDef {
    let mut cal = Vec::new();
    for _ in 0..144 {
        cal.push(f(r));
    }
    ModelDef {
        descriptions: vec![
            Description::MarkerSet {
                name: name(r),
                markers: list(r, 4, name),
            },
            Description::RigidBody(rb_desc(r)),
            Description::Skeleton {
                name: name(r),
                id: i(r),
                bones: list(r, 3, rb_desc),
            },
            Description::ForcePlate(Box::new(ForcePlateDescription {
                id: i(r),
                serial: name(r),
                width: f(r),
                length: f(r),
                origin: v3(r),
                calibration: cal,
                corners: [v3(r), v3(r), v3(r), v3(r)],
                plate_type: i(r),
                channel_data_type: i(r),
                channels: list(r, 4, name),
            })),
            Description::Device(DeviceDescription {
                id: i(r),
                name: name(r),
                serial: name(r),
                device_type: i(r),
                channel_data_type: i(r),
                channels: list(r, 3, name),
            }),
            Description::Camera {
                name: name(r),
                position: v3(r),
                orientation: q(r),
            },
            Description::Asset(AssetDescription {
                name: name(r),
                asset_type: i(r),
                id: i(r),
                rigid_bodies: list(r, 2, rb_desc),
                markers: list(r, 3, |r| AssetMarkerDescription {
                    name: name(r),
                    id: i(r),
                    position: v3(r),
                    size: f(r),
                    params: 5,
                }),
            }),
        ],
    }
}

fn all_versions() -> Vec<Version> {
    let mut v = SUPPORTED_VERSIONS.to_vec();
    v.extend([
        Version::new(2, 0),
        Version::new(2, 1),
        Version::new(2, 3),
        Version::new(2, 8),
        Version::new(2, 10),
        Version::new(4, 4),
    ]);
    v
}

// ---------------------------------------------------------------------------
// Round trips
// ---------------------------------------------------------------------------

#[test]
fn frames_round_trip_in_every_version_byte_exactly() {
    let mut r = Rng::new(1);
    for v in all_versions() {
        for _ in 0..50 {
            let full = frame(&mut r);
            let want = full.restricted_to(v);
            let bytes = encode(&Packet::FrameOfData(Box::new(full)), v).unwrap();
            let got = decode(&bytes, v).unwrap_or_else(|e| panic!("{v}: {e}"));
            assert_eq!(got, Packet::FrameOfData(Box::new(want.clone())), "{v}");
            // Encoding what was decoded gives the same bytes.
            assert_eq!(encode(&got, v).unwrap(), bytes, "{v}");
        }
    }
}

#[test]
fn modeldefs_round_trip_in_every_version() {
    let mut r = Rng::new(2);
    for v in all_versions() {
        for _ in 0..20 {
            let full = modeldef(&mut r);
            let want = full.restricted_to(v);
            let bytes = encode(&Packet::ModelDef(want.clone()), v).unwrap();
            let got = decode(&bytes, v).unwrap_or_else(|e| panic!("{v}: {e}"));
            assert_eq!(got, Packet::ModelDef(want), "{v}");
            assert_eq!(encode(&got, v).unwrap(), bytes);
        }
        // Assets cannot be described before 4.1.
        if !v.has_section_sizes() {
            let e = encode(&Packet::ModelDef(modeldef(&mut r)), v).unwrap_err();
            assert!(e.to_string().contains("asset"), "{e}");
        }
    }
}

#[test]
fn every_other_message_round_trips() {
    let sender = Sender {
        name: "Motive".into(),
        version: [2, 1, 0, 0],
        natnet_version: [3, 0, 0, 0],
    };
    let packets = vec![
        Packet::Connect(Connect::Empty),
        Packet::Connect(Connect::Text("Ping".into())),
        Packet::Connect(Connect::Sender {
            sender: sender.clone(),
            options: None,
            spare: vec![],
        }),
        Packet::Connect(Connect::Sender {
            sender: sender.clone(),
            options: Some(ConnectionOptions {
                subscribed_data_only: true,
                bitstream: [4, 1, 0, 0],
            }),
            spare: vec![0, 0, 0, 0],
        }),
        Packet::Discovery(Connect::Sender {
            sender: sender.clone(),
            options: None,
            spare: vec![],
        }),
        Packet::ServerInfo(ServerInfo {
            sender: sender.clone(),
            connection: None,
        }),
        Packet::ServerInfo(ServerInfo {
            sender: sender.clone(),
            connection: Some(ServerConnection {
                clock_frequency: 3_312_787,
                data_port: 1511,
                multicast: true,
                multicast_group: [239, 255, 42, 99],
            }),
        }),
        Packet::Request("Bitstream,4.1".into()),
        Packet::Response(Response::float(120.0)),
        Packet::Response(Response::Text("Bitstream,4.1.0".into())),
        Packet::Response(Response::Unterminated("Bitstream,4.1.0".into())),
        Packet::RequestModelDef,
        Packet::RequestFrameOfData,
        Packet::MessageString("hello".into()),
        Packet::Disconnect,
        Packet::KeepAlive,
        Packet::DisconnectByTimeout,
        Packet::EchoRequest(123456789),
        Packet::EchoResponse {
            client_ticks: 1,
            server_ticks: u64::MAX,
        },
        Packet::UnrecognizedRequest(vec![1, 2, 3]),
    ];
    for v in [Version::new(2, 5), Version::new(3, 0), Version::new(4, 1)] {
        for p in &packets {
            let b = encode(p, v).unwrap();
            assert_eq!(&decode(&b, v).unwrap(), p, "{v}");
        }
    }
}

// ---------------------------------------------------------------------------
// Packets built by hand from the spec's byte layouts
// ---------------------------------------------------------------------------

/// A little-endian byte builder independent of the codec.
#[derive(Default)]
struct B(Vec<u8>);
impl B {
    fn u16(mut self, x: u16) -> Self {
        self.0.extend(x.to_le_bytes());
        self
    }
    fn i16(mut self, x: i16) -> Self {
        self.0.extend(x.to_le_bytes());
        self
    }
    fn i32(mut self, x: i32) -> Self {
        self.0.extend(x.to_le_bytes());
        self
    }
    fn u32(mut self, x: u32) -> Self {
        self.0.extend(x.to_le_bytes());
        self
    }
    fn u64(mut self, x: u64) -> Self {
        self.0.extend(x.to_le_bytes());
        self
    }
    fn f32(mut self, x: f32) -> Self {
        self.0.extend(x.to_le_bytes());
        self
    }
    fn f64(mut self, x: f64) -> Self {
        self.0.extend(x.to_le_bytes());
        self
    }
    fn raw(mut self, b: &[u8]) -> Self {
        self.0.extend_from_slice(b);
        self
    }
    /// Prepends the header with nDataBytes = payload length.
    fn packet(self, id: u16) -> Vec<u8> {
        let mut out = B::default().u16(id).u16(self.0.len() as u16).0;
        out.extend(self.0);
        out
    }
}

fn sender_bytes(name: &str, app: [u8; 4], natnet: [u8; 4]) -> Vec<u8> {
    let mut n = [0u8; 256];
    n[..name.len()].copy_from_slice(name.as_bytes());
    let mut v = n.to_vec();
    v.extend(app);
    v.extend(natnet);
    v
}

#[test]
fn server_info_3_0_as_motive_2_1_sends_it() {
    // spec §4: "Motive", app 2.1.0.0, NatNet 3.0.0.0, clock 3 312 787 Hz,
    // data port 1511, multicast=1, 239.255.42.99: 279 bytes.
    let p = B::default()
        .raw(&sender_bytes("Motive", [2, 1, 0, 0], [3, 0, 0, 0]))
        .u64(3_312_787)
        .u16(1511)
        .raw(&[1, 239, 255, 42, 99])
        .packet(1);
    assert_eq!(p.len(), 4 + 279);
    let Packet::ServerInfo(s) = decode(&p, Version::new(3, 0)).unwrap() else {
        panic!()
    };
    assert_eq!(s.sender.name, "Motive");
    assert_eq!(s.sender.natnet(), Version::new(3, 0));
    let c = s.connection.unwrap();
    assert_eq!(
        (
            c.clock_frequency,
            c.data_port,
            c.multicast,
            c.multicast_group
        ),
        (3_312_787, 1511, true, [239, 255, 42, 99])
    );
    // The 2.x ping response is 264 bytes (268 with the header).
    let p = B::default()
        .raw(&sender_bytes("NatNetLib", [2, 7, 0, 0], [2, 7, 0, 0]))
        .packet(1);
    assert_eq!(p.len(), 268);
    let Packet::ServerInfo(s) = decode(&p, Version::new(2, 7)).unwrap() else {
        panic!()
    };
    assert_eq!((s.sender.name.as_str(), s.connection), ("NatNetLib", None));
}

#[test]
fn connect_payloads_seen_in_the_wild() {
    let v = Version::new(3, 1);
    // SDK 2.x PacketClient: empty ping.
    assert_eq!(
        decode(&B::default().packet(0), v).unwrap(),
        Packet::Connect(Connect::Empty)
    );
    // PyPI natnet 0.3.0: "Ping\0", nDataBytes 5.
    assert_eq!(
        decode(&B::default().raw(b"Ping\0").packet(0), v).unwrap(),
        Packet::Connect(Connect::Text("Ping".into()))
    );
    // NatNetLib 3.0: sSender only (264).
    let p = B::default()
        .raw(&sender_bytes("NatNetLib", [3, 0, 0, 0], [3, 0, 0, 0]))
        .packet(0);
    let Packet::Connect(c) = decode(&p, v).unwrap() else {
        panic!()
    };
    assert!(matches!(c, Connect::Sender { options: None, .. }));
    // OptiTrack Python 4.1.1: "Ping" in the name, then 00 04 01 00 00 00 00 (271).
    let p = B::default()
        .raw(&sender_bytes("Ping", [0; 4], [0; 4]))
        .raw(&[0, 4, 1, 0, 0, 0, 0])
        .packet(0);
    let Packet::Connect(c) = decode(&p, v).unwrap() else {
        panic!()
    };
    assert_eq!(c.requested_bitstream(), Some(Version::new(4, 1)));
    // SDK 4.x PacketClient: zeros + options + 4 spare (273).
    let p = B::default()
        .raw(&[0u8; 264])
        .raw(&[0, 0, 0, 0, 0])
        .raw(&[0; 4])
        .packet(0);
    let Packet::Connect(c) = decode(&p, v).unwrap() else {
        panic!()
    };
    assert_eq!(c.requested_bitstream(), None);
    // libNatNet 4.4: sSender + options (269).
    let p = B::default()
        .raw(&sender_bytes("NatNetLib", [4, 4, 0, 0], [4, 4, 0, 0]))
        .raw(&[1, 4, 4, 0, 0])
        .packet(0);
    assert!(matches!(
        decode(&p, v).unwrap(),
        Packet::Connect(Connect::Sender {
            options: Some(ConnectionOptions {
                subscribed_data_only: true,
                ..
            }),
            ..
        })
    ));
    // Keep-alives: PY 4.1.1 sends 0a 00 00 00 00 (nDataBytes 0 + a stray NUL),
    // PyPI natnet 0a 00 01 00 00.
    assert_eq!(decode(&[10, 0, 0, 0, 0], v).unwrap(), Packet::KeepAlive);
    assert_eq!(decode(&[10, 0, 1, 0, 0], v).unwrap(), Packet::KeepAlive);
    assert_eq!(
        decode(&[4, 0, 0, 0, 0], v).unwrap(),
        Packet::RequestModelDef
    );
}

/// A 3.0 frame as in `mocapframe_packet_v3.bin` (spec §5): one unlabeled
/// marker id 50007 with params 0x12, built field by field.
#[test]
fn frame_3_0_built_from_the_layout() {
    let p = B::default()
        .i32(1234) // frame number
        .i32(1) // marker sets
        .raw(b"all\0")
        .i32(1)
        .f32(0.1)
        .f32(0.2)
        .f32(0.3)
        .i32(0) // other markers
        .i32(1) // rigid bodies
        .i32(2)
        .f32(1.0)
        .f32(2.0)
        .f32(3.0)
        .f32(0.0)
        .f32(0.0)
        .f32(0.0)
        .f32(1.0)
        .f32(0.0005) // mean error
        .i16(1) // params: tracking valid
        .i32(0) // skeletons
        .i32(1) // labeled markers
        .i32(50007)
        .f32(0.5)
        .f32(1.5)
        .f32(-0.25)
        .f32(0.014)
        .i16(0x12)
        .f32(0.0002)
        .i32(0) // force plates
        .i32(0) // devices
        .u32(0x0102_0304)
        .u32(0) // timecode
        .f64(12.345) // timestamp
        .u64(1000)
        .u64(1500)
        .u64(4312) // hi-res stamps
        .i16(0x01) // frame params
        .i32(0) // eod
        .packet(7);
    let Packet::FrameOfData(f) = decode(&p, Version::new(3, 0)).unwrap() else {
        panic!()
    };
    assert_eq!(f.frame_number, 1234);
    assert_eq!(f.marker_sets[0].name, "all");
    assert_eq!(f.rigid_bodies[0].id, 2);
    assert_eq!(f.rigid_bodies[0].params, 1);
    let m = f.labeled_markers[0];
    assert_eq!(
        (m.model_id(), m.marker_id(), m.is_unlabeled()),
        (0, 50007, true)
    );
    assert_eq!(m.position, [0.5, 1.5, -0.25]);
    assert_eq!(f.timestamp, 12.345);
    assert_eq!((f.camera_mid_exposure, f.transmit), (1000, 4312));
    // The same bytes decode the same with 3.1 and 4.0 (no layout change).
    assert!(decode(&p, Version::new(3, 1)).is_ok());
    assert!(decode(&p, Version::new(4, 0)).is_ok());
    // ... and are rejected as 2.9 or 4.1, whose layouts differ.
    assert!(decode(&p, Version::new(2, 9)).is_err());
    assert!(decode(&p, Version::new(4, 1)).is_err());
    // Our encoder produces exactly these bytes.
    let again = encode(&Packet::FrameOfData(f), Version::new(3, 0)).unwrap();
    assert_eq!(again, p);
}

/// 2.5 frame (no timestamp, no params, software latency, RB marker arrays)
/// and 2.6 (f32 timestamp, params).
#[test]
fn frames_2_5_and_2_6_built_from_the_layout() {
    let body = |b: B, with_params: bool| {
        let b = b
            .i32(77)
            .i32(0) // marker sets
            .i32(2)
            .f32(1.0)
            .f32(2.0)
            .f32(3.0)
            .f32(4.0)
            .f32(5.0)
            .f32(6.0) // other markers
            .i32(1) // one rigid body with 1 marker
            .i32(1)
            .f32(0.0)
            .f32(0.0)
            .f32(0.0)
            .f32(0.0)
            .f32(0.0)
            .f32(0.0)
            .f32(1.0)
            .i32(1)
            .f32(7.0)
            .f32(8.0)
            .f32(9.0)
            .i32(3)
            .f32(0.02)
            .f32(0.001);
        let b = if with_params { b.i16(1) } else { b };
        let b = b.i32(0); // skeletons
        let b = b.i32(1).i32(3).f32(7.0).f32(8.0).f32(9.0).f32(0.02); // labeled
        if with_params {
            b.i16(0x04)
        } else {
            b
        }
    };
    let p25 = body(B::default(), false)
        .f32(4.5)
        .u32(0)
        .u32(0)
        .i32(0)
        .packet(7);
    let Packet::FrameOfData(f) = decode(&p25, Version::new(2, 5)).unwrap() else {
        panic!()
    };
    assert_eq!(f.other_markers, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    assert_eq!(f.rigid_bodies[0].markers[0].id, 3);
    assert_eq!(f.software_latency, 4.5);
    assert_eq!(f.labeled_markers[0].id, 3);
    let p26 = body(B::default(), true)
        .f32(4.5)
        .u32(0)
        .u32(0)
        .f32(2.5)
        .i16(0)
        .i32(0)
        .packet(7);
    let Packet::FrameOfData(f) = decode(&p26, Version::new(2, 6)).unwrap() else {
        panic!()
    };
    assert_eq!((f.timestamp, f.labeled_markers[0].params), (2.5, 0x04));
    assert_eq!(
        encode(&Packet::FrameOfData(f), Version::new(2, 6)).unwrap(),
        p26
    );
}

/// 4.1: section sizes, assets, precision timestamps.
#[test]
fn frame_4_1_built_from_the_layout() {
    let labeled = B::default()
        .i32(5)
        .f32(1.0)
        .f32(2.0)
        .f32(3.0)
        .f32(0.01)
        .i16(0x10)
        .f32(0.0)
        .0;
    let p = B::default()
        .i32(9)
        .i32(0)
        .u32(0) // marker sets + size
        .i32(0)
        .u32(0) // other markers
        .i32(0)
        .u32(0) // rigid bodies
        .i32(0)
        .u32(0) // skeletons
        .i32(0)
        .u32(0) // assets
        .i32(1)
        .u32(labeled.len() as u32)
        .raw(&labeled)
        .i32(0)
        .u32(0) // force plates
        .i32(0)
        .u32(0) // devices
        .u32(0)
        .u32(0)
        .f64(1.0)
        .u64(1)
        .u64(2)
        .u64(3)
        .u32(1_700_000_000)
        .u32(42) // precision timestamp
        .i16(0)
        .i32(0)
        .packet(7);
    let Packet::FrameOfData(f) = decode(&p, Version::new(4, 1)).unwrap() else {
        panic!()
    };
    assert_eq!(f.labeled_markers.len(), 1);
    assert_eq!(
        (f.precision_seconds, f.precision_fraction),
        (1_700_000_000, 42)
    );
    assert_eq!(
        encode(&Packet::FrameOfData(f), Version::new(4, 1)).unwrap(),
        p
    );
    // Later 4.x versions decode the same layout.
    assert!(decode(&p, Version::new(4, 3)).is_ok());
}

// ---------------------------------------------------------------------------
// Bad input
// ---------------------------------------------------------------------------

fn sample_frame(v: Version) -> Vec<u8> {
    let mut r = Rng::new(99);
    let mut fr = frame(&mut r);
    fr.labeled_markers = (0..5)
        .map(|k| LabeledMarker {
            id: k,
            position: [1.0, 2.0, 3.0],
            ..Default::default()
        })
        .collect();
    encode(&Packet::FrameOfData(Box::new(fr)), v).unwrap()
}

#[test]
fn truncated_datagrams_are_incomplete_at_every_length() {
    for v in SUPPORTED_VERSIONS.iter().copied() {
        let p = sample_frame(v);
        for n in 0..p.len() {
            let e = decode(&p[..n], v).unwrap_err();
            assert_eq!(e.kind, DecodeErrorKind::Incomplete, "{v} len {n}: {e}");
            let text = e.to_string();
            assert!(text.contains("byte") && text.contains("field"), "{text}");
        }
    }
}

#[test]
fn header_byte_count_disagreeing_with_content_names_the_field() {
    let v = Version::new(3, 1);
    let mut p = sample_frame(v);
    // nDataBytes larger than the datagram.
    let n = u16::from_le_bytes([p[2], p[3]]);
    p[2..4].copy_from_slice(&(n + 10).to_le_bytes());
    let e = decode(&p, v).unwrap_err();
    assert_eq!(
        (e.kind, e.field, e.offset),
        (DecodeErrorKind::Incomplete, "nDataBytes", 2)
    );
    assert!(e.message.contains("FRAMEOFDATA"));
    // nDataBytes smaller: the payload ends inside a field.
    p[2..4].copy_from_slice(&(n - 7).to_le_bytes());
    let e = decode(&p, v).unwrap_err();
    assert_eq!(e.kind, DecodeErrorKind::Incomplete, "{e}");
    // Extra payload bytes after the end-of-data tag.
    let mut q = sample_frame(v);
    q.extend([0, 0]);
    let n = (q.len() - 4) as u16;
    q[2..4].copy_from_slice(&n.to_le_bytes());
    let e = decode(&q, v).unwrap_err();
    assert_eq!(e.kind, DecodeErrorKind::Invalid);
    assert!(e.to_string().contains("left over"), "{e}");
}

#[test]
fn counts_that_overflow_the_packet_are_invalid_and_allocate_nothing() {
    let v = Version::new(3, 0);
    let p = B::default()
        .i32(1)
        .i32(0) // marker sets
        .i32(0) // other
        .i32(0) // rigid bodies
        .i32(0) // skeletons
        .i32(i32::MAX) // labeled markers: 2^31 × 26 bytes
        .raw(&[0; 40])
        .packet(7);
    let e = decode(&p, v).unwrap_err();
    assert_eq!(
        (e.kind, e.field),
        (DecodeErrorKind::Invalid, "labeled marker count")
    );
    assert_eq!(e.offset, 4 + 20);
    let p = B::default().i32(1).i32(-3).raw(&[0; 40]).packet(7);
    let e = decode(&p, v).unwrap_err();
    assert_eq!(
        (e.kind, e.field),
        (DecodeErrorKind::Invalid, "marker set count")
    );
    assert!(e.detail.contains("negative"));
}

#[test]
fn wrong_section_size_and_eod_tag_are_invalid() {
    let v = Version::new(4, 1);
    let mut p = sample_frame(v);
    // The marker-set section size is the u32 after frame number and count.
    let sz = u32::from_le_bytes(p[12..16].try_into().unwrap());
    p[12..16].copy_from_slice(&(sz + 1).to_le_bytes());
    let e = decode(&p, v).unwrap_err();
    assert_eq!(
        (e.kind, e.field, e.offset),
        (DecodeErrorKind::Invalid, "marker set section size", 12)
    );
    let mut p = sample_frame(Version::new(3, 1));
    let n = p.len();
    p[n - 4] = 1;
    let e = decode(&p, Version::new(3, 1)).unwrap_err();
    assert_eq!(
        (e.kind, e.field),
        (DecodeErrorKind::Invalid, "end of data tag")
    );
}

#[test]
fn unknown_ids_and_malformed_server_info() {
    let v = Version::new(3, 1);
    let e = decode(&B::default().raw(&[1, 2, 3]).packet(77), v).unwrap_err();
    assert_eq!(
        (e.kind, e.field),
        (DecodeErrorKind::UnknownMessage, "iMessage")
    );
    let e = decode(&B::default().raw(&[0; 270]).packet(1), v).unwrap_err();
    assert_eq!(e.kind, DecodeErrorKind::Invalid);
    assert!(e.detail.contains("264") && e.detail.contains("279"), "{e}");
    // CONNECT with 266 bytes cannot hold connection options.
    let e = decode(&B::default().raw(&[0; 266]).packet(0), v).unwrap_err();
    assert_eq!(e.field, "sConnectionOptions");
    // A keep-alive with junk is not padding.
    let e = decode(&[10, 0, 2, 0, 0, 7], v).unwrap_err();
    assert_eq!(e.kind, DecodeErrorKind::Invalid);
    assert!(decode(&[], v).is_err() && decode(&[7], v).is_err());
}

/// The stand-in for the coverage-guided fuzzer where cargo-fuzz cannot run
/// (no nightly toolchain): seeded mutations of real packets of every version
/// (bit flips, byte overwrites, truncations, splices, count blow-ups). The
/// decoder must never panic, and whatever it accepts must re-encode to a
/// packet that decodes to the same value.
#[test]
fn seeded_mutations_never_panic() {
    let mut rng = Rng::new(0xF022);
    let mut seeds: Vec<(Version, Vec<u8>)> = Vec::new();
    for v in all_versions() {
        let mut r = rng.fork(v.major as u64 * 100 + v.minor as u64);
        seeds.push((
            v,
            encode(&Packet::FrameOfData(Box::new(frame(&mut r))), v).unwrap(),
        ));
        seeds.push((
            v,
            encode(&Packet::ModelDef(modeldef(&mut r).restricted_to(v)), v).unwrap(),
        ));
    }
    seeds.push((
        Version::new(3, 0),
        encode(
            &Packet::Connect(Connect::Text("Ping".into())),
            Version::new(3, 0),
        )
        .unwrap(),
    ));
    let mut accepted = 0;
    for round in 0..60_000u64 {
        let (v, base) = &seeds[(round as usize) % seeds.len()];
        let mut p = base.clone();
        for _ in 0..rng.int(1, 4) {
            match rng.int(0, 5) {
                0 if !p.is_empty() => {
                    let k = rng.int(0, p.len() as i64 - 1) as usize;
                    p[k] ^= 1 << rng.int(0, 7);
                }
                1 if !p.is_empty() => {
                    let k = rng.int(0, p.len() as i64 - 1) as usize;
                    p[k] = rng.next_u64() as u8;
                }
                2 => p.truncate(rng.int(0, p.len() as i64) as usize),
                3 if p.len() > 8 => {
                    // Overwrite an aligned i32 with a large or negative count.
                    let k = 4 + 4 * rng.int(0, (p.len() as i64 - 8) / 4) as usize;
                    let x = [i32::MAX, -1, 1 << 20, 65535][rng.int(0, 3) as usize];
                    p[k..k + 4].copy_from_slice(&x.to_le_bytes());
                }
                4 => {
                    let (_, other) = &seeds[rng.int(0, seeds.len() as i64 - 1) as usize];
                    let k = rng.int(0, other.len() as i64) as usize;
                    p.extend_from_slice(&other[k..]);
                }
                _ => {
                    let n = (p.len().saturating_sub(4)) as u16;
                    if p.len() >= 4 {
                        p[2..4].copy_from_slice(&n.to_le_bytes());
                    }
                }
            }
        }
        if let Ok(pk) = decode(&p, *v) {
            accepted += 1;
            // Compared as bytes: mutated floats may be NaN.
            if let Ok(b) = encode(&pk, *v) {
                assert_eq!(encode(&decode(&b, *v).unwrap(), *v).unwrap(), b);
            }
        }
    }
    // Some mutations (float bits) leave valid packets: the check above ran.
    assert!(accepted > 100, "{accepted}");
}
