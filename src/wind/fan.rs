//! Wind from a fan at a known place: it blows from the fan through the
//! crown's centre. The vertical part is dropped: a lab fan on a stand blows
//! roughly level, and the flow's wind force is horizontal in the paper.

use glam::DVec3;

use super::{WindEstimate, WindSource};

/// The fan's wind at `crown_centre`, or `None` when the fan stands (in plan
/// view) on the crown's centre and no direction follows.
pub fn fan_wind(
    fan_position: DVec3,
    crown_centre: DVec3,
    speed_m_s: Option<f64>,
    time_s: f64,
) -> Option<WindEstimate> {
    let mut d = crown_centre - fan_position;
    d.y = 0.0;
    if d.length() < 1e-6 {
        return None;
    }
    Some(WindEstimate {
        time_s,
        source: WindSource::Fan,
        direction: d.normalize(),
        speed_m_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blows_from_the_fan_through_the_crown() {
        let w = fan_wind(
            DVec3::new(-3.0, 1.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
            Some(4.0),
            0.0,
        )
        .unwrap();
        assert!((w.direction - DVec3::X).length() < 1e-12);
        assert!((w.azimuth_deg() - 90.0).abs() < 1e-9);
        assert!(fan_wind(DVec3::new(0.0, 5.0, 0.0), DVec3::ZERO, None, 0.0).is_none());
    }
}
