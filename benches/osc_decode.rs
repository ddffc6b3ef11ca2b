//! Decoding OSC marker frames: one hku-style bundle (`/marker ,ifff` per
//! marker) and one NatNetThree2OSC bracket (`/frame/start`, `/marker ,isfff`
//! per marker, `/frame/end`, one datagram each), for 70 markers (a big tree)
//! and 1000 (NatNet's cap). Time per whole frame.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rosc::{encoder, OscBundle, OscMessage, OscPacket, OscTime, OscType};
use treemocap::protocol::osc::{Assembler, DecodeOptions, Output};
use treemocap::rng::Rng;

fn msg(addr: &str, args: Vec<OscType>) -> OscPacket {
    OscPacket::Message(OscMessage {
        addr: addr.into(),
        args,
    })
}

fn positions(n: usize) -> Vec<[f32; 3]> {
    let mut rng = Rng::new(n as u64);
    (0..n)
        .map(|_| [0; 3].map(|_| rng.range(-3.0, 3.0) as f32))
        .collect()
}

fn bundle_datagram(n: usize) -> Vec<u8> {
    let content = positions(n)
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut args = vec![OscType::Int(i as i32)];
            args.extend(p.iter().map(|&v| OscType::Float(v)));
            msg("/marker", args)
        })
        .collect();
    encoder::encode(&OscPacket::Bundle(OscBundle {
        timetag: OscTime {
            seconds: 0,
            fractional: 1,
        },
        content,
    }))
    .unwrap()
}

fn bracket_datagrams(n: usize) -> Vec<Vec<u8>> {
    let mut out = vec![encoder::encode(&msg("/frame/start", vec![OscType::Int(7)])).unwrap()];
    for (i, p) in positions(n).iter().enumerate() {
        let mut args = vec![OscType::Int(i as i32), OscType::String("position".into())];
        args.extend(p.iter().map(|&v| OscType::Float(v)));
        out.push(encoder::encode(&msg("/marker", args)).unwrap());
    }
    out.push(encoder::encode(&msg("/frame/end", vec![OscType::Int(7)])).unwrap());
    out
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("osc_decode");
    for n in [70usize, 1000] {
        g.throughput(Throughput::Elements(n as u64));
        let bundle = bundle_datagram(n);
        g.bench_with_input(BenchmarkId::new("bundle", n), &bundle, |b, d| {
            let mut a = Assembler::new(DecodeOptions::default());
            let mut out = Output::default();
            b.iter(|| {
                a.datagram(d, 0.0, &mut out);
                assert_eq!(out.frames.pop().map(|f| f.markers.len()), Some(n));
            })
        });
        let bracket = bracket_datagrams(n);
        g.bench_with_input(BenchmarkId::new("bracket", n), &bracket, |b, ds| {
            let mut a = Assembler::new(DecodeOptions::default());
            let mut out = Output::default();
            b.iter(|| {
                for d in ds {
                    a.datagram(d, 0.0, &mut out);
                }
                assert_eq!(out.frames.pop().map(|f| f.markers.len()), Some(n));
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
