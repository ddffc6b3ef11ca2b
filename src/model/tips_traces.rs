//! The tips' trajectories in a tips.json (`tips --json --traces`,
//! docs/tracking.md): `frames` and `times_s` (one entry per frame of the
//! session) and, per tip, `trace` (`[x, y, z]` in metres, Y up, or `null`
//! where missing, aligned with `frames`) and `filled` (indices of the filled
//! entries). `treemocap reconstruct` animates the tree with them. A tips.json
//! without `times_s` has no traces.

use std::path::Path;

use glam::DVec3;
use serde::Deserialize;

use crate::error::{Error, Location, Result};

/// One tip's trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct TipTrace {
    /// The tip's marker (tips.json `marker`).
    pub marker: usize,
    /// One entry per frame: the position, `None` where missing.
    pub positions: Vec<Option<DVec3>>,
    /// Whether each entry was filled rather than measured.
    pub filled: Vec<bool>,
}

/// Every tip's trajectory over the session's frames.
#[derive(Debug, Clone, PartialEq)]
pub struct TipTraces {
    /// Time of each frame (s), not decreasing.
    pub times_s: Vec<f64>,
    /// The tips that have a trajectory.
    pub tips: Vec<TipTrace>,
}

#[derive(Deserialize)]
struct File {
    #[serde(default)]
    times_s: Option<Vec<f64>>,
    #[serde(default)]
    tips: Vec<FileTip>,
}

#[derive(Deserialize)]
struct FileTip {
    marker: usize,
    #[serde(default)]
    trace: Option<Vec<Option<[f64; 3]>>>,
    #[serde(default)]
    filled: Vec<usize>,
}

/// The trajectories of a tips.json text, `None` when it has none; `path`
/// only names the file in errors.
pub fn parse_traces(text: &str, path: &Path) -> Result<Option<TipTraces>> {
    let file: File = serde_json::from_str(text).map_err(|e| Error::json(path, &e))?;
    let field = |name: String, msg: &str| Error::parse(path, Location::Field(name), msg);
    let Some(times_s) = file.times_s else {
        return Ok(None);
    };
    if let Some(i) = (0..times_s.len())
        .find(|&i| !times_s[i].is_finite() || (i > 0 && times_s[i] < times_s[i - 1]))
    {
        return Err(field(
            format!("times_s[{i}]"),
            "not a finite time at or after the one before",
        ));
    }
    let mut tips = Vec::new();
    for (t, tip) in file.tips.into_iter().enumerate() {
        let Some(trace) = tip.trace else { continue };
        if trace.len() != times_s.len() {
            return Err(field(
                format!("tips[{t}].trace"),
                "must have one entry per entry of times_s",
            ));
        }
        let mut positions = Vec::with_capacity(trace.len());
        for (i, p) in trace.iter().enumerate() {
            let p = p.map(DVec3::from_array);
            if p.is_some_and(|p| !p.is_finite()) {
                return Err(field(
                    format!("tips[{t}].trace[{i}]"),
                    "not a finite position",
                ));
            }
            positions.push(p);
        }
        let mut filled = vec![false; positions.len()];
        for (j, &i) in tip.filled.iter().enumerate() {
            if positions.get(i).copied().flatten().is_none() {
                return Err(field(
                    format!("tips[{t}].filled[{j}]"),
                    "names an entry of trace that does not exist or is null",
                ));
            }
            filled[i] = true;
        }
        tips.push(TipTrace {
            marker: tip.marker,
            positions,
            filled,
        });
    }
    Ok(Some(TipTraces { times_s, tips }))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"{"version":1,"frames":[10,11,12,13],"times_s":[0.0,0.01,0.02,0.03],
      "tips":[{"marker":4,"rest":[0,1,0],"trace":[[0,1,0],[0.001,1,0],null,[0.003,1,0]],"filled":[1]},
              {"marker":7,"rest":[0,2,0]}]}"#;

    #[test]
    fn reads_trajectories_and_their_flags() {
        let t = parse_traces(GOOD, Path::new("tips.json")).unwrap().unwrap();
        assert_eq!(t.times_s.len(), 4);
        assert_eq!(t.tips.len(), 1);
        assert_eq!(t.tips[0].marker, 4);
        assert_eq!(t.tips[0].positions[2], None);
        assert_eq!(t.tips[0].positions[3], Some(DVec3::new(0.003, 1.0, 0.0)));
        assert_eq!(t.tips[0].filled, vec![false, true, false, false]);
        let plain = r#"{"version":1,"tips":[{"marker":0,"rest":[0,1,0]}]}"#;
        assert_eq!(parse_traces(plain, Path::new("t")).unwrap(), None);
    }

    #[test]
    fn errors_name_the_field() {
        let short = GOOD.replace("null,", "");
        let e = parse_traces(&short, Path::new("x.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.json") && e.contains("tips[0].trace"), "{e}");
        let bad_fill = GOOD.replace("\"filled\":[1]", "\"filled\":[2]");
        let e = parse_traces(&bad_fill, Path::new("t"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("tips[0].filled[0]"), "{e}");
        let back = GOOD.replace("0.02,0.03", "0.02,0.015");
        let e = parse_traces(&back, Path::new("t")).unwrap_err().to_string();
        assert!(e.contains("times_s[3]"), "{e}");
    }
}
