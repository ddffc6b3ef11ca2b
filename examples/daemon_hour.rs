//! Memory check for issue 6: the daemon over a 1-hour session at 240 Hz with
//! 70 markers, played as fast as possible. The session is first written to a
//! treemocap log (about 3.6 GB, generated frame by frame), then replayed
//! through `treemocap::daemon::run` in this process while its resident set
//! size is sampled. Target: RSS growth under 10 MB once the analysis window
//! is full.
//!
//! `cargo run --release --example daemon_hour [seconds] [rate] [markers]`

#[path = "common/hour_session.rs"]
mod hour_session;

use std::time::{Duration, Instant};

use treemocap::config::Config;
use treemocap::format::log::{LogHeader, LogWriter};

fn rss_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}

fn main() {
    let (seconds, rate, n) = hour_session::args();
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("hour.log.csv");
    let header = LogHeader {
        source: "daemon_hour".into(),
        frame_rate: rate,
    };
    let mut w = LogWriter::create(&log, &header, Duration::from_secs(1)).unwrap();
    let t0 = Instant::now();
    hour_session::for_each_frame(seconds, rate, n, |f| w.write_frame(f).unwrap());
    w.finish().unwrap();
    let total = (seconds * rate) as u64;
    println!(
        "wrote {total} frames ({:.2} GB) in {:.0} s",
        std::fs::metadata(&log).map(|m| m.len()).unwrap_or(0) as f64 / 1e9,
        t0.elapsed().as_secs_f64()
    );

    let config = Config::load(
        None,
        &[
            format!("daemon.replay_file={}", log.display()),
            "daemon.replay_speed=0".into(),
            "daemon.http=127.0.0.1:18322".into(),
        ],
    )
    .unwrap();
    let out = dir.path().join("out");
    let rt = tokio::runtime::Runtime::new().unwrap();
    let stop = treemocap::shutdown::Shutdown::new();
    let flag = stop.clone();
    let handle_rt = rt.handle().clone();
    let out2 = out.clone();
    let t0 = Instant::now();
    let daemon =
        std::thread::spawn(move || treemocap::daemon::run(config, &out2, &handle_rt, &flag, None));
    let mut samples: Vec<(f64, u64, f64)> = Vec::new();
    loop {
        std::thread::sleep(Duration::from_secs(1));
        let status = std::process::Command::new("python3")
            .args(["-c", "import urllib.request as u; print(u.urlopen('http://127.0.0.1:18322/status').read().decode())"])
            .output()
            .ok()
            .and_then(|o| serde_json::from_slice::<serde_json::Value>(&o.stdout).ok());
        let Some(s) = status else { continue };
        let done = s["frames"].as_u64().unwrap_or(0) + s["dropped"].as_u64().unwrap_or(0);
        samples.push((t0.elapsed().as_secs_f64(), done, rss_mb()));
        if done >= total {
            println!(
                "frames {} dropped {} trees {} analyses {}",
                s["frames"], s["dropped"], s["trees"], s["analyses"]
            );
            break;
        }
    }
    stop.trigger();
    daemon.join().unwrap().unwrap();
    // Growth after the window (60 s of capture) has filled: from the sample
    // nearest 10 % of the session to the end.
    let tenth = samples
        .iter()
        .find(|s| s.1 >= total / 10)
        .copied()
        .unwrap_or(samples[0]);
    let last = *samples.last().unwrap();
    let peak = samples.iter().map(|s| s.2).fold(0.0, f64::max);
    for q in [10, 25, 50, 75, 90, 100] {
        if let Some(s) = samples.iter().find(|s| s.1 * 100 >= total * q) {
            println!("  {q:>3} % of the session: RSS {:.1} MB", s.2);
        }
    }
    println!(
        "RSS {:.1} MB at 10 % of the session, {:.1} MB at the end (growth {:+.1} MB), peak {:.1} MB; {:.0} s",
        tenth.2, last.2, last.2 - tenth.2, peak, last.0
    );
}
