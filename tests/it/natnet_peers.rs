//! Interoperability with NatNet clients we did not write, against the real
//! `treemocap serve` binary on loopback:
//! - OptiTrack's own Python client (`natnetsdk` 4.1.1, `python -m natnetsdk
//!   127.0.0.1 127.0.0.1 u`), bitstreams 3.0, 3.1 and 4.1 (its 2.x and 4.0
//!   decoding is buggy, spec §9): the frame numbers and marker positions it
//!   prints must match the recording.
//! - PyPI `natnet` 0.3.0 (3.0, 3.1, 4.0; it has no 4.1 suffix): every frame,
//!   every marker, bit-exact f32 positions and f64 timestamps.
//!
//! OptiTrack's client only talks to the default ports 1510/1511, so where a
//! private network namespace can be made (`unshare -n`) each run happens in
//! one; otherwise on the host's loopback, one run at a time.
//!
//! The peers are installed by `pip install -r tests/peers/requirements.txt`;
//! these tests fail with that hint when they are missing.

use std::process::Command;
use std::sync::Mutex;

use crate::common::natnet::{free_port, session};
use treemocap::model::frame::MarkerFrame;

static HOST_PORTS: Mutex<()> = Mutex::new(());

fn python() -> String {
    std::env::var("TREEMOCAP_PYTHON").unwrap_or_else(|_| "python3".into())
}

fn require(module: &str) {
    let ok = Command::new(python())
        .args(["-c", &format!("import {module}")])
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        ok,
        "Python module '{module}' is missing: pip install -r tests/peers/requirements.txt \
         (or set TREEMOCAP_PYTHON to a python that has it)"
    );
}

fn netns_available() -> bool {
    Command::new("unshare")
        .args(["-n", "true"])
        .status()
        .is_ok_and(|s| s.success())
}

/// Runs `script` with sh, inside a fresh network namespace when possible.
fn run_script(script: &str) -> String {
    let _guard;
    let mut cmd = if netns_available() {
        let mut c = Command::new("unshare");
        c.args(["-n", "sh", "-c", &format!("ip link set lo up && {script}")]);
        c
    } else {
        _guard = HOST_PORTS.lock().unwrap_or_else(|e| e.into_inner());
        let mut c = Command::new("sh");
        c.args(["-c", script]);
        c
    };
    let out = cmd
        .env("TREEMOCAP", env!("CARGO_BIN_EXE_treemocap"))
        .env("PY", python())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// A frame printed in detail: its number and labeled-marker positions.
type Detailed = (i64, Vec<[f64; 3]>);

/// Frame numbers printed ("MoCap Frame: N") and, for frames printed in
/// detail, the labeled-marker positions ("pos : [x, y, z]", 2 decimals).
fn parse_natnetsdk(text: &str) -> (Vec<i64>, Vec<Detailed>) {
    let mut numbers = Vec::new();
    let mut detailed: Vec<Detailed> = Vec::new();
    for line in text.lines() {
        let t = line.trim();
        // Its main thread prints too ("Ready..."), so a line may start
        // with another thread's text.
        if let Some((_, n)) = t.split_once("MoCap Frame:") {
            numbers.push(n.trim().parse().unwrap());
        } else if let Some((_, n)) = t.split_once("Frame #:") {
            detailed.push((n.trim().parse().unwrap(), Vec::new()));
        } else if t.starts_with("pos ") && t.contains(": [") {
            let inner = t.split(": [").nth(1).unwrap().trim_end_matches(']');
            let v: Vec<f64> = inner
                .split(',')
                .map(|x| x.trim().parse().unwrap())
                .collect();
            detailed
                .last_mut()
                .expect("pos inside a frame")
                .1
                .push([v[0], v[1], v[2]]);
        }
    }
    (numbers, detailed)
}

#[test]
fn optitrack_python_client_decodes_our_stream() {
    require("natnetsdk");
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 21, 300, 6, 100.0);
    for version in ["3.0", "3.1", "4.1"] {
        // 'k' prints every frame in detail; 'q' quits after the 3 s take.
        // After 'q' its data thread stays blocked in recvfrom, so `timeout`
        // ends it; unbuffered output keeps everything it printed.
        let script = format!(
            "\"$TREEMOCAP\" serve '{}' --natnet-version {version} --bind 127.0.0.1 & S=$!; sleep 0.5; \
             (sleep 0.5; echo k; sleep 4.5; echo q) | PYTHONUNBUFFERED=1 timeout 7 \"$PY\" -m natnetsdk 127.0.0.1 127.0.0.1 u; \
             wait $S",
            path.display()
        );
        let out = run_script(&script);
        assert!(
            out.contains(&format!(
                "NatNetVersion  {} {} 0 0",
                &version[..1],
                &version[2..]
            )),
            "{out}"
        );
        let (numbers, detailed) = parse_natnetsdk(&out);
        let want: Vec<i64> = sent.iter().map(|f| f.frame).collect();
        assert_eq!(numbers, want, "bitstream {version}: frame numbers");
        assert!(
            detailed.len() >= 100,
            "bitstream {version}: {} frames printed in detail",
            detailed.len()
        );
        for (n, pos) in &detailed {
            let f: &MarkerFrame = &sent[*n as usize];
            assert_eq!(pos.len(), f.markers.len(), "bitstream {version} frame {n}");
            for (p, m) in pos.iter().zip(&f.markers) {
                let q = m.position;
                for (a, b) in p.iter().zip([q.x, q.y, q.z]) {
                    // Printed with %3.2f.
                    assert!(
                        (a - b).abs() <= 0.005 + 1e-6,
                        "bitstream {version} frame {n}: {a} vs {b}"
                    );
                }
            }
        }
    }
}

#[test]
fn pypi_natnet_decodes_our_stream_exactly() {
    require("natnet");
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 22, 200, 25, 100.0);
    let driver = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/peers/natnet_pypi_client.py"
    );
    for version in ["3.0", "3.1", "4.0"] {
        let (cp, dp) = (free_port(), free_port());
        let script = format!(
            "\"$TREEMOCAP\" serve '{}' --natnet-version {version} --bind 127.0.0.1 --command-port {cp} --data-port {dp} & S=$!; \
             sleep 0.5; timeout 60 \"$PY\" '{driver}' 127.0.0.1 {cp} {dp} {} 20; wait $S",
            path.display(),
            sent.len()
        );
        let out = run_script(&script);
        let mut lines = out
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap());
        let head = lines.next().unwrap();
        assert_eq!(head["server"], "treemocap");
        assert_eq!(head["version"], format!("{version}.0.0"));
        let got: Vec<serde_json::Value> = lines.collect();
        assert_eq!(got.len(), sent.len(), "bitstream {version}");
        for (g, f) in got.iter().zip(&sent) {
            assert_eq!(g["frame"].as_i64(), Some(f.frame));
            assert_eq!(g["timestamp"].as_u64(), Some(f.time_s.to_bits()));
            let labeled = g["labeled"].as_array().unwrap();
            assert_eq!(labeled.len(), f.markers.len(), "frame {}", f.frame);
            for (p, m) in labeled.iter().zip(&f.markers) {
                let p: Vec<u64> = p
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_u64().unwrap())
                    .collect();
                let q = m.position;
                let want: Vec<u64> = [q.x, q.y, q.z]
                    .iter()
                    .map(|&c| (c as f32 as f64).to_bits())
                    .collect();
                assert_eq!(p, want, "frame {}", f.frame);
            }
            assert!(g["unlabeled"].as_array().unwrap().iter().all(|u| u == true));
        }
    }
}
