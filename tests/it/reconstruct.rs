//! Reconstruction end to end: tree invariants on generated crowns, the
//! paper's parameter effects, the Khronos glTF validator on our .glb files,
//! determinism, and the `treemocap reconstruct` command.

use std::path::PathBuf;
use std::process::Command;

use crate::common::crowns::{crown_tips, replay_truth, sim_tips, tips_json, Shape};
use crate::common::gltf::{glb_json, validate};
use glam::DVec3;
use treemocap::app::reconstruct::run_and_write;
use treemocap::config::Config;
use treemocap::model::tips::CapturedTip;
use treemocap::model::tree::{Kind, Tree};
use treemocap::reconstruct::reconstruct;
use treemocap::reconstruct::{ReconstructSettings, VolumeKind};
use treemocap::render::outputs::Motion;
use treemocap::rng::Rng;
use treemocap::sim::CrownShape;

fn cfg_with(f: impl FnOnce(&mut ReconstructSettings)) -> ReconstructSettings {
    let mut c = ReconstructSettings::default();
    f(&mut c);
    c
}

// ---------------------------------------------------------------- invariants

/// Checks every promise of the tree against the input, without using the
/// tree's own helpers.
fn check_invariants(tree: &Tree, tips: &[CapturedTip], cfg: &ReconstructSettings, what: &str) {
    let n = tree.nodes.len();
    let mut has_child = vec![false; n];
    for (i, node) in tree.nodes.iter().enumerate() {
        if let Some(p) = node.parent {
            assert!(p < n && p != i, "{what}: node {i} has parent {p}");
            has_child[p] = true;
            assert!(
                node.radius <= tree.nodes[p].radius,
                "{what}: radius grows from node {p} ({}) to its child {i} ({})",
                tree.nodes[p].radius,
                node.radius
            );
        } else {
            assert_eq!(i, 0, "{what}: node {i} has no parent but is not the root");
        }
    }
    // Rooted at the trunk base: node 0 is a trunk node on the ground.
    assert_eq!(tree.nodes[0].kind, Kind::Trunk);
    assert!((tree.nodes[0].position.y - cfg.ground_height).abs() < 1e-12);
    // Connected and acyclic: from every node, parents reach node 0 in
    // fewer than n steps.
    for start in 0..n {
        let mut at = start;
        let mut hops = 0;
        while let Some(p) = tree.nodes[at].parent {
            at = p;
            hops += 1;
            assert!(hops < n, "{what}: cycle through node {start}");
        }
        assert_eq!(at, 0, "{what}: node {start} does not reach the root");
    }
    // Every captured tip is a leaf at exactly its position, once.
    for t in tips {
        let found: Vec<usize> = (0..n)
            .filter(|&i| tree.nodes[i].kind == Kind::Captured { marker: t.marker })
            .collect();
        assert_eq!(
            found.len(),
            1,
            "{what}: marker {} appears {found:?}",
            t.marker
        );
        let i = found[0];
        assert!(
            tree.nodes[i].position.distance(t.position) <= 1e-9,
            "{what}: marker {} moved",
            t.marker
        );
        assert!(
            !has_child[i],
            "{what}: captured tip {} is not a branch end",
            t.marker
        );
    }
    let all_tips = tree
        .nodes
        .iter()
        .filter(|n| matches!(n.kind, Kind::Tip | Kind::Captured { .. }))
        .count();
    assert_eq!(
        all_tips,
        cfg.total_tips.max(tips.len()),
        "{what}: tip count"
    );
    assert_eq!(
        tree.forced_joins, 0,
        "{what}: forced joins with default parameters"
    );
}

/// Hull mode: every random tip is inside the captured tips' convex hull.
/// Checked through support functions (a point inside the hull is never
/// further along any direction than the farthest captured tip), which does
/// not use our quickhull.
fn check_inside_hull(tree: &Tree, tips: &[CapturedTip], what: &str) {
    let mut rng = Rng::new(99);
    let generated: Vec<DVec3> = tree
        .nodes
        .iter()
        .filter(|n| n.kind == Kind::Tip)
        .map(|n| n.position)
        .collect();
    assert!(!generated.is_empty());
    for _ in 0..500 {
        let u = DVec3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
        let support = tips
            .iter()
            .map(|t| t.position.dot(u))
            .fold(f64::MIN, f64::max);
        for p in &generated {
            assert!(
                p.dot(u) <= support + 1e-9,
                "{what}: random tip {p} outside the hull"
            );
        }
    }
}

