//! `treemocap run` outside the repository (issue 17): the shipped replay is
//! found beside the program, and where it cannot be, the message says what
//! to set.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn run_finds_the_shipped_replay_from_another_folder_or_says_what_to_set() {
    let elsewhere = tempfile::tempdir().unwrap();
    let http = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap();
    drop(std::net::TcpListener::bind(http).ok());
    // From a folder with no replays/ in it: found beside the program.
    let mut daemon = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args([
            "run",
            "--set",
            &format!("daemon.http={http}"),
            "--out",
            "out",
        ])
        .current_dir(elsewhere.path())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    let status = loop {
        let got = std::net::TcpStream::connect(http).ok().and_then(|mut s| {
            use std::io::{Read, Write};
            write!(
                s,
                "GET /status HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
            )
            .ok()?;
            let mut t = String::new();
            s.read_to_string(&mut t).ok()?;
            serde_json::from_str::<serde_json::Value>(t.split_once("\r\n\r\n")?.1).ok()
        });
        if let Some(v) = got.filter(|v| v["frames"].as_u64() > Some(0)) {
            break v;
        }
        assert!(daemon.try_wait().unwrap().is_none(), "the daemon exited");
        assert!(t0.elapsed() < Duration::from_secs(20), "no frames");
        std::thread::sleep(Duration::from_millis(100));
    };
    let _ = daemon.kill();
    let _ = daemon.wait();
    assert!(
        status["source"].as_str().unwrap().contains("maple-24.csv"),
        "{status}"
    );

    // A program with no replay anywhere near it: one clear error, exit 1.
    let bin = elsewhere.path().join("treemocap");
    if std::fs::hard_link(env!("CARGO_BIN_EXE_treemocap"), &bin).is_err() {
        std::fs::copy(env!("CARGO_BIN_EXE_treemocap"), &bin).unwrap();
    }
    let out = Command::new(&bin)
        .args([
            "run",
            "--set",
            &format!("daemon.http={http}"),
            "--out",
            "out",
        ])
        .current_dir(elsewhere.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("replays/maple-24.csv"), "{err}");
    assert!(
        err.contains("daemon.replay_file"),
        "the message says what to set: {err}"
    );
}
