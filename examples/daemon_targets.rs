//! Measured run of the daemon's targets (issue 6), in-process:
//! 1. frame-to-tips latency (p50/p99/max) at 360 Hz with 70 markers, played at
//!    the recorded speed, so frames arrive as from a rig;
//! 2. trigger-to-tree time for 35 tips and 500 total tips.
//!
//! `cargo run --release --example daemon_targets`

use std::time::{Duration, Instant};

use treemocap::config::Config;
use treemocap::sim::{CrownShape, SynthOptions};

fn session(dir: &std::path::Path, name: &str, opts: SynthOptions) -> std::path::PathBuf {
    let path = dir.join(format!("{name}.csv"));
    treemocap::app::synth::write_session(&opts, &path).expect("synthetic session");
    path
}

fn run(file: &std::path::Path, sets: &[&str], seconds: f64) -> serde_json::Value {
    let mut all: Vec<String> = vec![
        format!("daemon.replay_file={}", file.display()),
        "daemon.http=127.0.0.1:18321".into(),
    ];
    all.extend(sets.iter().map(|s| s.to_string()));
    let config = Config::load(None, &all).expect("config");
    let out = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let stop = treemocap::shutdown::Shutdown::new();
    let flag = stop.clone();
    let handle_rt = rt.handle().clone();
    let out_path = out.path().to_path_buf();
    let handle = std::thread::spawn(move || {
        treemocap::daemon::run(config, &out_path, &handle_rt, &flag, None)
    });
    let t0 = Instant::now();
    let mut last = serde_json::Value::Null;
    while t0.elapsed() < Duration::from_secs_f64(seconds) {
        std::thread::sleep(Duration::from_millis(500));
        if let Ok(o) = std::process::Command::new("python3")
            .args(["-c", "import urllib.request as u; print(u.urlopen('http://127.0.0.1:18321/status').read().decode())"])
            .output()
        {
            if let Ok(v) = serde_json::from_slice(&o.stdout) {
                last = v;
            }
        }
    }
    stop.trigger();
    handle.join().unwrap().unwrap();
    last
}

fn main() {
    let dir = tempfile::tempdir().unwrap();
    let a = session(
        dir.path(),
        "s70",
        SynthOptions {
            seed: 7,
            tips: 70,
            shape: CrownShape::Maple,
            frame_rate: 360.0,
            still_s: 10.0,
            wind_s: 10.0,
            ..Default::default()
        },
    );
    let s = run(&a, &["daemon.replay_speed=1"], 21.0);
    println!(
        "360 Hz, 70 markers: frames {} dropped {} tips {} latency µs {}",
        s["frames"], s["dropped"], s["tips"], s["latency_us"]
    );
    println!("  first tree: {}", s["last_tree"]);

    let b = session(
        dir.path(),
        "s35",
        SynthOptions {
            seed: 35,
            tips: 35,
            shape: CrownShape::Pine,
            still_s: 10.0,
            wind_s: 2.0,
            ..Default::default()
        },
    );
    let s = run(
        &b,
        &["daemon.replay_speed=5", "reconstruct.total_tips=500"],
        5.0,
    );
    println!("35 tips, 500 total: tree {}", s["last_tree"]);
}
