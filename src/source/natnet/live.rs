//! The NatNet client as a [`LiveSource`], so `record` and the daemon drive
//! it like any other live source.

use std::sync::Arc;
use std::time::Instant;

use tokio::sync::watch;

use super::client::{self, ClientStatus, NatNetStatus};
use super::settings::NatNetSettings;
use crate::protocol::natnet::session::State;
use crate::source::channel::FrameSink;
use crate::source::live::{LiveSource, SourceFuture, SourceReport};

/// A NatNet client with its settings and its live status.
#[derive(Debug, Clone)]
pub struct NatNetSource {
    /// What the client is told.
    pub settings: NatNetSettings,
    /// What it is doing; shared with whoever shows it (`/status`).
    pub status: Arc<NatNetStatus>,
}

impl NatNetSource {
    /// A source with a fresh status.
    pub fn new(settings: NatNetSettings) -> Self {
        NatNetSource {
            settings,
            status: Arc::default(),
        }
    }

    fn server(&self) -> String {
        if self.settings.discovery {
            "a discovered server".into()
        } else {
            self.settings.server_addr().to_string()
        }
    }

    /// The client's status now.
    pub fn snapshot(&self) -> ClientStatus {
        self.status.snapshot()
    }
}

impl LiveSource for NatNetSource {
    fn describe(&self) -> String {
        match self.snapshot().server {
            Some(s) => format!(
                "natnet {} (NatNet {}) at {}",
                s.name,
                s.version,
                self.server()
            ),
            None => format!("natnet {}", self.server()),
        }
    }

    fn status(&self) -> Option<String> {
        let st = self.snapshot();
        let s = st.server?;
        let mut line = format!(
            "connected to {} (NatNet {}) at {}",
            s.name,
            s.version,
            self.server()
        );
        if let Some(r) = st.frame_rate {
            line += &format!("; frame rate {r}");
        }
        if let Some(state) = st.state.filter(|s| *s != State::Streaming) {
            line += &format!("; {state}");
        }
        Some(line)
    }

    fn frame_rate(&self) -> Option<f64> {
        self.snapshot().frame_rate.map(|r| r.hz)
    }

    fn losses(&self) -> Vec<(String, u64)> {
        let c = self.snapshot().counters;
        vec![
            ("incomplete".into(), c.incomplete),
            ("invalid".into(), c.invalid),
            ("unknown".into(), c.unknown),
            ("wrong sender".into(), c.wrong_sender),
            ("skipped".into(), c.skipped),
            ("reconnects".into(), c.reconnects),
        ]
    }

    fn start(&self, sink: FrameSink, shutdown: watch::Receiver<bool>) -> SourceFuture {
        let me = self.clone();
        Box::pin(async move {
            let started = Instant::now();
            // Shares the sink's drop counter; dropped with this future.
            let probe = sink.clone();
            let r = client::run(&me.settings, &me.status, sink, shutdown).await?;
            Ok(SourceReport {
                source: format!("natnet {}", r.server),
                duration_s: started.elapsed().as_secs_f64(),
                frames: r.counters.frames,
                markers: r.counters.markers,
                dropped: probe.dropped(),
                rejected: me.losses(),
            })
        })
    }
}
