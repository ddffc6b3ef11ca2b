//! The bounded hand-off from live sources to the pipeline.
//!
//! Sources must never block on a slow pipeline (a UDP socket that is not read
//! drops datagrams in the kernel, silently). So the channel is bounded and,
//! when full, the *oldest* frame is dropped and counted: the newest data is
//! what a live tree needs.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};

use crate::model::frame::MarkerFrame;

/// The sending end every live source pushes into. Cheap to clone.
#[derive(Clone)]
pub struct FrameSink {
    tx: Sender<MarkerFrame>,
    /// A receiver kept only to pop the oldest frame when the channel is full.
    evict: Receiver<MarkerFrame>,
    dropped: Arc<AtomicU64>,
    pushed: Arc<AtomicU64>,
    /// Set when the [`FrameReceiver`] is dropped: the eviction receiver above
    /// keeps the channel connected, so disconnection alone cannot tell.
    closed: Arc<AtomicBool>,
}

/// The pipeline's end of the channel: a crossbeam receiver (it derefs to
/// one) that tells the sources when it is gone.
pub struct FrameReceiver {
    rx: Receiver<MarkerFrame>,
    closed: Arc<AtomicBool>,
}

impl std::ops::Deref for FrameReceiver {
    type Target = Receiver<MarkerFrame>;
    fn deref(&self) -> &Receiver<MarkerFrame> {
        &self.rx
    }
}

impl Drop for FrameReceiver {
    fn drop(&mut self) {
        self.closed.store(true, Ordering::Relaxed);
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
    /// Delivers a frame, dropping the oldest queued one if the channel is full.
    /// Returns false when the receiving side is gone (the pipeline shut down).
    pub fn push(&self, frame: MarkerFrame) -> bool {
        if self.closed.load(Ordering::Relaxed) {
            return false;
        }
        self.pushed.fetch_add(1, Ordering::Relaxed);
        let mut frame = frame;
        loop {
            match self.tx.try_send(frame) {
                Ok(()) => return true,
                Err(TrySendError::Disconnected(_)) => return false,
                Err(TrySendError::Full(back)) => {
                    if self.evict.try_recv().is_ok() {
                        self.dropped.fetch_add(1, Ordering::Relaxed);
                    }
                    frame = back;
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
        drop(rx);
        assert!(
            !sink.push(MarkerFrame::new(11, 0.0, vec![])),
            "receiver gone"
        );
    }
}
