//! The analysis thread: the marker stage (`track::process`) on the window,
//! the triggers, and a tree request when one fires. The same code as
//! `treemocap replay`, on the last `daemon.window_s` seconds.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;

use crossbeam_channel::Receiver;
use glam::DVec3;

use super::pipeline::AnalysisJob;
use super::shared::{lock, Shared, TreeRequest};
use super::triggers::{compare_tips, TriggerConfig, Triggers};
use crate::model::tips::{CapturedTip, Tips};
use crate::track::RestSource;
use crate::wind::fan;

/// The analysis's state between windows.
pub(crate) struct Analysis {
    shared: Arc<Shared>,
    triggers: Triggers,
    /// What the last tree was built from, reused when a rebuild finds nothing
    /// changed so that the tree does not jump.
    last_build: Option<Tips>,
    /// The configured fan's wind is set once the first still phase gives the
    /// crown's centre.
    fan_set: bool,
}

/// What one window said about the tips.
struct Findings {
    tips: Tips,
    /// The window held a still phase (else the rest positions are the mean
    /// of a sway, bent downwind, and are not used).
    still: bool,
    rest: Vec<DVec3>,
    rest_len_s: f64,
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
        Analysis {
            shared,
            triggers,
            last_build: None,
            fan_set: false,
        }
    }

    /// Runs until the pipeline stops sending windows, then closes the tree
    /// requests so that the builder stops too.
    pub(crate) fn run(mut self, rx: Receiver<AnalysisJob>) {
        for (mut rec, now) in rx {
            match crate::track::process(&mut rec, &self.shared.config.tracking) {
                Ok((tips, summary)) => {
                    self.shared.status.analyses.fetch_add(1, Ordering::Relaxed);
                    let still = summary.rest_source != RestSource::WholeRecording;
                    self.handle(now, tips, still);
                }
                Err(e) => tracing::warn!("analysis: {e}"),
            }
        }
        self.shared.requests.close();
    }

    fn findings(&self, tips: Tips, still: bool) -> Findings {
        // Rest positions come only from a still phase. In a window of
        // continuous wind the tracker falls back to the mean of the sway,
        // which is bent downwind: that is not a tip moving, so the last
        // tree's tips stand and only wind, request and period can fire.
        let (rest, rest_len_s) = if still {
            (
                tips.tips.iter().map(|t| t.rest).collect(),
                tips.rest_window_s[1] - tips.rest_window_s[0],
            )
        } else {
            let built = self.triggers.built_tips().map(<[DVec3]>::to_vec);
            (built.unwrap_or_default(), 0.0)
        };
        Findings {
            tips,
            still,
            rest,
            rest_len_s,
        }
    }

    /// One analysed window: triggers, and a tree request when one fires.
    fn handle(&mut self, now: f64, tips: Tips, still: bool) {
        let f = self.findings(tips, still);
        let shared = self.shared.clone();
        shared.status.progress.set_still(f.rest_len_s);
        if !self.fan_set && f.still && !f.rest.is_empty() {
            if let Some(e) = fan::configured_fan_wind(&shared.config.wind, &f.rest, now) {
                shared.new_wind(e);
            }
            self.fan_set = true;
        }
        let wind = lock(&shared.wind).current(now);
        if shared.rebuild.swap(false, Ordering::Relaxed) {
            self.triggers.request();
        }
        let Some(reason) =
            self.triggers
                .check(now, &f.rest, f.rest_len_s, wind.map(|w| w.direction))
        else {
            return;
        };
        let moved_m = shared.config.daemon.moved_mm / 1000.0;
        let same_tips = self.last_build.as_ref().is_some_and(|b| {
            let old: Vec<DVec3> = b.tips.iter().map(|t| t.rest).collect();
            compare_tips(&old, &f.rest, moved_m) == (0, 0, 0)
        });
        // Unchanged tips (or no still phase to take new ones from): the last
        // tree's tips exactly, with the wind of now.
        let mut built = match self.last_build.take() {
            Some(b) if same_tips || !f.still => b,
            _ => f.tips,
        };
        built.wind = wind;
        let captured = built.captured();
        let positions: Vec<DVec3> = captured.iter().map(|t: &CapturedTip| t.position).collect();
        self.triggers
            .built(now, &positions, wind.map(|w| w.direction));
        let tips_json = built.to_json();
        let links = sway_links(&shared, &built);
        self.last_build = Some(built);
        tracing::info!("new tree: {reason}");
        shared.requests.put(TreeRequest {
            fired: Instant::now(),
            reason,
            time_s: now,
            tips: captured,
            tips_json,
            wind: wind.map_or(DVec3::ZERO, |w| w.flow_vector()),
            links,
        });
    }
}

/// The tips of `tips` that sway together in the window (docs/forest.md),
/// for telling several trees apart; none when the sway is turned off.
fn sway_links(shared: &Shared, tips: &Tips) -> Vec<crate::reconstruct::forest::SwayLink> {
    let f = &lock(&shared.recon_config).forest;
    if f.sway_weight_m > 0.0 {
        crate::reconstruct::forest::sway::links(tips, f.sway_correlation)
    } else {
        Vec::new()
    }
}
