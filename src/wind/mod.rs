//! The wind on the tree: where it blows and how hard, from one of three
//! sources, logged, and handed to the particle flow's wind force.
//!
//! Sources by default priority: a wind sensor on a serial port (`serial`),
//! the fan's position in the config (`fan`), or the principal direction of
//! the tips' sway (`pca`). [`WindSelector`] keeps the latest estimate of each
//! and answers with the best one that is still fresh.

use crate::model::wind::{WindEstimate, WindSource};

pub mod fan;
pub mod pca;
pub mod settings;

pub use settings::WindSettings;

/// Keeps the latest estimate per source and picks by priority.
#[derive(Debug, Clone)]
pub struct WindSelector {
    priority: Vec<WindSource>,
    /// An estimate older than this (s, on the session clock) is ignored, so a
    /// sensor that was unplugged hands over to the next source.
    max_age_s: f64,
    latest: Vec<WindEstimate>,
}

impl WindSelector {
    /// A selector with no estimate yet; `priority` is `wind.priority`,
    /// `max_age_s` is `wind.max_age_s`.
    pub fn new(priority: Vec<WindSource>, max_age_s: f64) -> Self {
        WindSelector {
            priority,
            max_age_s,
            latest: Vec::new(),
        }
    }

    /// Replaces the latest estimate of the estimate's source.
    pub fn update(&mut self, estimate: WindEstimate) {
        self.latest.retain(|e| e.source != estimate.source);
        self.latest.push(estimate);
    }

    /// The best fresh estimate at `now_s`. The fan never goes stale: it is a
    /// fixed fact of the rig.
    pub fn current(&self, now_s: f64) -> Option<WindEstimate> {
        self.priority.iter().find_map(|source| {
            self.latest
                .iter()
                .find(|e| e.source == *source)
                .filter(|e| e.source == WindSource::Fan || now_s - e.time_s <= self.max_age_s)
                .copied()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::wind::direction_of;

    fn est(source: WindSource, t: f64, az: f64) -> WindEstimate {
        WindEstimate {
            time_s: t,
            source,
            direction: direction_of(az),
            speed_m_s: None,
        }
    }

    #[test]
    fn priority_and_staleness() {
        let mut s = WindSelector::new(
            vec![WindSource::Sensor, WindSource::Fan, WindSource::Pca],
            5.0,
        );
        assert!(s.current(0.0).is_none());
        s.update(est(WindSource::Pca, 0.0, 10.0));
        assert_eq!(s.current(1.0).unwrap().source, WindSource::Pca);
        s.update(est(WindSource::Sensor, 1.0, 20.0));
        s.update(est(WindSource::Fan, 0.0, 30.0));
        assert_eq!(s.current(2.0).unwrap().source, WindSource::Sensor);
        // The sensor went quiet: the fan takes over, and never goes stale.
        assert_eq!(s.current(100.0).unwrap().source, WindSource::Fan);
    }
}