/// Box mode: random tips per horizontal slab are proportional to the
/// captured tips in that slab, within ±1.
fn check_box_counts(tree: &Tree, tips: &[CapturedTip], boxes: usize, what: &str) {
    let lo = tips.iter().map(|t| t.position.y).fold(f64::MAX, f64::min);
    let hi = tips.iter().map(|t| t.position.y).fold(f64::MIN, f64::max);
    let slab = |y: f64| (((y - lo) / (hi - lo) * boxes as f64).floor() as usize).min(boxes - 1);
    let mut captured = vec![0usize; boxes];
    for t in tips {
        captured[slab(t.position.y)] += 1;
    }
    let mut random = vec![0usize; boxes];
    let mut total = 0;
    for n in tree.nodes.iter().filter(|n| n.kind == Kind::Tip) {
        assert!(
            n.position.y >= lo && n.position.y <= hi,
            "{what}: random tip outside the stack"
        );
        random[slab(n.position.y)] += 1;
        total += 1;
    }
    for k in 0..boxes {
        let quota = total as f64 * captured[k] as f64 / tips.len() as f64;
        assert!(
            (random[k] as f64 - quota).abs() <= 1.0,
            "{what}: box {k} has {} random tips, expected {quota:.2} ({captured:?} captured)",
            random[k]
        );
    }
}

#[test]
fn invariants_hold_on_twenty_generated_crowns() {
    for seed in 1..=20u64 {
        let shape = if seed % 2 == 0 {
            Shape::Maple
        } else {
            Shape::Pine
        };
        let count = 24 + (seed as usize * 7) % 47; // 24 to 70 markers
        let tips = crown_tips(shape, count, seed);
        let wind = DVec3::new(1.0, 0.0, 0.5).normalize() * (seed % 4) as f64;
        for volume in [VolumeKind::Boxes, VolumeKind::Hull] {
            let cfg = cfg_with(|c| {
                c.volume = volume;
                c.boxes = 3 + (seed as usize % 4);
            });
            let what = format!("seed {seed} {shape:?} {count} tips {volume:?}");
            let tree = reconstruct(&tips, wind, &cfg, seed).unwrap();
            check_invariants(&tree, &tips, &cfg, &what);
            match volume {
                VolumeKind::Hull => check_inside_hull(&tree, &tips, &what),
                VolumeKind::Boxes => check_box_counts(&tree, &tips, cfg.boxes, &what),
            }
        }
    }
}

/// The `sim` helper's trees (20 generated sessions' tips) and the two
/// shipped replays, both volume kinds, default parameters.
#[test]
fn invariants_hold_on_simulated_trees_and_shipped_replays() {
    let mut cases: Vec<(String, Vec<CapturedTip>, DVec3)> = Vec::new();
    for seed in 1..=20u64 {
        let shape = if seed % 2 == 0 {
            CrownShape::Maple
        } else {
            CrownShape::Pine
        };
        let count = 20 + (seed as usize * 11) % 41; // 20 to 60 markers
        let wind = DVec3::new(-0.8, 0.0, 0.6) * (seed % 3) as f64;
        cases.push((
            format!("sim {shape} seed {seed} ({count} tips)"),
            sim_tips(shape, count, seed),
            wind,
        ));
    }
    for name in ["maple-24", "pine-35"] {
        let (tips, direction) = replay_truth(name);
        // The truth gives the wind's direction; 2 m/s is a lab fan.
        cases.push((format!("replay {name}"), tips, direction * 2.0));
    }
    for (what, tips, wind) in &cases {
        for volume in [VolumeKind::Boxes, VolumeKind::Hull] {
            let cfg = cfg_with(|c| c.volume = volume);
            let what = format!("{what} {volume:?}");
            let tree = reconstruct(tips, *wind, &cfg, 1).unwrap();
            check_invariants(&tree, tips, &cfg, &what);
            match volume {
                VolumeKind::Hull => check_inside_hull(&tree, tips, &what),
                VolumeKind::Boxes => check_box_counts(&tree, tips, cfg.boxes, &what),
            }
        }
    }
}

