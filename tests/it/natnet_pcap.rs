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
use treemocap::format::Recording;
use treemocap::model::frame::MarkerFrame;
use treemocap::protocol::natnet::{Version, SUPPORTED_VERSIONS};
use treemocap::serve::natnet::{self as server, ServeOptions, ServerStats};
use treemocap::source::channel::frame_channel;
use treemocap::source::natnet::client::{self, NatNetStatus};
use treemocap::source::natnet::settings::NatNetSettings;

/// tcpdump on loopback for the two server ports, ready when it says so,
/// and what it says after that (its counts when it stops: received by the
/// filter, dropped by the kernel). Its stderr stays read to the end, so
/// its last words never meet a closed pipe.
fn tcpdump(out: &Path, ports: [u16; 2]) -> (Child, std::thread::JoinHandle<String>) {
    let filter = format!("udp port {} or udp port {}", ports[0], ports[1]);
    let mut child = Command::new("tcpdump")
        // Immediate mode: packets reach the file as they come, not when the
        // kernel ring's block times out (a short capture would be empty).
        // A 16 MB ring: eight captures at once on a busy machine.
        .args([
            "-i",
            "lo",
            "--immediate-mode",
            "-U",
            "-B",
            "16384",
            "-s",
            "0",
            "-n",
            "-w",
        ])
        .arg(out)
        .arg(&filter)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("tcpdump is missing: scripts/test.sh installs it (apt-get install tcpdump)");
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let ready = lines.next().and_then(|l| l.ok()).unwrap_or_default();
    assert!(ready.contains("listening on lo"), "tcpdump: {ready}");
    let rest =
        std::thread::spawn(move || lines.map_while(|l| l.ok()).collect::<Vec<_>>().join("; "));
    (child, rest)
}

/// The FRAMEOFDATA datagrams in the complete records of a legacy pcap of
/// loopback (Ethernet, IPv4, UDP) being written: a record still being
/// written ends the count.
fn frames_captured(bytes: &[u8]) -> usize {
    let le = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
    };
    let mut at = 24;
    let mut n = 0;
    while let Some(len) = le(at + 8).map(|l| l as usize) {
        let Some(record) = bytes.get(at + 16..at + 16 + len) else {
            break;
        };
        // Ethernet header 14 bytes, then IPv4 with its own header length.
        let ihl = record.get(14).map_or(0, |b| usize::from(b & 0x0f) * 4);
        let payload = 14 + ihl + 8;
        if record.get(payload..payload + 2) == Some(&7u16.to_le_bytes()[..]) {
            n += 1;
        }
        at += 16 + len;
    }
    n
}

