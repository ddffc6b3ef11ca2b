//! The captured motion on the tree (issue 13): `treemocap replay` of the
//! shipped maple session writes an animated tree.glb, and
//! - the Khronos validator finds no error and no warning in it;
//! - read back from the file, every captured tip is where the tracker had it
//!   (0.5 mm) and where the simulator truly moved it (the tracker's own
//!   error + 1 mm), at every key; the trunk base never moves;
//! - three.js (GLTFLoader + AnimationMixer in headless Chromium) and Blender
//!   (background import) play it and put the tips at the same places (1 mm);
//! - `reconstruct` animates from a tips.json with trajectories, same bytes
//!   twice, and `--still` writes no skin and no animation.
//!
//! Needs the peers of tests/peers (npm) and Debian's chromium, blender and
//! python3-numpy, all installed by scripts/test.sh.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use glam::DVec3;
use treemocap::app::replay::{run, ReplayReport};
use treemocap::config::Config;
use treemocap::model::tips::Tips;
use treemocap::model::trace::SampleKind;
use treemocap::sim::Truth;

use crate::common::gltf::{validate, Glb};
use crate::common::tracked::tracked_tips;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// One replay of maple-24 shared by the tests of this module.
struct Maple {
    _dir: tempfile::TempDir,
    glb_path: PathBuf,
    glb: Glb,
    report: ReplayReport,
    /// The replay's tips with their trajectories (the report drops them).
    tips: Tips,
    truth: Truth,
}

fn maple() -> &'static Maple {
    static MAPLE: OnceLock<Maple> = OnceLock::new();
    MAPLE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let csv = root().join("replays/maple-24.csv");
        let report = run(&csv, &Config::default(), dir.path()).unwrap();
        let mut tips = tracked_tips(&csv, &Config::default());
        tips.wind = report.tips.wind;
        let glb_path = dir.path().join("tree.glb");
        let glb = Glb::parse(&std::fs::read(&glb_path).unwrap());
        let text = std::fs::read_to_string(root().join("replays/maple-24.truth.json")).unwrap();
        Maple {
            _dir: dir,
            glb_path,
            glb,
            report,
            tips,
            truth: serde_json::from_str(&text).unwrap(),
        }
    })
}

/// A captured tip's joint: its node, marker and name.
struct TipJoint {
    node: usize,
    marker: usize,
    name: String,
}

fn tip_joints(glb: &Glb) -> Vec<TipJoint> {
    glb.json["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .filter_map(|(i, n)| {
            let marker = n["extras"]["marker"].as_u64()? as usize;
            Some(TipJoint {
                node: i,
                marker,
                name: n["name"].as_str().unwrap().to_string(),
            })
        })
        .collect()
}

/// The recorded frame a key shows (its time is start_s + the key's time).
fn key_frame(m: &Maple, key_time: f32) -> usize {
    let start = m.glb.json["animations"][0]["extras"]["start_s"]
        .as_f64()
        .unwrap();
    let t = start + f64::from(key_time);
    let times = &m.tips.timeline.times;
    let i = times.partition_point(|&x| x < t).min(times.len() - 1);
    if i > 0 && (t - times[i - 1]).abs() < (times[i] - t).abs() {
        i - 1
    } else {
        i
    }
}

/// Where the tracker had marker `marker` in `frame` (measured or filled).
fn tracked(m: &Maple, marker: usize, frame: usize) -> Option<DVec3> {
    let tip = m.tips.tips.iter().find(|t| t.marker == marker)?;
    let s = tip.trace.samples().find(|s| s.frame == frame as i64)?;
    (s.kind != SampleKind::Missing).then_some(s.position)
}

