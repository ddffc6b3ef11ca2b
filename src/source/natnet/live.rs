//! The NatNet client as a [`LiveSource`], so `record` and the daemon drive
//! it like any other live source.

use std::sync::atomic::Ordering;
use std::time::Instant;

use tokio::sync::watch;

use super::client::{self, NatNetOptions};
use crate::source::channel::FrameSink;
use crate::source::live::{LiveSource, SourceFuture, SourceReport};

/// A NatNet client with its options (and, through them, its counters).
#[derive(Debug, Clone)]
pub struct NatNetSource(pub NatNetOptions);

impl NatNetSource {
    fn server(&self) -> String {
        match self.0.server {
            Some(ip) => format!("{ip}:{}", self.0.command_port),
            None => "a discovered server".into(),
        }
    }
}

impl LiveSource for NatNetSource {
    fn describe(&self) -> String {
        match self.0.stats.server.lock().ok().and_then(|g| g.clone()) {
            Some((name, version)) => {
                format!("natnet {name} (NatNet {version}) at {}", self.server())
            }
            None => format!("natnet {}", self.server()),
        }
    }

    fn status(&self) -> Option<String> {
        let (name, version) = self.0.stats.server.lock().ok()?.clone()?;
        Some(format!(
            "connected to {name} (NatNet {version}) at {}",
            self.server()
        ))
    }

    fn frame_rate(&self) -> Option<f64> {
        // The client does not publish the server's FrameRate answer yet.
        None
    }

    fn losses(&self) -> Vec<(String, u64)> {
        let s = &self.0.stats;
        let get = |a: &std::sync::atomic::AtomicU64| a.load(Ordering::Relaxed);
        vec![
            ("incomplete".into(), get(&s.incomplete)),
            ("invalid".into(), get(&s.invalid)),
            ("unknown".into(), get(&s.unknown)),
            ("skipped".into(), get(&s.skipped)),
            ("reconnects".into(), get(&s.reconnects)),
        ]
    }

    fn start(&self, sink: FrameSink, shutdown: watch::Receiver<bool>) -> SourceFuture {
        let me = self.clone();
        Box::pin(async move {
            let started = Instant::now();
            // Shares the sink's drop counter; dropped with this future.
            let probe = sink.clone();
            let r = client::run(&me.0, sink, shutdown).await?;
            Ok(SourceReport {
                source: format!("natnet {}", r.server),
                duration_s: started.elapsed().as_secs_f64(),
                frames: r.frames,
                markers: r.markers,
                dropped: probe.dropped(),
                rejected: me.losses(),
            })
        })
    }
}
