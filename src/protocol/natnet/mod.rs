//! NatNet, OptiTrack Motive's streaming protocol, as pure code: no socket, no
//! clock. The message types ([`types`]) and their bitstream [`Version`]s, a
//! strict decoder ([`decode()`]) and a byte-exact encoder ([`encode()`]) for
//! every bitstream from 2.0 to 4.x, which markers of a frame become a
//! [`MarkerFrame`](crate::model::frame::MarkerFrame) ([`select`]), and the client's
//! protocol state ([`session`]): datagrams and the time in, actions out.
//!
//! The layouts are those of OptiTrack's `PacketClient.cpp` of each SDK,
//! checked against real captures (`docs/natnet.md` tells what we learnt). A
//! frame carries no version number, so decoding and encoding take the
//! [`Version`] negotiated with the server.
//!
//! The I/O lives elsewhere: the live client in `source::natnet`, the replay
//! server in `serve::natnet`.

pub mod decode;
pub mod encode;
pub mod select;
pub mod session;
pub mod types;
pub mod version;

pub use decode::{decode, peek_id, DecodeError, DecodeErrorKind};
pub use encode::{encode, encode_into, EncodeError};
pub use types::*;
pub use version::{Version, OLDEST_VERSION, SUPPORTED_VERSIONS};

use std::net::Ipv4Addr;

/// Default command port of a NatNet server (`NATNET_DEFAULT_PORT_COMMAND`).
/// The one home of NatNet's defaults: the client, the server and the
/// command line all read them here.
pub const DEFAULT_COMMAND_PORT: u16 = 1510;
/// Default data port of a NatNet server (`NATNET_DEFAULT_PORT_DATA`).
pub const DEFAULT_DATA_PORT: u16 = 1511;
/// Default multicast group (`NATNET_DEFAULT_MULTICAST_ADDRESS`).
pub const DEFAULT_MULTICAST_GROUP: Ipv4Addr = Ipv4Addr::new(239, 255, 42, 99);
/// The bitstream `treemocap serve` streams unless told otherwise: the most
/// widely read one (Motive 2.x–3.x, every client we test against).
pub const DEFAULT_SERVE_VERSION: Version = Version::new(3, 1);

/// How frames travel from a NatNet server to its clients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Transport {
    /// To each client that sent CONNECT, from the server's data port to the
    /// client's command socket.
    Unicast,
    /// To a multicast group on the data port.
    Multicast,
}

impl std::fmt::Display for Transport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Transport::Unicast => "unicast",
            Transport::Multicast => "multicast",
        })
    }
}
