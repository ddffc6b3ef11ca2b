//! Coverage-guided fuzzing of the NatNet decoder: any bytes, decoded with
//! every bitstream layout, must never panic; anything accepted must
//! re-encode to bytes that decode to the same bytes again.
#![no_main]

use libfuzzer_sys::fuzz_target;
use treemocap::protocol::natnet::{decode, encode, SUPPORTED_VERSIONS};

fuzz_target!(|data: &[u8]| {
    for &v in SUPPORTED_VERSIONS {
        if let Ok(p) = decode(data, v) {
            if let Ok(b) = encode(&p, v) {
                let again = decode(&b, v).expect("re-encoded packet decodes");
                assert_eq!(encode(&again, v).expect("encodes"), b);
            }
        }
    }
});
