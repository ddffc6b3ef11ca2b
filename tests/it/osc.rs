//! The OSC source against a program we did not write: python-osc (PyPI)
//! sends marker frames the way the NatNet→OSC bridges do, to treemocap's
//! OSC source on 127.0.0.1, and to `treemocap record --osc`.
//!
//! Needs `pip install -r tests/peers/requirements.txt`.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use glam::DVec3;
use treemocap::format::Recording;
use treemocap::rng::Rng;
use treemocap::source::channel::frame_channel;
use treemocap::source::osc::{self, OscCounts, OscOptions};
use treemocap::MarkerFrame;

const SENDER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/peers/osc_send.py");

/// Fails loudly, with the fix, when the peer is not installed.
fn require_python_osc() {
    let ok = Command::new("python3")
        .args(["-c", "import pythonosc"])
        .stderr(Stdio::null())
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    assert!(
        ok,
        "python-osc is missing: pip install -r tests/peers/requirements.txt \
         (python3 with the python-osc package is needed for the OSC tests)"
    );
}

/// A sent frame: number, time in ms, markers as (id, x, y, z) with values a
/// float32 holds exactly, so every position must arrive bit for bit.
#[derive(Debug, Clone)]
struct Sent {
    frame: i64,
    time_ms: i64,
    markers: Vec<(i64, [f32; 3])>,
}

fn make_frames(seed: u64, count: usize, first: i64, markers: usize) -> Vec<Sent> {
    let mut rng = Rng::new(seed);
    let mut out = Vec::new();
    for k in 0..count {
        // A few frames are empty (every marker occluded).
        let n = if k % 7 == 3 {
            0
        } else {
            rng.int(1, markers as i64) as usize
        };
        let ms = (rng.int(0, 3) == 0) as i64; // a jittery clock
        out.push(Sent {
            frame: first + k as i64,
            time_ms: 3_600_000 + 10 * k as i64 + ms,
            markers: (0..n)
                .map(|i| {
                    let p = [
                        rng.range(-3.0, 3.0),
                        rng.range(0.0, 5.0),
                        rng.range(-3.0, 3.0),
                    ];
                    (((i as i64) << 16) | 1, p.map(|v| v as f32))
                })
                .collect(),
        });
    }
    out
}

fn write_frames(dir: &Path, frames: &[Sent]) -> PathBuf {
    let json: Vec<serde_json::Value> = frames
        .iter()
        .map(|f| {
            serde_json::json!({
                "frame": f.frame,
                "time_ms": f.time_ms,
                "markers": f.markers.iter().map(|(id, p)| {
                    serde_json::json!([id, p[0] as f64, p[1] as f64, p[2] as f64])
                }).collect::<Vec<_>>(),
            })
        })
        .collect();
    let path = dir.join("frames.json");
    std::fs::write(&path, serde_json::to_string(&json).unwrap()).unwrap();
    path
}

/// Runs python-osc's sender to completion; returns its final JSON line.
fn send(addr: SocketAddr, args: &[&str]) -> serde_json::Value {
    let out = Command::new("python3")
        .arg(SENDER)
        .arg(addr.ip().to_string())
        .arg(addr.port().to_string())
        .args(args)
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "osc_send.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    serde_json::from_str(stdout.lines().last().unwrap()).unwrap()
}

/// Runs the OSC source in-process while `drive` sends to it; returns the
/// frames it delivered and its final counters.
fn with_source(
    opts: OscOptions,
    drive: impl FnOnce(SocketAddr) -> serde_json::Value,
) -> (Vec<MarkerFrame>, OscCounts) {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    let (sink, rx) = frame_channel(100_000);
    let (stop, shutdown) = tokio::sync::watch::channel(false);
    let stats = opts.stats.clone();
    let task = runtime.spawn(async move { osc::run(&opts, sink, shutdown).await });
    let start = Instant::now();
    let addr = loop {
        if let Some(a) = stats.local_addr() {
            break a;
        }
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "source did not bind"
        );
        std::thread::sleep(Duration::from_millis(5));
    };
    let sent = drive(addr);
    // Wait until every datagram the peer sent was taken in.
    let expected = sent["datagrams"].as_u64().unwrap();
    let start = Instant::now();
    while stats.snapshot().datagrams + stats.snapshot().not_allowed < expected {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "only {:?} of {expected} datagrams arrived",
            stats.snapshot()
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    stop.send(true).unwrap();
    let report = runtime.block_on(task).unwrap().unwrap();
    let counts = stats.snapshot();
    assert_eq!(report.frames, counts.frames);
    (rx.try_iter().collect(), counts)
}

