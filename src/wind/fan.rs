//! Wind from a fan at a known place: it blows from the fan through the
//! crown's centre. The vertical part is dropped: a lab fan on a stand blows
//! roughly level, and the flow's wind force is horizontal in the paper.

use glam::DVec3;

use crate::model::wind::{WindEstimate, WindSource};

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

/// Centre of the bounding box of the tips (the crown's centre), or `None`
/// for no tips.
pub fn crown_centre(tips: &[DVec3]) -> Option<DVec3> {
    let first = *tips.first()?;
    let (lo, hi) = tips
        .iter()
        .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    Some((lo + hi) / 2.0)
}

/// The wind of the fan in the config (`wind.fan_position`, `fan_speed_m_s`)
/// through the centre of these tips; `None` without a fan or tips.
pub fn configured_fan_wind(
    config: &crate::wind::WindSettings,
    tips: &[DVec3],
    time_s: f64,
) -> Option<WindEstimate> {
    let fan = config.fan()?;
    let speed = (config.fan_speed_m_s > 0.0).then_some(config.fan_speed_m_s);
    fan_wind(fan, crown_centre(tips)?, speed, time_s)
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

    #[test]
    fn crown_centre_is_the_bounding_box_centre() {
        let tips = [
            DVec3::new(-1.0, 1.0, 0.0),
            DVec3::new(3.0, 2.0, 4.0),
            DVec3::ONE,
        ];
        assert_eq!(crown_centre(&tips), Some(DVec3::new(1.0, 1.5, 2.0)));
        assert_eq!(crown_centre(&[]), None);
    }
}
