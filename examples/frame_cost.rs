//! What one frame costs the live tracker, frame by frame, with the window
//! full: the daemon scale runs' session (`examples/common/steady_session.rs`:
//! still for a minute, then swaying) fed to the daemon's live tips
//! (`track::live::LiveTips`, the tracker in live mode) with a tree of all the
//! markers, as `treemocap run` does after its first tree. Prints the
//! percentiles of the per-frame cost over the swaying part, the frames
//! that daemon's latency p99 is made of.
//!
//! `cargo run --release --example frame_cost -- [SECONDS] [RATE] [MARKERS]
//! [--paced] [--natnet] [--evict-kb N] [--cpu N] [--warm]`
//! (defaults: 90 s at 360 Hz with 1 000 markers, frames back to back).
//!
//! The options reproduce, one at a time, what differs inside the daemon:
//! - `--paced`: each measured frame waits for its time on the session's
//!   clock (the thread sleeps between frames, as the daemon's pipeline does
//!   between datagrams) instead of following the previous one at once;
//! - `--natnet`: each frame goes through NatNet as the daemon receives it
//!   (encoded by treemocap's server in its default bitstream, decoded and
//!   selected by the client's code: f32 positions, the server's order);
//! - `--evict-kb N`: after each frame the thread reads and writes N KB of
//!   other memory, as the pipeline's own work (window, recording) and the
//!   other threads sharing its core do between two frames;
//! - `--cpu N`: the thread is pinned to CPU N;
//! - `--warm`: just before each frame the tracker's state is prefetched
//!   (`LiveTips::warm`, what `daemon.warm_us` does before a frame is due);
//!   its cost is printed apart, it is not in the frame's.
//!
//! Besides the wall time of each `LiveTips::update` it prints the thread's
//! CPU time for it (time the thread was preempted is not in it), and what
//! the tracker did (traces started, markers taken), so that two runs can be
//! told apart by their work as well as their time.

use std::time::{Duration, Instant};

use glam::DVec3;
use treemocap::model::frame::MarkerFrame;
use treemocap::protocol::natnet::select::{to_marker_frame, FrameContext, MarkerSelection};
use treemocap::protocol::natnet::{decode, encode, Packet, DEFAULT_SERVE_VERSION};
use treemocap::serve::natnet::to_natnet_frame;
use treemocap::track::live::LiveTips;
use treemocap::track::TrackingSettings;

#[path = "common/steady_session.rs"]
mod steady_session;

/// The frames measured: the swaying part, the wind fully up.
const MEASURE_FROM_S: f64 = 63.0;

/// The command line.
struct Options {
    seconds: f64,
    rate: f64,
    markers: usize,
    paced: bool,
    natnet: bool,
    evict_kb: usize,
    cpu: Option<usize>,
    warm: bool,
}

impl Options {
    fn parse() -> Options {
        let mut numbers = Vec::new();
        let mut o = Options {
            seconds: 90.0,
            rate: 360.0,
            markers: 1000,
            paced: false,
            natnet: false,
            evict_kb: 0,
            cpu: None,
            warm: false,
        };
        let mut args = std::env::args().skip(1);
        while let Some(a) = args.next() {
            let mut value = |name: &str| -> usize {
                args.next()
                    .and_then(|v| v.parse().ok())
                    .unwrap_or_else(|| panic!("{name} needs a whole number"))
            };
            match a.as_str() {
                "--paced" => o.paced = true,
                "--natnet" => o.natnet = true,
                "--warm" => o.warm = true,
                "--evict-kb" => o.evict_kb = value("--evict-kb"),
                "--cpu" => o.cpu = Some(value("--cpu")),
                _ => numbers.push(a.parse::<f64>().expect("SECONDS RATE MARKERS are numbers")),
            }
        }
        o.seconds = numbers.first().copied().unwrap_or(o.seconds);
        o.rate = numbers.get(1).copied().unwrap_or(o.rate);
        o.markers = numbers.get(2).map_or(o.markers, |n| *n as usize);
        o
    }

    fn label(&self) -> String {
        let mut l = vec![if self.paced { "paced" } else { "back to back" }.to_string()];
        if self.natnet {
            l.push("through NatNet".into());
        }
        if self.evict_kb > 0 {
            l.push(format!("{} KB touched between frames", self.evict_kb));
        }
        if let Some(c) = self.cpu {
            l.push(format!("pinned to CPU {c}"));
        }
        if self.warm {
            l.push("state prefetched before each frame".into());
        }
        l.join(", ")
    }
}