#[test]
fn more_captured_than_total_tips_adds_none_and_single_tip_works() {
    let tips = crown_tips(Shape::Maple, 40, 5);
    let cfg = cfg_with(|c| c.total_tips = 10);
    let tree = reconstruct(&tips, DVec3::ZERO, &cfg, 1).unwrap();
    check_invariants(&tree, &tips, &cfg, "total < captured");
    // One marker: a flat crown; the hull cannot place tips but boxes can.
    let one = &tips[..1];
    let tree = reconstruct(one, DVec3::ZERO, &ReconstructSettings::default(), 1).unwrap();
    check_invariants(&tree, one, &ReconstructSettings::default(), "one tip");
    let hull = cfg_with(|c| c.volume = VolumeKind::Hull);
    let e = reconstruct(one, DVec3::ZERO, &hull, 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("hull") && e.contains("boxes"), "{e}");
    // Fifty markers at one point (a user's copy-paste error): a tree, not a
    // panic, even though every random tip lands on the same spot.
    let same: Vec<CapturedTip> = (0..50)
        .map(|m| CapturedTip {
            marker: m,
            position: DVec3::new(0.1, 1.5, 0.2),
        })
        .collect();
    let cfg = ReconstructSettings::default();
    let tree = reconstruct(&same, DVec3::ZERO, &cfg, 1).unwrap();
    assert!(
        tree.nodes
            .iter()
            .filter(|n| matches!(n.kind, Kind::Captured { .. }))
            .count()
            == 50
    );
    // Bad input is an error, not a panic.
    let bad = [CapturedTip {
        marker: 0,
        position: DVec3::new(f64::NAN, 0.0, 0.0),
    }];
    assert!(reconstruct(&bad, DVec3::ZERO, &ReconstructSettings::default(), 1).is_err());
    assert!(reconstruct(&[], DVec3::ZERO, &ReconstructSettings::default(), 1).is_err());
    let far = [CapturedTip {
        marker: 0,
        position: DVec3::new(0.0, 1e300, 0.0),
    }];
    assert!(reconstruct(&far, DVec3::ZERO, &ReconstructSettings::default(), 1).is_err());
    let tips = crown_tips(Shape::Pine, 10, 1);
    assert!(reconstruct(
        &tips,
        DVec3::splat(f64::INFINITY),
        &ReconstructSettings::default(),
        1
    )
    .is_err());
}

// ---------------------------------------------------------- paper's effects

/// Branches between structural nodes: from a tip or junction, walking
/// towards the root through plain branch points, until a junction or a
/// trunk node. Returned as node paths, far end first.
fn branches(tree: &Tree) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    for (i, n) in tree.nodes.iter().enumerate() {
        if !matches!(n.kind, Kind::Tip | Kind::Captured { .. } | Kind::Junction) {
            continue;
        }
        let mut path = vec![i];
        let mut at = i;
        while let Some(p) = tree.nodes[at].parent {
            path.push(p);
            if tree.nodes[p].kind != Kind::Branch {
                break;
            }
            at = p;
        }
        out.push(path);
    }
    out
}

/// Mean of (far end − start).y over branches that end in a tip.
fn mean_tip_rise(tree: &Tree) -> f64 {
    let b: Vec<f64> = branches(tree)
        .iter()
        .filter(|p| tree.nodes[p[0]].kind.is_tip())
        .map(|p| tree.nodes[p[0]].position.y - tree.nodes[*p.last().unwrap()].position.y)
        .collect();
    b.iter().sum::<f64>() / b.len() as f64
}

/// Mean offset along `dir` of each branch's arc-length midpoint from the
/// midpoint of its chord.
fn mean_midpoint_offset(tree: &Tree, dir: DVec3) -> f64 {
    let mut sum = 0.0;
    let mut count = 0;
    for path in branches(tree) {
        let pts: Vec<DVec3> = path.iter().map(|&i| tree.nodes[i].position).collect();
        let lengths: Vec<f64> = pts.windows(2).map(|w| w[0].distance(w[1])).collect();
        let total: f64 = lengths.iter().sum();
        if total <= 0.0 {
            continue;
        }
        let mut left = total / 2.0;
        let mut mid = pts[0];
        for (k, l) in lengths.iter().enumerate() {
            if left <= *l {
                mid = pts[k].lerp(pts[k + 1], left / l);
                break;
            }
            left -= l;
        }
        let chord = (pts[0] + pts[pts.len() - 1]) / 2.0;
        sum += (mid - chord).dot(dir);
        count += 1;
    }
    sum / count as f64
}

