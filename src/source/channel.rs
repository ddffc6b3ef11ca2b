//! The bounded hand-off from live sources to the pipeline.
//!
//! Sources must never block on a slow pipeline (a UDP socket that is not read
//! drops datagrams in the kernel, silently). So the channel is bounded and,
//! when full, the *oldest* frame is dropped and counted: the newest data is
//! what a live tree needs.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::{
    bounded, Receiver, RecvError, RecvTimeoutError, Sender, TryRecvError, TrySendError,
};

use crate::model::frame::MarkerFrame;

/// A frame and the instant it arrived: the daemon's latency is measured from
/// here, so time spent waiting in the channel (a backlog) counts.
pub type Arrived = (MarkerFrame, Instant);

/// The sending end every live source pushes into. Cheap to clone.
#[derive(Clone)]
pub struct FrameSink {
    tx: Sender<Arrived>,
    /// A receiver kept only to pop the oldest frame when the channel is full.
    evict: Receiver<Arrived>,
    dropped: Arc<AtomicU64>,
    pushed: Arc<AtomicU64>,
    /// Set when the [`FrameReceiver`] is dropped: the eviction receiver above
    /// keeps the channel connected, so disconnection alone cannot tell.
    closed: Arc<AtomicBool>,
}

/// The pipeline's end of the channel. Frames come out in order; the
/// `*_arrived` methods also give each frame's arrival instant.
pub struct FrameReceiver {
    rx: Receiver<Arrived>,
    closed: Arc<AtomicBool>,
}

impl Drop for FrameReceiver {
    fn drop(&mut self) {
        self.closed.store(true, Ordering::Relaxed);
    }
}

impl FrameReceiver {
    /// Waits for the next frame.
    pub fn recv(&self) -> Result<MarkerFrame, RecvError> {
        self.rx.recv().map(|a| a.0)
    }

    /// Waits at most `timeout` for the next frame.
    pub fn recv_timeout(&self, timeout: Duration) -> Result<MarkerFrame, RecvTimeoutError> {
        self.rx.recv_timeout(timeout).map(|a| a.0)
    }

    /// Like [`Self::recv_timeout`], with the instant the frame arrived.
    pub fn recv_timeout_arrived(&self, timeout: Duration) -> Result<Arrived, RecvTimeoutError> {
        self.rx.recv_timeout(timeout)
    }

    /// The next frame if one is queued.
    pub fn try_recv(&self) -> Result<MarkerFrame, TryRecvError> {
        self.rx.try_recv().map(|a| a.0)
    }

    /// Every frame queued now.
    pub fn try_iter(&self) -> impl Iterator<Item = MarkerFrame> + '_ {
        self.rx.try_iter().map(|a| a.0)
    }

    /// The underlying receiver, for `select!` (items carry their arrival).
    pub fn receiver(&self) -> &Receiver<Arrived> {
        &self.rx
    }

    /// Frames waiting in the channel (the backlog).
    pub fn len(&self) -> usize {
        self.rx.len()
    }

    /// True when no frame is waiting.
    pub fn is_empty(&self) -> bool {
        self.rx.is_empty()
    }
}

/// Creates a channel holding at most `capacity` frames.
pub fn frame_channel(capacity: usize) -> (FrameSink, FrameReceiver) {
    let (tx, rx) = bounded(capacity.max(1));
    let closed = Arc::new(AtomicBool::new(false));
    (
        FrameSink {
            tx,
            evict: rx.clone(),
            dropped: Arc::new(AtomicU64::new(0)),
            pushed: Arc::new(AtomicU64::new(0)),
            closed: closed.clone(),
        },
        FrameReceiver { rx, closed },
    )
}

impl FrameSink {
    /// Delivers a frame that arrives now, dropping the oldest queued one if
    /// the channel is full. Returns false when the receiving side is gone
    /// (the pipeline shut down).
    pub fn push(&self, frame: MarkerFrame) -> bool {
        self.push_arrived(frame, Instant::now())
    }

    /// Like [`Self::push`] for a frame that arrived at `arrived` (a source
    /// that takes the time as the datagram comes in, before decoding it).
    pub fn push_arrived(&self, frame: MarkerFrame, arrived: Instant) -> bool {
        if self.closed.load(Ordering::Relaxed) {
            return false;
        }
        self.pushed.fetch_add(1, Ordering::Relaxed);
        let mut item = (frame, arrived);
        loop {
            match self.tx.try_send(item) {
                Ok(()) => return true,
                Err(TrySendError::Disconnected(_)) => return false,
                Err(TrySendError::Full(back)) => {
                    if self.evict.try_recv().is_ok() {
                        self.dropped.fetch_add(1, Ordering::Relaxed);
                    }
                    item = back;
                }
            }
        }
    }

    /// Frames dropped because the pipeline fell behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Frames pushed in all.
    pub fn pushed(&self) -> u64 {
        self.pushed.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_channel_drops_oldest_and_counts() {
        let (sink, rx) = frame_channel(3);
        for i in 0..10 {
            assert!(sink.push(MarkerFrame::new(i, 0.0, vec![])));
        }
        let got: Vec<i64> = rx.try_iter().map(|f| f.frame).collect();
        assert_eq!(got, vec![7, 8, 9]);
        assert_eq!(sink.dropped(), 7);
        assert_eq!(sink.pushed(), 10);
        // Arrival instants travel with the frames, oldest first.
        let t0 = Instant::now();
        sink.push_arrived(MarkerFrame::new(20, 0.0, vec![]), t0);
        sink.push(MarkerFrame::new(21, 0.0, vec![]));
        assert_eq!(rx.len(), 2);
        let (f, at) = rx.recv_timeout_arrived(Duration::from_secs(1)).unwrap();
        assert_eq!((f.frame, at), (20, t0));
        let (f, at) = rx.recv_timeout_arrived(Duration::from_secs(1)).unwrap();
        assert!(f.frame == 21 && at >= t0);
        drop(rx);
        assert!(
            !sink.push(MarkerFrame::new(11, 0.0, vec![])),
            "receiver gone"
        );
    }
}
