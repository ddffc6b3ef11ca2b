//! Several trees in one capture (docs/forest.md), checked against the
//! simulator's truth of which tip belongs to which tree: tips given to
//! their true trees, the number of trees found, one tree exactly as before,
//! no branch in a neighbour's volume, a validator-clean glb with a node per
//! tree, `replay` end to end (every tree skinned and animated, its tips
//! where the tracker had them), and the daemon's cache regrowing only the
//! trees whose tips changed.

use std::path::Path;
use std::process::Command;

use glam::DVec3;
use treemocap::config::Config;
use treemocap::model::trace::SampleKind;
use treemocap::reconstruct::forest::{
    self, sway, AssignRule, ConfiguredTree, CountBasis, ForestCache, ForestPlan, ForestSettings,
    SwayLink,
};
use treemocap::reconstruct::ReconstructSettings;
use treemocap::render::forest::forest_outputs;
use treemocap::render::outputs::{build_outputs, Motion};
use treemocap::sim::{generate, CrownShape, SynthOptions, Truth};

use crate::common::gltf::Glb;
use crate::common::tracked::tracked_tips;

/// A forest session without the capture's imperfections (the marker stage
/// is checked elsewhere; `replay_splits_a_forest_session` runs it too).
fn forest(seed: u64, trees: usize, overlap: f64) -> Truth {
    let opts = SynthOptions {
        still_s: 2.0,
        wind_s: 12.0,
        frame_rate: 50.0,
        ..SynthOptions::forest_sweep(seed, trees, overlap)
    };
    generate(&opts).expect("session").truth
}

/// The true trunk bases as `[[trees]]`.
fn true_bases(t: &Truth) -> Vec<ConfiguredTree> {
    let f = t.forest.as_ref().expect("a forest session");
    f.trees
        .iter()
        .map(|p| ConfiguredTree {
            name: String::new(),
            base: p.base.to_array(),
        })
        .collect()
}

/// Sway links from the truth's motion over the wind phase (25 Hz).
fn links(t: &Truth) -> Vec<SwayLink> {
    let markers: Vec<usize> = (0..t.tips.len()).collect();
    sway::links_of_series(&t.wind_sway(25.0), &markers, 50)
}

/// Tips of `plan` on their true tree (tree ids = true tree indices when the
/// bases are the true ones).
fn correct(plan: &ForestPlan, t: &Truth) -> usize {
    let f = t.forest.as_ref().unwrap();
    plan.trees
        .iter()
        .map(|tree| {
            tree.tips
                .iter()
                .filter(|c| f.tip_tree[c.marker] == tree.id)
                .count()
        })
        .sum()
}

#[test]
fn every_tip_goes_to_its_true_tree() {
    let recon = ReconstructSettings::default();
    let crown = ForestSettings::default();
    let livny = ForestSettings {
        rule: AssignRule::Livny,
        ..ForestSettings::default()
    };
    // Crowns apart: every tip, every session.
    for seed in 0..8 {
        let t = forest(100 + seed, 2 + (seed % 4) as usize, -0.1);
        let plan =
            forest::plan(&t.rest_tips(), &links(&t), &true_bases(&t), &crown, &recon).unwrap();
        assert_eq!(correct(&plan, &t), t.tips.len(), "seed {}", 100 + seed);
    }
    // Overlapping by up to a third of the narrower crown: ≥ 98 % overall,
    // and better than Livny's shortest paths.
    let (mut good, mut good_livny, mut all) = (0, 0, 0);
    for (k, overlap) in [1.0 / 6.0, 0.25, 1.0 / 3.0].into_iter().enumerate() {
        for seed in 0..8 {
            let s = 200 + 10 * k as u64 + seed;
            let t = forest(s, 2 + (seed % 4) as usize, overlap);
            let tips = t.rest_tips();
            let plan = forest::plan(&tips, &links(&t), &true_bases(&t), &crown, &recon).unwrap();
            let by_paths = forest::plan(&tips, &[], &true_bases(&t), &livny, &recon).unwrap();
            good += correct(&plan, &t);
            good_livny += correct(&by_paths, &t);
            all += tips.len();
        }
    }
    let share = good as f64 / all as f64;
    let share_livny = good_livny as f64 / all as f64;
    eprintln!(
        "overlapping crowns: {:.2} % (Livny {:.2} %) of {all} tips",
        100.0 * share,
        100.0 * share_livny
    );
    assert!(share >= 0.98, "{:.2} %", 100.0 * share);
    assert!(share > share_livny, "crown {share} vs Livny {share_livny}");
}

