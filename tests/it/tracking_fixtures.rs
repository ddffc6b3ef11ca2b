//! The marker stage on the two real Motive exports in tests/fixtures/motive
//! (see PROVENANCE.md there). Expected values come from an independent
//! reading of the CSV files with Python's csv module (per column: frames
//! with all three cells present, first/last row, mean position, RMS
//! distance from the mean), not from treemocap's own output.

use std::path::Path;
use std::process::Command;

use glam::DVec3;
use treemocap::config::Config;
use treemocap::track::{process, RestSource};

fn run(name: &str) -> (treemocap::model::tips::Tips, treemocap::track::Summary) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/motive")
        .join(name);
    let config = Config::default();
    let mut rec = treemocap::app::open::open_with(
        &path,
        &treemocap::app::open::ReplayOptions::from_config(&config),
    )
    .unwrap();
    process(rec.as_mut(), &config.tracking).unwrap()
}

#[test]
fn ha5dzs_18_unlabeled_columns_give_17_tips_and_one_flash() {
    let (tips, summary) = run("ha5dzs_test_markers_enabled_v1.23_unlabeled.csv");
    assert_eq!(summary.frames, 1353);
    // 18 columns: 15 present throughout, 1051 from row 348, 1052 from row
    // 349, and 1053 present in row 669 only.
    assert_eq!(summary.traces, 18);
    assert_eq!(summary.tips, 17);
    // The one-row flash is never confirmed as a marker: a ghost.
    assert_eq!(summary.ghosts, 1);
    assert!(summary.dropped.is_empty());
    assert_eq!(summary.tracking.markers, 15 * 1353 + 1005 + 1004 + 1);
    // The markers barely move: the whole take is the rest window.
    assert_eq!(summary.rest_source, RestSource::Auto);
    assert!(summary.rest_window_s[0] < 0.01 && summary.rest_window_s[1] > 3.75);
    // Column means (m), from Python, in order of first appearance.
    let expected = [
        [2.65978, -0.8308, -2.86225],
        [2.03117, 0.03464, 0.72445],
        [0.00594, 1.47014, 1.8737],
        [0.00254, 1.4878, 1.80082],
        [-0.25357, 1.45145, 1.80173],
        [-0.00708, 1.42821, 1.54163],
        [0.2914, 1.39367, 1.42541],
        [-0.11074, 1.37015, 1.43251],
        [0.2032, 1.38615, 1.39921],
        [-0.02909, 1.36658, 1.40027],
        [0.26808, 1.37888, 1.37753],
        [0.13235, 1.47395, 1.61982],
        [-0.09395, 1.3624, 1.37984],
        [0.43893, 1.48086, 1.77436],
        [0.4322, 1.43449, 1.56286],
        [0.4406, 1.47135, 1.80324],
        [-0.25355, 1.44347, 1.83004],
    ];
    for (tip, want) in tips.tips.iter().zip(expected) {
        let d = tip.rest.distance(DVec3::from_array(want));
        assert!(
            d < 2e-5,
            "marker {}: {:?} vs {want:?}",
            tip.marker,
            tip.rest
        );
    }
    assert_eq!(tips.tips[15].samples, 1005);
    assert_eq!(tips.tips[16].samples, 1004);
    assert!((tips.tips[15].gap_fraction - (1.0 - 1005.0 / 1353.0)).abs() < 1e-9);
    // Every tip is one source column: no swaps between columns.
    for tip in &tips.tips {
        assert_eq!(tip.trace.sources().len(), 1, "marker {}", tip.marker);
    }
}

#[test]
fn cmuphyscomp_six_markers_with_data_become_six_tips() {
    let (tips, summary) = run("cmuphyscomp_sample_take_v1.21.csv");
    // 9 Marker columns, 3 of them empty in every row; rigid bodies are not tips.
    assert_eq!(summary.frames, 250);
    assert!(summary.traces >= 6);
    assert_eq!(summary.tips, 6);
    assert!(summary.dropped.is_empty());
    // Five markers hold still: each is one tip with every sample, at the
    // position and spread read from the file.
    let still = [
        ([-0.73364, 0.73126, 2.33717], 0.329),
        ([-0.72487, 0.71866, 2.66139], 0.031),
        ([0.01003, 0.01916, 0.00975], 0.118),
        ([0.01003, 0.0192, 0.21013], 0.139),
        ([0.16013, 0.01915, 0.00974], 0.139),
    ];
    let nearest = |want: DVec3| {
        tips.tips
            .iter()
            .min_by(|a, b| a.rest.distance(want).total_cmp(&b.rest.distance(want)))
            .unwrap()
    };
    for (want, spread_mm) in still {
        let want = DVec3::from_array(want);
        let tip = nearest(want);
        assert!(
            tip.rest.distance(want) < 2e-5,
            "{want:?}: nearest tip at {:?}",
            tip.rest
        );
        assert!(
            (tip.spread_m * 1000.0 - spread_mm).abs() < 0.01,
            "{}",
            tip.spread_m
        );
        assert_eq!(tip.samples, 250);
    }
    // The sixth marker's centroid flips, frame by frame, between two spots
    // 9.5 mm apart (two centroid solutions in Motive). It is one marker:
    // one tip with every sample of its column, its rest position their
    // mean and its spread their RMS distance from it (4.73 mm), both read
    // from the file.
    let mean = DVec3::new(-0.7225846, 0.7147400, 2.8287007);
    let flipping = nearest(mean);
    assert_eq!(flipping.samples, 250);
    assert!(flipping.rest.distance(mean) < 1e-5, "{:?}", flipping.rest);
    assert!(
        (flipping.spread_m * 1000.0 - 4.731).abs() < 0.01,
        "{}",
        flipping.spread_m
    );
    assert_eq!(flipping.trace.measured(), 250);
    assert_eq!(flipping.gap_fraction, 0.0);
    // Its pieces on the other spot were adopted, not dropped as ghosts.
    assert_eq!(summary.ghosts, 0);
    assert!(summary.adopted >= 2, "{}", summary.adopted);
    // Every marker is still (the sixth flips, but stays put): the whole
    // take is the rest window, found as such.
    assert_eq!(summary.rest_source, RestSource::Auto);
    assert!(summary.rest_window_s[0] <= 0.01 && summary.rest_window_s[1] >= 2.07);
}

#[test]
fn tips_command_writes_tips_json_and_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("tips.json");
    let png = dir.path().join("traces.png");
    let out = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .arg("tips")
        .arg(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/fixtures/motive/ha5dzs_test_markers_enabled_v1.23_unlabeled.csv"),
        )
        .arg("--json")
        .arg(&json)
        .arg("--plot")
        .arg(&png)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("markers found: 17 tips"), "{stdout}");
    assert!(stdout.contains("1 ghosts never confirmed"), "{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["version"], 1);
    assert_eq!(v["frame_rate"], 360.0);
    assert_eq!(v["tips"].as_array().unwrap().len(), 17);
    let t0 = &v["tips"][0];
    for key in ["marker", "rest", "samples", "gap_fraction", "spread_m"] {
        assert!(t0.get(key).is_some(), "{key} missing");
    }
    assert!(v["wind"].is_null());
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    // A missing file is an error naming it, exit code 1.
    let out = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(["tips", "/nonexistent/take.csv"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/take.csv"));
}
