//! Everything that yields `MarkerFrame`s: recorded files (`replay`) and live
//! network sources, which deliver through a [`channel::FrameSink`].

pub mod channel;
pub mod natnet;
pub mod replay;