/// Mean elevation (degrees, negative = downwards) of every tip's first step.
fn mean_first_step_elevation(tree: &Tree) -> f64 {
    let tips: Vec<f64> = tree
        .nodes
        .iter()
        .filter(|n| n.kind.is_tip())
        .map(|n| {
            let d = (tree.nodes[n.parent.unwrap()].position - n.position).normalize();
            d.y.asin().to_degrees()
        })
        .collect();
    tips.iter().sum::<f64>() / tips.len() as f64
}

#[test]
fn negative_gravity_weight_makes_a_willow() {
    // Figure 13 uses ω1 = 0.2 and −0.2; the willow shows when the
    // shape-format force is small enough for gravity to matter (α = 0.05).
    let run = |shape, seed, w: f64| {
        let tips = crown_tips(shape, 35, seed);
        let cfg = cfg_with(|c| {
            c.gravity_weight = w;
            c.alpha = 0.05;
        });
        let tree = reconstruct(&tips, DVec3::ZERO, &cfg, 1).unwrap();
        (mean_tip_rise(&tree), tree.forced_joins)
    };
    for seed in [4, 10] {
        let (up, forced_up) = run(Shape::Pine, seed, 0.2);
        let (willow, forced_willow) = run(Shape::Pine, seed, -0.2);
        eprintln!("pine {seed}: mean tip rise {up:.3} m (ω1 = 0.2) vs {willow:.3} m (ω1 = -0.2)");
        assert!(
            up > 0.05,
            "pine {seed}: with gravity branch ends rise above their starts: {up}"
        );
        assert!(
            willow < 0.0,
            "pine {seed}: willow branch ends must hang below their starts: {willow}"
        );
        assert_eq!((forced_up, forced_willow), (0, 0));
    }
    // A maple's crown reaches far above its trunk top (the trunk is 1.2 ×
    // the crown's depth); there upward gravity grows with the distance to
    // the top trunk node and can pin a particle at the crown's ceiling,
    // which then joins the trunk by force. It droops all the same.
    let (up, _) = run(Shape::Maple, 3, 0.2);
    let (willow, forced) = run(Shape::Maple, 3, -0.2);
    eprintln!("maple: mean tip rise {up:.3} m vs {willow:.3} m, {forced} forced joins");
    assert!(up > 0.05 && willow < 0.0, "maple: {up} vs {willow}");
    assert!(forced <= 2, "maple willow: {forced} forced joins");
}

#[test]
fn larger_wind_weight_bends_branches_further_downwind() {
    // A 1 m/s wind: with ω3 up to 0.15 (Figure 14) the wind stays weaker
    // than the shape-format force, as the paper requires for particles to
    // reach the trunk.
    let downwind = DVec3::new(0.6, 0.0, 0.8);
    let wind = downwind * 1.0;
    for (shape, seed) in [(Shape::Maple, 8), (Shape::Pine, 9)] {
        let tips = crown_tips(shape, 35, seed);
        let offsets: Vec<f64> = [0.0, 0.01, 0.07, 0.15]
            .iter()
            .map(|&w| {
                let cfg = cfg_with(|c| c.wind_weight = w);
                let tree = reconstruct(&tips, wind, &cfg, 2).unwrap();
                assert_eq!(tree.forced_joins, 0);
                mean_midpoint_offset(&tree, downwind)
            })
            .collect();
        eprintln!("{shape:?}: mean downwind midpoint offset (m) for ω3 0, 0.01, 0.07, 0.15: {offsets:.4?}");
        assert!(offsets[0].abs() < offsets[3], "{shape:?}: {offsets:?}");
        for w in offsets.windows(2) {
            assert!(
                w[1] > w[0],
                "{shape:?}: downwind offset must grow with ω3: {offsets:?}"
            );
        }
    }
}

