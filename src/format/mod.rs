//! Recorded sessions: Motive CSV exports, C3D files, Wireshark/tcpdump
//! captures of NatNet and our own recording format.
//!
//! Each reader is a streaming [`Recording`]: frames are read one at a time,
//! so memory does not grow with the length of the file. Which reader a file
//! needs is decided by its content, not its extension (`app::open`).

pub use crate::model::recording::{Channel, ChannelKind, Format, Recording, RecordingInfo};

pub mod c3d;
mod cells;
mod csv_rows;
pub mod log;
pub mod motive_csv;
pub mod pcap;