#[test]
fn the_number_of_trees_is_found_when_trunks_stand_a_metre_apart() {
    let recon = ReconstructSettings::default();
    let s = ForestSettings::default();
    let (mut sessions, mut right, mut pure, mut all) = (0, 0, 0, 0);
    for seed in 0..24 {
        let trees = 2 + (seed % 4) as usize;
        let overlap = [1.0 / 3.0, 0.0, -0.1, 0.2][(seed / 4 % 4) as usize];
        let t = forest(300 + seed, trees, overlap);
        let f = t.forest.as_ref().unwrap();
        let closest = (0..trees)
            .flat_map(|i| (0..i).map(move |j| (i, j)))
            .map(|(i, j)| (f.trees[i].base - f.trees[j].base).length())
            .fold(f64::INFINITY, f64::min);
        if closest < 1.0 {
            continue;
        }
        sessions += 1;
        let plan = forest::plan(&t.rest_tips(), &links(&t), &[], &s, &recon).unwrap();
        if plan.trees.len() != trees {
            eprintln!(
                "seed {}: {} trees found of {trees}; fits {:?}",
                300 + seed,
                plan.trees.len(),
                plan.fits
            );
            continue;
        }
        right += 1;
        // How many tips of each found tree belong to its main true tree.
        for tree in &plan.trees {
            let mut votes = vec![0; trees];
            for c in &tree.tips {
                votes[f.tip_tree[c.marker]] += 1;
            }
            pure += *votes.iter().max().unwrap();
            all += tree.tips.len();
        }
    }
    eprintln!("count right in {right} of {sessions}; {pure} of {all} tips with their tree's main true tree");
    // The README's sweep: right in 94 % of sessions; allow one miss in ten.
    assert!(
        right * 10 >= sessions * 9,
        "count right in {right} of {sessions}"
    );
    // The trees found are the true ones: ≥ 97 % of their tips from one.
    assert!(pure as f64 >= 0.97 * all as f64, "{pure} of {all}");
    assert!(
        sessions >= 12,
        "only {sessions} sessions with trunks ≥ 1 m apart"
    );
    // A tree alone is never split, whatever its habit and marker count.
    for seed in 0..12 {
        let opts = SynthOptions {
            seed: 400 + seed,
            tips: [14, 24, 35, 50, 70][seed as usize % 5],
            shape: if seed % 2 == 0 {
                CrownShape::Maple
            } else {
                CrownShape::Pine
            },
            still_s: 1.0,
            wind_s: 0.0,
            ..SynthOptions::default()
        };
        let t = generate(&opts).unwrap().truth;
        let plan = forest::plan(&t.rest_tips(), &[], &[], &s, &recon).unwrap();
        assert!(
            plan.is_single(),
            "seed {}: {} trees, fits {:?}",
            400 + seed,
            plan.trees.len(),
            plan.fits
        );
    }
}

/// A session as `examples/forest_accuracy` makes it (5 s still, 15 s of
/// wind), and its sway correlations at 50 Hz as that sweep takes them.
fn sweep_session(seed: u64, trees: usize, overlap: f64) -> (Truth, Vec<SwayLink>) {
    let opts = SynthOptions::forest_sweep(seed, trees, overlap);
    let t = generate(&opts).expect("session").truth;
    let markers: Vec<usize> = (0..t.tips.len()).collect();
    let l = sway::links_of_series(&t.wind_sway(50.0), &markers, 100);
    (t, l)
}

