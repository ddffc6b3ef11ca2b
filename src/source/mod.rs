//! Everything that yields `MarkerFrame`s: recorded files (`replay`) and live
//! network sources, which deliver through a [`channel::FrameSink`].

pub mod allow;
pub mod channel;
pub mod live;
pub mod natnet;
pub mod osc;
pub mod record;
pub mod replay;
