//! `treemocap replay`, the main job, as a user runs it: a shipped replay in,
//! tips.json / tree.glb / tree.json / tree.png out, checked against the
//! simulator's truth; the wind it finds; byte-identical reruns.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::DVec3;
use treemocap::config::Config;
use treemocap::model::wind::angle_between_deg;
use treemocap::sim::{CrownShape, SynthOptions};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn replay(file: &Path, out: &Path) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .arg("replay")
        .arg(file)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

fn vec3(v: &serde_json::Value) -> DVec3 {
    DVec3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn shipped_replays_give_true_tips_wind_and_a_tree() {
    for (name, n) in [("maple-24", 24), ("pine-35", 35)] {
        let dir = tempfile::tempdir().unwrap();
        let csv = root().join(format!("replays/{name}.csv"));
        let text = replay(&csv, dir.path());
        assert!(text.contains(&format!("markers found: {n} tips")), "{text}");
        assert!(text.contains("0 forced joins"), "{text}");

        let truth = json(&root().join(format!("replays/{name}.truth.json")));
        let tips = json(&dir.path().join("tips.json"));
        let got: Vec<DVec3> = tips["tips"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| vec3(&t["rest"]))
            .collect();
        assert_eq!(got.len(), n);
        // Every true tip has exactly one found tip within 0.5 mm.
        for t in truth["tips"].as_array().unwrap() {
            let rest = vec3(&t["rest"]);
            let close = got.iter().filter(|g| g.distance(rest) < 0.0005).count();
            assert_eq!(close, 1, "{name}: tip at {rest}");
        }
        // The wind from the sway agrees with the fan's true direction.
        let wind = vec3(&tips["wind"]["direction"]);
        let true_wind = vec3(&truth["wind_direction"]);
        assert!(
            angle_between_deg(wind, true_wind) < 10.0,
            "{name}: {wind} vs {true_wind}"
        );

        // Every captured tip is a branch end of the tree at its rest position.
        let tree = json(&dir.path().join("tree.json"));
        let nodes = tree["nodes"].as_array().unwrap();
        for g in &got {
            assert!(
                nodes.iter().any(|nd| vec3(nd).distance(*g) < 1e-9),
                "{name}: no node at tip {g}"
            );
        }
        let glb = std::fs::read(dir.path().join("tree.glb")).unwrap();
        assert_eq!(&glb[..4], b"glTF");
        let png = std::fs::read(dir.path().join("tree.png")).unwrap();
        assert_eq!(&png[1..4], b"PNG");
    }
}

#[test]
fn same_replay_twice_gives_identical_files() {
    let csv = root().join("replays/maple-24.csv");
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    replay(&csv, a.path());
    replay(&csv, b.path());
    for f in ["tips.json", "tree.glb", "tree.json", "tree.png"] {
        assert_eq!(
            std::fs::read(a.path().join(f)).unwrap(),
            std::fs::read(b.path().join(f)).unwrap(),
            "{f} differs"
        );
    }
}

#[test]
fn pca_wind_within_10_degrees_on_generated_sessions() {
    let config = Config::default();
    for (seed, tips, shape) in [
        (501, 30, CrownShape::Maple),
        (502, 45, CrownShape::Pine),
        (503, 60, CrownShape::Maple),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("s.csv");
        let opts = SynthOptions {
            seed,
            tips,
            shape,
            still_s: 8.0,
            wind_s: 8.0,
            ..SynthOptions::default()
        };
        let summary = treemocap::app::synth::write_session(&opts, &csv).unwrap();
        let mut rec = treemocap::app::open::open(&csv).unwrap();
        let (found, _) = treemocap::track::process(rec.as_mut(), &config.tracking).unwrap();
        let w = treemocap::app::replay::estimate_wind(&found, &config).expect("a wind estimate");
        let err = angle_between_deg(w.direction, summary.wind_direction);
        assert!(err < 10.0, "seed {seed}: {err:.1}° off");
    }
}

#[test]
fn fan_position_in_the_config_wins_over_the_sway() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("fan.toml");
    // A fan due -X of the crown blows towards +X (azimuth 90°).
    std::fs::write(
        &cfg,
        "[wind]\nfan_position = [-5, 1, 0]\nfan_speed_m_s = 3\n",
    )
    .unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(["replay", "replays/maple-24.csv", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(dir.path())
        .current_dir(root())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("wind: from fan"), "{text}");
    let tips = json(&dir.path().join("tips.json"));
    let d = vec3(&tips["wind"]["direction"]);
    assert!(angle_between_deg(d, DVec3::X) < 6.0, "{d}");
    assert_eq!(tips["wind"]["speed"], 3.0);
}