/// Waits until tcpdump has written `n` frames to `path` (at most 30 s);
/// the frames it holds. On a loaded machine tcpdump can be seconds behind
/// the kernel's ring; stopping it earlier loses what it has not read yet.
fn settle(path: &Path, n: usize) -> usize {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let held = frames_captured(&std::fs::read(path).unwrap_or_default());
        if held >= n || Instant::now() >= deadline {
            return held;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Ends tcpdump as Ctrl-C would, so it writes out everything; what it
/// said at the end.
fn stop((mut child, said): (Child, std::thread::JoinHandle<String>)) -> String {
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let _ = child.wait();
    said.join().unwrap_or_default()
}

/// Serves `path` in `version` on fixed ports and receives it with our
/// client, while tcpdump records; returns the capture and what the client
/// got.
///
/// The ports are picked free before tcpdump starts (its filter names
/// them), so another test can take one before the server binds it; the
/// server then refuses to start (seen once in a full run). Such a run is
/// tried again on other ports; any other failure is the test's.
fn capture(dir: &Path, path: &Path, version: Version, n: usize) -> (PathBuf, Vec<MarkerFrame>) {
    for attempt in 1..=3 {
        match capture_on(dir, path, version, n, (free_port(), free_port())) {
            Ok(done) => return done,
            Err(bind) => eprintln!("NatNet {version}, attempt {attempt}: {bind}"),
        }
    }
    panic!("NatNet {version}: the server could not bind free ports three times")
}

/// One [`capture`] on the given ports; `Err` when the server could not
/// bind them.
fn capture_on(
    dir: &Path,
    path: &Path,
    version: Version,
    n: usize,
    (cmd, data): (u16, u16),
) -> Result<(PathBuf, Vec<MarkerFrame>), String> {
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
            stats: stats.clone(),
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
        let status = Arc::new(NatNetStatus::default());
        let cli_status = status.clone();
        let cli =
            tokio::spawn(async move { client::run(&settings, &cli_status, sink, cshut).await });
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut got = Vec::new();
        while got.len() < n && Instant::now() < deadline {
            got.extend(rx.try_iter());
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let _ = stop_client.send(true);
        let client = cli.await.unwrap();
        let _ = stop_server.send(true);
        match srv.await.unwrap() {
            Err(e) if e.to_string().contains("cannot") => return Err(e.to_string()),
            Err(e) => panic!("NatNet {version}: the server failed: {e}"),
            Ok(_) => {}
        }
        client.unwrap();
        if got.len() != n {
            // What each side counted, to tell a frame never sent from one
            // lost on the way or held by the client.
            let numbers: Vec<i64> = got.iter().map(|f| f.frame).collect();
            let c = status.snapshot();
            eprintln!(
                "NatNet {version}: client got frames {numbers:?}; client state {:?} rate {:?} \
                 counters {:?}; server sent {} frames in {} datagrams, {} connects, {} requests",
                c.state,
                c.frame_rate,
                c.counters,
                stats.frames.load(std::sync::atomic::Ordering::Relaxed),
                stats.datagrams.load(std::sync::atomic::Ordering::Relaxed),
                stats.connects.load(std::sync::atomic::Ordering::Relaxed),
                stats.requests.load(std::sync::atomic::Ordering::Relaxed),
            );
        }
        Ok(got)
    });
    let got = match got {
        Ok(got) => got,
        Err(bind) => {
            stop(dump);
            return Err(bind);
        }
    };
    // Every frame the client got must reach tcpdump's file first.
    let held = settle(&out, got.len());
    let said = stop(dump);
    if held < got.len() {
        eprintln!(
            "NatNet {version}: tcpdump wrote {held} of the {} frames the client got in 30 s; it said: {said}",
            got.len()
        );
    }
    Ok((out, got))
}

fn read_capture(path: &Path, options: PcapOptions) -> (PcapRecording, Vec<MarkerFrame>) {
    let file = std::fs::File::open(path).unwrap();
    let mut r =
        PcapRecording::new(Box::new(file), path.to_path_buf(), options).unwrap_or_else(|e| {
            // What tcpdump itself reads in the capture, to tell a bad
            // capture from a bad reader.
            let dump = Command::new("tcpdump")
                .args(["-r"])
                .arg(path)
                .args(["-n", "-c", "12"])
                .output()
                .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
                .unwrap_or_default();
            panic!("{e}\ntcpdump -r says:\n{dump}")
        });
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
        assert_eq!(rec.info().format, treemocap::format::Format::Pcap);
        if frames.len() != sent.len() {
            // Kept for a look with tcpdump -r or Wireshark.
            let kept = std::env::temp_dir().join(format!("treemocap-failed-natnet-{version}.pcap"));
            let _ = std::fs::copy(&pcap, &kept);
            eprintln!(
                "NatNet {version}: the capture holds {} FRAMEOFDATA datagrams, the reader gave {} frames; kept as {}",
                frames_captured(&std::fs::read(&pcap).unwrap()),
                frames.len(),
                kept.display()
            );
        }
        // What the capture holds is what the client got, frame for frame.
        check_session(version, &sent, &frames);
        assert_eq!(frames, live, "NatNet {version}");
    }
}

/// The records of a legacy pcap file written on this machine (tcpdump:
/// little-endian, microseconds): link type and (seconds, micros, bytes).
fn pcap_records(bytes: &[u8]) -> (u32, Vec<(u32, u32, Vec<u8>)>) {
    let le = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    assert_eq!(le(0), 0xa1b2_c3d4, "a little-endian microsecond pcap");
    let mut out = Vec::new();
    let mut at = 24;
    while at + 16 <= bytes.len() {
        let len = le(at + 8) as usize;
        out.push((le(at), le(at + 4), bytes[at + 16..at + 16 + len].to_vec()));
        at += 16 + len;
    }
    (le(20), out)
}

/// The same packets as pcapng: a section header, one interface, enhanced
/// packet blocks (what Wireshark writes).
fn to_pcapng(link: u32, records: &[(u32, u32, Vec<u8>)]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut block = |kind: u32, body: &[u8]| {
        let len = (12 + body.len().div_ceil(4) * 4) as u32;
        out.extend_from_slice(&kind.to_le_bytes());
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(body);
        out.resize(out.len() + (4 - body.len() % 4) % 4, 0);
        out.extend_from_slice(&len.to_le_bytes());
    };
    let mut shb = 0x1a2b_3c4d_u32.to_le_bytes().to_vec();
    shb.extend_from_slice(&[1, 0, 0, 0]);
    shb.extend_from_slice(&u64::MAX.to_le_bytes());
    block(0x0a0d_0d0a, &shb);
    let mut idb = (link as u16).to_le_bytes().to_vec();
    idb.extend_from_slice(&[0, 0, 0, 0, 4, 0]);
    block(1, &idb);
    for (sec, usec, data) in records {
        let ts = u64::from(*sec) * 1_000_000 + u64::from(*usec);
        let mut epb = 0u32.to_le_bytes().to_vec();
        epb.extend_from_slice(&((ts >> 32) as u32).to_le_bytes());
        epb.extend_from_slice(&(ts as u32).to_le_bytes());
        epb.extend_from_slice(&(data.len() as u32).to_le_bytes());
        epb.extend_from_slice(&(data.len() as u32).to_le_bytes());
        epb.extend_from_slice(data);
        block(6, &epb);
    }
    out
}

