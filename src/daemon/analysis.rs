//! The analysis thread: the marker stage on a snapshot of the window, the
//! triggers, and a tree request when one fires. The same code as
//! `treemocap replay`, on the last `daemon.window_s` seconds. Every tree is
//! built from the best rest positions seen so far (`rest_estimate`): they
//! improve while a still phase goes on, and a rebuild uses the latest.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

use super::handoff::{track_snapshot, AnalysisHandoff};
use super::rest_estimate::{BestRest, RestEstimate};
use super::shared::{lock, Shared, TreeRequest};
use super::triggers::{TriggerConfig, Triggers};
use crate::model::tips::Tips;
use crate::model::trace::{Timeline, Trace};
use crate::reconstruct::forest::SwayLink;
use crate::track::RestSource;
use crate::wind::fan;

/// The analysis's state between windows.
pub(crate) struct Analysis {
    shared: Arc<Shared>,
    triggers: Triggers,
    /// The best rest positions seen, from a still phase, with the tips they
    /// belong to; every tree is built from them, so a rebuild on unchanged
    /// data gives the very same tree.
    best: BestRest<Tips>,
    /// The configured fan's wind is set once the first still phase gives the
    /// crown's centre.
    fan_set: bool,
    /// Tips that swayed together in the last window with wind (for telling
    /// several trees apart, docs/forest.md). Taken from the window's traces
    /// before `best` drops them; still windows (no sway) keep the last.
    links: Vec<SwayLink>,
}

impl Analysis {
    /// The analysis with the daemon's trigger settings.
    pub(crate) fn new(shared: Arc<Shared>) -> Self {
        let d = &shared.config.daemon;
        let triggers = Triggers::new(TriggerConfig {
            rest_min_s: d.rest_min_s,
            tip_change_s: d.tip_change_s,
            moved_m: d.moved_mm / 1000.0,
            wind_turn_deg: d.wind_turn_deg,
            period_s: d.period_s,
        });
        let best = BestRest::new(d.moved_mm / 1000.0);
        Analysis {
            shared,
            triggers,
            best,
            fan_set: false,
            links: Vec::new(),
        }
    }

    /// Runs until the pipeline closes the hand-off, then closes the tree
    /// requests so that the builder stops too.
    pub(crate) fn run(mut self, handoff: &AnalysisHandoff) {
        while let Some(job) = handoff.recv() {
            let now = job.snapshot.now_s;
            let (tips, summary) = track_snapshot(&job, &self.shared.config.tracking);
            drop(job);
            handoff.done();
            self.shared.status.analyses.fetch_add(1, Ordering::Relaxed);
            let links = sway_links(&self.shared, &tips);
            if !links.is_empty() {
                self.links = links;
            }
            // Rest positions come only from a still phase. In a window of
            // continuous wind the tracker falls back to the mean of the
            // sway, which is bent downwind: that is not a tip moving, so the
            // best rest positions stand and only wind, request and period
            // can fire.
            if summary.rest_source != RestSource::WholeRecording && !tips.tips.is_empty() {
                self.offer_rest(tips);
            }
            self.handle(now);
        }
        self.shared.requests.close();
    }

    /// Offers an analysis's rest positions to the best estimate, without the
    /// traces (they are the window's size; only the rest positions are kept).
    fn offer_rest(&mut self, mut tips: Tips) {
        for t in &mut tips.tips {
            t.trace = Trace::new(t.trace.id, 0, t.rest, None);
        }
        tips.timeline = Timeline::default();
        self.best.offer(RestEstimate {
            positions: tips.tips.iter().map(|t| t.rest).collect(),
            window_s: tips.rest_window_s,
            payload: tips,
        });
    }

    /// After an analysis: triggers, and a tree request when one fires.
    fn handle(&mut self, now: f64) {
        let shared = self.shared.clone();
        let Some(rest) = self.best.get() else {
            return;
        };
        shared.status.progress.set_still(rest.len_s());
        if !self.fan_set {
            if let Some(e) = fan::configured_fan_wind(&shared.config.wind, &rest.positions, now) {
                shared.new_wind(e);
            }
            self.fan_set = true;
        }
        let wind = lock(&shared.wind).current(now);
        if shared.rebuild.swap(false, Ordering::Relaxed) {
            self.triggers.request();
        }
        let Some(reason) = self.triggers.check(
            now,
            &rest.positions,
            rest.len_s(),
            wind.map(|w| w.direction),
        ) else {
            return;
        };
        let mut built = rest.payload.clone();
        built.wind = wind;
        self.triggers
            .built(now, &rest.positions, wind.map(|w| w.direction));
        let links = self.links.clone();
        tracing::info!("new tree: {reason}");
        shared.requests.put(TreeRequest {
            fired: Instant::now(),
            reason,
            time_s: now,
            tips: built.captured(),
            tips_json: built.to_json(),
            wind: wind.map_or(DVec3::ZERO, |w| w.flow_vector()),
            links,
        });
    }
}

/// The tips of `tips` that sway together in the window (docs/forest.md),
/// for telling several trees apart; none when the sway is turned off.
fn sway_links(shared: &Shared, tips: &Tips) -> Vec<SwayLink> {
    let f = &lock(&shared.recon_config).forest;
    if f.sway_weight_m > 0.0 {
        crate::reconstruct::forest::sway::links(tips)
    } else {
        Vec::new()
    }
}
