//! The daemon with its window full: treemocap's NatNet server streams a
//! generated session (still for a minute, then swaying) at the rig's rate
//! over loopback to a daemon in this process, for the window plus five
//! minutes; /status is read over HTTP as a user would.

use std::sync::Arc;
use std::time::{Duration, Instant};

use treemocap::config::Config;
use treemocap::format::Recording;
use treemocap::serve::natnet::{self as server, ServeOptions, ServerStats};

use crate::util::{get_json, get_text, rss_mb, Row, Scale};

#[path = "../common/steady_session.rs"]
mod steady_session;
use steady_session::Session;

/// The daemon's window (`daemon.window_s`, its default): the runs measure
/// once it is full.
const WINDOW_S: f64 = 60.0;

/// What one run measured.
struct Run {
    sent: u64,
    status: serde_json::Value,
    peak_rss_mb: f64,
    /// The latency histogram's buckets (edge in µs, frames at or below)
    /// counted after the window filled: the end's scrape minus the scrape
    /// at the moment the window was full.
    full_window: Vec<(f64, u64)>,
}

/// `(edge µs, cumulative count)` of `/metrics`' latency histogram.
fn latency_buckets(metrics: &str) -> Vec<(f64, u64)> {
    let key = "treemocap_frame_latency_seconds_bucket{le=\"";
    metrics
        .lines()
        .filter_map(|l| l.strip_prefix(key))
        .filter_map(|rest| {
            let (le, count) = rest.split_once("\"} ")?;
            let edge = if le == "+Inf" {
                f64::INFINITY
            } else {
                (le.parse::<f64>().ok()? * 1e6).round()
            };
            Some((edge, count.trim().parse().ok()?))
        })
        .collect()
}

/// The latency (µs) below which a fraction `q` of the counted frames fell,
/// interpolated within its bucket; `None` without frames.
fn quantile(buckets: &[(f64, u64)], q: f64) -> Option<f64> {
    let total = buckets.last()?.1;
    if total == 0 {
        return None;
    }
    let want = q * total as f64;
    let mut below = (0.0, 0u64);
    for &(edge, count) in buckets {
        if count as f64 >= want {
            if edge.is_infinite() {
                return Some(below.0);
            }
            let share = (want - below.1 as f64) / (count - below.1).max(1) as f64;
            return Some(below.0 + share * (edge - below.0));
        }
        below = (edge, count);
    }
    None
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
    let mut sets = vec![
        "daemon.source=natnet".into(),
        format!("daemon.natnet_server=127.0.0.1:{port}"),
        format!("daemon.http={http}"),
        "daemon.channel_frames=4096".into(),
    ];
    // SCALE_DAEMON_SET="key=value,key=value": more settings, to see what a
    // setting (the analysis interval, say) does to the latency.
    if let Ok(more) = std::env::var("SCALE_DAEMON_SET") {
        sets.extend(more.split(',').map(str::to_owned));
    }
    let config = Config::load(None, &sets).expect("config");
    let stop = treemocap::shutdown::Shutdown::new();
    let (flag, out) = (stop.clone(), scale.path(&format!("daemon-{n}")));
    let handle_rt = rt.handle().clone();
    let daemon =
        std::thread::spawn(move || treemocap::daemon::run(config, &out, &handle_rt, &flag, None));
    let t0 = Instant::now();
    let mut status = serde_json::Value::Null;
    let mut peak_rss_mb: f64 = 0.0;
    let mut at_full: Option<Vec<(f64, u64)>> = None;
    while t0.elapsed().as_secs_f64() < seconds + 3.0 && !server.is_finished() {
        std::thread::sleep(Duration::from_secs(2));
        peak_rss_mb = peak_rss_mb.max(rss_mb());
        if let Some(s) = get_json(http, "/status") {
            // The session's clock, not ours: the window is full once the
            // daemon has seen `window` seconds of frames.
            if at_full.is_none() && s["time_s"].as_f64().unwrap_or(0.0) >= WINDOW_S {
                at_full = get_text(http, "/metrics").map(|m| latency_buckets(&m));
            }
            status = s;
        }
    }
    std::thread::sleep(Duration::from_secs(2));
    if let Some(s) = get_json(http, "/status") {
        status = s;
    }
    let at_end = get_text(http, "/metrics").map_or_else(Vec::new, |m| latency_buckets(&m));
    let full_window = match at_full {
        Some(start) if start.len() == at_end.len() => at_end
            .iter()
            .zip(&start)
            .map(|(e, s)| (e.0, e.1.saturating_sub(s.1)))
            .collect(),
        _ => Vec::new(),
    };
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
        full_window,
    }
}

/// 1 000 Hz × 100 markers and 360 Hz × 1 000 markers with the window full.
pub fn runs(scale: &Scale) -> Vec<Row> {
    let minutes = if scale.quick { 0.5 } else { 5.0 };
    let mut rows = Vec::new();
    let only = std::env::var("SCALE_DAEMON_RATE").ok();
    for (rate, n, http) in [
        (1000.0, 100, "127.0.0.1:18431"),
        (360.0, 1000, "127.0.0.1:18432"),
    ] {
        if only.as_deref().is_some_and(|o| o != format!("{rate}")) {
            continue;
        }
        let seconds = WINDOW_S + minutes * 60.0;
        let r = run(scale, seconds, rate, n, http);
        let s = &r.status;
        let got = s["frames"].as_u64().unwrap_or(0);
        let lost = r.sent.saturating_sub(got);
        println!(
            "daemon {rate} Hz × {n}: sent {} received {got} status {s}",
            r.sent
        );
        let full = &r.full_window;
        let us = |q| quantile(full, q).map_or("—".to_string(), |v| format!("{v:.0}"));
        let counted = full.last().map_or(0, |b| b.1);
        let over_1ms = counted - full.iter().find(|b| b.0 == 1000.0).map_or(counted, |b| b.1);
        rows.push(Row::new(
            format!("daemon, {rate} Hz × {n} markers, window full for {minutes} min"),
            "0 dropped, p99 < 1 ms from arrival",
            format!(
                "{} dropped, {lost} not received of {}; window full ({counted} frames): latency p50 {} µs, p99 {} µs, {over_1ms} frames over 1 ms; whole run: p50 {} µs, p99 {} µs, max {} µs; backlog max {} frames; {} analyses, {} trees; RSS {:.0} MB",
                s["dropped"], r.sent, us(0.5), us(0.99), s["latency_us"]["p50"], s["latency_us"]["p99"],
                s["latency_us"]["max"], s["backlog"]["max_frames"], s["analyses"], s["trees"],
                r.peak_rss_mb
            ),
            "—".into(),
        ));
    }
    rows
}
