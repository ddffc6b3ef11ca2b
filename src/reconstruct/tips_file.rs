//! Reader of `tips.json` (contract 2, written by the marker processing):
//! the captured tips' rest positions and the wind, the input of
//! `treemocap reconstruct`. Fields we do not use (samples, spread, traces,
//! later additions) are accepted and ignored so older readers keep working.

use std::path::Path;

use glam::DVec3;
use serde::Deserialize;

use crate::error::{Error, Location, Result};
use crate::reconstruct::CapturedTip;

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
struct File {
    version: u32,
    #[serde(default)]
    source: Option<String>,
    tips: Vec<Tip>,
    #[serde(default)]
    wind: Option<Wind>,
}

#[derive(Deserialize)]
struct Tip {
    marker: usize,
    rest: [f64; 3],
}

#[derive(Deserialize)]
struct Wind {
    direction: [f64; 3],
    speed: f64,
}

/// Reads and checks a tips.json file.
pub fn read_tips(path: &Path) -> Result<TipsInput> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_tips(&text, path)
}

/// Parses tips.json text; `path` only names the file in errors.
pub fn parse_tips(text: &str, path: &Path) -> Result<TipsInput> {
    let file: File = serde_json::from_str(text).map_err(|e| {
        Error::at_line(
            path,
            e.line() as u64,
            Some(e.column() as u64),
            e.to_string(),
        )
    })?;
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
            if !dir.is_finite() || !w.speed.is_finite() || w.speed < 0.0 {
                return Err(field(
                    "wind".into(),
                    "direction must be finite and speed finite and not negative".into(),
                ));
            }
            // Direction is documented as a unit vector; normalise anyway so a
            // hand-edited file cannot scale the wind force by accident.
            dir.try_normalize().unwrap_or(DVec3::ZERO) * w.speed
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
    fn reads_the_contract_format() {
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
}