fn options() -> OscOptions {
    let mut opts = OscOptions::from_settings(&treemocap::config::Config::default().osc).unwrap();
    opts.bind = "127.0.0.1:0".parse().unwrap();
    opts
}

/// What a user checks: the same frames, markers, ids and positions (exact:
/// float32 → float64 is exact), in order.
fn assert_frames(
    got: &[MarkerFrame],
    sent: &[Sent],
    numbered: bool,
    convert: impl Fn([f32; 3]) -> DVec3,
) {
    assert_eq!(got.len(), sent.len(), "frame count");
    for (k, (g, s)) in got.iter().zip(sent).enumerate() {
        if numbered {
            assert_eq!(g.frame, s.frame, "frame {k}: number");
            assert_eq!(
                g.time_s,
                s.time_ms as f64 / 1000.0,
                "frame {k}: time from the sender"
            );
        } else {
            assert_eq!(g.frame, k as i64, "frame {k}: numbered on from 0");
        }
        assert_eq!(g.markers.len(), s.markers.len(), "frame {k}: marker count");
        for (m, (id, p)) in g.markers.iter().zip(&s.markers) {
            let want = convert(*p);
            assert!(
                (m.position - want).abs().max_element() <= 1e-12,
                "frame {k}: {:?} != {want:?}",
                m.position
            );
            assert_eq!(m.id, Some(*id), "frame {k}: id hint");
        }
    }
}

fn y_up(p: [f32; 3]) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

#[test]
fn every_bridge_family_becomes_the_right_frames() {
    require_python_osc();
    let dir = tempfile::tempdir().unwrap();
    for (i, family) in ["hku", "max", "max-bundled", "path", "treemocap"]
        .into_iter()
        .enumerate()
    {
        let sent = make_frames(10 + i as u64, 40, 1000 * (i as i64 + 1), 12);
        let file = write_frames(dir.path(), &sent);
        let (got, counts) = with_source(options(), |addr| {
            send(
                addr,
                &[
                    "--family",
                    family,
                    "--frames",
                    file.to_str().unwrap(),
                    "--rate",
                    "400",
                ],
            )
        });
        assert_eq!(
            counts.failed_decode + counts.invalid + counts.incomplete,
            0,
            "{family}: {counts:?}"
        );
        match family {
            // No frame numbers or times in this family: numbered on from 0,
            // timed by arrival.
            "hku" => {
                assert_frames(&got, &sent, false, y_up);
                assert!(got.windows(2).all(|w| w[0].time_s <= w[1].time_s));
                assert_eq!(counts.ignored, 40, "one /rigidBody per bundle ignored");
            }
            "treemocap" => {
                // Our message carries no ids.
                assert_eq!(got.len(), sent.len());
                for (g, s) in got.iter().zip(&sent) {
                    assert_eq!((g.frame, g.time_s), (s.frame, s.time_ms as f64 / 1000.0));
                    let want: Vec<DVec3> = s.markers.iter().map(|(_, p)| y_up(*p)).collect();
                    assert_eq!(g.positions().collect::<Vec<_>>(), want);
                    assert!(g.markers.iter().all(|m| m.id.is_none()));
                }
            }
            _ => {
                assert_frames(&got, &sent, true, y_up);
                assert_eq!(
                    counts.ignored, 40,
                    "{family}: one /rigidbody per frame ignored"
                );
            }
        }
    }
}

#[test]
fn z_up_millimetre_senders_arrive_in_metres_y_up() {
    require_python_osc();
    let dir = tempfile::tempdir().unwrap();
    let sent: Vec<Sent> = make_frames(3, 20, 1, 8)
        .into_iter()
        .map(|mut f| {
            for (_, p) in &mut f.markers {
                *p = p.map(|v| (v * 1000.0).round());
            }
            f
        })
        .collect();
    let file = write_frames(dir.path(), &sent);
    let mut config = treemocap::config::Config::default().osc;
    config.up_axis = treemocap::model::frame::UpAxis::Z;
    config.units = treemocap::model::frame::LengthUnit::Mm;
    let mut opts = OscOptions::from_settings(&config).unwrap();
    opts.bind = "127.0.0.1:0".parse().unwrap();
    let (got, _) = with_source(opts, |addr| {
        send(
            addr,
            &["--family", "max", "--frames", file.to_str().unwrap()],
        )
    });
    // Z up: x right, y forward, z up. Y up: x right, y up, z backward.
    assert_frames(&got, &sent, true, |p| {
        DVec3::new(
            p[0] as f64 / 1000.0,
            p[2] as f64 / 1000.0,
            -(p[1] as f64) / 1000.0,
        )
    });
}

