//! One shutdown signal for the whole process, made in `main` and handed down.
//!
//! Async tasks wait for it ([`Shutdown::triggered`], or the `watch` receiver
//! the live sources and the HTTP server take); threads blocked on channels
//! put [`Shutdown::gate`] into their `select!` and wake when it closes;
//! blocking loops that already wake on their own I/O (a serial read with a
//! timeout, a replay pacing its frames) read [`Shutdown::flag`]. Nothing polls
//! just to notice the end.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use tokio::sync::watch;

/// A cloneable handle on the process's shutdown signal.
#[derive(Clone)]
pub struct Shutdown {
    inner: Arc<Inner>,
}

struct Inner {
    /// For blocking loops that check between reads.
    flag: Arc<AtomicBool>,
    /// For async tasks and the APIs that take a `watch::Receiver<bool>`.
    watch: watch::Sender<bool>,
    /// Dropped on trigger, which disconnects every clone of `gate_rx`: a
    /// thread in `crossbeam_channel::select!` wakes at once.
    gate_tx: Mutex<Option<crossbeam_channel::Sender<()>>>,
    gate_rx: crossbeam_channel::Receiver<()>,
}

impl Default for Shutdown {
    fn default() -> Self {
        Shutdown::new()
    }
}

impl Shutdown {
    /// A signal that has not fired yet.
    pub fn new() -> Self {
        let (gate_tx, gate_rx) = crossbeam_channel::bounded(0);
        Shutdown {
            inner: Arc::new(Inner {
                flag: Arc::new(AtomicBool::new(false)),
                watch: watch::channel(false).0,
                gate_tx: Mutex::new(Some(gate_tx)),
                gate_rx,
            }),
        }
    }

    /// Fires the signal; every waiter wakes. Firing twice is harmless.
    pub fn trigger(&self) {
        self.inner.flag.store(true, Ordering::SeqCst);
        self.inner.watch.send_replace(true);
        // A poisoned lock only means a panic elsewhere while holding it; the
        // sender inside is still ours to drop.
        self.inner
            .gate_tx
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
    }

    /// Whether the signal has fired.
    pub fn is_triggered(&self) -> bool {
        self.inner.flag.load(Ordering::SeqCst)
    }

    /// Waits until the signal fires.
    pub async fn triggered(&self) {
        let mut rx = self.inner.watch.subscribe();
        // The sender lives in `inner`, so waiting cannot fail.
        let _ = rx.wait_for(|fired| *fired).await;
    }

    /// A `watch` receiver that turns true on shutdown, for the sources and
    /// servers whose API takes one.
    pub fn receiver(&self) -> watch::Receiver<bool> {
        self.inner.watch.subscribe()
    }

    /// A channel that never delivers and disconnects on shutdown: put it in
    /// a `crossbeam_channel::select!` beside the channels a thread serves.
    pub fn gate(&self) -> crossbeam_channel::Receiver<()> {
        self.inner.gate_rx.clone()
    }

    /// The flag itself, for blocking loops that already wake on their own
    /// I/O and check it between reads.
    pub fn flag(&self) -> Arc<AtomicBool> {
        self.inner.flag.clone()
    }

    /// Fires the signal on Ctrl-C or SIGTERM: the process's one signal
    /// handler, installed by `main` on its runtime.
    pub fn trigger_on_signals(&self, rt: &tokio::runtime::Handle) {
        let me = self.clone();
        rt.spawn(async move {
            tokio::select! {
                _ = wait_for_signal() => {
                    tracing::info!("shutting down");
                    me.trigger();
                }
                _ = me.triggered() => {}
            }
        });
    }
}

/// Resolves when the flag turns true (or its sender is gone).
pub async fn until_true(mut flag: watch::Receiver<bool>) {
    loop {
        if *flag.borrow_and_update() {
            return;
        }
        if flag.changed().await.is_err() {
            return;
        }
    }
}

async fn wait_for_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        if let Ok(mut term) = signal(SignalKind::terminate()) {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
            return;
        }
    }
    let _ = tokio::signal::ctrl_c().await;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_of_waiter_sees_the_trigger() {
        let s = Shutdown::new();
        let gate = s.gate();
        let rx = s.receiver();
        assert!(!s.is_triggered());
        assert!(!*rx.borrow());
        assert!(gate.try_recv().is_err_and(|e| e.is_empty()));
        let waiter = {
            let s = s.clone();
            std::thread::spawn(move || {
                crossbeam_channel::select! {
                    recv(s.gate()) -> r => r.is_err(),
                }
            })
        };
        s.trigger();
        assert!(waiter.join().unwrap(), "the gate disconnects");
        assert!(s.is_triggered());
        assert!(*rx.borrow());
        assert!(gate.try_recv().is_err_and(|e| e.is_disconnected()));
        let rt = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        rt.block_on(s.triggered());
        s.trigger();
    }
}
