//! Pure codecs: bytes in, types out (and back), no I/O, no clock.

pub mod natnet;
