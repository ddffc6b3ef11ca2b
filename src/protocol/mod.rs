//! Pure codecs: bytes in, values out (and back), no sockets, no clock.

pub mod live_frame;
pub mod natnet;
pub mod nmea;
pub mod osc;
