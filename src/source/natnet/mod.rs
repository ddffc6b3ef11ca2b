//! NatNet, OptiTrack Motive's streaming protocol: the wire codec
//! ([`packet`]), which markers of a frame become a [`MarkerFrame`]
//! ([`select`]), a live client ([`client`]) and a replay server ([`server`]).
//!
//! [`MarkerFrame`]: crate::model::frame::MarkerFrame

pub mod client;
pub mod live;
pub mod packet;
pub mod select;
pub mod server;

/// How frames travel from a NatNet server to its clients.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transport {
    /// To each client that sent CONNECT, from the server's data port to the
    /// client's command socket.
    Unicast,
    /// To a multicast group on the data port.
    Multicast,
}
