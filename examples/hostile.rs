//! The hostile loads of issue 11 against a running daemon, with the figures
//! the README's reliability section quotes: crashes, hangs, the daemon's
//! peak RSS, and `/status` latency while each load runs.
//!
//! ```sh
//! cargo build --release && cargo run --release --example hostile
//! ```
//!
//! Starts `target/release/treemocap run` (OSC source, OSC control, HTTP) and
//! runs, one after the other: OSC nesting beyond any stack on both OSC
//! ports, 20 000 garbage datagrams, 5 000 from a sender outside the
//! allow-list, 2 000 slowloris and 15 000 idle HTTP connections, 2 000
//! `POST /rebuild`, 200 WebSocket viewers; then reads hostile Motive CSVs
//! (a first row of 5 million fields, 10 MB and 100 MB) with `inspect`.
//! Traffic goes to 127.0.0.1 only; every loop is bounded in count and time.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn free_udp() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The release binary beside this example (target/release/examples/..).
fn treemocap() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let bin = exe.parent().unwrap().parent().unwrap().join("treemocap");
    assert!(
        bin.exists(),
        "build it first: cargo build --release ({})",
        bin.display()
    );
    bin
}

/// Peak resident memory of a process (VmHWM), in MB.
fn peak_rss_mb(pid: u32) -> f64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}

/// One `GET /status`: the time to the whole answer, or `None` if it did not
/// come within 1 s (a hang).
fn status_ms(http: SocketAddr) -> Option<f64> {
    let t0 = Instant::now();
    let mut s = TcpStream::connect_timeout(&http, Duration::from_secs(1)).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(1))).ok()?;
    s.write_all(b"GET /status HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .ok()?;
    let mut answer = Vec::new();
    s.read_to_end(&mut answer).ok()?;
    answer
        .starts_with(b"HTTP/1.1 200")
        .then(|| t0.elapsed().as_secs_f64() * 1000.0)
}

/// Samples `/status` every 50 ms while a load runs.
struct Probe {
    stop: Arc<AtomicBool>,
    samples: Arc<Mutex<(Vec<f64>, u64)>>,
    thread: std::thread::JoinHandle<()>,
}