/// The frame as the daemon's NatNet client hands it on.
fn through_natnet(frame: &MarkerFrame) -> MarkerFrame {
    let version = DEFAULT_SERVE_VERSION;
    let up = treemocap::model::frame::UpAxis::Y;
    let data = to_natnet_frame(frame, version, 0, up);
    let bytes = encode(&Packet::FrameOfData(Box::new(data)), version).expect("encode");
    let Ok(Packet::FrameOfData(f)) = decode(&bytes, version) else {
        panic!("a frame decodes as a frame");
    };
    let cx = FrameContext {
        version,
        selection: MarkerSelection::default(),
        up,
        clock_frequency: 0,
    };
    to_marker_frame(&f, &cx, frame.time_s)
}

/// The calling thread's CPU time.
fn thread_cpu() -> Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid pointer to a timespec on the stack.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

fn pin(cpu: usize) {
    // SAFETY: a zeroed cpu_set_t is a valid empty set; the calls take
    // pointers to it only.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        if libc::sched_setaffinity(0, std::mem::size_of_val(&set), &set) != 0 {
            eprintln!("could not pin to CPU {cpu}");
        }
    }
}

/// Reads and writes every cache line of `buf`.
fn touch(buf: &mut [u8]) {
    for b in buf.iter_mut().step_by(64) {
        *b = b.wrapping_add(1);
    }
    std::hint::black_box(&buf);
}

fn percentiles(mut v: Vec<f64>) -> String {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return "—".into();
    }
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    format!(
        "p50 {:.0} µs, p90 {:.0}, p99 {:.0}, p99.9 {:.0}, max {:.0}",
        q(0.5),
        q(0.9),
        q(0.99),
        q(0.999),
        q(1.0)
    )
}

fn main() {
    let o = Options::parse();
    if let Some(c) = o.cpu {
        pin(c);
    }
    let session = steady_session::Session::new(o.seconds, o.rate, o.markers);
    let rest: Vec<(usize, DVec3)> = session.rest_positions().into_iter().enumerate().collect();
    let mut live = LiveTips::new(&TrackingSettings::default(), None, 0.05);
    live.set_tips(&rest);
    let mut evict = vec![0u8; o.evict_kb * 1024];
    let (mut wall, mut cpu, mut warm) = (Vec::new(), Vec::new(), Vec::new());
    let mut seen_total = 0usize;
    let mut started_before = None;
    let mut clock: Option<(Instant, f64)> = None;
    for frame in session {
        let mut frame = frame.expect("generated frame");
        if o.natnet {
            frame = through_natnet(&frame);
        }
        let measured = frame.time_s >= MEASURE_FROM_S;
        if o.paced && frame.time_s >= MEASURE_FROM_S - 1.0 {
            // The session's clock from here on: the thread sleeps until
            // the frame is due, as the pipeline waits for its datagram.
            let (t0, s0) = *clock.get_or_insert((Instant::now(), frame.time_s));
            let due = t0 + Duration::from_secs_f64(frame.time_s - s0);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        if o.warm {
            let t0 = Instant::now();
            live.warm();
            if measured {
                warm.push(t0.elapsed().as_secs_f64() * 1e6);
            }
        }
        if measured && started_before.is_none() {
            started_before = Some(live.stats().traces_started);
        }
        let (t0, c0) = (Instant::now(), thread_cpu());
        let seen = live.update(&frame);
        let (us, cpu_us) = (
            t0.elapsed().as_secs_f64() * 1e6,
            (thread_cpu() - c0).as_secs_f64() * 1e6,
        );
        if measured {
            wall.push(us);
            cpu.push(cpu_us);
            seen_total += seen.tips.len();
        }
        if !evict.is_empty() {
            touch(&mut evict);
        }
    }
    let frames = wall.len().max(1);
    let stats = live.stats();
    let started = stats.traces_started - started_before.unwrap_or(0);
    if o.warm {
        println!("prefetch before each frame: {}", percentiles(warm));
    }
    println!(
        "{} frames at {} Hz × {} markers, swaying, {}:\n  wall {}\n  cpu  {}\n  {:.1} tips seen a frame; traces started while measured {started}, in all {}; markers {}, duplicates {}",
        wall.len(),
        o.rate,
        o.markers,
        o.label(),
        percentiles(wall),
        percentiles(cpu),
        seen_total as f64 / frames as f64,
        stats.traces_started,
        stats.markers,
        stats.duplicate_markers,
    );
}