#[test]
fn garbage_and_wrong_type_tags_are_counted_and_survived() {
    require_python_osc();
    let mut expected = serde_json::Value::Null;
    let (got, counts) = with_source(options(), |addr| {
        expected = send(addr, &["--bad"]);
        expected.clone()
    });
    assert_eq!(
        counts.failed_decode,
        expected["garbage"].as_u64().unwrap(),
        "{counts:?}"
    );
    assert_eq!(
        counts.invalid,
        expected["bad_args"].as_u64().unwrap(),
        "{counts:?}"
    );
    // The source carried on: the good frame after the bad ones arrived.
    assert_eq!(got.len(), 1, "{got:?}");
    assert_eq!((got[0].frame, got[0].time_s), (77, 7.7));
    assert_eq!(
        got[0].positions().collect::<Vec<_>>(),
        vec![DVec3::new(0.5, 1.5, -0.25)]
    );
}

#[test]
fn senders_outside_the_allow_list_are_dropped_and_counted() {
    require_python_osc();
    let dir = tempfile::tempdir().unwrap();
    let sent = make_frames(5, 10, 500, 4);
    let file = write_frames(dir.path(), &sent);
    let mut opts = options();
    opts.allow =
        treemocap::source::allow::AllowList::parse("osc.allow", &["127.0.0.2".into()]).unwrap();
    let (got, counts) = with_source(opts, |addr| {
        let refused = send(
            addr,
            &["--family", "max", "--frames", file.to_str().unwrap()],
        );
        let accepted = send(
            addr,
            &[
                "--family",
                "max",
                "--frames",
                file.to_str().unwrap(),
                "--source-ip",
                "127.0.0.2",
            ],
        );
        let n = refused["datagrams"].as_u64().unwrap();
        assert_eq!(n, accepted["datagrams"].as_u64().unwrap());
        serde_json::json!({ "datagrams": 2 * n })
    });
    let per_run = sent.iter().map(|f| f.markers.len() as u64 + 4).sum::<u64>();
    assert_eq!(
        counts.not_allowed, per_run,
        "every datagram from 127.0.0.1 refused"
    );
    assert_eq!(counts.datagrams, per_run);
    assert_frames(&got, &sent, true, y_up);
}

/// Starts `treemocap record --osc 127.0.0.1:0 OUT`; returns the child, the
/// address it listens on, and its remaining stdout lines.
fn start_recorder(
    out: &Path,
    extra: &[&str],
) -> (std::process::Child, SocketAddr, mpsc::Receiver<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(["record", "--osc", "127.0.0.1:0"])
        .arg(out)
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let addr = loop {
        let line = rx
            .recv_timeout(Duration::from_secs(10))
            .expect("treemocap record printed no 'listening' line");
        if let Some(a) = line.strip_prefix("listening for OSC on udp ") {
            break a.parse().unwrap();
        }
    };
    (child, addr, rx)
}

#[test]
fn record_osc_writes_what_python_osc_sent() {
    require_python_osc();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("session.log.csv");
    let sent = make_frames(21, 100, 9000, 30);
    let file = write_frames(dir.path(), &sent);
    let (mut child, addr, lines) = start_recorder(&out, &["--seconds", "3"]);
    send(
        addr,
        &[
            "--family",
            "max",
            "--frames",
            file.to_str().unwrap(),
            "--rate",
            "200",
        ],
    );
    let status = child.wait().unwrap();
    assert!(status.success(), "record exited with {status}");
    let printed: Vec<String> = lines.try_iter().collect();
    assert!(
        printed
            .iter()
            .any(|l| l.contains("100 frames") && l.contains("invalid 0")),
        "progress lines: {printed:#?}"
    );
    let mut reader = treemocap::app::open::log(&out).unwrap();
    assert!(
        reader.info().source.contains("osc udp 127.0.0.1"),
        "{:?}",
        reader.info()
    );
    let got: Vec<MarkerFrame> = reader.by_ref().map(|f| f.unwrap()).collect();
    assert!(reader.finish().is_empty());
    assert_frames(&got, &sent, true, y_up);
}