#[test]
fn maple_animation_is_valid_and_tips_follow_tracked_and_true_paths() {
    let m = maple();
    let (errors, warnings, messages) = validate(&m.glb_path);
    assert_eq!((errors, warnings), (0, 0), "{messages}");
    let doc = &m.glb.json;
    assert_eq!(doc["skins"].as_array().unwrap().len(), 1);
    assert_eq!(doc["animations"].as_array().unwrap().len(), 1);
    let a = m.report.tree.animation.expect("an animation report");
    println!(
        "maple-24: {} keys over {:.2} s, tree.glb {} bytes, branch length change max {:.3} % mean {:.4} %",
        a.keys, a.duration_s, a.glb_bytes, a.stretch.max_pct, a.stretch.mean_pct
    );
    // The whole 40 s session at 30 Hz.
    assert!(a.duration_s > 39.0 && a.keys > 1150, "{a:?}");
    assert!(
        a.stretch.mean_pct < 0.5 && a.stretch.max_pct < 10.0,
        "{a:?}"
    );

    let tips = tip_joints(&m.glb);
    assert_eq!(tips.len(), 24);
    let times = m.glb.key_times();
    let base = m.glb.node("node_0").unwrap();
    let base_rest = m.glb.world(base, None);
    // Truth tip ↔ marker by rest position.
    let truth_of = |marker: usize| {
        let rest = m
            .report
            .tips
            .tips
            .iter()
            .find(|t| t.marker == marker)
            .unwrap()
            .rest;
        (0..m.truth.tips.len())
            .min_by(|&a, &b| {
                m.truth.tips[a]
                    .rest
                    .distance(rest)
                    .total_cmp(&m.truth.tips[b].rest.distance(rest))
            })
            .unwrap()
    };
    let (mut checked, mut worst_tracked, mut worst_true_excess) = (0, 0.0f64, f64::MIN);
    for (k, &t) in times.iter().enumerate().step_by(7) {
        let frame = key_frame(m, t);
        assert!(m.glb.world(base, Some(k)).distance(base_rest) < 1e-9);
        for tip in &tips {
            let got = m.glb.world(tip.node, Some(k));
            let Some(tracked) = tracked(m, tip.marker, frame) else {
                continue;
            };
            let err = got.distance(tracked);
            assert!(
                err < 0.0005,
                "{} key {k}: {:.3} mm from tracked",
                tip.name,
                err * 1e3
            );
            let truth = m
                .truth
                .position(truth_of(tip.marker), m.truth.time_of(frame as i64));
            let excess = got.distance(truth) - tracked.distance(truth);
            assert!(
                excess < 0.001,
                "{} key {k}: {:.3} mm beyond the tracker's error",
                tip.name,
                excess * 1e3
            );
            worst_tracked = worst_tracked.max(err);
            worst_true_excess = worst_true_excess.max(excess);
            checked += 1;
        }
    }
    println!(
        "{checked} tip positions: worst {:.4} mm from tracked, worst {:.4} mm beyond the tracker's error from true",
        worst_tracked * 1e3,
        worst_true_excess * 1e3
    );
    assert!(checked > 3000, "{checked}");
}

/// Three key times in the wind phase and the positions the tips must have
/// then (tracked where tracked, else the file's own).
fn probes(m: &Maple) -> (Vec<f32>, Vec<String>, Vec<Vec<DVec3>>) {
    let times = m.glb.key_times();
    let n = times.len();
    let keys = [n * 3 / 5, n * 3 / 4, n * 9 / 10];
    let tips = tip_joints(&m.glb);
    let expected = keys
        .iter()
        .map(|&k| {
            let frame = key_frame(m, times[k]);
            tips.iter()
                .map(|t| {
                    tracked(m, t.marker, frame).unwrap_or_else(|| m.glb.world(t.node, Some(k)))
                })
                .collect()
        })
        .collect();
    (
        keys.iter().map(|&k| times[k]).collect(),
        tips.into_iter().map(|t| t.name).collect(),
        expected,
    )
}

/// Compares a peer's `{"<time>": {"<name>": [x, y, z]}}` with `expected`.
fn compare(
    peer: &str,
    got: &serde_json::Value,
    times: &[f32],
    names: &[String],
    expected: &[Vec<DVec3>],
) {
    let rows: Vec<&serde_json::Value> = got.as_object().unwrap().values().collect();
    assert_eq!(rows.len(), times.len(), "{peer}: {got}");
    let mut worst: f64 = 0.0;
    for (row, want) in rows.iter().zip(expected) {
        for (name, w) in names.iter().zip(want) {
            let v = &row[name.as_str()];
            let p = DVec3::new(
                v[0].as_f64().unwrap(),
                v[1].as_f64().unwrap(),
                v[2].as_f64().unwrap(),
            );
            worst = worst.max(p.distance(*w));
        }
    }
    println!("{peer}: worst tip {:.4} mm from expected", worst * 1e3);
    assert!(worst < 0.001, "{peer}: a tip is {:.3} mm off", worst * 1e3);
}

