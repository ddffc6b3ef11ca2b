//! `tips.json`: the captured tips' rest positions and the wind, written by
//! the marker stage and read by reconstruction. [`Tips::to_json`] is its one
//! writer and [`parse_tips`] its one reader; the format is described in
//! docs/formats.md. Fields the reader does not use (samples, spread, later
//! additions) are accepted and ignored so older readers keep working.

use std::path::Path;

use glam::DVec3;
use serde::{Deserialize, Serialize, Serializer};

use crate::error::{Error, Location, Result};
use crate::model::trace::{Timeline, Trace};
use crate::model::wind::{WindEstimate, WindSource, UNKNOWN_SPEED};

/// A captured branch tip: a marker's rest position, what reconstruction
/// starts from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CapturedTip {
    /// The marker's index in tips.json, kept through to the outputs so a
    /// captured tip can be matched to its live motion.
    pub marker: usize,
    /// Rest position (m, Y up).
    pub position: DVec3,
}

fn vec3<S: Serializer>(v: &DVec3, s: S) -> Result<S::Ok, S::Error> {
    [v.x, v.y, v.z].serialize(s)
}

/// One branch tip: a cleaned marker and its rest position (an entry of
/// tips.json, docs/formats.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Tip {
    /// Index of the marker, 0.., in order of first appearance.
    pub marker: usize,
    /// Mean of the measured samples in the rest window (m, Y up).
    #[serde(serialize_with = "vec3")]
    pub rest: DVec3,
    /// Measured samples that went into `rest`.
    pub samples: usize,
    /// Fraction of the session's frames in which the marker was not measured.
    pub gap_fraction: f64,
    /// Root mean square distance of those samples from `rest` (m): how
    /// still the marker was, and with `samples` how precise `rest` is.
    pub spread_m: f64,
    /// The cleaned trace (measured, filled and missing frames).
    #[serde(skip)]
    pub trace: Trace,
}

/// Result of the marker stage: what reconstruction reads (`tips.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Tips {
    /// Format version of `tips.json`.
    pub version: u32,
    /// Where the frames came from (take name, server, simulator seed).
    pub source: String,
    /// Frames per second of the recording.
    pub frame_rate: f64,
    /// The rest window in seconds from the start of the recording.
    pub rest_window_s: [f64; 2],
    /// One entry per marker that survived cleaning, in marker order: the
    /// captured tips the tree grows from.
    pub tips: Vec<Tip>,
    /// The wind the flow used (`wind` in tips.json: direction, speed or
    /// null when only the direction is known, and its source).
    #[serde(serialize_with = "wind_json")]
    pub wind: Option<WindEstimate>,
    /// Time of every internal frame (for plots of the traces).
    #[serde(skip)]
    pub timeline: Timeline,
}

impl Tips {
    /// `tips.json` (pretty-printed, stable field order, newline at the end):
    /// the one writer of the format that [`parse_tips`] reads.
    pub fn to_json(&self) -> String {
        // Every field is a plain number, string or list: serialising cannot
        // fail, and an empty object would silently lose the tips.
        let mut text = serde_json::to_string_pretty(self).expect("tips serialise");
        text.push('\n');
        text
    }

    /// The captured tips as reconstruction takes them.
    pub fn captured(&self) -> Vec<CapturedTip> {
        self.tips
            .iter()
            .map(|t| CapturedTip {
                marker: t.marker,
                position: t.rest,
            })
            .collect()
    }
}

fn wind_json<S: Serializer>(w: &Option<WindEstimate>, s: S) -> Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct Json {
        direction: [f64; 3],
        /// m/s; null when only the direction is known (sway PCA).
        speed: Option<f64>,
        source: WindSource,
    }
    w.map(|w| Json {
        direction: w.direction.to_array(),
        speed: w.speed_m_s,
        source: w.source,
    })
    .serialize(s)
}

/// What reconstruction takes from a tips.json.
#[derive(Debug, Clone, PartialEq)]
pub struct TipsInput {
    /// Captured tips in file order.
    pub tips: Vec<CapturedTip>,
    /// Wind direction × speed; zero when the file has no wind.
    pub wind: DVec3,
    /// The recording the tips came from, if the file names it.
    pub source: Option<String>,
}

#[derive(Deserialize)]
struct TipsJson {
    version: u32,
    #[serde(default)]
    source: Option<String>,
    tips: Vec<TipJson>,
    #[serde(default)]
    wind: Option<WindJson>,
}

#[derive(Deserialize)]
struct TipJson {
    marker: usize,
    rest: [f64; 3],
}

#[derive(Deserialize)]
struct WindJson {
    direction: [f64; 3],
    /// Null when only the direction was measured: a relative strength of 1.
    #[serde(default)]
    speed: Option<f64>,
}

