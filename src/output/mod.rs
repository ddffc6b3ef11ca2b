//! Everything that leaves treemocap: files, pictures, OSC, HTTP/WebSocket.
//! Outputs read an immutable [`snapshot::TreeSnapshot`]; none of them can
//! slow the pipeline. Pictures use a small rasterizer of our own (`raster`).

pub mod http;
pub mod osc;
pub mod plot;
pub mod raster;
pub mod snapshot;
