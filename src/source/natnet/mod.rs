//! NatNet, OptiTrack Motive's streaming protocol: the wire codec
//! ([`packet`]), which markers of a frame become a [`MarkerFrame`]
//! ([`select`]), a live client ([`client`]) and a replay server ([`server`]).
//!
//! [`MarkerFrame`]: crate::frame::MarkerFrame

pub mod packet;
pub mod select;
