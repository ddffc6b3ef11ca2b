//! Which markers of a NatNet frame become the [`MarkerFrame`], in which
//! axes, and its timestamps: the edge where NatNet's types become ours.
//!
//! A tree rig wants the unlabeled point cloud. Where NatNet puts it depends on
//! the version (spec §5): from 3.0 the unlabeled markers are the entries of
//! the *labeled* list with params bit 0x10 (model id 0); before 3.0 the only
//! unlabeled list is the legacy "other markers". The legacy list is not a
//! reliable unlabeled list in 3.x+ (Motive 2.1 fills it with rigid-body
//! markers), so it is used there only when asked for.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::{FrameOfData, Version};
pub use crate::model::frame::UpAxis;
use crate::model::frame::{Marker, MarkerFrame};

/// The `natnet.markers` setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MarkerSelection {
    /// The unlabeled point cloud: labeled-list entries with the unlabeled bit
    /// (3.0+), the legacy other markers (2.x). What a tree rig needs.
    #[default]
    Unlabeled,
    /// Markers that belong to a model: labeled-list entries without the
    /// unlabeled bit (3.0+), every labeled-list entry (2.x).
    Labeled,
    /// The legacy "other markers" list, whatever the version (for servers
    /// configured to put the point cloud there).
    Other,
    /// The whole labeled list (3.0+: labeled and unlabeled); 2.x adds the
    /// other markers, since its labeled list has no unlabeled ones.
    All,
}

impl std::str::FromStr for MarkerSelection {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "unlabeled" => Ok(MarkerSelection::Unlabeled),
            "labeled" => Ok(MarkerSelection::Labeled),
            "other" => Ok(MarkerSelection::Other),
            "all" => Ok(MarkerSelection::All),
            _ => Err(format!(
                "'{s}' is not a marker selection; use unlabeled, labeled, other or all"
            )),
        }
    }
}

/// The `natnet.up_axis` setting: which axis of the stream points up.
/// treemocap works Y up; a Z-up stream is turned at this edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpAxisSetting {
    /// Ask the server (`GetProperty,,Up Axis`, Motive 2.0+); Y up when it
    /// cannot say (frames themselves never say).
    #[default]
    Auto,
    /// The stream is Y up (Motive's default).
    Y,
    /// The stream is Z up (Motive's "Z up" streaming option).
    Z,
}

impl std::str::FromStr for UpAxisSetting {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "auto" => Ok(UpAxisSetting::Auto),
            "y" => Ok(UpAxisSetting::Y),
            "z" => Ok(UpAxisSetting::Z),
            _ => Err(format!("'{s}' is not an up axis; use y, z or auto")),
        }
    }
}

/// Reads Motive's answer to `GetProperty,,Up Axis`: a text naming the axis
/// ("Y", "Z up", …). None when it names neither.
pub fn up_axis_from_answer(text: &str) -> Option<UpAxis> {
    let t = text.trim().to_ascii_uppercase();
    match (t.contains('Z'), t.contains('Y')) {
        (true, false) => Some(UpAxis::Z),
        (false, true) => Some(UpAxis::Y),
        _ => None,
    }
}

/// The axis as the server names it in its answer and the log says it.
pub fn up_axis_name(up: UpAxis) -> &'static str {
    match up {
        UpAxis::Y => "Y",
        UpAxis::Z => "Z",
    }
}

fn v3(p: &[f32; 3], up: UpAxis) -> DVec3 {
    up.to_y_up(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
}

/// What a NatNet frame becomes a [`MarkerFrame`] with: known once the
/// session has talked to the server.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameContext {
    /// The bitstream the frame was decoded with.
    pub version: Version,
    /// Which markers to take.
    pub selection: MarkerSelection,
    /// The stream's up axis.
    pub up: UpAxis,
    /// Ticks per second of the server's clock (0: unknown), for latency.
    pub clock_frequency: u64,
}

/// The markers of `frame` that `selection` asks for, positions in metres
/// (NatNet streams metres), turned Y up. Labeled-list entries keep their
/// NatNet id as the hint; other markers have none.
pub fn select_markers(
    frame: &FrameOfData,
    version: Version,
    selection: MarkerSelection,
    up: UpAxis,
) -> Vec<Marker> {
    let labeled = |keep: &dyn Fn(bool) -> bool| -> Vec<Marker> {
        frame
            .labeled_markers
            .iter()
            .filter(|m| keep(m.is_unlabeled()))
            .map(|m| Marker {
                position: v3(&m.position, up),
                id: Some(m.id as i64),
            })
            .collect()
    };
    let other = || -> Vec<Marker> {
        frame
            .other_markers
            .iter()
            .map(|p| Marker::new(v3(p, up)))
            .collect()
    };
    let modern = version.major >= 3;
    match selection {
        MarkerSelection::Unlabeled if modern => labeled(&|u| u),
        MarkerSelection::Unlabeled => other(),
        MarkerSelection::Labeled if modern => labeled(&|u| !u),
        MarkerSelection::Labeled => labeled(&|_| true),
        MarkerSelection::Other => other(),
        MarkerSelection::All if modern => labeled(&|_| true),
        MarkerSelection::All => {
            let mut m = labeled(&|_| true);
            m.extend(other());
            m
        }
    }
}

