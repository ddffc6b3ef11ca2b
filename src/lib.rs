//! treemocap: motion capture of tree branch tips in, 3D tree models out.
//!
//! The method is Long & Jones 2013 (see `../shared/papers/`). Every stage is a
//! plain library type so that replays, benchmarks and the live daemon run the
//! same code; only `daemon` knows about threads, sockets and timing.

pub mod config;
pub mod daemon;
pub mod error;
pub mod format;
pub mod frame;
pub mod inspect;
pub mod output;
pub mod protocol;
pub mod reconstruct;
pub mod replay;
pub mod rng;
pub mod serve;
pub mod sim;
pub mod source;
pub mod track;
pub mod wind;

pub use error::{Error, Location, Result};
pub use frame::{Marker, MarkerFrame};
