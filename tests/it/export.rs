//! `treemocap export` and `tips --json --traces` on a synthetic session:
//! the C3D read back by two independent readers (ezc3d, py-c3d) gives
//! exactly the positions of the JSON trajectories, fills flagged with
//! residual 0; pandas reads the CSV with no options; the TRC has OpenSim's
//! header. Needs python3 with tests/peers/requirements.txt.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

fn treemocap(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn exported_trajectories_read_back_exactly_in_third_party_readers() {
    let dir = tempfile::tempdir().unwrap();
    let csv_in = dir.path().join("take.csv");
    let opts = treemocap::sim::SynthOptions {
        seed: 3,
        tips: 6,
        frame_rate: 100.0,
        still_s: 2.0,
        wind_s: 2.0,
        gap_fraction: 0.1,
        ..Default::default()
    };
    treemocap::app::synth::write_session(&opts, &csv_in).unwrap();
    let json = dir.path().join("tips.json");
    let (c3d, csv, trc) = (
        dir.path().join("t.c3d"),
        dir.path().join("t.csv"),
        dir.path().join("t.trc"),
    );
    treemocap(&["tips", path(&csv_in), "--json", path(&json), "--traces"]);
    for out in [&c3d, &csv, &trc] {
        treemocap(&["export", path(&csv_in), "--out", path(out)]);
    }
    let tips: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let list = tips["tips"].as_array().unwrap();
    assert_eq!(list.len(), 6);
    let frames = tips["frames"].as_array().unwrap().len();
    assert_eq!(frames, 400);

    let python = std::env::var("TREEMOCAP_PYTHON").unwrap_or_else(|_| "python3".into());
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/peers/read_export.py");
    let out = Command::new(&python)
        .arg(script)
        .arg(&c3d)
        .arg(&csv)
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run {python} ({e}); pip install -r tests/peers/requirements.txt")
        });
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let read: Value = serde_json::from_slice(&out.stdout).unwrap();

    let mut filled_seen = 0;
    for reader in ["ezc3d", "py_c3d"] {
        let r = &read[reader];
        assert_eq!(r["rate"], 100.0, "{reader}");
        for (k, tip) in list.iter().enumerate() {
            let label = tip["label"].as_str().unwrap();
            assert_eq!(label, format!("tip_{:02}", k + 1));
            assert_eq!(r["labels"][k].as_str().unwrap().trim(), label, "{reader}");
            let filled: Vec<u64> = tip["filled"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_u64().unwrap())
                .collect();
            for (i, sample) in tip["trace"].as_array().unwrap().iter().enumerate() {
                let got = &r["points"][k][i];
                let residual = got[3].as_f64().unwrap();
                match sample.as_array() {
                    None => assert!(
                        residual < 0.0 || got[0].is_null(),
                        "{reader} {label} frame {i}: missing read as {got}"
                    ),
                    Some(p) => {
                        let (x, y, z) = (
                            p[0].as_f64().unwrap(),
                            p[1].as_f64().unwrap(),
                            p[2].as_f64().unwrap(),
                        );
                        // Millimetres, Z up, float32: exactly what was written.
                        let want = [
                            (x * 1000.0) as f32,
                            (-z * 1000.0) as f32,
                            (y * 1000.0) as f32,
                        ];
                        for a in 0..3 {
                            assert_eq!(
                                got[a].as_f64().unwrap() as f32,
                                want[a],
                                "{reader} {label} frame {i}"
                            );
                        }
                        if filled.contains(&(i as u64)) {
                            assert_eq!(
                                residual, 0.0,
                                "{reader} {label} frame {i}: a fill is residual 0"
                            );
                            filled_seen += 1;
                        } else {
                            assert!(
                                residual > 0.0,
                                "{reader} {label} frame {i}: measured has residual > 0"
                            );
                        }
                    }
                }
            }
        }
    }
    assert!(filled_seen > 0, "the session has filled samples");

    let pd = &read["pandas"];
    assert_eq!(pd["rows"], 400);
    assert_eq!(pd["columns"][0], "frame");
    assert_eq!(pd["columns"].as_array().unwrap().len(), 2 + 5 * 6);
    assert_eq!(pd["dtypes"]["tip_01_x_m"], "float64");
    let first = list[0]["trace"].as_array().unwrap();
    for (i, v) in pd["tip_01_x_m"].as_array().unwrap().iter().enumerate() {
        match first[i].as_array() {
            None => assert!(v.is_null()),
            Some(p) => assert!((v.as_f64().unwrap() - p[0].as_f64().unwrap()).abs() < 1e-6),
        }
    }

    let trc_text = std::fs::read_to_string(&trc).unwrap();
    let lines: Vec<&str> = trc_text.lines().collect();
    assert!(lines[0].starts_with("PathFileType\t4\t(X/Y/Z)\tt.trc"));
    assert_eq!(lines[2].split('\t').nth(2), Some("400"));
    assert_eq!(lines[2].split('\t').nth(4), Some("mm"));
    assert!(lines[3].starts_with("Frame#\tTime\ttip_01\t\t\ttip_02"));
    assert_eq!(lines.len(), 6 + 400);
}
