//! The live NatNet client's I/O: its settings, its sockets and its place
//! among the live sources. The protocol itself (codec, session, marker
//! selection) is in `protocol::natnet`; the replay server in `serve::natnet`.

pub mod client;
pub mod live;
pub mod settings;