#[test]
fn the_sway_finds_the_count_where_the_crown_fit_alone_misses() {
    // Sessions of the settings sweeps (seeds 5000–5079, then 0–39) where
    // the crown fit alone takes a tree too many (a lumpy crown fitted two
    // surfaces) or too few (two crowns fitted one; at seed 7 five trees
    // fitted within the tolerance by four crowns, and clearly better by
    // five whose crowns do not sway as one; at held-out seed 1019, crowns
    // overlapping by a third, the same, though only the RMS over all tips
    // shows it, the worst crown being a lumpy tree elsewhere):
    // the trunks' sway sets them right (docs/forest.md, "The count: one
    // criterion for the fit and the sway"), and a still take (no sway)
    // falls back on the fit alone.
    let recon = ReconstructSettings::default();
    let s = ForestSettings::default();
    for (seed, overlap) in [(5063, 0.0), (5026, 1.0 / 6.0), (7, 0.25), (1019, 1.0 / 3.0)] {
        let trees = 2 + (seed % 4) as usize;
        let (t, l) = sweep_session(seed as u64, trees, overlap);
        let tips = t.rest_tips();
        let still = forest::plan(&tips, &[], &[], &s, &recon).unwrap();
        assert_ne!(still.trees.len(), trees, "seed {seed}: the fit alone");
        let swayed = forest::plan(&tips, &l, &[], &s, &recon).unwrap();
        assert_eq!(
            swayed.trees.len(),
            trees,
            "seed {seed}: fits {:?}",
            swayed.fits
        );
        // The plan says which evidence settled the count: the still take's
        // by the crown fit; the swayed one's by the criterion of the fit
        // and the sway, whose crowns the sway pulled — "by the sway" when
        // the fit's rule among those same crowns would have taken another
        // number (named), "by the crown fit" when the pulled crowns
        // already fit right (seed 5063) — and a margin in (0, 1].
        let (by_fit, by_sway) = (still.count.unwrap(), swayed.count.unwrap());
        assert_eq!(by_fit.basis, CountBasis::Fit, "seed {seed}: {by_fit:?}");
        assert!(!by_fit.swayed && by_sway.swayed, "seed {seed}");
        assert!(by_fit.reason.contains("fit tolerance"), "{by_fit:?}");
        assert!(by_sway.reason.contains("sway best"), "{by_sway:?}");
        match by_sway.basis {
            CountBasis::Sway => assert_ne!(by_sway.fit_trees, trees, "{by_sway:?}"),
            CountBasis::Fit => assert_eq!(by_sway.fit_trees, trees, "{by_sway:?}"),
        }
        for c in [&by_fit, &by_sway] {
            assert!(c.margin > 0.0 && c.margin <= 1.0, "seed {seed}: {c:?}");
        }
    }
}

#[test]
fn the_counts_the_threshold_rule_missed_are_right() {
    // Held-out sessions (not looked at while the criterion's two factors
    // were chosen on seeds 0–39) that the threshold rule before it got
    // wrong: 1030 (two halves of a tree at 0.61 of their own, under the
    // 0.65 that merged), 2002 (a fifth crown of 7 tips fitting very well),
    // 2009 (a tree's halves at 0.57 of their own, two trees at 0.27 by
    // chance), 2022 (no split into four by shape was the four trees) and
    // 3009 (three trees hardly swaying with their trunks, a fourth crown
    // "swaying apart" as nothing correlates). The trunk's pull in the
    // search and one criterion for the fit and the sway count them right
    // (docs/forest.md, "The count: one criterion for the fit and the
    // sway").
    let recon = ReconstructSettings::default();
    let s = ForestSettings::default();
    for (seed, overlap) in [
        (1030, 1.0 / 3.0),
        (2002, 1.0 / 3.0),
        (2009, -0.1),
        (2022, 1.0 / 3.0),
        (3009, -0.1),
    ] {
        let trees = 2 + (seed % 4) as usize;
        let (t, l) = sweep_session(seed as u64, trees, overlap);
        let plan = forest::plan(&t.rest_tips(), &l, &[], &s, &recon).unwrap();
        let count = plan.count.clone().unwrap();
        assert_eq!(
            plan.trees.len(),
            trees,
            "seed {seed}: fits {:?}, {count:?}",
            plan.fits
        );
        assert!(count.swayed, "seed {seed}: {count:?}");
        assert!(count.reason.contains("sway best"), "seed {seed}: {count:?}");
    }
}