/// System latency in seconds (3.0+): transmit minus mid-exposure, in server
/// clock ticks, over the clock frequency from SERVERINFO. None when the
/// version has no hi-res timestamps, the clock is unknown or the stamps are
/// not in order.
pub fn latency_s(frame: &FrameOfData, version: Version, clock_frequency: u64) -> Option<f64> {
    if version.major < 3 || clock_frequency == 0 || frame.camera_mid_exposure == 0 {
        return None;
    }
    let ticks = frame.transmit.checked_sub(frame.camera_mid_exposure)?;
    Some(ticks as f64 / clock_frequency as f64)
}

/// Builds the [`MarkerFrame`]. Its time is the frame's own timestamp
/// (2.6+); for 2.5 and earlier, which have none, the caller's
/// `fallback_time_s` (frame number over the frame rate, or arrival time).
pub fn to_marker_frame(
    frame: &FrameOfData,
    cx: &FrameContext,
    fallback_time_s: f64,
) -> MarkerFrame {
    let time_s = if cx.version.at_least(2, 6) {
        frame.timestamp
    } else {
        fallback_time_s
    };
    MarkerFrame {
        frame: frame.frame_number as i64,
        time_s,
        markers: select_markers(frame, cx.version, cx.selection, cx.up),
        latency_s: latency_s(frame, cx.version, cx.clock_frequency),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::natnet::LabeledMarker;

    fn frame() -> FrameOfData {
        FrameOfData {
            frame_number: 5,
            other_markers: vec![[9.0, 9.0, 9.0]],
            labeled_markers: vec![
                LabeledMarker {
                    id: 50007,
                    position: [1.0, 2.0, 3.0],
                    params: 0x12,
                    ..Default::default()
                },
                LabeledMarker {
                    id: 131073,
                    position: [4.0, 5.0, 6.0],
                    params: 0x02,
                    ..Default::default()
                },
            ],
            timestamp: 12.5,
            camera_mid_exposure: 1_000,
            transmit: 4_000,
            ..Default::default()
        }
    }

    #[test]
    fn unlabeled_is_the_flagged_labeled_entries_in_3x_and_other_markers_in_2x() {
        let f = frame();
        let m = select_markers(
            &f,
            Version::new(3, 1),
            MarkerSelection::Unlabeled,
            UpAxis::Y,
        );
        assert_eq!(m.len(), 1);
        assert_eq!(m[0].id, Some(50007));
        assert_eq!(m[0].position, DVec3::new(1.0, 2.0, 3.0));
        let m = select_markers(
            &f,
            Version::new(2, 9),
            MarkerSelection::Unlabeled,
            UpAxis::Y,
        );
        assert_eq!(m, vec![Marker::new(DVec3::splat(9.0))]);
        let m = select_markers(&f, Version::new(4, 1), MarkerSelection::Labeled, UpAxis::Y);
        assert_eq!(m[0].id, Some(131073));
        assert_eq!(
            select_markers(&f, Version::new(4, 1), MarkerSelection::All, UpAxis::Y).len(),
            2
        );
        assert_eq!(
            select_markers(&f, Version::new(2, 7), MarkerSelection::All, UpAxis::Y).len(),
            3
        );
        assert_eq!(
            select_markers(&f, Version::new(4, 1), MarkerSelection::Other, UpAxis::Y).len(),
            1
        );
    }

    #[test]
    fn z_up_streams_are_turned_y_up_and_the_answer_is_read() {
        let f = frame();
        let m = select_markers(
            &f,
            Version::new(3, 1),
            MarkerSelection::Unlabeled,
            UpAxis::Z,
        );
        // Z up (1, 2, 3): height 3 becomes y, depth is -2.
        assert_eq!(m[0].position, DVec3::new(1.0, 3.0, -2.0));
        assert_eq!(up_axis_from_answer("Z Up"), Some(UpAxis::Z));
        assert_eq!(up_axis_from_answer("y"), Some(UpAxis::Y));
        assert_eq!(up_axis_from_answer("1"), None);
        assert_eq!("Z".parse(), Ok(UpAxisSetting::Z));
        assert!("up".parse::<UpAxisSetting>().is_err());
    }

    #[test]
    fn latency_is_transmit_minus_mid_exposure_over_clock() {
        let f = frame();
        // 3000 ticks at 1 MHz = 3 ms.
        assert_eq!(latency_s(&f, Version::new(3, 0), 1_000_000), Some(0.003));
        assert_eq!(latency_s(&f, Version::new(2, 9), 1_000_000), None);
        assert_eq!(latency_s(&f, Version::new(3, 0), 0), None);
        let cx = |version, clock_frequency| FrameContext {
            version,
            selection: MarkerSelection::Unlabeled,
            up: UpAxis::Y,
            clock_frequency,
        };
        let mf = to_marker_frame(&f, &cx(Version::new(2, 5), 0), 0.25);
        assert_eq!((mf.frame, mf.time_s, mf.latency_s), (5, 0.25, None));
        let mf = to_marker_frame(&f, &cx(Version::new(3, 0), 1_000_000), 0.25);
        assert_eq!((mf.time_s, mf.latency_s), (12.5, Some(0.003)));
    }
}
