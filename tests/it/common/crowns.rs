//! Simple seeded tip sets for tests and benchmarks: markers on the surface
//! of a maple-like (ellipsoid) or pine-like (cone) crown, as a person would
//! place them on the periphery of a real tree (paper §3). The simulator on
//! branch `sim` makes full sessions; this only needs rest positions.

#![allow(dead_code)]

use glam::DVec3;
use treemocap::model::tips::CapturedTip;
use treemocap::rng::Rng;

/// Crown outline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A broad rounded crown: an ellipsoid from y ≈ 0.9 to 2.3 m.
    Maple,
    /// A narrow cone from y ≈ 0.4 to 2.4 m.
    Pine,
}

/// `n` tips on the crown surface, with a few cm of depth jitter, centred
/// at (cx, cz) chosen from the seed so trees do not all stand at the origin.
pub fn crown_tips(shape: Shape, n: usize, seed: u64) -> Vec<CapturedTip> {
    let mut rng = Rng::new(seed);
    let centre = DVec3::new(rng.range(-1.0, 1.0), 0.0, rng.range(-1.0, 1.0));
    let mut tips = Vec::with_capacity(n);
    while tips.len() < n {
        let p = match shape {
            Shape::Maple => {
                let (rx, ry, rz) = (0.8, 0.7, 0.75);
                let d = DVec3::new(rng.normal(), rng.normal(), rng.normal()).normalize_or(DVec3::Y);
                // No markers on the underside near the trunk.
                if d.y < -0.6 {
                    continue;
                }
                let depth = 1.0 - rng.range(0.0, 0.08);
                DVec3::new(d.x * rx, 1.6 + d.y * ry, d.z * rz) * DVec3::new(depth, 1.0, depth)
            }
            Shape::Pine => {
                let (bottom, top, radius) = (0.4, 2.4, 0.7);
                // Area of a cone's side grows linearly towards the base.
                let u = rng.f64().sqrt();
                let y = top - u * (top - bottom);
                let r = radius * u * (1.0 - rng.range(0.0, 0.1));
                let a = rng.range(0.0, std::f64::consts::TAU);
                DVec3::new(r * a.cos(), y, r * a.sin())
            }
        };
        tips.push(CapturedTip {
            marker: tips.len(),
            position: p + centre,
        });
    }
    tips
}

/// A tips.json (docs/formats.md) for `tips` and a wind.
pub fn tips_json(tips: &[CapturedTip], wind: Option<(DVec3, f64)>) -> String {
    let tips: Vec<serde_json::Value> = tips
        .iter()
        .map(|t| {
            serde_json::json!({"marker": t.marker, "rest": t.position.to_array(),
                "samples": 2000, "gap_fraction": 0.0, "spread_m": 0.0003})
        })
        .collect();
    let wind = match wind {
        Some((d, s)) => serde_json::json!({"direction": d.to_array(), "speed": s}),
        None => serde_json::Value::Null,
    };
    serde_json::json!({"version": 1, "source": "test", "frame_rate": 100.0,
        "rest_window_s": [0.0, 20.0], "tips": tips, "wind": wind})
    .to_string()
}

/// Rest positions of `n` marked tips of a tree grown by the simulator
/// (`treemocap::sim`, the same trees as `treemocap synth`), with their
/// marker numbers in order.
pub fn sim_tips(shape: treemocap::sim::CrownShape, n: usize, seed: u64) -> Vec<CapturedTip> {
    let tree = treemocap::sim::tree::grow(shape, &mut Rng::new(seed));
    let chosen = tree
        .choose_tips(n, 0.06)
        .expect("simulated tree has enough tips");
    chosen
        .iter()
        .enumerate()
        .map(|(marker, &node)| CapturedTip {
            marker,
            position: tree.nodes[node].position,
        })
        .collect()
}

/// The captured tips and wind direction of a shipped replay, from its
/// NAME.truth.json (the true rest positions).
pub fn replay_truth(name: &str) -> (Vec<CapturedTip>, DVec3) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("replays/{name}.truth.json"));
    let text = std::fs::read_to_string(&path).expect("shipped replay truth");
    let truth: treemocap::sim::Truth = serde_json::from_str(&text).expect("truth parses");
    let tips = truth
        .tips
        .iter()
        .enumerate()
        .map(|(marker, t)| CapturedTip {
            marker,
            position: t.rest,
        })
        .collect();
    (tips, truth.wind_direction)
}
