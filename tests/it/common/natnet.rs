//! Shared helpers for the NatNet integration tests: a recorded session
//! written as a real treemocap log, and a server + client pair on loopback.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use glam::DVec3;
use treemocap::format::log::{LogHeader, LogWriter};
use treemocap::model::frame::{Marker, MarkerFrame};
use treemocap::protocol::natnet::Version;
use treemocap::rng::Rng;

/// A session of `frames` frames at `rate` Hz with up to `markers` markers
/// (some frames drop a few, one is empty), positions in a 2 m crown with full
/// f64 precision (so the f32 rounding on the wire is exercised), written to
/// `dir/session.log`. Returns the path and the frames as written.
pub fn session(
    dir: &Path,
    seed: u64,
    frames: usize,
    markers: usize,
    rate: f64,
) -> (PathBuf, Vec<MarkerFrame>) {
    let mut rng = Rng::new(seed);
    let mut out = Vec::with_capacity(frames);
    for f in 0..frames {
        let n = if f == 3 {
            0
        } else {
            markers - (rng.int(0, 2) as usize).min(markers)
        };
        let ms = (0..n)
            .map(|i| Marker {
                position: DVec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(0.5, 3.0),
                    rng.range(-1.0, 1.0),
                ),
                id: Some(1000 + i as i64),
            })
            .collect();
        out.push(MarkerFrame::new(f as i64, f as f64 / rate, ms));
    }
    let path = dir.join("session.log");
    let mut w = LogWriter::create(
        &path,
        &LogHeader {
            source: format!("test seed {seed}"),
            frame_rate: rate,
        },
        Duration::from_millis(100),
    )
    .unwrap();
    for f in &out {
        w.write_frame(f).unwrap();
    }
    w.finish().unwrap();
    (path, out)
}

/// The position a NatNet client must receive for `p`: the f32 on the wire.
pub fn wire(p: DVec3) -> DVec3 {
    DVec3::new(p.x as f32 as f64, p.y as f32 as f64, p.z as f32 as f64)
}

/// A UDP port that was free a moment ago.
pub fn free_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// What a NatNet client of bitstream `version` must have received of the
/// session `sent`: every frame, its time (f32 in 2.6), every marker
/// bit-exact as f32, point-cloud ids from 3.0, latency from 3.0.
pub fn check_session(version: Version, sent: &[MarkerFrame], got: &[MarkerFrame]) {
    assert_eq!(got.len(), sent.len(), "NatNet {version}: frame count");
    for (s, g) in sent.iter().zip(got) {
        assert_eq!(g.frame, s.frame, "NatNet {version}");
        let want_time = if version == Version::new(2, 6) {
            s.time_s as f32 as f64
        } else {
            s.time_s
        };
        assert_eq!(
            g.time_s.to_bits(),
            want_time.to_bits(),
            "NatNet {version} frame {} time",
            s.frame
        );
        assert_eq!(
            g.markers.len(),
            s.markers.len(),
            "NatNet {version} frame {}",
            s.frame
        );
        for (a, b) in s.markers.iter().zip(&g.markers) {
            let w = wire(a.position);
            assert_eq!(
                [w.x.to_bits(), w.y.to_bits(), w.z.to_bits()],
                [
                    b.position.x.to_bits(),
                    b.position.y.to_bits(),
                    b.position.z.to_bits()
                ],
                "NatNet {version} frame {}",
                s.frame
            );
            // 3.0+ carries the point-cloud id with the unlabeled marker.
            let id = if version.major >= 3 { a.id } else { None };
            assert_eq!(b.id, id);
        }
        if version.major >= 3 {
            let l = g.latency_s.expect("3.0+ frames carry latency");
            assert!((0.0..1.0).contains(&l), "{l}");
        } else {
            assert_eq!(g.latency_s, None);
        }
    }
}