#[test]
fn each_tree_sways_with_its_trunk_and_apart_from_the_others() {
    // The simulator's forests: the tips of one tree share their trunk's
    // sway (their mean correlation is clearly positive, even between tips
    // of different limbs), two trees sway independently.
    let (mut own, mut across) = (Vec::new(), Vec::new());
    for seed in 0..6 {
        let (t, l) = sweep_session(600 + seed, 2 + (seed % 3) as usize, 0.0);
        let f = t.forest.as_ref().unwrap();
        let pairs: Vec<(usize, usize, f64)> = l.iter().map(|x| (x.a, x.b, x.correlation)).collect();
        let c = sway::Coherence::new(t.tips.len(), &pairs);
        for k in 0..f.trees.len() {
            own.push(c.mean_between(&f.tip_tree, k, k).0);
            for j in 0..k {
                across.push(c.mean_between(&f.tip_tree, k, j).0);
            }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    eprintln!("within a tree {own:.2?}; between trees {across:.2?}");
    assert!(mean(&own) > 0.25, "{own:?}");
    assert!(mean(&across).abs() < 0.05, "{across:?}");
    assert!(mean(&own) > mean(&across) + 0.25);
}

#[test]
fn one_tree_gives_the_same_bytes_as_before() {
    let t = generate(&SynthOptions {
        seed: 24,
        still_s: 1.0,
        wind_s: 0.0,
        ..SynthOptions::default()
    })
    .unwrap()
    .truth;
    let tips = t.rest_tips();
    let cfg = ReconstructSettings::default();
    let plan = forest::plan(&tips, &[], &[], &ForestSettings::default(), &cfg).unwrap();
    assert!(plan.is_single());
    // Still (replay --still, reconstruct) and rigged (the daemon's glb).
    for motion in [|| Motion::Still, || Motion::Rigged] {
        let alone = build_outputs(&tips, DVec3::new(0.3, 0.0, 0.9), &cfg, motion()).unwrap();
        let via_forest = forest_outputs(&plan, DVec3::new(0.3, 0.0, 0.9), &cfg, motion()).unwrap();
        assert_eq!(alone.glb, via_forest.glb);
        assert_eq!(alone.tree_json, via_forest.tree_json);
        assert_eq!(alone.png, via_forest.png);
        assert!(via_forest.report.forest.is_none());
    }
}

/// Is `p` inside tree `j`'s volume: its crown boxes (the flow's bounds)
/// and its cell?
fn in_volume(plan: &ForestPlan, j: usize, p: DVec3) -> bool {
    let t = &plan.trees[j];
    let (lo, hi) = t.tips.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), c| (lo.min(c.position), hi.max(c.position)),
    );
    let inside = |s: &forest::cell::HalfSpace| s.normal.dot(p) < s.offset - 1e-6;
    p.cmpge(lo).all() && p.cmple(hi).all() && t.cell.sides.iter().all(inside)
}

#[test]
fn no_branch_grows_into_another_trees_volume() {
    let cfg = ReconstructSettings::default();
    for (seed, overlap) in [(500, 1.0 / 3.0), (501, 0.25)] {
        let t = forest(seed, 3, overlap);
        let plan = forest::plan(
            &t.rest_tips(),
            &links(&t),
            &true_bases(&t),
            &ForestSettings::default(),
            &cfg,
        )
        .unwrap();
        let trees = forest::grow(&plan, DVec3::new(1.0, 0.0, 0.0), &cfg).unwrap();
        let mut checked = 0;
        for (i, tree) in trees.iter().enumerate() {
            // Each tree is one tree: every node reaches its own root.
            assert!(tree.check().is_ok());
            for n in &tree.nodes {
                if matches!(n.kind, treemocap::model::tree::Kind::Captured { .. })
                    || n.kind == treemocap::model::tree::Kind::Trunk
                {
                    continue;
                }
                checked += 1;
                for j in (0..trees.len()).filter(|&j| j != i) {
                    assert!(
                        !in_volume(&plan, j, n.position),
                        "seed {seed}: a {} node of {} at {} is in {}'s volume",
                        n.kind.name(),
                        plan.trees[i].name,
                        n.position,
                        plan.trees[j].name
                    );
                }
            }
        }
        assert!(checked > 1000, "{checked}");
    }
}

