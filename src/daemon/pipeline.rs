//! The pipeline thread: every frame is counted, recorded, kept in the window,
//! followed by the live tips (→ WebSocket, OSC, sway PCA), and handed to the
//! analysis every `daemon.analysis_interval_s`. It owns its state and takes
//! no lock on the way.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::{select, Receiver};
use glam::DVec3;

use super::handoff::{AnalysisHandoff, Job};
use super::live_tips::LiveTips as ViewerTips;
use super::pose_feed::PoseFeed;
use super::shared::{lock, Shared};
use super::window::FrameWindow;
use crate::error::Result;
use crate::format::log::LogHeader;
use crate::model::frame::MarkerFrame;
use crate::serve::live::MAX_FRAMES_PER_S;
use crate::serve::osc::{tips_datagram, wind_datagram, OscSender};
use crate::source::channel::{FrameReceiver, FrameSink};
use crate::track::live::{LiveTips, Seen};
use crate::wind::pca::SwayPca;

/// How often the pipeline wakes with no frame: the recording's flush and a
/// rebuild asked for while the source is quiet must not wait for a frame.
const TICK: Duration = Duration::from_millis(50);

/// The pipeline's state.
pub(crate) struct Pipeline {
    shared: Arc<Shared>,
    window: FrameWindow,
    /// The tracker itself, frame by frame: live tips are the replay's tips.
    follower: LiveTips,
    /// The tips' states for the live page (measured, filled, not seen).
    live_tips: ViewerTips,
    /// Per marker of the frame shown: a tip's (reused buffer).
    claimed: Vec<bool>,
    pca: SwayPca,
    next_pca: f64,
    next_analysis: f64,
    /// Frames have entered the window since it was last handed to the
    /// analysis. A replay at full speed can end while the analysis is still
    /// busy with its first frames; the window's end is then handed over once
    /// the source is quiet, or no tree would come until the next frame.
    unanalysed: bool,
    rate: RateEstimate,
    osc: Option<OscSender>,
    /// The current tree swayed by the live tips (issue 13), on its own
    /// thread.
    pose: PoseFeed,
    /// When the viewers' frame was last built, and whether a later frame
    /// is still to be shown (see `show`).
    shown_at: Option<Instant>,
    unshown: Option<(MarkerFrame, Seen)>,
    /// The recording (`daemon.record`), which survives a full disk.
    recorder: Option<crate::app::recording::Recorder>,
    /// Where the window goes for analysis: a snapshot (shared chunks, no
    /// copy), offered only when the analysis is free.
    handoff: Arc<AnalysisHandoff>,
    /// When to prefetch the tracker's state for the next frame
    /// (`daemon.warm_us` before it is due), until done.
    warm_at: Option<Instant>,
}

/// A smoothed estimate of the source's frame rate. Until two frames have
/// been seen it is unknown; 100 Hz is only the placeholder for a header.
struct RateEstimate {
    hz: f64,
    known: bool,
    last_time: Option<f64>,
}

impl RateEstimate {
    fn update(&mut self, time_s: f64) -> Option<f64> {
        let prev = self.last_time.replace(time_s)?;
        let dt = time_s - prev;
        if dt <= 0.0 {
            return None;
        }
        self.hz = if self.known {
            0.99 * self.hz + 0.01 / dt
        } else {
            1.0 / dt
        };
        self.known = true;
        Some(self.hz)
    }
}

impl Pipeline {
    /// The pipeline's state from the settings; opens the recording when
    /// `daemon.record` asks for one.
    pub(crate) fn new(shared: Arc<Shared>, handoff: Arc<AnalysisHandoff>) -> Result<Self> {
        let c = &shared.config;
        let d = &c.daemon;
        let rate = RateEstimate {
            hz: 100.0,
            known: false,
            last_time: None,
        };
        let recorder = if d.record {
            let header = LogHeader {
                source: lock(&shared.status.source).clone(),
                frame_rate: rate.hz,
            };
            Some(super::counters::start_recording(
                &shared.out,
                c.record.flush_interval_s,
                &shared.status.recording,
                header,
            )?)
        } else {
            None
        };
        Ok(Pipeline {
            window: FrameWindow::new(d.window_s),
            follower: LiveTips::new(&c.tracking, None, d.follow_gate_mm / 1000.0),
            live_tips: ViewerTips::new(c.tracking.max_fill_s),
            claimed: Vec::new(),
            pose: PoseFeed::start(shared.clone())?,
            shown_at: None,
            unshown: None,
            pca: SwayPca::new(c.wind.pca_window_s, c.wind.pca_min_sway_mm / 1000.0),
            next_pca: f64::NEG_INFINITY,
            next_analysis: f64::NEG_INFINITY,
            unanalysed: false,
            rate,
            osc: super::osc_sender(&d.osc_targets)?,
            recorder,
            handoff,
            warm_at: None,
            shared,
        })
    }

