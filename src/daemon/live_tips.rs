//! The viewers' frame of the live daemon: the raw markers of a frame, which
//! of them the tips claim (the rest is noise once there are tips), and each
//! tip's state.
//!
//! The live tips come from the marker stage's tracker run frame by frame
//! (`crate::track::live`); a tip not found in a frame is held at its last
//! position and shown as gap-filled for up to `tracking.max_fill_s` (the
//! longest gap the marker stage fills), then as not seen now.

use glam::DVec3;

use crate::model::frame::MarkerFrame;
use crate::protocol::live_frame::{LiveFrame, LiveTip, MarkerClass, TipState};

/// One tip of the current tree as the viewers see it.
#[derive(Debug, Clone, Copy)]
struct Held {
    marker: u32,
    /// Last position seen (the rest position until first seen).
    position: [f32; 3],
    /// Frame time it was last seen; −∞ before.
    seen_s: f64,
}

/// Tip states across frames; memory bounded by the number of tips.
#[derive(Debug, Clone)]
pub(crate) struct LiveTips {
    /// How long a hidden tip counts as filled (s).
    hold_s: f64,
    /// The current tree's tips, in marker order.
    tips: Vec<Held>,
}

fn f32x3(p: DVec3) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

impl LiveTips {
    /// `hold_s`: how long a hidden tip is shown as filled.
    pub(crate) fn new(hold_s: f64) -> Self {
        LiveTips {
            hold_s,
            tips: Vec::new(),
        }
    }

    /// A new tree: its tips, at their rest positions until seen.
    pub(crate) fn set_tips(&mut self, tips: &[(usize, DVec3)]) {
        self.tips = tips
            .iter()
            .map(|&(m, p)| Held {
                marker: m as u32,
                position: f32x3(p),
                seen_s: f64::NEG_INFINITY,
            })
            .collect();
        self.tips.sort_by_key(|t| t.marker);
    }

    /// Records which tips were seen at `time_s` (every frame, viewers or
    /// not). `seen` comes by marker, as the tips are kept: the two are
    /// walked together (a search per tip was 10 steps each at 1 000 tips);
    /// one out of order is still found, by a search.
    pub(crate) fn update(&mut self, time_s: f64, seen: &[(usize, DVec3)]) {
        let mut at = 0;
        for &(m, p) in seen {
            let m = m as u32;
            while self.tips.get(at).is_some_and(|t| t.marker < m) {
                at += 1;
            }
            let i = match self.tips.get(at) {
                Some(t) if t.marker == m => at,
                _ => match self.tips.binary_search_by_key(&m, |t| t.marker) {
                    Ok(i) => i,
                    Err(_) => continue,
                },
            };
            self.tips[i].position = f32x3(p);
            self.tips[i].seen_s = time_s;
        }
    }

    /// The frame for the viewers. `claimed[i]` is true when marker `i` of the
    /// frame is a tip's; with no tips nothing is classified.
    pub(crate) fn frame(&self, frame: &MarkerFrame, claimed: &[bool]) -> LiveFrame {
        let classes = if self.tips.is_empty() {
            Vec::new()
        } else {
            (0..frame.markers.len())
                .map(|i| {
                    if claimed.get(i).copied().unwrap_or(false) {
                        MarkerClass::Tip
                    } else {
                        MarkerClass::Noise
                    }
                })
                .collect()
        };
        let now = frame.time_s;
        LiveFrame {
            frame: frame.frame,
            time_s: now,
            markers: frame.positions().map(f32x3).collect(),
            classes,
            tips: self
                .tips
                .iter()
                .map(|t| LiveTip {
                    marker: t.marker,
                    state: if t.seen_s == now {
                        TipState::Measured
                    } else if now - t.seen_s <= self.hold_s {
                        TipState::Filled
                    } else {
                        TipState::Unseen
                    },
                    position: t.position,
                })
                .collect(),
        }
    }
}
