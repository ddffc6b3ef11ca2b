//! When to build a new tree. Pure logic, fed after every analysis of the
//! recent frames, so each condition can be tested exactly.
//!
//! Rules (issue 6): the first tree once a still phase of `rest_min_s` has been
//! seen; a new tree when the set of tips has differed from the last tree's for
//! longer than `tip_change_s` (a marker added, fallen off, or moved by more
//! than `moved_mm`); when the wind became known (the last tree had none) or
//! turned by more than `wind_turn_deg`; on request; optionally every
//! `period_s`. Nothing else: an unchanged session gives one tree, not one
//! per analysis.

use glam::DVec3;
use serde::Serialize;

use crate::model::wind::angle_between_deg;

/// Thresholds, from the `[daemon]` config.
#[derive(Debug, Clone, Copy)]
pub struct TriggerConfig {
    /// Still phase (s) needed before the first tree.
    pub rest_min_s: f64,
    /// How long (s) tips must differ from the last tree's before a rebuild.
    pub tip_change_s: f64,
    /// Distance (m) beyond which a tip counts as moved.
    pub moved_m: f64,
    /// Wind turn (degrees) that triggers a rebuild.
    pub wind_turn_deg: f64,
    /// 0 disables the periodic rebuild.
    pub period_s: f64,
}

/// Why a tree was (re)built.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "trigger", rename_all = "snake_case")]
pub enum Reason {
    /// The first still phase of `rest_min_s` was seen.
    FirstTree,
    /// The tips differed from the last tree's for `tip_change_s`.
    TipsChanged {
        /// Tips with no old tip near them (a marker put on).
        added: usize,
        /// Old tips with no tip near them (a marker fallen off or hidden).
        removed: usize,
        /// Tips that moved beyond `moved_mm` (counted once, not as added
        /// and removed).
        moved: usize,
    },
    /// The wind turned by more than `wind_turn_deg`.
    WindTurned {
        /// Angle between the last tree's wind and now (degrees).
        degrees: f64,
    },
    /// The last tree was built without a wind and one is known now (the
    /// sway became measurable, a sensor started): a tree bent by it.
    WindKnown {
        /// Downwind azimuth of the wind now known (degrees).
        azimuth_deg: f64,
    },
    /// `POST /rebuild`, `/treemocap/rebuild` over OSC, or SIGHUP.
    Requested,
    /// `period_s` passed since the last tree.
    Period,
}

impl std::fmt::Display for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reason::FirstTree => write!(f, "first still phase"),
            Reason::TipsChanged {
                added,
                removed,
                moved,
            } => write!(
                f,
                "tips changed ({added} added, {removed} removed, {moved} moved)"
            ),
            Reason::WindTurned { degrees } => write!(f, "wind turned {degrees:.0}°"),
            Reason::WindKnown { azimuth_deg } => {
                write!(f, "wind known (towards azimuth {azimuth_deg:.0}°)")
            }
            Reason::Requested => write!(f, "requested"),
            Reason::Period => write!(f, "periodic"),
        }
    }
}

/// How two tip sets differ: tips of `now` with no old tip within `moved_m`
/// (added or moved) and old tips with no new tip within it (removed or moved).
pub fn compare_tips(old: &[DVec3], now: &[DVec3], moved_m: f64) -> (usize, usize, usize) {
    let unmatched = |a: &[DVec3], b: &[DVec3]| {
        a.iter()
            .filter(|p| !b.iter().any(|q| p.distance(*q) <= moved_m))
            .count()
    };
    let new_far = unmatched(now, old);
    let old_far = unmatched(old, now);
    // A tip that moved shows up once on each side; the rest were added or removed.
    let moved = new_far.min(old_far);
    (new_far - moved, old_far - moved, moved)
}

/// What the last tree was built from.
#[derive(Debug, Clone)]
struct Built {
    tips: Vec<DVec3>,
    wind: Option<DVec3>,
    time_s: f64,
}

