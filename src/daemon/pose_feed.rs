//! The live sway off the pipeline thread.
//!
//! Deforming the tree (hundreds to thousands of nodes) and writing the pose
//! as JSON and OSC costs far more than tracking a frame; done on the
//! pipeline thread at `animate.live_rate_hz` it made every sixth frame late
//! and doubled the daemon's frame → tips p99 as soon as someone watched
//! (issue 12). The pipeline now only copies the frame's live tips, when a
//! pose is due, into a one-slot channel; a worker thread deforms and sends.
//! If the worker is still busy with the previous pose the new one is
//! dropped: a display loses a pose, the pipeline never waits.

use std::sync::Arc;
use std::thread::JoinHandle;

use crossbeam_channel::{bounded, Receiver, Sender};
use glam::DVec3;

use super::pose::LivePose;
use super::shared::Shared;
use crate::error::Result;
use crate::serve::osc::OscSender;
use crate::serve::pose::{pose_datagrams, pose_message};

/// What the worker needs of one frame: its number, capture time and the
/// live tips measured in it (marker index, position).
struct PoseInput {
    frame: i64,
    time_s: f64,
    seen: Vec<(usize, DVec3)>,
}

/// The pipeline's end: decides when a pose is due and hands it over.
pub(crate) struct PoseFeed {
    shared: Arc<Shared>,
    /// `None` once dropped, so that the worker sees the channel close.
    tx: Option<Sender<PoseInput>>,
    worker: Option<JoinHandle<()>>,
    /// Whether anyone takes poses over OSC (the viewers are asked per frame).
    osc: bool,
    /// Seconds of capture time between poses; `None`: live sway is off.
    period_s: Option<f64>,
    next_s: f64,
}

impl PoseFeed {
    /// Starts the worker, with its own OSC socket to the daemon's targets.
    pub(crate) fn start(shared: Arc<Shared>) -> Result<Self> {
        let c = &shared.config;
        let rate = c.animate.live_rate_hz;
        let osc = super::osc_sender(&c.daemon.osc_targets)?;
        let (tx, rx) = bounded(1);
        let s = shared.clone();
        let mut pose = LivePose::new();
        let has_osc = osc.is_some();
        let placement = shared.placement;
        let idle = c.daemon.background_idle;
        let worker = super::spawn_background("treemocap-pose", placement, idle, move || {
            work(&s, &mut pose, osc, &rx)
        });
        Ok(PoseFeed {
            shared,
            tx: Some(tx),
            worker: Some(worker),
            osc: has_osc,
            period_s: (rate > 0.0).then(|| 1.0 / rate),
            next_s: f64::NEG_INFINITY,
        })
    }

    /// Called for every frame with its live tips; costs a comparison unless
    /// a pose is due, someone listens and there is a tree.
    pub(crate) fn offer(&mut self, frame: i64, time_s: f64, seen: &[(usize, DVec3)]) {
        let Some(period) = self.period_s else { return };
        // A clock that jumped back (a looped replay) restarts the schedule.
        if time_s < self.next_s && time_s >= self.next_s - 2.0 * period {
            return;
        }
        if !self.osc && !self.shared.hub.has_viewers() {
            return;
        }
        if self.shared.tree_tx.borrow().is_none() {
            return;
        }
        self.next_s = time_s + period;
        let input = PoseInput {
            frame,
            time_s,
            seen: seen.to_vec(),
        };
        if let Some(tx) = &self.tx {
            // Full: the worker is still on the previous pose; this one is
            // dropped (the next is due one period later).
            let _ = tx.try_send(input);
        }
    }
}

impl Drop for PoseFeed {
    fn drop(&mut self) {
        self.tx = None;
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

/// The worker: per input one pose per tree that sways, to the viewers
/// (JSON `pose` events, all of one frame published together) and OSC; ends
/// when the pipeline drops its feed.
fn work(
    shared: &Shared,
    pose: &mut LivePose,
    mut osc: Option<OscSender>,
    rx: &Receiver<PoseInput>,
) {
    let mut messages = Vec::new();
    for input in rx.iter() {
        let tree = shared.tree_tx.borrow().clone();
        let viewers = shared.hub.has_viewers();
        messages.clear();
        pose.update(
            tree.as_deref(),
            (input.frame, input.time_s),
            &input.seen,
            &mut |p| {
                if viewers {
                    messages.push(pose_message(p));
                }
                if let Some(o) = osc.as_mut() {
                    for d in pose_datagrams(p) {
                        o.send(&d);
                    }
                }
            },
        );
        if !messages.is_empty() {
            shared.hub.publish_pose(messages.as_slice().into());
        }
    }
}
