//! Pure codecs: bytes in, values out (and back), no sockets, no clock.

pub mod nmea;
pub mod osc;