#[test]
fn moving_the_attractor_changes_the_converging_direction() {
    for (shape, seed) in [(Shape::Maple, 5), (Shape::Pine, 6)] {
        let tips = crown_tips(shape, 35, seed);
        let cfg = ReconstructSettings::default();
        let direction = |node: i64| {
            let c = cfg_with(|c| c.attractor_node = node);
            let tree = reconstruct(&tips, DVec3::ZERO, &c, 1).unwrap();
            assert_eq!(tree.attractor as i64, node);
            assert_eq!(tree.forced_joins, 0);
            mean_first_step_elevation(&tree)
        };
        // Figure 12: the attractor at the trunk base makes branches converge
        // steeply downwards (decurrent), at the trunk top more sideways.
        let low = direction(0);
        let high = direction(cfg.trunk_nodes as i64 - 1);
        eprintln!(
            "{shape:?}: first-step elevation {low:.1}° (attractor at base) vs {high:.1}° (at top)"
        );
        assert!(
            low + 15.0 < high,
            "{shape:?}: first steps point {low:.1}° vs {high:.1}°"
        );
    }
}

// ------------------------------------------------------ files and validator

fn out_dir(name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    (dir, p)
}

#[test]
fn gltf_validator_reports_no_errors_or_warnings() {
    let mut sets = vec![
        ("maple crown".to_string(), crown_tips(Shape::Maple, 35, 21)),
        ("pine crown".to_string(), crown_tips(Shape::Pine, 35, 22)),
    ];
    for name in ["maple-24", "pine-35"] {
        sets.push((format!("replay {name}"), replay_truth(name).0));
    }
    for (shape, tips) in sets {
        for volume in ["boxes", "hull"] {
            for leaves in [false, true] {
                let config = Config::load(
                    None,
                    &[
                        format!("reconstruct.volume={volume}"),
                        format!("reconstruct.leaves={leaves}"),
                    ],
                )
                .unwrap();
                let (_keep, dir) = out_dir("out");
                let report = run_and_write(
                    &tips,
                    &[],
                    DVec3::new(2.0, 0.0, 0.0),
                    &config,
                    Motion::Still,
                    &dir,
                )
                .unwrap();
                let glb = dir.join("tree.glb");
                let (errors, warnings, messages) = validate(&glb);
                let what = format!("{shape} {volume} leaves={leaves}");
                assert_eq!((errors, warnings), (0, 0), "{what}: {messages}");

                // What a user's viewer will find in the file.
                let doc = glb_json(&std::fs::read(&glb).unwrap());
                let names: Vec<&str> = doc["meshes"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|m| m["name"].as_str().unwrap())
                    .collect();
                let expect: Vec<&str> = if leaves {
                    vec!["branches", "leaves", "skeleton"]
                } else {
                    vec!["branches", "skeleton"]
                };
                assert_eq!(names, expect, "{what}");
                assert_eq!(report.leaves > 0, leaves, "{what}");
                let skeleton = &doc["meshes"][names.len() - 1]["primitives"][0];
                assert_eq!(skeleton["mode"], 1, "{what}: skeleton is LINES");
                let idx = skeleton["indices"].as_u64().unwrap() as usize;
                assert_eq!(
                    doc["accessors"][idx]["count"].as_u64().unwrap() as usize,
                    2 * (report.nodes - 1)
                );
                for mesh in doc["meshes"].as_array().unwrap() {
                    let pos = mesh["primitives"][0]["attributes"]["POSITION"]
                        .as_u64()
                        .unwrap() as usize;
                    assert!(
                        doc["accessors"][pos]["min"].is_array()
                            && doc["accessors"][pos]["max"].is_array()
                    );
                }
            }
        }
    }
}

