//! I/O that yields `MarkerFrame`s: live network sources (NatNet, OSC), a
//! recording played at its recorded speed, and the serial wind sensor. They
//! deliver through a [`channel::FrameSink`] and never block on the pipeline.

pub mod allow;
pub mod bad_input;
pub mod channel;
pub mod live;
pub mod natnet;
pub mod osc;
pub mod player;
pub mod wind_sensor;