    /// Runs until the shutdown signal or until every source has gone; the
    /// recording is finished on the way out.
    pub(crate) fn run(
        mut self,
        rx: FrameReceiver,
        sink: &FrameSink,
        tips_rx: Receiver<Vec<(usize, DVec3)>>,
    ) {
        self.shared.placement.pin_pipeline();
        let stop = self.shared.shutdown.gate();
        let frames = rx.receiver();
        loop {
            select! {
                recv(frames) -> frame => match frame {
                    Ok((frame, arrived)) => {
                        self.shared.status.record_backlog(rx.len(), arrived.elapsed());
                        self.on_frame(frame, arrived, sink);
                    }
                    Err(_) => break,
                },
                recv(tips_rx) -> tips => {
                    if let Ok(tips) = tips {
                        self.on_tips(&tips);
                    }
                }
                recv(stop) -> _ => break,
                default(self.wait()) => self.on_timeout(),
            }
            self.flush_recording();
        }
        if let Some(w) = self.recorder.take() {
            super::counters::finish_recording(w);
        }
    }

    /// How long to wait for a frame: until the tracker's state is to be
    /// prefetched, at most `TICK`.
    fn wait(&self) -> Duration {
        self.warm_at
            .map_or(TICK, |at| at.saturating_duration_since(Instant::now()))
            .min(TICK)
    }

    /// No frame came in time: prefetch the tracker's state if the next
    /// frame is about due, else the source is quiet.
    fn on_timeout(&mut self) {
        match self.warm_at.take() {
            Some(_) => self.follower.warm(),
            None => self.on_quiet(),
        }
    }

    /// Sets when to prefetch for the frame after the one that arrived at
    /// `arrived`: `daemon.warm_us` before it is due at the source's rate.
    /// Not when that moment has passed (this frame's work ran long, the
    /// next may be waiting already) or the rate is not known yet.
    fn plan_warm(&mut self, arrived: Instant) {
        let lead = self.shared.config.daemon.warm_us;
        self.warm_at = None;
        if lead == 0 || !self.rate.known {
            return;
        }
        let period = Duration::from_secs_f64(1.0 / self.rate.hz.max(1.0));
        let lead = Duration::from_micros(u64::from(lead));
        self.warm_at = (arrived + period)
            .checked_sub(lead)
            .filter(|&at| at > Instant::now());
    }

    /// The tips of a new tree: the live follower starts from them.
    fn on_tips(&mut self, tips: &[(usize, DVec3)]) {
        self.follower.set_tips(tips);
        self.live_tips.set_tips(tips);
        self.shared
            .status
            .tips
            .store(tips.len() as u64, Ordering::Relaxed);
    }

    /// A quiet source (a finished replay, a paused rig) must not leave a
    /// requested rebuild, or frames no analysis has seen, waiting for the
    /// next frame.
    fn on_quiet(&mut self) {
        if let Some((frame, seen)) = self.unshown.take() {
            self.publish(&frame, &seen);
        }
        let rebuild = self.shared.rebuild.load(Ordering::Relaxed);
        if (rebuild || self.unanalysed) && !self.window.is_empty() {
            self.offer_window();
        }
    }

    fn flush_recording(&mut self) {
        if let Some(w) = self.recorder.as_mut() {
            w.tick();
        }
    }

    /// One frame through the pipeline; `arrived` is when its datagram
    /// arrived (the latency counts from there, decoding and queueing
    /// included).
    ///
    /// The latency is stamped once the frame's tips are out (OSC, the pose
    /// feed, the viewers' state): that is the latency a user of the tips
    /// sees. Recording the frame and keeping it in the window come after,
    /// still before the next frame is taken, so they delay no frame's tips
    /// unless the frame's whole work outlasts the frame interval, which the
    /// backlog on `/status` shows.
    fn on_frame(&mut self, frame: MarkerFrame, arrived: Instant, sink: &FrameSink) {
        self.shared.status.progress.frame_arrived();
        self.count(&frame, sink);
        let now = frame.time_s;
        let seen = self.follower.update(&frame);
        if !self.follower.is_empty() {
            self.follow(&frame, &seen.tips);
        }
        let us = arrived.elapsed().as_micros() as u64;
        let status = &self.shared.status;
        status.latency_us_last.store(us, Ordering::Relaxed);
        status.latency_us_max.fetch_max(us, Ordering::Relaxed);
        status.latency_us_sum.fetch_add(us, Ordering::Relaxed);
        status.latency_hist.record(us);
        if let Some(w) = self.recorder.as_mut() {
            w.write_frame(&frame);
        }
        self.window.push(&frame);
        self.unanalysed = true;
        self.maybe_analyse(now);
        self.show(frame, seen);
        self.plan_warm(arrived);
    }

