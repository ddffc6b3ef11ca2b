//! A `treemocap run` daemon under test, spoken to as a user would: HTTP
//! with a plain TCP client, its log read from stderr after it stops.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// A free TCP port on loopback.
pub fn free_tcp() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A free UDP port on loopback.
pub fn free_udp() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A running daemon; killed when dropped.
pub struct Daemon {
    child: Option<Child>,
    /// Its HTTP address.
    pub http: SocketAddr,
    log: PathBuf,
    /// Holds the log, apart from the output folder (which a test may fill).
    _log_dir: tempfile::TempDir,
}

impl Daemon {
    /// `treemocap run --out OUT --set daemon.http=… --set …` with stderr
    /// (the log, at info level) going to a file of its own.
    pub fn start(out: &Path, sets: &[String]) -> Daemon {
        let port = free_tcp();
        let log_dir = tempfile::tempdir().unwrap();
        let log = log_dir.path().join("daemon.log");
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_treemocap"));
        cmd.args([
            "run",
            "-v",
            "--set",
            &format!("daemon.http=127.0.0.1:{port}"),
        ])
        .arg("--out")
        .arg(out)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap());
        for s in sets {
            cmd.args(["--set", s]);
        }
        let d = Daemon {
            child: Some(cmd.spawn().unwrap()),
            http: SocketAddr::from(([127, 0, 0, 1], port)),
            log,
            _log_dir: log_dir,
        };
        let t0 = Instant::now();
        while d.get("/status").is_none() {
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "no HTTP: {}",
                d.log()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        d
    }

    /// `GET path` → (status code, body), or `None` when nothing answers
    /// within 5 s.
    pub fn request(&self, method: &str, path: &str) -> Option<(u16, String)> {
        let mut s = TcpStream::connect_timeout(&self.http, Duration::from_secs(5)).ok()?;
        s.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
        write!(
            s,
            "{method} {path} HTTP/1.1\r\nHost: {}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
            self.http
        )
        .ok()?;
        let mut raw = Vec::new();
        s.read_to_end(&mut raw).ok()?;
        let text = String::from_utf8_lossy(&raw).into_owned();
        let code = text.split(' ').nth(1)?.parse().ok()?;
        let body = text.split_once("\r\n\r\n").map_or("", |b| b.1).to_string();
        Some((code, body))
    }

    /// `GET path` → body of a 200 answer.
    pub fn get(&self, path: &str) -> Option<String> {
        match self.request("GET", path)? {
            (200, body) => Some(body),
            _ => None,
        }
    }

    /// `/status` as JSON.
    pub fn status(&self) -> serde_json::Value {
        let body = self
            .get("/status")
            .unwrap_or_else(|| panic!("no /status: {}", self.log()));
        serde_json::from_str(&body).unwrap()
    }

    /// Polls `/status` until `ok` holds (or panics after `secs` seconds).
    pub fn wait_status(
        &self,
        secs: u64,
        what: &str,
        ok: impl Fn(&serde_json::Value) -> bool,
    ) -> serde_json::Value {
        let t0 = Instant::now();
        loop {
            let s = self.status();
            if ok(&s) {
                return s;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(secs),
                "{what} not within {secs} s: {s:#}\n{}",
                self.log()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// True while the process runs.
    pub fn alive(&mut self) -> bool {
        self.child
            .as_mut()
            .is_some_and(|c| matches!(c.try_wait(), Ok(None)))
    }

    /// The log so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// SIGTERM, then waits (at most 10 s); the exit status and the whole log.
    pub fn stop(mut self) -> (ExitStatus, String) {
        let mut child = self.child.take().unwrap();
        Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        let t0 = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if t0.elapsed() > Duration::from_secs(10) {
                let _ = child.kill();
                panic!("daemon did not stop within 10 s: {}", self.log());
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        (status, self.log())
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