/// The trigger state machine.
#[derive(Debug, Clone)]
pub struct Triggers {
    cfg: TriggerConfig,
    built: Option<Built>,
    /// When the tips started to differ from the built ones.
    change_since: Option<f64>,
    requested: bool,
}

impl Triggers {
    /// Triggers with no tree built yet: the first still phase builds one.
    pub fn new(cfg: TriggerConfig) -> Self {
        Triggers {
            cfg,
            built: None,
            change_since: None,
            requested: false,
        }
    }

    /// An explicit rebuild (HTTP, OSC, SIGHUP); fires at the next check.
    pub fn request(&mut self) {
        self.requested = true;
    }

    /// Decides after an analysis at `now_s`: the tips' rest positions, the
    /// length of the still phase they were averaged over, and the wind.
    pub fn check(
        &mut self,
        now_s: f64,
        tips: &[DVec3],
        rest_len_s: f64,
        wind: Option<DVec3>,
    ) -> Option<Reason> {
        let Some(built) = &self.built else {
            if !tips.is_empty() && rest_len_s >= self.cfg.rest_min_s {
                return Some(Reason::FirstTree);
            }
            return None;
        };
        if std::mem::take(&mut self.requested) {
            return Some(Reason::Requested);
        }
        let (added, removed, moved) = compare_tips(&built.tips, tips, self.cfg.moved_m);
        if added + removed + moved > 0 {
            let since = *self.change_since.get_or_insert(now_s);
            if now_s - since >= self.cfg.tip_change_s {
                return Some(Reason::TipsChanged {
                    added,
                    removed,
                    moved,
                });
            }
        } else {
            self.change_since = None;
        }
        match (built.wind, wind) {
            (Some(a), Some(b)) => {
                let degrees = angle_between_deg(a, b);
                if degrees > self.cfg.wind_turn_deg {
                    return Some(Reason::WindTurned { degrees });
                }
            }
            (None, Some(b)) => {
                return Some(Reason::WindKnown {
                    azimuth_deg: crate::model::wind::azimuth_of(b),
                })
            }
            _ => {}
        }
        if self.cfg.period_s > 0.0 && now_s - built.time_s >= self.cfg.period_s {
            return Some(Reason::Period);
        }
        None
    }

    /// Records what the new tree was built from.
    pub fn built(&mut self, now_s: f64, tips: &[DVec3], wind: Option<DVec3>) {
        self.built = Some(Built {
            tips: tips.to_vec(),
            wind,
            time_s: now_s,
        });
        self.change_since = None;
        self.requested = false;
    }

