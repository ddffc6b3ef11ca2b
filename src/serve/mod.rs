//! What treemocap serves to the world while it runs: HTTP and WebSocket,
//! OSC out, and (for testing clients) a NatNet server. Every output reads one
//! immutable [`snapshot::TreeSnapshot`]; none of them can slow the pipeline.

pub mod http;
pub mod limits;
pub mod live;
pub mod natnet;
pub mod osc;
pub mod pose;
pub mod snapshot;
pub mod view;
mod web;
