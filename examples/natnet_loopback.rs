//! Sustained-load check of the NatNet client: treemocap's server streams
//! 1000 frames/s of 1000 unlabeled markers (NatNet's cap) over loopback to
//! treemocap's client for 60 s (or the seconds given), and every frame must
//! arrive. Prints what was sent, received, missed and dropped.
//!
//! cargo run --release --example natnet_loopback -- [seconds] [rate] [markers] [version]

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::DVec3;
use treemocap::format::{Format, Recording, RecordingInfo};
use treemocap::model::frame::{Marker, MarkerFrame};
use treemocap::protocol::natnet::Version;
use treemocap::rng::Rng;
use treemocap::serve::natnet::{self as server, ServeOptions, ServerStats};
use treemocap::source::channel::frame_channel;
use treemocap::source::natnet::client::{self, NatNetStatus};
use treemocap::source::natnet::settings::NatNetSettings;

/// Frames generated on the fly (60 000 × 1000 markers would not fit a file).
struct Synthetic {
    info: RecordingInfo,
    rng: Rng,
    next: i64,
    frames: i64,
    markers: usize,
}

impl Iterator for Synthetic {
    type Item = treemocap::Result<MarkerFrame>;
    fn next(&mut self) -> Option<Self::Item> {
        if self.next >= self.frames {
            return None;
        }
        let f = self.next;
        self.next += 1;
        let ms = (0..self.markers)
            .map(|i| Marker {
                position: DVec3::new(
                    self.rng.range(-1.0, 1.0),
                    self.rng.range(0.5, 3.0),
                    self.rng.range(-1.0, 1.0),
                ),
                id: Some(i as i64),
            })
            .collect();
        Some(Ok(MarkerFrame::new(f, f as f64 / self.info.frame_rate, ms)))
    }
}

impl Recording for Synthetic {
    fn info(&self) -> &RecordingInfo {
        &self.info
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seconds: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(60.0);
    let rate: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1000.0);
    let markers: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let version: Version = args
        .get(4)
        .and_then(|s| s.parse().ok())
        .unwrap_or(Version::new(3, 1));
    let frames = (seconds * rate) as i64;

    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async move {
        let stats = Arc::new(ServerStats::default());
        let sopts = ServeOptions {
            version,
            bind: "127.0.0.1".parse().unwrap(),
            command_port: 0,
            data_port: 0,
            stats: stats.clone(),
            ..Default::default()
        };
        let (stop_server, server_shutdown) = tokio::sync::watch::channel(false);
        let server = tokio::spawn(async move {
            let open = || -> treemocap::Result<Box<dyn Recording>> {
                Ok(Box::new(Synthetic {
                    info: RecordingInfo {
                        format: Format::Log,
                        version: "1".into(),
                        frame_rate: rate,
                        units: "m".into(),
                        up_axis: "Y".into(),
                        source: "natnet_loopback".into(),
                    },
                    rng: Rng::new(1),
                    next: 0,
                    frames,
                    markers,
                }))
            };
            server::serve(open, &sopts, server_shutdown).await
        });
        let port = loop {
            if let Some(a) = stats.command_addr.get() {
                break a.port();
            }
            tokio::time::sleep(Duration::from_millis(5)).await;
        };
        let copts = NatNetSettings { command_port: port, ..Default::default() };
        let cstatus = Arc::new(NatNetStatus::default());
        let cstatus2 = cstatus.clone();
        let (sink, rx) = frame_channel(4096);
        let (stop_client, client_shutdown) = tokio::sync::watch::channel(false);
        let client = tokio::spawn(async move { client::run(&copts, &cstatus2, sink.clone(), client_shutdown).await.map(|r| (r, sink.dropped())) });

        // The "pipeline": counts frames and markers, checks the sequence.
        let consumer = std::thread::spawn(move || {
            let (mut n, mut m, mut gaps, mut last) = (0u64, 0u64, 0u64, -1i64);

            while let Ok(f) = rx.recv() {
                if f.frame != last + 1 {
                    gaps += 1;
                }
                last = f.frame;
                n += 1;
                m += f.markers.len() as u64;

            }
            (n, m, gaps)
        });

        let t0 = Instant::now();
        let sreport = server.await.unwrap().unwrap();
        tokio::time::sleep(Duration::from_millis(500)).await;
        let elapsed = t0.elapsed().as_secs_f64();
        let _ = stop_client.send(true);
        let _ = stop_server.send(true);
        let (creport, dropped) = client.await.unwrap().unwrap();
        let (n, m, gaps) = consumer.join().unwrap();
        println!("NatNet {version} loopback, {rate} frames/s x {markers} markers for {seconds} s");
        println!("  server: {} frames played, {} datagrams sent, {:.2} s", sreport.frames, stats.datagrams.load(Ordering::Relaxed), sreport.elapsed_s);
        println!(
            "  client: {} frames, {} markers, {} missed frames, {} bad datagrams, {} dropped by the pipeline channel",
            creport.counters.frames, creport.counters.markers, creport.counters.missed_frames, creport.counters.bad_packets(), dropped
        );
        println!("  pipeline: {n} frames, {m} markers, {gaps} sequence gaps");
        println!("  achieved rate: {:.1} frames/s over {elapsed:.1} s", n as f64 / elapsed);
        let lost = frames as u64 - n;
        println!("  RESULT: {}", if lost == 0 && cstatus.snapshot().counters.bad_packets() == 0 { "no frame lost".to_string() } else { format!("{lost} frames lost") });
        if lost != 0 {
            std::process::exit(1);
        }
    });
}
