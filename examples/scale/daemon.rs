//! The daemon with its window full: treemocap's NatNet server streams a
//! generated session (still for a minute, then swaying) at the rig's rate
//! over loopback to a daemon in this process, for the window plus five
//! minutes; /status is read over HTTP as a user would.

use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use treemocap::config::Config;
use treemocap::format::{Format, Recording, RecordingInfo};
use treemocap::model::frame::{Marker, MarkerFrame};
use treemocap::rng::Rng;
use treemocap::serve::natnet::{self as server, ServeOptions, ServerStats};

use crate::util::{get_json, rss_mb, Row, Scale};

/// A session generated frame by frame: `n` tips on a crown, still for the
/// first minute, then each swaying with its own period; 1 % of samples
/// missing; never all in memory.
struct Session {
    info: RecordingInfo,
    rng: Rng,
    rest: Vec<(DVec3, f64, f64)>,
    next: i64,
    frames: i64,
}

impl Session {
    fn new(seconds: f64, rate: f64, n: usize) -> Session {
        let mut rng = Rng::new(15);
        let rest = (0..n)
            .map(|i| {
                let a = i as f64 * 2.399_963;
                let h = 1.0 + (i as f64 / n as f64) * 1.5;
                let r = 0.6 + 0.3 * (i as f64 / n as f64) + 0.02 * rng.f64();
                (
                    DVec3::new(r * a.cos(), h, r * a.sin()),
                    rng.range(0.5, 2.0),
                    rng.range(0.0, 6.3),
                )
            })
            .collect();
        Session {
            info: RecordingInfo {
                format: Format::Log,
                version: "2".into(),
                frame_rate: rate,
                units: "m".into(),
                up_axis: "Y".into(),
                source: "scale".into(),
            },
            rng,
            rest,
            next: 0,
            frames: (seconds * rate) as i64,
        }
    }
}

impl Iterator for Session {
    type Item = treemocap::Result<MarkerFrame>;
    fn next(&mut self) -> Option<Self::Item> {
        if self.next >= self.frames {
            return None;
        }
        let f = self.next;
        self.next += 1;
        let t = f as f64 / self.info.frame_rate;
        // The wind rises over 3 s: a tree starts swaying from rest. (A step
        // here would move every marker by up to 30 mm in one frame, which
        // no tree does and which the tracker rightly takes as every marker
        // lost at once.)
        let ramp = ((t - 60.0) / 3.0).clamp(0.0, 1.0);
        let wind = ramp * ramp * (3.0 - 2.0 * ramp);
        let mut markers = Vec::with_capacity(self.rest.len());
        for &(p, freq, ph) in &self.rest {
            if self.rng.chance(0.01) {
                continue;
            }
            let sway = DVec3::new(
                0.03 * (freq * t + ph).sin(),
                0.0,
                0.01 * (1.7 * freq * t).cos(),
            );
            let noise = DVec3::new(self.rng.normal(), self.rng.normal(), self.rng.normal()) * 2e-4;
            markers.push(Marker::new(p + sway * wind + noise));
        }
        Some(Ok(MarkerFrame::new(f, t, markers)))
    }
}

impl Recording for Session {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }
}

/// What one run measured.
struct Run {
    sent: u64,
    status: serde_json::Value,
    peak_rss_mb: f64,
}

/// Streams `seconds` at `rate` × `n` to a daemon and samples /status.
fn run(scale: &Scale, seconds: f64, rate: f64, n: usize, http: &str) -> Run {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .expect("runtime");
    let stats = Arc::new(ServerStats::default());
    let sopts = ServeOptions {
        bind: "127.0.0.1".parse().expect("address"),
        command_port: 0,
        data_port: 0,
        wait_for_client: true,
        stats: stats.clone(),
        ..Default::default()
    };
    let (stop_server, server_stop) = tokio::sync::watch::channel(false);
    let server = rt.spawn(async move {
        let open = move || -> treemocap::Result<Box<dyn Recording>> {
            Ok(Box::new(Session::new(seconds, rate, n)))
        };
        server::serve(open, &sopts, server_stop).await
    });
    let port = loop {
        if let Some(a) = stats.command_addr.get() {
            break a.port();
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let config = Config::load(
        None,
        &[
            "daemon.source=natnet".into(),
            format!("daemon.natnet_server=127.0.0.1:{port}"),
            format!("daemon.http={http}"),
            "daemon.channel_frames=4096".into(),
        ],
    )
    .expect("config");
    let stop = treemocap::shutdown::Shutdown::new();
    let (flag, out) = (stop.clone(), scale.path(&format!("daemon-{n}")));
    let handle_rt = rt.handle().clone();
    let daemon =
        std::thread::spawn(move || treemocap::daemon::run(config, &out, &handle_rt, &flag, None));
    let t0 = Instant::now();
    let mut status = serde_json::Value::Null;
    let mut peak_rss_mb: f64 = 0.0;
    while t0.elapsed().as_secs_f64() < seconds + 3.0 && !server.is_finished() {
        std::thread::sleep(Duration::from_secs(2));
        peak_rss_mb = peak_rss_mb.max(rss_mb());
        if let Some(s) = get_json(http, "/status") {
            status = s;
        }
    }
    std::thread::sleep(Duration::from_secs(2));
    if let Some(s) = get_json(http, "/status") {
        status = s;
    }
    stop.trigger();
    let _ = stop_server.send(true);
    daemon.join().expect("daemon thread").expect("daemon");
    let sent = rt
        .block_on(server)
        .ok()
        .and_then(Result::ok)
        .map_or(0, |r| r.frames);
    Run {
        sent,
        status,
        peak_rss_mb,
    }
}

/// 1 000 Hz × 100 markers and 360 Hz × 1 000 markers with the window full.
pub fn runs(scale: &Scale) -> Vec<Row> {
    let minutes = if scale.quick { 0.5 } else { 5.0 };
    let window = 60.0;
    let mut rows = Vec::new();
    let only = std::env::var("SCALE_DAEMON_RATE").ok();
    for (rate, n, http) in [
        (1000.0, 100, "127.0.0.1:18431"),
        (360.0, 1000, "127.0.0.1:18432"),
    ] {
        if only.as_deref().is_some_and(|o| o != format!("{rate}")) {
            continue;
        }
        let seconds = window + minutes * 60.0;
        let r = run(scale, seconds, rate, n, http);
        let s = &r.status;
        let got = s["frames"].as_u64().unwrap_or(0);
        let lost = r.sent.saturating_sub(got);
        println!(
            "daemon {rate} Hz × {n}: sent {} received {got} status {s}",
            r.sent
        );
        rows.push(Row::new(
            format!("daemon, {rate} Hz × {n} markers, window full for {minutes} min"),
            "0 dropped, p99 < 1 ms from arrival",
            format!(
                "{} dropped, {lost} not received of {}; latency p50 {} µs, p99 {} µs, max {} µs; backlog max {} frames; {} analyses, {} trees; RSS {:.0} MB",
                s["dropped"], r.sent, s["latency_us"]["p50"], s["latency_us"]["p99"],
                s["latency_us"]["max"], s["backlog"]["max_frames"], s["analyses"], s["trees"],
                r.peak_rss_mb
            ),
            "—".into(),
        ));
    }
    rows
}
