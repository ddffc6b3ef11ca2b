//! `treemocap record --natnet` end to end: `treemocap serve` streams a
//! recorded session over NatNet on loopback, `treemocap record` writes it to
//! a log, and the log reads back as the session (as the wire carries it).

use std::process::{Command, Stdio};
use std::time::Duration;

use glam::DVec3;
use treemocap::format::log::{LogHeader, LogWriter};
use treemocap::format::Recording;
use treemocap::rng::Rng;
use treemocap::{Marker, MarkerFrame};

fn free_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn session(path: &std::path::Path) -> Vec<MarkerFrame> {
    let mut rng = Rng::new(44);
    let frames: Vec<MarkerFrame> = (0..150)
        .map(|f| {
            let n = if f == 5 { 0 } else { rng.int(5, 12) as usize };
            let markers = (0..n)
                .map(|i| Marker {
                    position: DVec3::new(
                        rng.range(-1.0, 1.0),
                        rng.range(0.5, 3.0),
                        rng.range(-1.0, 1.0),
                    ),
                    id: Some(2000 + i as i64),
                })
                .collect();
            MarkerFrame::new(100 + f, f as f64 / 100.0, markers)
        })
        .collect();
    let header = LogHeader {
        source: "record_natnet test".into(),
        frame_rate: 100.0,
    };
    let mut w = LogWriter::create(path, &header, Duration::from_millis(100)).unwrap();
    for f in &frames {
        w.write_frame(f).unwrap();
    }
    w.finish().unwrap();
    frames
}

#[test]
fn record_natnet_writes_the_served_session() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("session.log.csv");
    let out = dir.path().join("recorded.log.csv");
    let sent = session(&input);
    let (cmd, data) = (free_port(), free_port());
    let bin = env!("CARGO_BIN_EXE_treemocap");
    let mut server = Command::new(bin)
        .args(["serve", "--bind", "127.0.0.1", "--natnet-version", "3.1"])
        .args([
            "--command-port",
            &cmd.to_string(),
            "--data-port",
            &data.to_string(),
        ])
        .arg(&input)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let rec = Command::new(bin)
        .args([
            "record",
            "--natnet",
            &format!("127.0.0.1:{cmd}"),
            "--unicast",
        ])
        .arg(&out)
        .args(["--seconds", "3"])
        .output()
        .unwrap();
    let _ = server.kill();
    let _ = server.wait();
    let stdout = String::from_utf8_lossy(&rec.stdout);
    assert!(
        rec.status.success(),
        "record failed: {}\n{stdout}",
        String::from_utf8_lossy(&rec.stderr)
    );
    assert!(stdout.contains("connected to "), "{stdout}");

    let mut reader = treemocap::app::open::log(&out).unwrap();
    assert!(
        reader.info().source.starts_with("natnet "),
        "{:?}",
        reader.info()
    );
    // The server's own rate (not the 120 Hz default), and said so.
    assert_eq!(reader.info().frame_rate, 100.0);
    assert!(
        stdout.contains("frame rate 100 Hz (the server's FrameRate answer)"),
        "{stdout}"
    );
    let got: Vec<MarkerFrame> = reader.by_ref().map(|f| f.unwrap()).collect();
    assert_eq!(got.len(), sent.len(), "every served frame recorded");
    for (g, s) in got.iter().zip(&sent) {
        assert_eq!(g.frame, s.frame);
        assert_eq!(g.time_s.to_bits(), s.time_s.to_bits(), "frame {}", s.frame);
        assert_eq!(g.markers.len(), s.markers.len(), "frame {}", s.frame);
        for (a, b) in s.markers.iter().zip(&g.markers) {
            // NatNet carries float32: the recording holds exactly the wire value.
            let wire = a.position.as_vec3().as_dvec3();
            assert_eq!(b.position, wire, "frame {}", s.frame);
            assert_eq!(b.id, a.id, "frame {}", s.frame);
        }
    }
}

#[test]
fn record_natnet_with_nothing_listening_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("none.log.csv");
    let rec = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args(["record", "--natnet", &format!("127.0.0.1:{}", free_port())])
        .arg(&out)
        .args(["--set", "natnet.connect_timeout_s=0.5"])
        .output()
        .unwrap();
    assert_eq!(rec.status.code(), Some(1));
    let err = String::from_utf8_lossy(&rec.stderr);
    assert!(err.contains("nothing is listening"), "{err}");
    assert!(!out.exists());
    let bad = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args([
            "record",
            "--natnet",
            "127.0.0.1",
            "--natnet-version",
            "three",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
}

/// A server that answers but never sends a frame: `record` says so, leaves
/// no file and exits 1 (it used to write an empty log and exit 0).
#[test]
fn record_natnet_with_no_frame_fails_with_a_message() {
    use treemocap::protocol::natnet::{decode, encode, Packet, Sender, ServerInfo, Version};
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("silent.log.csv");
    let server = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = server.local_addr().unwrap().port();
    let answer = std::thread::spawn(move || {
        server
            .set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
        let info = Packet::ServerInfo(ServerInfo {
            sender: Sender {
                name: "quiet".into(),
                version: [1, 0, 0, 0],
                natnet_version: [3, 1, 0, 0],
            },
            connection: None,
        });
        let info = encode(&info, Version::new(3, 1)).unwrap();
        let mut buf = [0u8; 2048];
        let mut quiet = 0;
        while quiet < 10 {
            match server.recv_from(&mut buf) {
                Ok((n, from)) => {
                    quiet = 0;
                    if let Ok(Packet::Connect(_)) = decode(&buf[..n], Version::new(3, 1)) {
                        let _ = server.send_to(&info, from);
                    }
                }
                Err(_) => quiet += 1,
            }
        }
    });
    let rec = Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args([
            "record",
            "--natnet",
            &format!("127.0.0.1:{port}"),
            "--unicast",
        ])
        .arg(&out)
        .args(["--seconds", "1"])
        .output()
        .unwrap();
    let _ = answer.join();
    let err = String::from_utf8_lossy(&rec.stderr);
    assert_eq!(rec.status.code(), Some(1), "{err}");
    assert!(err.contains("no frame came from natnet"), "{err}");
    assert!(!out.exists());
}
