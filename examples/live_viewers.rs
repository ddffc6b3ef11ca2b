//! Measured: the daemon's frame → tips latency with 10 live-page viewers
//! connected to `/live` against none (issue 12: p99 within 10 %).
//!
//! A synthetic 360 Hz session of 70 markers is played at its recorded speed
//! (frames arrive as from a rig) through the whole daemon, in-process; the
//! viewers are real WebSocket clients on 127.0.0.1 reading every message.
//! Runs alternate (none, ten, none, ten) so that a change in the machine's
//! load hits both alike.
//!
//! `cargo run --release --example live_viewers`

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use treemocap::config::Config;
use treemocap::sim::{CrownShape, SynthOptions};

const PORT: u16 = 18_337;

/// Frames and bytes the viewers received.
#[derive(Default)]
struct Received {
    frames: AtomicU64,
    bytes: AtomicU64,
}

fn status() -> Option<serde_json::Value> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            &format!("import urllib.request as u; print(u.urlopen('http://127.0.0.1:{PORT}/status').read().decode())"),
        ])
        .output()
        .ok()?;
    serde_json::from_slice(&out.stdout).ok()
}

/// Runs the daemon on `file` for `seconds` with `viewers` WebSocket clients.
fn run(file: &std::path::Path, viewers: usize, seconds: f64) -> (serde_json::Value, f64) {
    let config = Config::load(
        None,
        &[
            format!("daemon.replay_file={}", file.display()),
            format!("daemon.http=127.0.0.1:{PORT}"),
            "daemon.replay_speed=1".into(),
        ],
    )
    .expect("config");
    let out = tempfile::tempdir().unwrap();
    // The daemon's runtime as `treemocap run` has it; the viewers get their own.
    let daemon_rt = tokio::runtime::Runtime::new().unwrap();
    let stop = treemocap::shutdown::Shutdown::new();
    let flag = stop.clone();
    let handle_rt = daemon_rt.handle().clone();
    let out_path = out.path().to_path_buf();
    let daemon = std::thread::spawn(move || {
        treemocap::daemon::run(config, &out_path, &handle_rt, &flag, None)
    });
    let received = Arc::new(Received::default());
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    // Wait for the server, then connect the viewers.
    while status().is_none() {
        std::thread::sleep(Duration::from_millis(50));
    }
    for _ in 0..viewers {
        let r = received.clone();
        rt.spawn(async move {
            let url = format!("ws://127.0.0.1:{PORT}/live");
            let Ok((mut ws, _)) = tokio_tungstenite::connect_async(url).await else {
                return;
            };
            while let Some(Ok(msg)) = ws.next().await {
                if msg.is_binary() {
                    r.frames.fetch_add(1, Ordering::Relaxed);
                }
                r.bytes.fetch_add(msg.len() as u64, Ordering::Relaxed);
            }
        });
    }
    let t0 = Instant::now();
    let mut last = serde_json::Value::Null;
    while t0.elapsed() < Duration::from_secs_f64(seconds) {
        std::thread::sleep(Duration::from_millis(500));
        if let Some(v) = status() {
            last = v;
        }
    }
    let per_viewer_fps = if viewers == 0 {
        0.0
    } else {
        received.frames.load(Ordering::Relaxed) as f64 / viewers as f64 / t0.elapsed().as_secs_f64()
    };
    stop.trigger();
    daemon.join().unwrap().unwrap();
    rt.shutdown_timeout(Duration::from_millis(200));
    (last, per_viewer_fps)
}

fn main() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("s70.csv");
    let opts = SynthOptions {
        seed: 7,
        tips: 70,
        shape: CrownShape::Maple,
        frame_rate: 360.0,
        still_s: 10.0,
        wind_s: 10.0,
        ..Default::default()
    };
    treemocap::app::synth::write_session(&opts, &file).expect("synthetic session");
    let mut p99 = [Vec::new(), Vec::new()];
    for round in 0..2 {
        for (k, viewers) in [0usize, 10].into_iter().enumerate() {
            let (s, fps) = run(&file, viewers, 20.0);
            let l = &s["latency_us"];
            println!(
                "round {round}, {viewers:2} viewers: frames {} dropped {} latency µs p50 {} p99 {} max {}; {fps:.1} frames/s per viewer",
                s["frames"], s["dropped"], l["p50"], l["p99"], l["max"]
            );
            if let Some(v) = l["p99"].as_f64() {
                p99[k].push(v);
            }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let (none, ten) = (mean(&p99[0]), mean(&p99[1]));
    println!(
        "p99 frame → tips: {none:.0} µs with no viewer, {ten:.0} µs with 10 ({:+.1} %)",
        (ten / none - 1.0) * 100.0
    );
}