impl Probe {
    fn start(http: SocketAddr) -> Probe {
        let stop = Arc::new(AtomicBool::new(false));
        let samples = Arc::new(Mutex::new((Vec::new(), 0)));
        let (s, m) = (stop.clone(), samples.clone());
        let thread = std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                let r = status_ms(http);
                if let Ok(mut g) = m.lock() {
                    match r {
                        Some(ms) => g.0.push(ms),
                        None => g.1 += 1,
                    }
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        Probe {
            stop,
            samples,
            thread,
        }
    }

    /// (median ms, max ms, requests that hung).
    fn finish(self) -> (f64, f64, u64) {
        self.stop.store(true, Ordering::Relaxed);
        let _ = self.thread.join();
        let (mut ms, hung) = self.samples.lock().unwrap().clone();
        ms.sort_by(f64::total_cmp);
        let median = ms.get(ms.len() / 2).copied().unwrap_or(f64::NAN);
        (median, ms.last().copied().unwrap_or(f64::NAN), hung)
    }
}

fn deepest_bundle() -> Vec<u8> {
    let mut inner: Vec<u8> = b"/a\0\0,\0\0\0".to_vec();
    while inner.len() + 20 <= 65_507 {
        let mut b = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
        b.extend_from_slice(&(inner.len() as u32).to_be_bytes());
        b.extend_from_slice(&inner);
        inner = b;
    }
    inner
}

fn nested_arrays(depth: usize) -> Vec<u8> {
    let mut b = b"/treemocap/rebuild\0\0,".to_vec();
    b.extend(std::iter::repeat_n(b'[', depth));
    b.extend(std::iter::repeat_n(b']', depth));
    b.push(0);
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    b
}

fn udp_flood(from: &str, to: u16, datagrams: &[Vec<u8>], n: usize) {
    let s = UdpSocket::bind((from, 0)).unwrap();
    for i in 0..n {
        let _ = s.send_to(&datagrams[i % datagrams.len()], ("127.0.0.1", to));
        if i % 500 == 499 {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// Opens `n` connections; with `trickle`, each sends a header line every
/// second for `hold` and never finishes its request.
fn hold_connections(http: SocketAddr, n: usize, trickle: bool, hold: Duration) -> usize {
    let mut socks = Vec::new();
    for _ in 0..n {
        match TcpStream::connect_timeout(&http, Duration::from_secs(1)) {
            Ok(mut s) => {
                if trickle {
                    let _ = s.write_all(b"GET /status HTTP/1.1\r\nHost: x\r\n");
                }
                socks.push(s);
            }
            Err(_) => break, // out of descriptors on our side
        }
    }
    let opened = socks.len();
    let t0 = Instant::now();
    while t0.elapsed() < hold {
        if trickle {
            for s in &mut socks {
                let _ = s.write_all(b"X-Slow: 1\r\n");
            }
        }
        std::thread::sleep(Duration::from_secs(1));
    }
    opened
}

fn post_rebuilds(http: SocketAddr, n: usize) -> usize {
    let mut accepted = 0;
    for _ in 0..n {
        if let Ok(mut s) = TcpStream::connect(http) {
            let _ = s.write_all(
                b"POST /rebuild HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
            );
            let mut a = Vec::new();
            let _ = s.read_to_end(&mut a);
            accepted += a.starts_with(b"HTTP/1.1 202") as usize;
        }
    }
    accepted
}

fn websockets(http: SocketAddr, n: usize, hold: Duration) -> usize {
    use tokio_tungstenite::tungstenite;
    let mut open = Vec::new();
    for _ in 0..n {
        let Ok(tcp) = TcpStream::connect(http) else {
            break;
        };
        if let Ok((ws, _)) = tungstenite::client(format!("ws://{http}/live"), tcp) {
            open.push(ws);
        }
    }
    let opened = open.len();
    std::thread::sleep(hold);
    opened
}

/// `treemocap inspect FILE`: (exit code, peak RSS MB, seconds, first line of stderr).
fn inspect(file: &Path) -> (i32, f64, f64, String) {
    let t0 = Instant::now();
    let mut child = Command::new(treemocap())
        .arg("inspect")
        .arg(file)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut peak: f64 = 0.0;
    let status = loop {
        peak = peak.max(peak_rss_mb(child.id()));
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    let mut err = String::new();
    let _ = child.stderr.take().unwrap().read_to_string(&mut err);
    let line = err.lines().next().unwrap_or("").chars().take(110).collect();
    (
        status.code().unwrap_or(-1),
        peak,
        t0.elapsed().as_secs_f64(),
        line,
    )
}

fn main() {
    let dir = tempfile::tempdir().unwrap();
    let (osc, control, port) = (free_udp(), free_udp(), free_port());
    let http = SocketAddr::from(([127, 0, 0, 1], port));
    let mut daemon: Child = Command::new(treemocap())
        .args(["run", "--out"])
        .arg(dir.path().join("out"))
        .args(["--set", "daemon.source=osc"])
        .args(["--set", &format!("osc.bind=127.0.0.1:{osc}")])
        .args(["--set", "osc.allow=[\"127.0.0.1\"]"])
        .args(["--set", &format!("daemon.osc_control=127.0.0.1:{control}")])
        .args(["--set", &format!("daemon.http=127.0.0.1:{port}")])
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.path().join("daemon.log")).unwrap())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while status_ms(http).is_none() {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "the daemon did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let pid = daemon.id();
    println!("| load | done | /status median | /status max | hangs | daemon alive |");
    println!("|---|---|---|---|---|---|");
    let mut row = |name: &str, load: &mut dyn FnMut() -> String| {
        let probe = Probe::start(http);
        let done = load();
        let (median, max, hung) = probe.finish();
        let alive = matches!(daemon.try_wait(), Ok(None));
        println!("| {name} | {done} | {median:.1} ms | {max:.1} ms | {hung} | {alive} |");
    };
    let deep = vec![
        deepest_bundle(),
        nested_arrays(10_000),
        nested_arrays(32_000),
    ];
    row(
        "OSC nesting (3 275 bundles, 10 000 and 32 000 arrays) ×100 on both OSC ports",
        &mut || {
            udp_flood("127.0.0.1", osc, &deep, 300);
            udp_flood("127.0.0.1", control, &deep, 300);
            "600 datagrams".into()
        },
    );
    row("20 000 garbage datagrams", &mut || {
        udp_flood("127.0.0.1", osc, &[b"hello, treemocap".to_vec()], 20_000);
        "20 000".into()
    });
    row("5 000 datagrams from outside osc.allow", &mut || {
        udp_flood("127.0.0.2", osc, &[b"/a\0\0,\0\0\0".to_vec()], 5_000);
        "5 000".into()
    });
    row("2 000 slowloris connections held 15 s", &mut || {
        format!(
            "{} opened",
            hold_connections(http, 2_000, true, Duration::from_secs(15))
        )
    });
    row("15 000 idle connections held 15 s", &mut || {
        format!(
            "{} opened",
            hold_connections(http, 15_000, false, Duration::from_secs(15))
        )
    });
    row("2 000 POST /rebuild", &mut || {
        format!("{} accepted", post_rebuilds(http, 2_000))
    });
    row("200 WebSocket viewers held 5 s", &mut || {
        format!("{} opened", websockets(http, 200, Duration::from_secs(5)))
    });
    let status = status_ms(http).map(|_| {
        let mut s = TcpStream::connect(http).unwrap();
        s.write_all(b"GET /status HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
            .unwrap();
        let mut a = String::new();
        let _ = s.read_to_string(&mut a);
        a
    });
    let bad = status
        .as_deref()
        .and_then(|a| a.split_once("\r\n\r\n"))
        .and_then(|(_, b)| serde_json::from_str::<serde_json::Value>(b).ok())
        .map(|v| v["bad_input"].to_string())
        .unwrap_or_default();
    let rss = peak_rss_mb(pid);
    let _ = Command::new("kill")
        .args(["-TERM", &pid.to_string()])
        .status();
    let exit = daemon.wait().unwrap();
    let log = std::fs::read_to_string(dir.path().join("daemon.log")).unwrap_or_default();
    println!();
    println!(
        "daemon: peak RSS {rss:.1} MB, exit {exit}, {} log lines",
        log.lines().count()
    );
    println!("bad_input: {bad}");

    println!();
    println!("| hostile Motive CSV | exit | peak RSS | time | message |");
    println!("|---|---|---|---|---|");
    let head = "Format Version,1.23,Take Name,t,Capture Frame Rate,100,Export Frame Rate,100,Length Units,Meters";
    for (name, fields) in [
        ("10 MB, first row of 5 million fields", 5_000_000),
        ("100 MB, first row of 50 million fields", 50_000_000),
    ] {
        let f = dir.path().join("hostile.csv");
        let mut w = std::io::BufWriter::new(std::fs::File::create(&f).unwrap());
        w.write_all(head.as_bytes()).unwrap();
        for _ in 0..fields {
            w.write_all(b",a").unwrap();
        }
        w.write_all(b"\n").unwrap();
        drop(w);
        let (code, rss, secs, line) = inspect(&f);
        println!("| {name} | {code} | {rss:.1} MB | {secs:.2} s | {line} |");
    }
}
