//! The daemon: sources → bounded channel → marker pipeline → analysis and
//! triggers → reconstruction → outputs. The only module that knows about
//! threads, sockets and timing.

pub mod player;
pub mod triggers;
pub mod window;