/// The README's command for the shipped three-tree replay.
const SHIPPED: &[&str] = &[
    "synth",
    "--seed",
    "3",
    "--trees",
    "3",
    "--tips",
    "16",
    "--overlap",
    "0.3",
    "--mixed",
    "--rate",
    "50",
    "--still",
    "8",
    "--wind",
    "10",
];

#[test]
fn the_shipped_forest_replay_regenerates_byte_identically() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("forest-3.csv");
    let run = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(SHIPPED)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("replays");
    for name in ["forest-3.csv", "forest-3.truth.json"] {
        let shipped = std::fs::read(root.join(name)).unwrap();
        assert!(shipped.len() < 3_000_000, "{name} is too big");
        assert!(
            std::fs::read(dir.path().join(name)).unwrap() == shipped,
            "{name} differs from its synth command"
        );
    }
}

#[test]
fn replay_splits_the_shipped_forest_replay_into_trees() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("replays");
    let csv = root.join("forest-3.csv");
    let truth: Truth =
        serde_json::from_str(&std::fs::read_to_string(root.join("forest-3.truth.json")).unwrap())
            .unwrap();
    let out = dir.path().join("out");
    let config = Config {
        reconstruct: ReconstructSettings {
            leaves: true,
            ..Config::default().reconstruct
        },
        ..Config::default()
    };
    let report = treemocap::app::replay::run(&csv, &config, &out).unwrap();
    let tracked = tracked_tips(&csv, &config);
    let printed = report.to_string();
    assert!(
        printed.contains("trees: 3 found") && printed.contains("[[trees]]"),
        "{printed}"
    );

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tree.json")).unwrap()).unwrap();
    assert_eq!(json["version"], 2);
    // How the count was chosen, printed and in tree.json alike: the
    // evidence (crown fit or sway), the margin and the rule.
    let count = &json["count"];
    let line = printed
        .lines()
        .find(|l| l.starts_with("count: 3 by "))
        .unwrap_or_else(|| panic!("no count line in {printed}"));
    let by = if count["basis"] == "fit" {
        "the crown fit"
    } else {
        "the sway"
    };
    let margin = count["margin"].as_f64().unwrap();
    assert!(margin > 0.0 && margin <= 1.0, "{count}");
    assert!(
        line.contains(by) && line.contains(&format!("margin {:.0} %", 100.0 * margin)),
        "{line} vs {count}"
    );
    assert_eq!(count["swayed"], true, "the take has a wind phase: {count}");
    assert!(line.ends_with(count["reason"].as_str().unwrap()), "{line}");
    let trees = json["trees"].as_array().unwrap();
    assert_eq!(trees.len(), 3);
    // Tips of tips.json matched to the truth by rest position.
    let tips: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("tips.json")).unwrap()).unwrap();
    let f = truth.forest.as_ref().unwrap();
    let true_tree_of = |marker: u64| {
        let tip = tips["tips"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["marker"] == marker)
            .unwrap();
        let rest = DVec3::new(
            tip["rest"][0].as_f64().unwrap(),
            tip["rest"][1].as_f64().unwrap(),
            tip["rest"][2].as_f64().unwrap(),
        );
        let i = (0..truth.tips.len())
            .min_by(|&a, &b| {
                truth.tips[a]
                    .rest
                    .distance(rest)
                    .total_cmp(&truth.tips[b].rest.distance(rest))
            })
            .unwrap();
        f.tip_tree[i]
    };
    let (mut right, mut all) = (0, 0);
    for tree in trees {
        let markers: Vec<u64> = tree["markers"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|m| m.as_u64())
            .collect();
        let owners: Vec<usize> = markers.iter().map(|&m| true_tree_of(m)).collect();
        let main = (0..3)
            .max_by_key(|k| owners.iter().filter(|o| *o == k).count())
            .unwrap();
        right += owners.iter().filter(|&&o| o == main).count();
        all += owners.len();
        assert_eq!(tree["kinds"][0], "trunk");
    }
    assert_eq!(all, truth.tips.len(), "every tip in one tree");
    assert!(right as f64 >= 0.98 * all as f64, "{right} of {all}");

    // Per tree, a scene node named as the tree holding its joints, and its
    // skinned branches, leaves and skeleton beside it; one animation; clean.
    let glb = Glb::parse(&std::fs::read(out.join("tree.glb")).unwrap());
    let g = &glb.json;
    let scene: Vec<&serde_json::Value> = g["scenes"][0]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| &g["nodes"][n.as_u64().unwrap() as usize])
        .collect();
    assert_eq!(scene.len(), 3 * 4);
    assert_eq!(g["skins"].as_array().unwrap().len(), 3);
    assert_eq!(g["animations"].as_array().unwrap().len(), 1);
    for k in 0..3 {
        let holder = scene[4 * k];
        assert_eq!(holder["name"], format!("tree-{k}"));
        assert_eq!(holder["children"].as_array().unwrap().len(), 1, "{holder}");
        for (j, part) in ["branches", "leaves", "skeleton"].iter().enumerate() {
            let mesh = scene[4 * k + 1 + j];
            assert_eq!(mesh["name"], format!("tree-{k} {part}"));
            assert_eq!(mesh["skin"].as_u64(), Some(k as u64), "{mesh}");
        }
    }
    let (errors, warnings, messages) = crate::common::gltf::validate(&out.join("tree.glb"));
    assert_eq!((errors, warnings), (0, 0), "{messages}");
    let a = report.tree.animation.expect("an animation report");
    assert!(a.keys > 100, "{a:?}");
    // A captured tip of each tree, at a key late in the session, is where
    // the tracker had it (read back from the file's own data).
    let times = glb.key_times();
    let start = g["animations"][0]["extras"]["start_s"].as_f64().unwrap();
    let key = times.len() * 3 / 4;
    let t = start + f64::from(times[key]);
    let timeline = &tracked.timeline.times;
    let i = timeline.partition_point(|&x| x < t).min(timeline.len() - 1);
    let frame = if i > 0 && t - timeline[i - 1] < timeline[i] - t {
        i - 1
    } else {
        i
    } as i64;
    for tree in trees {
        let (mut checked, mut moved) = (0, 0.0f64);
        for marker in tree["markers"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|m| m.as_u64())
        {
            let tip = tracked
                .tips
                .iter()
                .find(|t| t.marker as u64 == marker)
                .unwrap();
            let Some(s) = tip.trace.samples().find(|s| s.frame == frame) else {
                continue;
            };
            if s.kind == SampleKind::Missing {
                continue;
            }
            let joint = glb.node(&format!("tip_{marker:02}")).unwrap();
            let at = glb.world(joint, Some(key));
            let off = at.distance(s.position);
            assert!(
                off < 0.5e-3,
                "{}: tip {marker} {:.3} mm off",
                tree["name"],
                off * 1e3
            );
            moved = moved.max(at.distance(glb.world(joint, None)));
            checked += 1;
        }
        assert!(
            checked > 0,
            "no tracked tip of {} at key {key}",
            tree["name"]
        );
        assert!(moved > 1e-3, "{} does not move ({moved} m)", tree["name"]);
    }
    assert!(std::fs::metadata(out.join("tree.png")).unwrap().len() > 10_000);

    // Pinning the trees found gives the same trees.
    let pinned: Vec<ConfiguredTree> = trees
        .iter()
        .map(|t| ConfiguredTree {
            name: t["name"].as_str().unwrap().to_string(),
            base: [0, 1, 2].map(|k| t["base"][k].as_f64().unwrap()),
        })
        .collect();
    let out2 = dir.path().join("pinned");
    let pinned_config = Config {
        trees: pinned,
        ..config
    };
    treemocap::app::replay::run(&csv, &pinned_config, &out2).unwrap();
    let json2: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out2.join("tree.json")).unwrap()).unwrap();
    for (a, b) in trees.iter().zip(json2["trees"].as_array().unwrap()) {
        assert_eq!(a["markers"], b["markers"]);
        assert_eq!(b["base_source"], "configured");
    }
    // Configured trees were not counted.
    assert!(json2["count"].is_null(), "{}", json2["count"]);
}

