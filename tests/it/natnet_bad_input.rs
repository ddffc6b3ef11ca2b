//! The client fed bad and forged datagrams by a hand-driven fake server on
//! real UDP sockets (127.0.0.1, and 127.0.0.2 for a stranger): each is
//! counted by kind and logged, the client carries on and still delivers the
//! good frames that follow; only the server's own reply changes the
//! version; frames that keep failing to decode show on the status and make
//! the client renegotiate; untimed frames held at shutdown are delivered.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use tokio::net::UdpSocket;
use treemocap::model::frame::MarkerFrame;
use treemocap::protocol::natnet::session::State;
use treemocap::protocol::natnet::*;
use treemocap::source::channel::{frame_channel, FrameReceiver};
use treemocap::source::natnet::client::{self, ClientReport, NatNetStatus};
use treemocap::source::natnet::settings::{NatNetSettings, TransportSetting};

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

fn frame(n: i32, version: Version) -> Vec<u8> {
    let f = FrameOfData {
        frame_number: n,
        labeled_markers: vec![LabeledMarker {
            id: 7,
            position: [0.25, 1.5, -0.5],
            params: MARKER_UNLABELED,
            ..Default::default()
        }],
        timestamp: n as f64 / 100.0,
        ..Default::default()
    };
    encode(&Packet::FrameOfData(Box::new(f)), version).unwrap()
}

fn good_frame(n: i32) -> Vec<u8> {
    frame(n, Version::new(3, 1))
}

fn server_info(version: Version, data_port: u16) -> Vec<u8> {
    let info = ServerInfo {
        sender: Sender {
            name: "fake".into(),
            version: [1, 0, 0, 0],
            natnet_version: [version.major, version.minor, 0, 0],
        },
        connection: (version.major >= 3).then_some(ServerConnection {
            clock_frequency: 1_000_000,
            data_port,
            multicast: false,
            multicast_group: [239, 255, 42, 99],
        }),
    };
    encode(&Packet::ServerInfo(info), version).unwrap()
}

/// A fake unicast server: a command socket that answers CONNECT with
/// SERVERINFO (the version `versions[k]` for the k-th CONNECT, the last one
/// after that) and every request (FrameRate 100 Hz when `rate`, else no
/// answer at all), and a data socket frames are sent from.
struct Fake {
    data: UdpSocket,
    /// The client's command address, from its first CONNECT.
    client: tokio::sync::oneshot::Receiver<SocketAddr>,
}

async fn fake(versions: Vec<Version>, rate: bool) -> (Fake, NatNetSettings) {
    let cmd = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let data = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let command_port = cmd.local_addr().unwrap().port();
    let data_port = data.local_addr().unwrap().port();
    let (tx, rx) = tokio::sync::oneshot::channel();
    tokio::spawn(async move {
        let mut tx = Some(tx);
        let mut connects = 0;
        let mut buf = [0u8; 2048];
        let v31 = Version::new(3, 1);
        while let Ok((n, from)) = cmd.recv_from(&mut buf).await {
            let reply = match decode(&buf[..n], v31) {
                Ok(Packet::Connect(_)) => {
                    let v = versions[connects.min(versions.len() - 1)];
                    connects += 1;
                    if connects > 1 {
                        // A server slow to answer again: long enough for
                        // the client's state to be seen meanwhile.
                        tokio::time::sleep(Duration::from_millis(300)).await;
                    }
                    if let Some(tx) = tx.take() {
                        let _ = tx.send(from);
                    }
                    Some(server_info(v, data_port))
                }
                Ok(Packet::Request(_)) if !rate => None,
                Ok(Packet::Request(r)) if r == "FrameRate" => {
                    Some(encode(&Packet::Response(Response::float(100.0)), v31).unwrap())
                }
                Ok(Packet::Request(_)) => {
                    Some(encode(&Packet::UnrecognizedRequest(Vec::new()), v31).unwrap())
                }
                _ => None,
            };
            if let Some(r) = reply {
                let _ = cmd.send_to(&r, from).await;
            }
        }
    });
    let settings = NatNetSettings {
        command_port,
        transport: TransportSetting::Unicast,
        ..Default::default()
    };
    (Fake { data, client: rx }, settings)
}

/// Starts the client; returns its frames' receiver, status, stop switch and
/// task.
fn start(
    settings: NatNetSettings,
) -> (
    FrameReceiver,
    Arc<NatNetStatus>,
    tokio::sync::watch::Sender<bool>,
    tokio::task::JoinHandle<treemocap::Result<ClientReport>>,
) {
    let (sink, rx) = frame_channel(1000);
    let (stop, shutdown) = tokio::sync::watch::channel(false);
    let status = Arc::new(NatNetStatus::default());
    let s2 = status.clone();
    let task = tokio::spawn(async move { client::run(&settings, &s2, sink, shutdown).await });
    (rx, status, stop, task)
}

