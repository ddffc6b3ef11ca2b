//! What every part of the scale run shares: sizes, the work folder, timing
//! of whole processes, the Python peers, HTTP GET of /status.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

/// One line of the final table.
pub struct Row {
    pub what: String,
    pub target: String,
    pub measured: String,
    pub peers: String,
}

impl Row {
    pub fn new(what: impl Into<String>, target: &str, measured: String, peers: String) -> Row {
        Row {
            what: what.into(),
            target: target.into(),
            measured,
            peers,
        }
    }
}

/// Sizes of the run and its scratch folder (removed at the end).
pub struct Scale {
    pub quick: bool,
    pub dir: tempfile::TempDir,
}

impl Scale {
    pub fn new(quick: bool) -> Scale {
        // Large files go beside the build, not to a RAM-backed /tmp.
        let base = std::env::var_os("SCALE_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("target"));
        std::fs::create_dir_all(&base).expect("scratch folder");
        Scale {
            quick,
            dir: tempfile::tempdir_in(base).expect("scratch folder"),
        }
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }
}

/// Seconds `f` took.
pub fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let v = f();
    (v, t.elapsed().as_secs_f64())
}

/// The best of `n` wall-clock timings of a whole process (the machine is
/// shared: the minimum is the least disturbed run).
pub fn best_of(n: usize, mut f: impl FnMut() -> f64) -> f64 {
    (0..n).map(|_| f()).fold(f64::INFINITY, f64::min)
}

/// Seconds `cat FILE > /dev/null` takes with the file in the page cache.
pub fn cat_seconds(file: &Path) -> f64 {
    let run = || {
        let t = Instant::now();
        let ok = Command::new("cat")
            .arg(file)
            .stdout(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        assert!(ok, "cat {}", file.display());
        t.elapsed().as_secs_f64()
    };
    run(); // warm the cache
    best_of(3, run)
}

/// MB/s for `bytes` in `seconds`.
pub fn mb_s(bytes: u64, seconds: f64) -> f64 {
    bytes as f64 / seconds / 1e6
}

/// Runs `scripts/peers_bench.py ARGS` and returns its JSON lines
/// (`None` when Python or the tool is missing).
pub fn peer(args: &[&str]) -> Option<serde_json::Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/peers_bench.py");
    let out = Command::new("python3")
        .arg(script)
        .args(args)
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let v: serde_json::Value = serde_json::from_str(text.lines().last()?).ok()?;
    if let Some(e) = v.get("error") {
        eprintln!("peer {}: not measured ({e})", args[0]);
        return None;
    }
    Some(v)
}

/// The peer's seconds, if it ran.
pub fn peer_seconds(args: &[&str]) -> Option<f64> {
    peer(args).and_then(|v| v["seconds"].as_f64())
}

/// The treemocap program built beside this example (`cargo build --release`).
pub fn treemocap_bin() -> PathBuf {
    let exe = std::env::current_exe().expect("own path");
    let bin = exe
        .parent()
        .and_then(Path::parent)
        .map(|d| d.join("treemocap"))
        .expect("target folder");
    assert!(
        bin.exists(),
        "{} is missing: run `cargo build --release` first",
        bin.display()
    );
    bin
}

/// Runs a command under GNU time; returns (seconds, peak RSS in MB).
pub fn peak_rss(cmd: &mut Command) -> (f64, f64) {
    let program = cmd.get_program().to_owned();
    let args: Vec<_> = cmd.get_args().map(|a| a.to_owned()).collect();
    let t = Instant::now();
    let out = Command::new("/usr/bin/time")
        .arg("-f")
        .arg("peak_rss_kb=%M")
        .arg(program)
        .args(args)
        .stdout(Stdio::null())
        .output()
        .expect("/usr/bin/time (GNU time) is needed for peak RSS");
    let seconds = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let kb: f64 = err
        .lines()
        .find_map(|l| l.strip_prefix("peak_rss_kb="))
        .and_then(|v| v.trim().parse().ok())
        .expect("GNU time output");
    (seconds, kb / 1024.0)
}

/// GET `path` from an HTTP server on loopback; the body as JSON.
pub fn get_json(addr: &str, path: &str) -> Option<serde_json::Value> {
    serde_json::from_str(&get_text(addr, path)?).ok()
}

/// The body of `GET path` from `addr`.
pub fn get_text(addr: &str, path: &str) -> Option<String> {
    let mut s = std::net::TcpStream::connect(addr).ok()?;
    s.set_read_timeout(Some(std::time::Duration::from_secs(2)))
        .ok()?;
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut text = String::new();
    s.read_to_string(&mut text).ok()?;
    Some(text.split_once("\r\n\r\n")?.1.to_owned())
}

/// This process's resident set size now, MB.
pub fn rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .unwrap_or_default()
        .lines()
        .find(|l| l.starts_with("VmRSS:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}

/// `x` as "12.3" or "—" when not measured.
pub fn or_dash(x: Option<f64>, f: impl Fn(f64) -> String) -> String {
    x.map_or("—".into(), f)
}
