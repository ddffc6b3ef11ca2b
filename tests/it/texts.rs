//! What users read is right (issue 17): the help names every format the
//! commands read, our log opens in pandas with no options, and tips.json
//! says `"speed": null` when only the wind's direction is known.

use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn treemocap() -> Command {
    Command::new(env!("CARGO_BIN_EXE_treemocap"))
}

fn python() -> String {
    std::env::var("TREEMOCAP_PYTHON").unwrap_or_else(|_| "python3".into())
}

#[test]
fn help_names_c3d_beside_motive_csv_and_our_log() {
    for cmd in ["replay", "tips", "inspect", "serve"] {
        let out = treemocap().args([cmd, "--help"]).output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{cmd} --help");
        for format in ["Motive CSV", "C3D", "treemocap log"] {
            assert!(
                text.contains(format),
                "`{cmd} --help` must name {format}:\n{text}"
            );
        }
    }
}

#[test]
fn our_log_reads_in_pandas_with_no_options_and_keeps_its_metadata() {
    use treemocap::format::log::{sidecar_path, LogHeader, LogWriter};
    use treemocap::model::frame::{Marker, MarkerFrame};
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("take.log.csv");
    let header = LogHeader {
        source: "natnet 127.0.0.1:1510".into(),
        frame_rate: 120.0,
    };
    let mut w = LogWriter::create(&log, &header, Duration::from_secs(1)).unwrap();
    let mut samples = 0;
    for i in 0..50i64 {
        let markers: Vec<Marker> = (0..(i % 4) as usize)
            .map(|k| Marker::new(glam::DVec3::new(i as f64 * 0.001, 1.0 + k as f64, -0.5)))
            .collect();
        samples += markers.len();
        w.write_frame(&MarkerFrame::new(i, i as f64 / 120.0, markers))
            .unwrap();
    }
    w.finish().unwrap();
    let script = "import sys, pandas\n\
                  df = pandas.read_csv(sys.argv[1])\n\
                  print(','.join(df.columns)); print(len(df)); print(int(df['x'].count())); print(df['frame'].max())";
    let out = Command::new(python())
        .args(["-c", script])
        .arg(&log)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<String> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(String::from)
        .collect();
    assert_eq!(lines[0], "frame,time_s,id,x,y,z");
    // One row per marker sample, one per empty frame (13 frames of 50 have none).
    assert_eq!(lines[1].parse::<usize>().unwrap(), samples + 13);
    assert_eq!(lines[2].parse::<usize>().unwrap(), samples);
    assert_eq!(lines[3], "49");
    // treemocap reads it back with the sidecar's metadata…
    assert!(sidecar_path(&log).exists());
    let out = treemocap()
        .args(["inspect", "--json"])
        .arg(&log)
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frame_rate"], 120.0, "{v}");
    assert_eq!(v["source"], "natnet 127.0.0.1:1510");
    // …and without it, from the frame numbers and times, saying so.
    std::fs::remove_file(sidecar_path(&log)).unwrap();
    let out = treemocap()
        .args(["inspect", "--json"])
        .arg(&log)
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["frame_rate"], 120.0, "{v}");
    assert!(v.to_string().contains("no sidecar"), "{v}");
}

#[test]
fn tips_json_of_a_sway_wind_stores_speed_null_and_reconstructs() {
    let dir = tempfile::tempdir().unwrap();
    let out = treemocap()
        .arg("replay")
        .arg(root().join("replays/maple-24.csv"))
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tips: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("tips.json")).unwrap()).unwrap();
    assert!(tips["wind"]["direction"].is_array(), "{}", tips["wind"]);
    assert!(
        tips["wind"]["speed"].is_null(),
        "PCA knows no speed: {}",
        tips["wind"]
    );
    let again = dir.path().join("again");
    let out = treemocap()
        .arg("reconstruct")
        .arg(dir.path().join("tips.json"))
        .arg("--out")
        .arg(&again)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // tree.json: replay's tree.glb also carries the captured motion,
    // which tips.json does not hold.
    assert!(
        std::fs::read(dir.path().join("tree.json")).unwrap()
            == std::fs::read(again.join("tree.json")).unwrap(),
        "the same tips and wind give the same tree"
    );
}
