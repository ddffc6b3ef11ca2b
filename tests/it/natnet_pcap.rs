//! Wireshark/tcpdump captures of NatNet as recordings. The captures are
//! made here: tcpdump (Debian's package; scripts/test.sh installs it)
//! records loopback while our own server streams a session to our own
//! client, every bitstream version; the capture must then read back as
//! exactly the session the client received. One capture is also rewritten
//! as pcapng, and one is served again by `treemocap serve`.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::common::natnet::{check_session, free_port, session};
use treemocap::format::pcap::{PcapOptions, PcapRecording};
use treemocap::model::frame::MarkerFrame;
use treemocap::protocol::natnet::{Version, SUPPORTED_VERSIONS};
use treemocap::serve::natnet::{self as server, ServeOptions, ServerStats};
use treemocap::source::channel::frame_channel;
use treemocap::source::natnet::client::{self, NatNetStatus};
use treemocap::source::natnet::settings::NatNetSettings;

/// tcpdump on loopback for the two server ports, ready when it says so.
fn tcpdump(out: &Path, ports: [u16; 2]) -> Child {
    let filter = format!("udp port {} or udp port {}", ports[0], ports[1]);
    let mut child = Command::new("tcpdump")
        .args(["-i", "lo", "-U", "-s", "0", "-n", "-w"])
        .arg(out)
        .arg(&filter)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("tcpdump is missing: scripts/test.sh installs it (apt-get install tcpdump)");
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let ready = lines.next().and_then(|l| l.ok()).unwrap_or_default();
    assert!(ready.contains("listening on lo"), "tcpdump: {ready}");
    child
}

/// Ends tcpdump as Ctrl-C would, so it writes out everything.
fn stop(mut child: Child) {
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let _ = child.wait();
}

/// Serves `path` in `version` on fixed ports and receives it with our
/// client, while tcpdump records; returns the capture and what the client
/// got.
fn capture(dir: &Path, path: &Path, version: Version, n: usize) -> (PathBuf, Vec<MarkerFrame>) {
    let (cmd, data) = (free_port(), free_port());
    let out = dir.join(format!("natnet-{version}.pcap"));
    let dump = tcpdump(&out, [cmd, data]);
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let got = rt.block_on(async {
        let stats = Arc::new(ServerStats::default());
        let opts = ServeOptions {
            version,
            speed: 4.0,
            bind: "127.0.0.1".parse().unwrap(),
            command_port: cmd,
            data_port: data,
            stats,
            ..Default::default()
        };
        let (stop_server, shutdown) = tokio::sync::watch::channel(false);
        let path = path.to_path_buf();
        let srv = tokio::spawn(async move {
            server::serve(|| treemocap::app::open::open(&path), &opts, shutdown).await
        });
        tokio::time::sleep(Duration::from_millis(50)).await;
        let (sink, rx) = frame_channel(10_000);
        let (stop_client, cshut) = tokio::sync::watch::channel(false);
        let settings = NatNetSettings {
            command_port: cmd,
            ..Default::default()
        };
        let status = NatNetStatus::default();
        let cli = tokio::spawn(async move { client::run(&settings, &status, sink, cshut).await });
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut got = Vec::new();
        while got.len() < n && Instant::now() < deadline {
            got.extend(rx.try_iter());
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let _ = stop_client.send(true);
        cli.await.unwrap().unwrap();
        let _ = stop_server.send(true);
        let _ = srv.await;
        got
    });
    // Let the last datagrams reach tcpdump's file.
    std::thread::sleep(Duration::from_millis(100));
    stop(dump);
    (out, got)
}

fn read_capture(path: &Path, options: PcapOptions) -> (PcapRecording, Vec<MarkerFrame>) {
    let file = std::fs::File::open(path).unwrap();
    let mut r = PcapRecording::new(Box::new(file), path.to_path_buf(), options)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let frames = r.by_ref().collect::<treemocap::Result<Vec<_>>>().unwrap();
    (r, frames)
}

#[test]
fn captures_of_every_version_read_back_as_the_session() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 31, 40, 6, 100.0);
    // Each version in its own thread: tcpdump start-up dominates.
    let runs: Vec<_> = SUPPORTED_VERSIONS
        .iter()
        .map(|&v| {
            let (d, p) = (dir.path().to_path_buf(), path.clone());
            let n = sent.len();
            std::thread::spawn(move || (v, capture(&d, &p, v, n)))
        })
        .collect();
    for run in runs {
        let (version, (pcap, live)) = run.join().unwrap();
        check_session(version, &sent, &live);
        let (rec, frames) = read_capture(&pcap, PcapOptions::default());
        assert_eq!(rec.version(), Some(version));
        assert_eq!(
            rec.frame_rate(),
            100.0,
            "NatNet {version}: FrameRate answer"
        );
        assert!(rec.source().contains("treemocap"), "{}", rec.source());
        // What the capture holds is what the client got, frame for frame.
        check_session(version, &sent, &frames);
        assert_eq!(frames, live, "NatNet {version}");
    }
}