/// A legacy pcap of `records`.
fn to_pcap(link: u32, records: &[(u32, u32, Vec<u8>)]) -> Vec<u8> {
    let mut out = 0xa1b2_c3d4_u32.to_le_bytes().to_vec();
    out.extend_from_slice(&[2, 0, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 4, 0]);
    out.extend_from_slice(&link.to_le_bytes());
    for (sec, usec, data) in records {
        for x in [*sec, *usec, data.len() as u32, data.len() as u32] {
            out.extend_from_slice(&x.to_le_bytes());
        }
        out.extend_from_slice(data);
    }
    out
}

/// pcapng reads like pcap; a capture cut after the handshake needs the
/// version and measures the rate; `inspect` and `serve` take captures.
#[test]
fn pcapng_cut_captures_and_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 32, 60, 5, 100.0);
    let v = Version::new(3, 1);
    let (pcap, live) = capture(dir.path(), &path, v, sent.len());
    let (_, frames) = read_capture(&pcap, PcapOptions::default());
    assert_eq!(frames, live);

    let (link, records) = pcap_records(&std::fs::read(&pcap).unwrap());
    let ng = dir.path().join("natnet.pcapng");
    std::fs::write(&ng, to_pcapng(link, &records)).unwrap();
    let (rec, ng_frames) = read_capture(&ng, PcapOptions::default());
    assert_eq!((rec.version(), rec.frame_rate()), (Some(v), 100.0));
    assert_eq!(ng_frames, live);

    // Cut from the first frame on: no SERVERINFO, no FrameRate answer.
    let first = records
        .iter()
        .position(|r| r.2.len() > 46 && r.2[42] == 7 && r.2[43] == 0)
        .expect("a frame in the capture");
    let cut = dir.path().join("cut.pcap");
    std::fs::write(&cut, to_pcap(link, &records[first..])).unwrap();
    let file = std::fs::File::open(&cut).unwrap();
    let e = PcapRecording::new(Box::new(file), cut.clone(), PcapOptions::default())
        .err()
        .expect("no version in a cut capture")
        .to_string();
    assert!(e.contains("--natnet-version"), "{e}");
    let options = PcapOptions {
        version: Some(v),
        ..Default::default()
    };
    let (rec, cut_frames) = read_capture(&cut, options);
    // Without SERVERINFO the server's clock is unknown: no latency.
    let strip = |f: &[MarkerFrame]| -> Vec<_> {
        f.iter()
            .map(|f| (f.frame, f.time_s, f.markers.clone()))
            .collect()
    };
    assert_eq!(strip(&cut_frames), strip(&live));
    assert!(
        (rec.frame_rate() - 100.0).abs() < 0.01,
        "measured {}",
        rec.frame_rate()
    );
    assert!(rec.warnings().iter().any(|w| w.contains("measured")));

    // The command line: inspect reads it, serve streams it again.
    let bin = env!("CARGO_BIN_EXE_treemocap");
    let out = Command::new(bin)
        .args(["inspect", "--json", "--natnet-version", "3.1"])
        .arg(&cut)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["frames"], sent.len());
    let (cmd, data) = (free_port(), free_port());
    let mut server = Command::new(bin)
        .args(["serve", "--bind", "127.0.0.1", "--speed", "4"])
        .args([
            "--command-port",
            &cmd.to_string(),
            "--data-port",
            &data.to_string(),
        ])
        .arg(&ng)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let again = receive(cmd, sent.len());
    let _ = server.kill();
    let _ = server.wait();
    check_session(v, &sent, &again);
}

/// Our client against a server on `cmd`, until `n` frames came.
fn receive(cmd: u16, n: usize) -> Vec<MarkerFrame> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let (sink, rx) = frame_channel(10_000);
        let (stop, shutdown) = tokio::sync::watch::channel(false);
        let settings = NatNetSettings {
            command_port: cmd,
            ..Default::default()
        };
        let status = NatNetStatus::default();
        let cli =
            tokio::spawn(async move { client::run(&settings, &status, sink, shutdown).await });
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut got = Vec::new();
        while got.len() < n && Instant::now() < deadline {
            got.extend(rx.try_iter());
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let _ = stop.send(true);
        cli.await.unwrap().unwrap();
        got
    })
}