    /// The viewers' frame, built at most `MAX_FRAMES_PER_S` times a second
    /// of wall time: no viewer takes more, and building it for every frame
    /// of a 360 Hz rig was work on the latency path for nothing. A frame
    /// not shown is kept (it is owned here anyway, no copy) so that the last
    /// frame before the source goes quiet still reaches the page.
    fn show(&mut self, frame: MarkerFrame, seen: Seen) {
        if !self.shared.hub.has_viewers() {
            self.unshown = None;
            return;
        }
        let gap = Duration::from_secs_f64(1.0 / MAX_FRAMES_PER_S);
        if self.shown_at.is_some_and(|t| t.elapsed() < gap) {
            self.unshown = Some((frame, seen));
            return;
        }
        self.unshown = None;
        self.publish(&frame, &seen);
    }

    /// Builds the viewers' frame and puts it in the latest-wins slot (never
    /// a wait on a viewer).
    fn publish(&mut self, frame: &MarkerFrame, seen: &Seen) {
        self.shown_at = Some(Instant::now());
        self.claimed.clear();
        self.claimed.resize(frame.markers.len(), false);
        for &i in &seen.frame_markers {
            self.claimed[i] = true;
        }
        let live = self.live_tips.frame(frame, &self.claimed);
        self.shared.hub.publish_frame(live);
    }

    fn count(&mut self, frame: &MarkerFrame, sink: &FrameSink) {
        let status = &self.shared.status;
        status.frames.fetch_add(1, Ordering::Relaxed);
        let n = frame.markers.len() as u64;
        status.samples.fetch_add(n, Ordering::Relaxed);
        status.markers.store(n, Ordering::Relaxed);
        status
            .last_frame
            .store(frame.frame as u64, Ordering::Relaxed);
        status
            .last_frame_time_bits
            .store(frame.time_s.to_bits(), Ordering::Relaxed);
        status.dropped.store(sink.dropped(), Ordering::Relaxed);
        if let Some(hz) = self.rate.update(frame.time_s) {
            status
                .frame_rate_bits
                .store(hz.to_bits(), Ordering::Relaxed);
        }
    }

    /// The live tips of this frame → viewers, OSC, and the sway PCA.
    fn follow(&mut self, frame: &MarkerFrame, seen: &[(usize, DVec3)]) {
        let now = frame.time_s;
        self.shared
            .status
            .tips_live
            .store(seen.len() as u64, Ordering::Relaxed);
        self.pca.push(now, self.follower.displacements(seen));
        self.live_tips.update(now, seen);
        if let Some(o) = self.osc.as_mut() {
            o.send(&tips_datagram(frame.frame, now, seen));
        }
        self.pose.offer(frame.frame, now, seen);
        let shared = &self.shared;
        if now >= self.next_pca {
            self.next_pca = now + shared.config.wind.pca_window_s;
            if let Some(e) = self.pca.estimate() {
                shared.new_wind(e);
                if let Some(o) = self.osc.as_mut() {
                    o.send(&wind_datagram(&e));
                }
            }
        }
    }

    /// Hands the window to the analysis when one is due (or the clock went
    /// back: a restarted source) and the analysis is free; while it is busy
    /// this costs two atomic loads per frame and nothing is copied.
    fn maybe_analyse(&mut self, now: f64) {
        let interval = self.shared.config.daemon.analysis_interval_s;
        if now < self.next_analysis && now >= self.next_analysis - 2.0 * interval {
            return;
        }
        if self.offer_window() {
            self.next_analysis = now + interval;
        }
    }

    /// Offers a snapshot of the window if the analysis is free; true if it was.
    fn offer_window(&mut self) -> bool {
        if !self.handoff.wants() {
            return false;
        }
        self.handoff.offer(Job {
            snapshot: self.window.snapshot(),
            frame_rate: self.rate.hz.round().max(1.0),
        });
        self.unanalysed = false;
        true
    }
}