/// Polls until `n` frames arrived or 3 s passed.
async fn frames(rx: &FrameReceiver, n: usize) -> Vec<MarkerFrame> {
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(3);
    while got.len() < n && Instant::now() < deadline {
        got.extend(rx.try_iter());
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    got
}

/// The client's address, once it connected and had its answers.
async fn connected(fake: &mut Fake) -> SocketAddr {
    let to = (&mut fake.client).await.unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    to
}

#[test]
fn bad_datagrams_are_counted_and_the_client_carries_on() {
    runtime().block_on(async {
        let (mut fake, settings) = fake(vec![Version::new(3, 1)], true).await;
        let (rx, _status, stop, client) = start(settings);
        let to = connected(&mut fake).await;
        let frame = good_frame(1);
        let send = |b: Vec<u8>| {
            let data = &fake.data;
            async move { data.send_to(&b, to).await.unwrap() }
        };
        // Truncated datagram.
        send(frame[..frame.len() - 9].to_vec()).await;
        // nDataBytes says less than the content.
        let mut short = frame.clone();
        let n = (frame.len() - 4 - 6) as u16;
        short[2..4].copy_from_slice(&n.to_le_bytes());
        send(short).await;
        // A labeled-marker count that would overflow the packet.
        let mut big = frame.clone();
        // frame number, 4 empty section counts, then the labeled count.
        big[4 + 20..4 + 24].copy_from_slice(&i32::MAX.to_le_bytes());
        send(big).await;
        // An unknown message id.
        send(vec![77, 0, 2, 0, 1, 2]).await;
        // A SERVERINFO on the data channel (Motive 1.x does this): skipped,
        // never taken as the server's reply.
        send(server_info(Version::new(2, 9), 1)).await;
        // Good frames afterwards.
        for k in 2..5 {
            send(good_frame(k)).await;
        }
        let got = frames(&rx, 3).await;
        let _ = stop.send(true);
        let report = client.await.unwrap().unwrap();
        assert_eq!(
            got.iter().map(|f| f.frame).collect::<Vec<_>>(),
            vec![2, 3, 4]
        );
        assert_eq!(got[0].markers[0].position.y, 1.5);
        let c = report.counters;
        assert_eq!((c.incomplete, c.invalid, c.unknown), (2, 1, 1));
        assert_eq!((c.skipped, c.wrong_sender), (1, 0));
        assert_eq!(c.frames, 3);
        assert_eq!(report.version, Some(Version::new(3, 1)));
    });
}

/// Issue: a forged SERVERINFO declaring 4.1, sent to the client from another
/// address (127.0.0.2) or from another port of the server's address, made
/// every real 3.1 frame fail to decode; forged frames were taken as frames.
#[test]
fn forged_server_info_and_frames_from_others_are_ignored() {
    runtime().block_on(async {
        let (mut fake, settings) = fake(vec![Version::new(3, 1)], true).await;
        let (rx, status, stop, client) = start(settings);
        let to = connected(&mut fake).await;
        let stranger = UdpSocket::bind("127.0.0.2:0").await.unwrap();
        let other_port = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let forged = server_info(Version::new(4, 1), 1);
        stranger.send_to(&forged, to).await.unwrap();
        other_port.send_to(&forged, to).await.unwrap();
        // Forged frames, well formed, from both.
        for k in 0..50 {
            stranger.send_to(&good_frame(1000 + k), to).await.unwrap();
            other_port.send_to(&good_frame(2000 + k), to).await.unwrap();
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
        for k in 1..=5 {
            fake.data.send_to(&good_frame(k), to).await.unwrap();
        }
        let got = frames(&rx, 5).await;
        let snap = status.snapshot();
        let _ = stop.send(true);
        let report = client.await.unwrap().unwrap();
        assert_eq!(
            got.iter().map(|f| f.frame).collect::<Vec<_>>(),
            vec![1, 2, 3, 4, 5]
        );
        assert_eq!(report.version, Some(Version::new(3, 1)));
        assert_eq!(snap.server.unwrap().version, Version::new(3, 1));
        let c = report.counters;
        assert_eq!(c.wrong_sender, 102, "{c:?}");
        assert_eq!(c.bad_packets(), 0);
        assert_eq!(c.frames, 5);
    });
}

/// A server that streams frames in another bitstream than its SERVERINFO
/// said: after a second of undecodable frames the status says so and the
/// client renegotiates (CONNECT again), and takes the version the second
/// SERVERINFO gives.
#[test]
fn frames_that_keep_failing_to_decode_are_shown_and_renegotiated() {
    runtime().block_on(async {
        let v41 = Version::new(4, 1);
        let (mut fake, settings) = fake(vec![Version::new(3, 1), v41], true).await;
        let (rx, status, stop, client) = start(settings);
        let to = connected(&mut fake).await;
        let started = Instant::now();
        let mut seen_failing = None;
        let mut k = 0;
        while started.elapsed() < Duration::from_millis(2500) {
            k += 1;
            fake.data.send_to(&frame(k, v41), to).await.unwrap();
            if seen_failing.is_none() && status.snapshot().state == Some(State::DecodeFailing) {
                seen_failing = Some(started.elapsed());
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let got: Vec<MarkerFrame> = rx.try_iter().collect();
        let snap = status.snapshot();
        let _ = stop.send(true);
        let report = client.await.unwrap().unwrap();
        let when = seen_failing.expect("the status showed the decode failures");
        assert!(when >= Duration::from_millis(900), "{when:?}");
        assert_eq!(report.counters.renegotiations, 1);
        assert!(report.counters.invalid + report.counters.incomplete > 10);
        assert_eq!(report.version, Some(v41));
        assert_eq!(snap.state, Some(State::Streaming));
        // After the renegotiation, frames decode again.
        assert!(got.len() > 10, "{} frames", got.len());
        assert_eq!(got[0].markers[0].position.y, 1.5);
    });
}

/// NatNet 2.5 frames carry no timestamp; a server that never answers
/// FrameRate: frames held while waiting keep their arrival time, and
/// frames still held when the client stops are delivered, not dropped.
#[test]
fn untimed_frames_held_at_shutdown_are_delivered_with_arrival_times() {
    runtime().block_on(async {
        let v25 = Version::new(2, 5);
        let (mut fake, settings) = fake(vec![v25], false).await;
        let (rx, _status, stop, client) = start(settings);
        let to = connected(&mut fake).await;
        fake.data.send_to(&frame(10, v25), to).await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
        fake.data.send_to(&frame(11, v25), to).await.unwrap();
        tokio::time::sleep(Duration::from_millis(100)).await;
        assert!(rx.try_recv().is_err(), "held until the rate is known");
        let _ = stop.send(true);
        client.await.unwrap().unwrap();
        let got: Vec<MarkerFrame> = rx.try_iter().collect();
        assert_eq!(
            got.iter().map(|f| f.frame).collect::<Vec<_>>(),
            vec![10, 11]
        );
        // Frames stamped when they were released would come out
        // milliseconds apart. The stamp is the instant the client read the
        // datagram, and on a loaded 2-core machine that read was once 77 ms
        // late for the first frame, so the lower bound leaves the scheduler
        // 150 ms; the gap cannot be longer than 0.5 s (two frames that far
        // apart measure the rate and are no longer held).
        let dt = got[1].time_s - got[0].time_s;
        assert!(
            (0.15..0.45).contains(&dt),
            "{dt} s between frames sent 0.3 s apart"
        );
    });
}

/// The same server under the daemon: while its frames fail to decode,
/// `/status` names the state under `source_state` and the log says it, and
/// once the client has renegotiated, frames arrive again.
#[test]
fn the_daemon_shows_frames_that_fail_to_decode_on_status() {
    let rt = runtime();
    let v41 = Version::new(4, 1);
    let (mut fake, settings) = rt.block_on(fake(vec![Version::new(3, 1), v41], true));
    let dir = tempfile::tempdir().unwrap();
    let d = crate::common::running::Daemon::start(
        &dir.path().join("out"),
        &[
            "daemon.source=natnet".into(),
            format!("daemon.natnet_server=127.0.0.1:{}", settings.command_port),
            "daemon.natnet_transport=unicast".into(),
        ],
    );
    let to = rt.block_on(async {
        tokio::time::timeout(Duration::from_secs(20), connected(&mut fake))
            .await
            .expect("the daemon connected")
    });
    // Frames in the bitstream the first SERVERINFO did not announce, sent
    // from the runtime while the test polls /status.
    let data = fake.data;
    let sender = rt.spawn(async move {
        for k in 1.. {
            if data.send_to(&frame(k, v41), to).await.is_err() {
                return;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    });
    let failing = d.wait_status(20, "source_state naming the decode failures", |s| {
        s["source_state"]
            .as_str()
            .is_some_and(|t| t.contains("fail to decode"))
    });
    assert!(
        failing["source_state"]
            .as_str()
            .unwrap()
            .contains("NatNet 3.1"),
        "{failing:#}"
    );
    let streaming = d.wait_status(20, "frames after the renegotiation", |s| {
        s["frames"].as_u64().unwrap_or(0) > 10
            && s["source_state"]
                .as_str()
                .is_some_and(|t| t.contains("NatNet 4.1") && !t.contains("fail"))
    });
    assert_eq!(streaming["source_error"], serde_json::Value::Null);
    sender.abort();
    let (status, log) = d.stop();
    assert!(status.success(), "{status}");
    assert!(
        log.lines()
            .any(|l| l.contains("WARN") && l.contains("fail to decode")),
        "{log}"
    );
}