    /// The tips of the last tree, so an unchanged rebuild reuses them exactly.
    pub fn built_tips(&self) -> Option<&[DVec3]> {
        self.built.as_ref().map(|b| b.tips.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> TriggerConfig {
        TriggerConfig {
            rest_min_s: 5.0,
            tip_change_s: 3.0,
            moved_m: 0.01,
            wind_turn_deg: 20.0,
            period_s: 0.0,
        }
    }

    fn tips(n: usize) -> Vec<DVec3> {
        (0..n)
            .map(|i| DVec3::new(i as f64 * 0.2, 1.5, 0.0))
            .collect()
    }

    #[test]
    fn first_tree_waits_for_a_long_enough_still_phase() {
        let mut t = Triggers::new(cfg());
        assert_eq!(t.check(1.0, &tips(5), 2.0, None), None);
        assert_eq!(t.check(2.0, &[], 9.0, None), None);
        assert_eq!(t.check(6.0, &tips(5), 5.0, None), Some(Reason::FirstTree));
    }

    #[test]
    fn unchanged_session_gives_one_tree() {
        let mut t = Triggers::new(cfg());
        let mut fired = 0;
        for k in 0..600 {
            let now = k as f64;
            // Rest positions jitter by a few micrometres between analyses.
            let jitter: Vec<DVec3> = tips(24)
                .iter()
                .map(|p| *p + DVec3::splat(((k % 7) as f64) * 1e-6))
                .collect();
            if let Some(r) = t.check(now, &jitter, 20.0, Some(DVec3::X)) {
                fired += 1;
                assert_eq!(r, Reason::FirstTree);
                t.built(now, &jitter, Some(DVec3::X));
            }
        }
        assert_eq!(fired, 1);
    }

    #[test]
    fn a_removed_marker_fires_after_tip_change_s_not_before() {
        let mut t = Triggers::new(cfg());
        t.built(0.0, &tips(24), None);
        let fewer = &tips(24)[..23];
        assert_eq!(t.check(10.0, fewer, 20.0, None), None);
        assert_eq!(t.check(12.9, fewer, 20.0, None), None);
        assert_eq!(
            t.check(13.0, fewer, 20.0, None),
            Some(Reason::TipsChanged {
                added: 0,
                removed: 1,
                moved: 0
            })
        );
        // A blip shorter than tip_change_s does not fire.
        let mut t = Triggers::new(cfg());
        t.built(0.0, &tips(24), None);
        assert_eq!(t.check(10.0, fewer, 20.0, None), None);
        assert_eq!(t.check(11.0, &tips(24), 20.0, None), None);
        assert_eq!(t.check(14.5, fewer, 20.0, None), None);
    }

    #[test]
    fn moved_tip_and_wind_turn_and_request() {
        let mut t = Triggers::new(cfg());
        t.built(0.0, &tips(3), Some(DVec3::X));
        let mut moved = tips(3);
        moved[1].x += 0.05;
        assert_eq!(t.check(1.0, &moved, 20.0, Some(DVec3::X)), None);
        assert_eq!(
            t.check(4.0, &moved, 20.0, Some(DVec3::X)),
            Some(Reason::TipsChanged {
                added: 0,
                removed: 0,
                moved: 1
            })
        );
        t.built(4.0, &moved, Some(DVec3::X));
        let turned = DVec3::new(1.0, 0.0, 0.3).normalize(); // 16.7°
        assert_eq!(t.check(5.0, &moved, 20.0, Some(turned)), None);
        let turned = DVec3::new(1.0, 0.0, 0.5).normalize(); // 26.6°
        assert!(matches!(
            t.check(6.0, &moved, 20.0, Some(turned)),
            Some(Reason::WindTurned { .. })
        ));
        t.built(6.0, &moved, Some(turned));
        t.request();
        assert_eq!(
            t.check(7.0, &moved, 20.0, Some(turned)),
            Some(Reason::Requested)
        );
        assert_eq!(t.check(8.0, &moved, 20.0, Some(turned)), None);
    }

    #[test]
    fn a_wind_that_becomes_known_fires_once() {
        let mut t = Triggers::new(cfg());
        t.built(0.0, &tips(3), None);
        assert_eq!(t.check(1.0, &tips(3), 20.0, None), None);
        assert_eq!(
            t.check(2.0, &tips(3), 20.0, Some(DVec3::X)),
            Some(Reason::WindKnown { azimuth_deg: 90.0 })
        );
        t.built(2.0, &tips(3), Some(DVec3::X));
        assert_eq!(t.check(3.0, &tips(3), 20.0, Some(DVec3::X)), None);
        // Losing the wind (a stale sensor) is no reason to rebuild.
        assert_eq!(t.check(4.0, &tips(3), 20.0, None), None);
    }

    #[test]
    fn period() {
        let mut t = Triggers::new(TriggerConfig {
            period_s: 30.0,
            ..cfg()
        });
        t.built(0.0, &tips(3), None);
        assert_eq!(t.check(29.0, &tips(3), 20.0, None), None);
        assert_eq!(t.check(30.0, &tips(3), 20.0, None), Some(Reason::Period));
    }
}