#[test]
fn the_cache_regrows_only_the_trees_whose_tips_changed() {
    let cfg = ReconstructSettings {
        total_tips: 120,
        ..ReconstructSettings::default()
    };
    let s = ForestSettings::default();
    let t = forest(600, 3, 0.0);
    let bases = true_bases(&t);
    let mut tips = t.rest_tips();
    let wind = DVec3::new(0.0, 0.0, 1.0);
    let mut cache = ForestCache::default();
    let plan = forest::plan(&tips, &[], &bases, &s, &cfg).unwrap();
    let first = cache.grow(&plan, wind, &cfg).unwrap();
    assert!(first.iter().all(|g| g.rebuilt));
    // Nothing changed: nothing regrown.
    let again = cache.grow(&plan, wind, &cfg).unwrap();
    assert!(again.iter().all(|g| !g.rebuilt));

    // A tip of one tree moves 1 cm, away from the planes (the tip nearest
    // its own trunk): that tree alone is regrown.
    let f = t.forest.as_ref().unwrap();
    let inner = (0..tips.len())
        .filter(|&i| f.tip_tree[i] == 1)
        .min_by(|&a, &b| {
            let d = |i: usize| (tips[i].position - f.trees[1].base).length();
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    tips[inner].position += DVec3::new(0.0, 0.01, 0.0);
    let plan = forest::plan(&tips, &[], &bases, &s, &cfg).unwrap();
    let moved = cache.grow(&plan, wind, &cfg).unwrap();
    let rebuilt: Vec<usize> = plan
        .trees
        .iter()
        .zip(&moved)
        .filter(|(_, g)| g.rebuilt)
        .map(|(t, _)| t.id)
        .collect();
    assert_eq!(rebuilt, vec![1]);
    // The same trees as growing all afresh.
    let fresh = forest::grow(&plan, wind, &cfg).unwrap();
    for (a, b) in moved.iter().zip(&fresh) {
        assert_eq!(*a.tree, *b);
    }

    // A marker moves from tree 0's crown onto tree 2's, beside its tip
    // farthest from tree 0: both trees change.
    let from0 = (0..tips.len()).find(|&i| f.tip_tree[i] == 0).unwrap();
    let far = |i: usize| (tips[i].position - f.trees[0].base).length();
    let on2 = (0..tips.len())
        .filter(|&i| f.tip_tree[i] == 2)
        .max_by(|&a, &b| far(a).total_cmp(&far(b)))
        .unwrap();
    tips[from0].position = tips[on2].position + DVec3::new(0.0, 0.08, 0.0);
    let plan = forest::plan(&tips, &[], &bases, &s, &cfg).unwrap();
    let after = cache.grow(&plan, wind, &cfg).unwrap();
    let rebuilt: Vec<usize> = plan
        .trees
        .iter()
        .zip(&after)
        .filter(|(_, g)| g.rebuilt)
        .map(|(t, _)| t.id)
        .collect();
    assert!(rebuilt.contains(&0) && rebuilt.contains(&2), "{rebuilt:?}");
    let owner = plan
        .trees
        .iter()
        .find(|t| t.tips.iter().any(|c| c.marker == from0))
        .unwrap();
    assert_eq!(owner.id, 2);
}
