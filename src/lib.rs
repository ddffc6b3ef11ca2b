//! treemocap: motion capture of tree branch tips in, 3D tree models out.
#![warn(missing_docs, unreachable_pub)]
//!
//! The method is Long & Jones 2013. The modules are layers whose imports
//! point one way (docs/architecture.md): `model` (plain data) ← `protocol`,
//! `format` (codecs and files as bytes) ← `source` (I/O that yields frames),
//! `track`, `wind`, `reconstruct` (pure stages) ← `render` (model → bytes) ←
//! `serve` (HTTP, OSC, NatNet server) ← `app` (one module per command) and
//! `daemon` (threads and channels). Only `app` and `daemon` name files.

pub mod animate;
pub mod app;
pub mod config;
pub mod daemon;
pub mod error;
pub mod format;
pub mod memory;
pub mod model;
pub mod protocol;
pub mod reconstruct;
pub mod render;
pub mod rng;
pub mod serve;
pub mod shutdown;
pub mod sim;
pub mod source;
pub mod throttle;
pub mod track;
pub mod wind;

pub use error::{Error, Location, Result};
pub use model::frame::{Marker, MarkerFrame};