#[test]
fn tree_json_matches_the_tree() {
    let tips = crown_tips(Shape::Pine, 30, 31);
    let config = Config::load(None, &["reconstruct.seed=77".into()]).unwrap();
    let (_keep, dir) = out_dir("o");
    run_and_write(&tips, &[], DVec3::ZERO, &config, Motion::Still, &dir).unwrap();
    let tree = reconstruct(&tips, DVec3::ZERO, &config.reconstruct, 77).unwrap();
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("tree.json")).unwrap()).unwrap();
    assert_eq!(v["seed"], 77);
    assert_eq!(v["parameters"]["seed"], 77);
    assert_eq!(
        v["parameters"]["merge_distance"],
        config.reconstruct.merge_distance
    );
    assert_eq!(v["nodes"].as_array().unwrap().len(), tree.nodes.len());
    for (i, n) in tree.nodes.iter().enumerate() {
        assert_eq!(v["parents"][i].as_u64().map(|p| p as usize), n.parent);
        assert_eq!(v["radii"][i].as_f64().unwrap(), n.radius);
        assert_eq!(v["kinds"][i], n.kind.name());
        // serde_json with float_roundtrip reads back the exact f64.
        let p = &v["nodes"][i];
        assert_eq!(
            DVec3::new(
                p[0].as_f64().unwrap(),
                p[1].as_f64().unwrap(),
                p[2].as_f64().unwrap()
            ),
            n.position
        );
        match n.kind {
            Kind::Captured { marker } => assert_eq!(v["markers"][i], marker),
            _ => assert!(v["markers"][i].is_null()),
        }
    }
    // The picture is a real PNG of the documented size.
    let png = std::fs::read(dir.join("tree.png")).unwrap();
    let info = png::Decoder::new(std::io::Cursor::new(png))
        .read_info()
        .unwrap();
    assert_eq!((info.info().width, info.info().height), (1400, 820));
}

#[test]
fn same_seed_gives_identical_files() {
    let tips = crown_tips(Shape::Maple, 35, 41);
    let wind = DVec3::new(0.0, 0.0, 2.5);
    for volume in ["boxes", "hull"] {
        let sets = [
            format!("reconstruct.volume={volume}"),
            "reconstruct.leaves=true".to_string(),
        ];
        let config = Config::load(None, &sets).unwrap();
        let (_a, dir_a) = out_dir("a");
        let (_b, dir_b) = out_dir("b");
        run_and_write(&tips, &[], wind, &config, Motion::Still, &dir_a).unwrap();
        run_and_write(&tips, &[], wind, &config, Motion::Still, &dir_b).unwrap();
        for f in ["tree.glb", "tree.json", "tree.png"] {
            let a = std::fs::read(dir_a.join(f)).unwrap();
            let b = std::fs::read(dir_b.join(f)).unwrap();
            assert!(
                a == b,
                "{volume}: {f} differs between runs with the same seed"
            );
        }
        // And the seed matters.
        let mut other = config.clone();
        other.reconstruct.seed += 1;
        let (_c, dir_c) = out_dir("c");
        run_and_write(&tips, &[], wind, &other, Motion::Still, &dir_c).unwrap();
        assert_ne!(
            std::fs::read(dir_a.join("tree.glb")).unwrap(),
            std::fs::read(dir_c.join("tree.glb")).unwrap()
        );
    }
}

// ---------------------------------------------------------------------- CLI

#[test]
fn reconstruct_command_writes_the_three_files() {
    let dir = tempfile::tempdir().unwrap();
    let tips = crown_tips(Shape::Pine, 35, 51);
    let tips_path = dir.path().join("tips.json");
    std::fs::write(&tips_path, tips_json(&tips, Some((DVec3::X, 3.0)))).unwrap();
    let out = dir.path().join("res");
    let run = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .arg("reconstruct")
        .arg(&tips_path)
        .args([
            "--set",
            "reconstruct.volume=hull",
            "--set",
            "reconstruct.total_tips=200",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout} {}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(
        stdout.contains("35 captured + 165 random tips") && stdout.contains("0 forced joins"),
        "{stdout}"
    );
    for f in ["tree.glb", "tree.json", "tree.png"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("tree.json")).unwrap()).unwrap();
    assert_eq!(v["parameters"]["volume"], "hull");
    assert_eq!(v["wind"], serde_json::json!([3.0, 0.0, 0.0]));

    // A config error exits with 2 and names the key.
    let bad = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .arg("reconstruct")
        .arg(&tips_path)
        .args(["--set", "reconstruct.beta=3"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("reconstruct.beta"));
    // A broken tips file exits with 1 and names the file and line.
    let broken = dir.path().join("broken.json");
    std::fs::write(&broken, "{\"version\": 1,\n \"tips\": [ {\"marker\": 0 ]}").unwrap();
    let bad = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .arg("reconstruct")
        .arg(&broken)
        .arg("--out")
        .arg(dir.path().join("x"))
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("broken.json") && err.contains("line 2"),
        "{err}"
    );
}
