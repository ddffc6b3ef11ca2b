//! Shared helpers for the NatNet integration tests: a recorded session
//! written as a real treemocap log, and a server + client pair on loopback.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use glam::DVec3;
use treemocap::format::log::{LogHeader, LogWriter};
use treemocap::model::frame::{Marker, MarkerFrame};
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
