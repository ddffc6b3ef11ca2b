//! The command line as a user meets it: inspect a real export, get JSON for a
//! script, and get one clear line and the right exit code when something is wrong.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn treemocap(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run treemocap")
}

fn fixture(name: &str) -> PathBuf {
    Path::new("tests/fixtures/motive").join(name)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn inspect_prints_the_take_summary() {
    let f = fixture("ha5dzs_test_markers_enabled_v1.23_unlabeled.csv");
    let out = treemocap(&["inspect", f.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let s = text(&out.stdout);
    assert!(s.contains("Motive CSV 1.23"), "{s}");
    assert!(s.contains("360 Hz"), "{s}");
    assert!(s.contains("frames      1353  (numbers 0 to 1352"), "{s}");
    assert!(s.contains("min 15 / median 17 / max 18"), "{s}");
    assert!(s.contains("gap cells   6147"), "{s}");
}

#[test]
fn inspect_json_is_one_object_for_scripts() {
    let f = fixture("cmuphyscomp_sample_take_v1.21.csv");
    let out = treemocap(&["inspect", "--json", f.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["format"], "motive_csv");
    assert_eq!(v["version"], "1.21");
    assert_eq!(v["frames"], 250);
    assert_eq!(v["first_frame"], 0);
    assert_eq!(v["last_frame"], 249);
    assert_eq!(v["markers_per_frame"]["median"], 6);
    assert_eq!(v["marker_columns"].as_array().unwrap().len(), 9);
    assert_eq!(v["empty_columns"], 3);
    assert_eq!(v["gap_cells"], 2250);
    assert_eq!(v["other_channels"]["rigid_body"], 1);
}

#[test]
fn bad_input_is_one_line_naming_the_file_exit_1() {
    let f = fixture("quirks/bad_not_a_number.csv");
    let out = treemocap(&["inspect", f.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let e = text(&out.stderr);
    assert_eq!(e.lines().count(), 1, "{e}");
    assert!(e.contains("bad_not_a_number.csv: line 9, column 4"), "{e}");

    let out = treemocap(&["inspect", "no/such/file.csv"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("no/such/file.csv"));
}

#[test]
fn bad_usage_and_bad_config_exit_2() {
    let out = treemocap(&["inspect"]);
    assert_eq!(out.status.code(), Some(2));
    let out = treemocap(&["frobnicate"]);
    assert_eq!(out.status.code(), Some(2));

    let f = fixture("quirks/v1.24_timecode.csv");
    let out = treemocap(&[
        "replay",
        f.to_str().unwrap(),
        "--set",
        "record.flush_interval_s=9",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let e = text(&out.stderr);
    assert!(
        e.contains("record.flush_interval_s") && e.contains("0.01 to 1"),
        "{e}"
    );

    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("rig.toml");
    std::fs::write(&cfg, "[replay]\ntime_tolerance = 1\n").unwrap();
    let out = treemocap(&[
        "replay",
        f.to_str().unwrap(),
        "--config",
        cfg.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("replay.time_tolerance"));
}

#[test]
fn help_explains_the_commands() {
    let out = treemocap(&["--help"]);
    assert!(out.status.success());
    let s = text(&out.stdout);
    assert!(s.contains("replay") && s.contains("inspect"), "{s}");
}

#[test]
fn shipped_rig_configs_are_valid() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("config");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            treemocap::config::Config::load(Some(&path), &[])
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            n += 1;
        }
    }
    assert!(n >= 4, "default.toml and the rig examples");
}
