//! What every live network source (NatNet, OSC) has in common, so that
//! `record` and the daemon drive any of them the same way.
//!
//! A source runs until a shutdown signal, pushing frames into a
//! [`FrameSink`]; while it runs, its counters can be read from another task;
//! when it stops it returns a [`SourceReport`].

use std::future::Future;
use std::pin::Pin;

use serde::Serialize;
use tokio::sync::watch;

use crate::error::Result;
use crate::source::channel::FrameSink;

/// What a live source did, returned when it stops.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SourceReport {
    /// The source as the user named it ("osc 127.0.0.1:9000").
    pub source: String,
    /// Seconds the source ran.
    pub duration_s: f64,
    /// Frames handed to the sink.
    pub frames: u64,
    /// Markers in those frames.
    pub markers: u64,
    /// Frames the sink dropped because the consumer fell behind.
    pub dropped: u64,
    /// Rejected or lost input by kind (garbage, bad arguments, senders not
    /// allowed, …), so a user can tell a quiet source from a broken one.
    /// Kinds with a zero count are included: a zero is information too.
    pub rejected: Vec<(String, u64)>,
}

impl std::fmt::Display for SourceReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {} frames, {} markers in {:.1} s; {} dropped by a slow consumer",
            self.source, self.frames, self.markers, self.duration_s, self.dropped
        )?;
        for (kind, n) in &self.rejected {
            write!(f, ", {kind} {n}")?;
        }
        Ok(())
    }
}

/// The future a live source runs as.
pub type SourceFuture = Pin<Box<dyn Future<Output = Result<SourceReport>> + Send + 'static>>;

/// A live source as `record` and the daemon see it: described, started, and
/// watched through its counters while it runs.
pub trait LiveSource: Send + Sync {
    /// One line naming the source, for log headers and the console.
    fn describe(&self) -> String;
    /// The source's state in words once it has one ("listening on udp
    /// 127.0.0.1:9000", "connected to Motive 3.1"); `record` prints changes.
    fn status(&self) -> Option<String> {
        None
    }
    /// The nominal frame rate if the source knows it by now (asked when the
    /// first frame arrives; NatNet learns it from the server).
    fn frame_rate(&self) -> Option<f64>;
    /// Input rejected or lost so far, by kind (the kinds of
    /// [`SourceReport::rejected`]); frames the sink dropped are counted by
    /// whoever owns the channel.
    fn losses(&self) -> Vec<(String, u64)>;
    /// Starts the source; the future returns when `shutdown` turns true or
    /// the sink's receiver is gone.
    fn start(&self, sink: FrameSink, shutdown: watch::Receiver<bool>) -> SourceFuture;
}