#[test]
fn killed_recorder_loses_at_most_the_last_second() {
    require_python_osc();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("killed.log.csv");
    // Few markers at 100 Hz: the buffer never fills, so only the 1 s flush
    // timer gets rows to the disk.
    let sent = make_frames(33, 600, 0, 3);
    let file = write_frames(dir.path(), &sent);
    let (mut child, addr, _lines) = start_recorder(&out, &[]);
    let mut sender = Command::new("python3")
        .arg(SENDER)
        .args([&addr.ip().to_string(), &addr.port().to_string()])
        .args([
            "--family",
            "treemocap",
            "--frames",
            file.to_str().unwrap(),
            "--rate",
            "100",
            "--progress",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // When each frame left python-osc, on our clock (reading the line can
    // only make it look later, which makes the check below weaker, not flaky).
    let progress = BufReader::new(sender.stdout.take().unwrap());
    let mut sent_at: Vec<(i64, Instant)> = Vec::new();
    let start = Instant::now();
    // Kill after 2.5 s, once the flush timer has put rows on the disk: on a
    // machine loaded many times over its cores (seen at load 17 on 2 cores)
    // the recorder may not have run its first flush by then, and killing it
    // before would test the scheduler, not the recorder.
    let on_disk = || std::fs::metadata(&out).map_or(0, |m| m.len());
    let mut at_first_frame = None;
    for line in progress.lines().map_while(Result::ok) {
        if let Some(n) = line.strip_prefix("sent ") {
            sent_at.push((n.parse().unwrap(), Instant::now()));
            at_first_frame.get_or_insert_with(on_disk);
        }
        let flushed = at_first_frame.is_some_and(|len| on_disk() > len);
        let waited = start.elapsed();
        if waited > Duration::from_millis(2500) && (flushed || waited > Duration::from_secs(30)) {
            break;
        }
    }
    child.kill().unwrap(); // SIGKILL: no chance to flush
    let killed = Instant::now();
    child.wait().unwrap();
    let _ = sender.kill();
    let _ = sender.wait();

    let mut reader = treemocap::app::open::log(&out).unwrap();
    let got: Vec<MarkerFrame> = reader.by_ref().map(|f| f.unwrap()).collect();
    assert!(!got.is_empty(), "nothing reached the disk in 2.5 s");
    // Every frame read back is what was sent (the last one may be cut at a row).
    for (k, g) in got.iter().enumerate() {
        let s = &sent[g.frame as usize];
        let want: Vec<DVec3> = s.markers.iter().map(|(_, p)| y_up(*p)).collect();
        let have: Vec<DVec3> = g.positions().collect();
        if k + 1 < got.len() {
            assert_eq!(have, want, "frame {}", g.frame);
        } else {
            assert_eq!(have[..], want[..have.len()], "last frame {}", g.frame);
        }
    }
    // Flush interval 1 s (the default) plus scheduling slack on a busy machine.
    let horizon = killed - Duration::from_millis(1250);
    let must_have = sent_at
        .iter()
        .filter(|(_, t)| *t <= horizon)
        .map(|(n, _)| *n)
        .max();
    let last = got.last().unwrap().frame;
    if let Some(must) = must_have {
        assert!(
            last >= must,
            "log ends at frame {last}, but frame {must} was sent more than 1.25 s before the kill"
        );
    }
    eprintln!(
        "killed after {} frames sent; log holds {} frames (last {last}); lost {:.2} s",
        sent_at.len(),
        got.len(),
        (sent_at.len() as f64 - got.len() as f64) / 100.0
    );
}

#[test]
fn record_on_a_port_in_use_says_so_and_leaves_no_file() {
    let busy = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let addr = busy.local_addr().unwrap().to_string();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("never.log.csv");
    let run = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(["record", "--osc", &addr])
        .arg(&out)
        .args(["--seconds", "5"])
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(1));
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        err.contains(&format!("cannot listen for OSC on udp {addr}")),
        "{err}"
    );
    assert!(!out.exists(), "no empty log left behind");
    let bad = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(["record", "--osc", "localhost"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(
        bad.status.code(),
        Some(2),
        "a malformed address is a usage error"
    );
}
