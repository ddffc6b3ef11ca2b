//! The formats users otherwise read with Python: a C3D file (py-c3d, ezc3d),
//! a NatNet frame (OptiTrack's natnetsdk), our log (pandas, no options).

use std::hint::black_box;
use std::time::Duration;

use treemocap::format::c3d::encode::{encode, Sample, WriteSpec};
use treemocap::format::log::{LogHeader, LogWriter};
use treemocap::protocol::natnet::{
    decode, encode as encode_packet, FrameOfData, LabeledMarker, Packet, Version, MARKER_UNLABELED,
};
use treemocap::rng::Rng;

use crate::util::{or_dash, peer_seconds, timed, Row, Scale};

/// Samples read by treemocap from any recording, and the seconds it took.
fn read_recording(path: &std::path::Path) -> (u64, f64) {
    timed(|| {
        let rec = treemocap::app::open::open(path).expect("open");
        rec.map(|f| f.expect("frame").markers.len() as u64)
            .sum::<u64>()
    })
}

fn c3d_row(scale: &Scale) -> Row {
    let (frames, points) = (if scale.quick { 2_400 } else { 14_400 }, 70);
    let mut rng = Rng::new(3);
    let spec = WriteSpec {
        float: true,
        scale: -0.1,
        rate: 240.0,
        units: "mm".into(),
        labels: (0..points).map(|i| format!("tip{i}")).collect(),
        frames: (0..frames)
            .map(|_| {
                (0..points)
                    .map(|_| Sample {
                        position: [
                            rng.range(-1e3, 1e3),
                            rng.range(500.0, 3e3),
                            rng.range(-1e3, 1e3),
                        ],
                        residual: if rng.chance(0.05) { -1.0 } else { 0.5 },
                    })
                    .collect()
            })
            .collect(),
        ..Default::default()
    };
    let path = scale.path("peers.c3d");
    std::fs::write(&path, encode(&spec)).expect("c3d");
    let (samples, ours) = read_recording(&path);
    let p = path.to_string_lossy();
    let py = peer_seconds(&["c3d", &p]);
    let ez = peer_seconds(&["ezc3d", &p]);
    Row::new(
        format!("C3D reading, {frames} frames × {points} points"),
        "—",
        format!("{:.1} M samples/s", samples as f64 / ours / 1e6),
        format!(
            "py-c3d {}, ezc3d {}",
            or_dash(py, |s| format!("{:.0}× slower", s / ours)),
            or_dash(ez, |s| format!("{:.0}× slower", s / ours))
        ),
    )
}

fn natnet_row(scale: &Scale) -> Row {
    let mut r = Rng::new(5);
    let frame = FrameOfData {
        frame_number: 123_456,
        labeled_markers: (0..70)
            .map(|i| LabeledMarker {
                id: 50_000 + i,
                position: [
                    r.range(-1.0, 1.0) as f32,
                    r.range(0.5, 3.0) as f32,
                    r.range(-1.0, 1.0) as f32,
                ],
                size: 0.014,
                params: MARKER_UNLABELED | 0x02,
                residual: 0.0002,
            })
            .collect(),
        timestamp: 1234.5,
        ..Default::default()
    };
    let v = Version::new(3, 1);
    let bytes = encode_packet(&Packet::FrameOfData(Box::new(frame)), v).expect("encode");
    let path = scale.path("frame-3.1.bin");
    std::fs::write(&path, &bytes).expect("packet");
    let n = 200_000;
    let (_, s) = timed(|| {
        for _ in 0..n {
            black_box(decode(black_box(&bytes), v).expect("decode"));
        }
    });
    let ours = s / n as f64;
    let sdk = peer_seconds(&["natnetsdk", &path.to_string_lossy(), "3", "1", "2000"]);
    Row::new(
        "NatNet 3.1 frame decode, 70 markers",
        "—",
        format!("{:.2} µs", ours * 1e6),
        or_dash(sdk, |s| {
            format!("natnetsdk {:.0} µs ({:.0}× slower)", s * 1e6, s / ours)
        }),
    )
}

fn log_row(scale: &Scale) -> Row {
    let path = scale.path("peers.log.csv");
    let header = LogHeader {
        source: "peers".into(),
        frame_rate: 240.0,
    };
    let mut w = LogWriter::create(&path, &header, Duration::from_secs(1)).expect("log");
    crate::replay::hour_session::for_each_frame(
        if scale.quick { 60.0 } else { 300.0 },
        240.0,
        70,
        |f| w.write_frame(f).expect("write"),
    );
    w.finish().expect("finish");
    let (samples, ours) = read_recording(&path);
    let pandas = peer_seconds(&["pandas-log", &path.to_string_lossy()]);
    Row::new(
        format!(
            "our log reading ({} M samples), pandas.read_csv with no options",
            samples / 1_000_000
        ),
        "—",
        format!("{:.1} M samples/s", samples as f64 / ours / 1e6),
        or_dash(pandas, |s| format!("pandas {:.1}× slower", s / ours)),
    )
}

/// C3D, NatNet and log beside their Python readers.
pub fn c3d_and_natnet(scale: &Scale) -> Vec<Row> {
    vec![c3d_row(scale), natnet_row(scale), log_row(scale)]
}
