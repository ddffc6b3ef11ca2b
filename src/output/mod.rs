//! Everything that leaves treemocap: files, OSC, HTTP/WebSocket. Outputs read
//! an immutable [`snapshot::TreeSnapshot`]; none of them can slow the pipeline.

pub mod http;
pub mod osc;
pub mod snapshot;
