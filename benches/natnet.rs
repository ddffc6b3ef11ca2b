//! NatNet frame decoding speed: a 3.x frame of 70 unlabeled markers (a big
//! tree rig; target < 2 µs) and of 1000 (NatNet's cap; target < 20 µs).

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use treemocap::protocol::natnet::select::{to_marker_frame, FrameContext, MarkerSelection, UpAxis};
use treemocap::protocol::natnet::{
    decode, encode, FrameOfData, LabeledMarker, Packet, Version, MARKER_UNLABELED,
};
use treemocap::rng::Rng;

fn frame(markers: usize) -> Vec<u8> {
    let mut r = Rng::new(5);
    let f = FrameOfData {
        frame_number: 123_456,
        labeled_markers: (0..markers)
            .map(|i| LabeledMarker {
                id: 50_000 + i as i32,
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
        camera_mid_exposure: 1,
        transmit: 2,
        ..Default::default()
    };
    encode(&Packet::FrameOfData(Box::new(f)), Version::new(3, 1)).unwrap()
}

fn bench(c: &mut Criterion) {
    let v = Version::new(3, 1);
    let cx = FrameContext {
        version: v,
        selection: MarkerSelection::Unlabeled,
        up: UpAxis::Y,
        clock_frequency: 1_000_000,
    };
    for n in [70, 1000] {
        let bytes = frame(n);
        c.bench_function(&format!("natnet_decode_3.1_{n}_markers"), |b| {
            b.iter(|| decode(black_box(&bytes), v).unwrap())
        });
        c.bench_function(
            &format!("natnet_decode_to_marker_frame_3.1_{n}_markers"),
            |b| {
                b.iter(|| match decode(black_box(&bytes), v).unwrap() {
                    Packet::FrameOfData(f) => to_marker_frame(&f, &cx, 0.0),
                    _ => unreachable!(),
                })
            },
        );
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
