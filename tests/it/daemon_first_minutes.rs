//! The daemon's first minutes (issue 17): the first tree comes from the
//! first seconds of the still phase; a rebuild asked for later uses the
//! rest positions of the longer still phase seen by then; the sway's wind,
//! once known, brings a tree bent by it. Through the real program: a
//! replay played at 3× its speed, /status and POST /rebuild over HTTP,
//! tips.json read from the output folder.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Killed(Child);
impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn request(port: u16, method: &str, path: &str) -> Option<(u16, String)> {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).ok()?;
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut t = String::new();
    s.read_to_string(&mut t).ok()?;
    let code = t.split(' ').nth(1)?.parse().ok()?;
    Some((code, t.split_once("\r\n\r\n")?.1.to_string()))
}

fn wait_status(
    port: u16,
    what: &str,
    ok: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    let t0 = Instant::now();
    loop {
        if let Some(v) = request(port, "GET", "/status")
            .and_then(|(_, b)| serde_json::from_str::<serde_json::Value>(&b).ok())
            .filter(|v| ok(v))
        {
            return v;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(40),
            "timed out waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn rest_window(out: &std::path::Path) -> (f64, f64, serde_json::Value) {
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("tips.json")).unwrap()).unwrap();
    let w = &v["rest_window_s"];
    (
        w[0].as_f64().unwrap(),
        w[1].as_f64().unwrap(),
        v["wind"].clone(),
    )
}

#[test]
fn rest_improves_a_rebuild_uses_it_and_a_known_wind_rebuilds() {
    let dir = tempfile::tempdir().unwrap();
    let session = dir.path().join("session.csv");
    let opts = treemocap::sim::SynthOptions {
        seed: 17,
        tips: 24,
        still_s: 20.0,
        wind_s: 16.0,
        ..Default::default()
    };
    treemocap::app::synth::write_session(&opts, &session).unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let out = dir.path().join("out");
    let _daemon = Killed(
        Command::new(env!("CARGO_BIN_EXE_treemocap"))
            .arg("run")
            .args(["--set", &format!("daemon.http=127.0.0.1:{port}")])
            .args([
                "--set",
                &format!("daemon.replay_file={}", session.display()),
            ])
            .args(["--set", "daemon.replay_speed=3"])
            .arg("--out")
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let first = wait_status(port, "the first tree", |v| v["trees"] == 1);
    assert_eq!(first["last_tree"]["reason"]["trigger"], "first_tree");
    let (a1, b1, wind1) = rest_window(&out);
    assert!(wind1.is_null(), "no wind in a still phase");

    // Well into the still phase, a rebuild takes the rest positions of all
    // of it so far, not those of the first tree.
    wait_status(port, "16 s of capture", |v| {
        v["time_s"].as_f64() > Some(16.0)
    });
    assert_eq!(request(port, "POST", "/rebuild").unwrap().0, 202);
    let second = wait_status(port, "the requested tree", |v| v["trees"] == 2);
    assert_eq!(second["last_tree"]["reason"]["trigger"], "requested");
    let (a2, b2, _) = rest_window(&out);
    assert!(
        b2 - a2 > (b1 - a1) + 5.0,
        "rest window of the rebuild {a2}–{b2} s is not longer than the first tree's {a1}–{b1} s"
    );

    // The wind starts at 20 s; once the sway gives its direction, a tree
    // bent by it follows without being asked, and tips.json says the speed
    // is not known.
    let third = wait_status(port, "a tree for the known wind", |v| v["trees"] == 3);
    assert_eq!(
        third["last_tree"]["reason"]["trigger"], "wind_known",
        "{third}"
    );
    let (_, _, wind) = rest_window(&out);
    assert!(wind["direction"].is_array(), "{wind}");
    assert!(wind["speed"].is_null(), "{wind}");
}
