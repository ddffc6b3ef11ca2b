//! The OSC decoder on arbitrary bytes: as one datagram, then as a run of
//! datagrams (split at 0xC0) through one assembler, so the bracket state
//! across datagrams is fuzzed too. It must never panic, and every frame it
//! yields must have finite positions.
#![no_main]

use libfuzzer_sys::fuzz_target;
use treemocap::protocol::osc::{Assembler, DecodeOptions, Output};

fuzz_target!(|data: &[u8]| {
    let opts = DecodeOptions {
        scale: 0.001,
        z_up: data.first().is_some_and(|b| b & 1 == 1),
        othermarkers: true,
    };
    let mut a = Assembler::new(opts);
    let mut out = Output::default();
    a.datagram(data, 0.0, &mut out);
    for (i, piece) in data.split(|&b| b == 0xC0).enumerate() {
        a.datagram(piece, i as f64, &mut out);
    }
    a.finish(&mut out);
    for f in &out.frames {
        assert!(f.markers.iter().all(|m| m.position.is_finite()));
        assert!(f.time_s.is_finite());
    }
});