/// Parses tips.json text; `path` only names the file in errors.
pub fn parse_tips(text: &str, path: &Path) -> Result<TipsInput> {
    let file: TipsJson = serde_json::from_str(text).map_err(|e| Error::json(path, &e))?;
    let field = |name: String, msg: String| Error::parse(path, Location::Field(name), msg);
    if file.version != 1 {
        return Err(Error::Unsupported {
            path: path.into(),
            msg: format!(
                "tips.json version {} (this build reads version 1)",
                file.version
            ),
        });
    }
    if file.tips.is_empty() {
        return Err(field(
            "tips".into(),
            "no tips: nothing to reconstruct".into(),
        ));
    }
    let mut seen = std::collections::BTreeMap::new();
    let mut tips = Vec::with_capacity(file.tips.len());
    for (i, t) in file.tips.iter().enumerate() {
        let position = DVec3::from_array(t.rest);
        if !position.is_finite() {
            return Err(field(
                format!("tips[{i}].rest"),
                "not a finite position".into(),
            ));
        }
        if let Some(first) = seen.insert(t.marker, i) {
            return Err(field(
                format!("tips[{i}].marker"),
                format!("marker {} already used by tips[{first}]", t.marker),
            ));
        }
        tips.push(CapturedTip {
            marker: t.marker,
            position,
        });
    }
    let wind = match file.wind {
        None => DVec3::ZERO,
        Some(w) => {
            let dir = DVec3::from_array(w.direction);
            let speed = w.speed.unwrap_or(UNKNOWN_SPEED);
            if !dir.is_finite() || !speed.is_finite() || speed < 0.0 {
                return Err(field(
                    "wind".into(),
                    "direction must be finite and speed finite and not negative".into(),
                ));
            }
            // Direction is documented as a unit vector; normalise anyway so a
            // hand-edited file cannot scale the wind force by accident.
            dir.try_normalize().unwrap_or(DVec3::ZERO) * speed
        }
    };
    Ok(TipsInput {
        tips,
        wind,
        source: file.source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"{"version":1,"source":"a.csv","frame_rate":100,
      "rest_window_s":[0,20],
      "tips":[{"marker":0,"rest":[0.1,1.5,-0.2],"samples":2000,"gap_fraction":0.0,"spread_m":0.0004},
              {"marker":3,"rest":[-0.3,1.9,0.25],"samples":1990,"gap_fraction":0.005,"spread_m":0.0002}],
      "wind":{"direction":[0,0,2],"speed":3.0}}"#;

    #[test]
    fn reads_the_documented_format() {
        let t = parse_tips(GOOD, Path::new("tips.json")).unwrap();
        assert_eq!(t.tips.len(), 2);
        assert_eq!(t.tips[1].marker, 3);
        assert_eq!(t.tips[1].position, DVec3::new(-0.3, 1.9, 0.25));
        assert_eq!(t.wind, DVec3::new(0.0, 0.0, 3.0));
        assert_eq!(t.source.as_deref(), Some("a.csv"));
        let no_wind = GOOD.replace(r#"{"direction":[0,0,2],"speed":3.0}"#, "null");
        assert_eq!(
            parse_tips(&no_wind, Path::new("t")).unwrap().wind,
            DVec3::ZERO
        );
    }

    #[test]
    fn errors_name_the_file_and_the_place() {
        let e = parse_tips("{\"version\":1,\n\"tips\":[}", Path::new("x/tips.json")).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("x/tips.json") && msg.contains("line 2"),
            "{msg}"
        );
        let dup = GOOD.replace("\"marker\":3", "\"marker\":0");
        let msg = parse_tips(&dup, Path::new("t.json"))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("tips[1].marker"), "{msg}");
        let v2 = GOOD.replace("\"version\":1", "\"version\":2");
        assert!(parse_tips(&v2, Path::new("t"))
            .unwrap_err()
            .to_string()
            .contains("version 2"));
        let nan = GOOD.replace("[0.1,1.5,-0.2]", "[0.1,1e999,-0.2]");
        assert!(parse_tips(&nan, Path::new("t")).is_err());
        let empty = r#"{"version":1,"tips":[],"wind":null}"#;
        assert!(parse_tips(empty, Path::new("t"))
            .unwrap_err()
            .to_string()
            .contains("tips"));
    }

    #[test]
    fn tips_json_has_the_documented_fields() {
        let tips = Tips {
            version: 1,
            source: "test".into(),
            frame_rate: 100.0,
            rest_window_s: [0.0, 8.0],
            tips: vec![Tip {
                marker: 0,
                rest: DVec3::new(0.1, 1.5, -0.2),
                samples: 800,
                gap_fraction: 0.05,
                spread_m: 0.0002,
                trace: Trace::new(0, 0, DVec3::ZERO, None),
            }],
            wind: None,
            timeline: Timeline::default(),
        };
        let v: serde_json::Value = serde_json::from_str(&tips.to_json()).unwrap();
        assert_eq!(v["version"], 1);
        assert_eq!(v["rest_window_s"][1], 8.0);
        assert_eq!(v["tips"][0]["rest"][1], 1.5);
        assert_eq!(v["tips"][0]["samples"], 800);
        assert!(v["tips"][0].get("trace").is_none());
        assert!(v["wind"].is_null());
    }
}