#[test]
fn three_js_plays_the_animation_with_tips_in_place() {
    let m = maple();
    let (times, names, expected) = probes(m);
    let out = Command::new("node")
        .arg(root().join("tests/peers/gltf_three.js"))
        .arg(&m.glb_path)
        .arg(serde_json::to_string(&times).unwrap())
        .arg(serde_json::to_string(&names).unwrap())
        .output()
        .expect("node (install Node.js and `npm install --prefix tests/peers`)");
    assert!(
        out.status.success(),
        "three.js in Chromium failed (scripts/test.sh installs chromium and the npm peers): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    compare("three.js", &got, &times, &names, &expected);
}

#[test]
fn blender_imports_the_animation_with_tips_in_place() {
    let m = maple();
    let (times, names, expected) = probes(m);
    let out = Command::new("blender")
        .args(["-b", "--factory-startup", "--python"])
        .arg(root().join("tests/peers/gltf_blender.py"))
        .arg("--")
        .arg(&m.glb_path)
        .arg(serde_json::to_string(&times).unwrap())
        .arg(serde_json::to_string(&names).unwrap())
        .output()
        .expect("blender (scripts/test.sh installs Debian's blender and python3-numpy)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix("RESULT "))
        .unwrap_or_else(|| {
            panic!(
                "Blender printed no result:\n{stdout}\n{}",
                String::from_utf8_lossy(&out.stderr)
            )
        });
    let got: serde_json::Value = serde_json::from_str(line).unwrap();
    compare("Blender", &got["positions"], &times, &names, &expected);
}

/// A tips.json with the trajectories (`tips --json --traces` layout) of the
/// maple replay's tips.
fn tips_with_traces(m: &Maple, path: &Path) {
    let tips = &m.tips;
    let mut doc: serde_json::Value = serde_json::from_str(&tips.to_json()).unwrap();
    let n = tips.timeline.len();
    doc["frames"] = serde_json::json!((0..n).collect::<Vec<_>>());
    doc["times_s"] = serde_json::json!(tips.timeline.times);
    for (j, tip) in tips.tips.iter().enumerate() {
        let mut trace = vec![serde_json::Value::Null; n];
        let mut filled = Vec::new();
        for s in tip.trace.samples() {
            if s.kind != SampleKind::Missing {
                trace[s.frame as usize] = serde_json::json!(s.position.to_array());
            }
            if s.kind == SampleKind::Filled {
                filled.push(s.frame);
            }
        }
        doc["tips"][j]["trace"] = serde_json::Value::Array(trace);
        doc["tips"][j]["filled"] = serde_json::json!(filled);
    }
    std::fs::write(path, doc.to_string()).unwrap();
}

#[test]
fn reconstruct_animates_from_a_tips_file_with_trajectories() {
    let m = maple();
    let dir = tempfile::tempdir().unwrap();
    let tips_path = dir.path().join("tips.json");
    tips_with_traces(m, &tips_path);
    let bin = env!("CARGO_BIN_EXE_treemocap");
    let reconstruct = |out: &str, still: bool| {
        let mut c = Command::new(bin);
        c.arg("reconstruct")
            .arg(&tips_path)
            .arg("--out")
            .arg(dir.path().join(out));
        if still {
            c.arg("--still");
        }
        let o = c.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (
            String::from_utf8(o.stdout).unwrap(),
            std::fs::read(dir.path().join(out).join("tree.glb")).unwrap(),
        )
    };
    let (text, a) = reconstruct("a", false);
    assert!(text.contains("animation: "), "{text}");
    let (_, b) = reconstruct("b", false);
    assert!(
        a == b,
        "same tips, config and seed gave different tree.glb bytes"
    );
    // The same tree and keys as the replay's: the same file.
    assert!(
        a == std::fs::read(&m.glb_path).unwrap(),
        "reconstruct and replay differ"
    );
    let (text, still) = reconstruct("c", true);
    assert!(!text.contains("animation: "), "{text}");
    let doc = Glb::parse(&still).json;
    assert!(doc.get("skins").is_none() && doc.get("animations").is_none());
}
