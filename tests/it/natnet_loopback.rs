//! treemocap's NatNet client against treemocap's NatNet server on real UDP
//! sockets (127.0.0.1): every supported bitstream version, the whole session
//! must arrive intact (every frame, every marker, bit-exact f32 positions).

use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::common::natnet::{check_session, free_port, session};
use treemocap::model::frame::MarkerFrame;
use treemocap::protocol::natnet::select::{UpAxis, UpAxisSetting};
use treemocap::protocol::natnet::session::RateSource;
use treemocap::protocol::natnet::{Transport, Version, SUPPORTED_VERSIONS};
use treemocap::serve::natnet::{self as server, ServeOptions, ServerStats};
use treemocap::source::channel::frame_channel;
use treemocap::source::natnet::client::{self, NatNetStatus};
use treemocap::source::natnet::settings::{Interface, NatNetSettings, TransportSetting};

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// Receives until `n` frames arrived or `timeout`, then stops the client.
async fn collect(
    opts: NatNetSettings,
    n: usize,
    timeout: Duration,
) -> (treemocap::Result<client::ClientReport>, Vec<MarkerFrame>) {
    let (sink, rx) = frame_channel(100_000);
    let (stop, shutdown) = tokio::sync::watch::channel(false);
    let status = Arc::new(NatNetStatus::default());
    let task = tokio::spawn(async move { client::run(&opts, &status, sink, shutdown).await });
    let deadline = Instant::now() + timeout;
    let mut got = Vec::new();
    while got.len() < n && Instant::now() < deadline && !task.is_finished() {
        while let Ok(f) = rx.try_recv() {
            got.push(f);
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let _ = stop.send(true);
    let report = task.await.unwrap();
    got.extend(rx.try_iter());
    (report, got)
}

fn start_server(
    path: std::path::PathBuf,
    opts: ServeOptions,
) -> (
    tokio::task::JoinHandle<treemocap::Result<server::ServeReport>>,
    tokio::sync::watch::Sender<bool>,
) {
    let (stop, shutdown) = tokio::sync::watch::channel(false);
    let h = tokio::spawn(async move {
        server::serve(|| treemocap::app::open::open(&path), &opts, shutdown).await
    });
    (h, stop)
}

/// A server on 127.0.0.1 with ports the OS picks, reporting into `stats`.
fn loopback_server(stats: &Arc<ServerStats>) -> ServeOptions {
    ServeOptions {
        bind: "127.0.0.1".parse().unwrap(),
        command_port: 0,
        data_port: 0,
        stats: stats.clone(),
        ..Default::default()
    }
}

async fn command_port(stats: &ServerStats) -> u16 {
    for _ in 0..500 {
        if let Some(a) = stats.command_addr.get() {
            return a.port();
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    panic!("server did not start");
}

#[test]
fn every_version_arrives_intact_over_unicast() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 7, 120, 40, 100.0);
    let rt = runtime();
    rt.block_on(async {
        let mut runs = Vec::new();
        for &version in SUPPORTED_VERSIONS {
            let stats = Arc::new(ServerStats::default());
            let (server, _stop) = start_server(
                path.clone(),
                ServeOptions {
                    version,
                    speed: 4.0,
                    ..loopback_server(&stats)
                },
            );
            let port = command_port(&stats).await;
            let opts = NatNetSettings {
                command_port: port,
                ..Default::default()
            };
            let n = sent.len();
            runs.push((
                version,
                server,
                tokio::spawn(collect(opts, n, Duration::from_secs(20))),
            ));
        }
        for (version, server, run) in runs {
            let (report, got) = run.await.unwrap();
            let report = report.unwrap_or_else(|e| panic!("NatNet {version}: {e}"));
            assert_eq!(report.version, Some(version));
            assert!(report.server.starts_with("treemocap"), "{}", report.server);
            check_session(version, &sent, &got);
            let c = report.counters;
            assert_eq!(c.bad_packets() + c.wrong_sender, 0, "NatNet {version}");
            assert_eq!(c.missed_frames, 0);
            assert!(c.modeldefs >= 1, "NatNet {version}: MODELDEF answered");
            // The server's FrameRate answer, not a guess.
            let rate = report.frame_rate.expect("frame rate known");
            assert_eq!((rate.hz, rate.source), (100.0, RateSource::Server));
            let sr = server.await.unwrap().unwrap();
            assert_eq!(sr.frames, sent.len() as u64);
        }
    });
}

#[test]
fn bitstream_negotiation_switches_the_decoder_and_refusals_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 8, 60, 10, 100.0);
    let rt = runtime();
    rt.block_on(async {
        // 3.1 server, client asks for 4.1: frames decode as 4.1 (section sizes).
        for (server_v, want, ok) in [
            ((3, 1), (4, 1), true),
            ((4, 1), (3, 0), true),
            ((3, 1), (5, 0), false),
            ((2, 9), (3, 1), false),
        ] {
            let (server_v, want) = (
                Version::new(server_v.0, server_v.1),
                Version::new(want.0, want.1),
            );
            let stats = Arc::new(ServerStats::default());
            let (server, stop) = start_server(
                path.clone(),
                ServeOptions {
                    version: server_v,
                    speed: 2.0,
                    ..loopback_server(&stats)
                },
            );
            let opts = NatNetSettings {
                command_port: command_port(&stats).await,
                bitstream: Some(want),
                ..Default::default()
            };
            let (report, got) = collect(opts, sent.len(), Duration::from_secs(10)).await;
            if ok {
                let report = report.unwrap();
                assert_eq!(report.version, Some(want));
                // Frames sent before the switch was confirmed may be lost;
                // the rest must be exact.
                assert!(
                    got.len() + 5 >= sent.len(),
                    "{} of {}",
                    got.len(),
                    sent.len()
                );
                let first = (got[0].frame) as usize;
                check_session(want, &sent[first..], &got);
                assert_eq!(report.counters.bad_packets(), 0);
            } else {
                let e = report.unwrap_err().to_string();
                assert!(e.contains(&want.to_string()), "{e}");
                assert!(e.contains("refused") || e.contains("cannot change"), "{e}");
            }
            let _ = stop.send(true);
            let _ = server.await;
        }
    });
}

#[test]
fn nothing_listening_is_a_clear_error() {
    let rt = runtime();
    rt.block_on(async {
        let port = free_port();
        let opts = NatNetSettings {
            command_port: port,
            connect_timeout: Duration::from_millis(300),
            ..Default::default()
        };
        let (report, _) = collect(opts, 1, Duration::from_secs(5)).await;
        let e = report.unwrap_err().to_string();
        assert!(
            e.contains(&format!("127.0.0.1:{port}")) && e.contains("nothing is listening"),
            "{e}"
        );
    });
}

#[test]
fn multicast_join_failure_names_the_interface() {
    let rt = runtime();
    rt.block_on(async {
        let dir = tempfile::tempdir().unwrap();
        let (path, _) = session(dir.path(), 9, 10, 3, 100.0);
        let stats = Arc::new(ServerStats::default());
        let (server, stop) = start_server(
            path,
            ServeOptions {
                bind: "127.0.0.1".parse().unwrap(),
                command_port: 0,
                data_port: free_port(),
                stats: stats.clone(),
                ..Default::default()
            },
        );
        // 192.0.2.1 (TEST-NET-1) is no interface of this machine.
        let opts = NatNetSettings {
            command_port: command_port(&stats).await,
            transport: TransportSetting::Multicast,
            data_port: Some(free_port()),
            interface: Interface::Address("192.0.2.1".parse().unwrap()),
            ..Default::default()
        };
        let (report, _) = collect(opts, 1, Duration::from_secs(5)).await;
        let e = report.unwrap_err().to_string();
        assert!(
            e.contains("239.255.42.99") && e.contains("interface 192.0.2.1"),
            "{e}"
        );
        let _ = stop.send(true);
        let _ = server.await;
    });
}

#[test]
fn client_reconnects_after_the_server_restarts() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 10, 40, 5, 100.0);
    let rt = runtime();
    rt.block_on(async {
        let port = free_port();
        let serve = |stats: Arc<ServerStats>| ServeOptions {
            bind: "127.0.0.1".parse().unwrap(),
            command_port: port,
            data_port: 0,
            stats,
            ..Default::default()
        };
        let (first, _s1) = start_server(path.clone(), serve(Arc::default()));
        let opts = NatNetSettings {
            command_port: port,
            silence_timeout: Duration::from_millis(300),
            ..Default::default()
        };
        let client = tokio::spawn(collect(opts, 2 * sent.len(), Duration::from_secs(15)));
        first.await.unwrap().unwrap();
        // The first server played everything and exited; after a pause a new
        // one starts on the same port (frame numbers start again at 0).
        tokio::time::sleep(Duration::from_millis(800)).await;
        let (second, _s2) = start_server(path.clone(), serve(Arc::default()));
        let (report, got) = client.await.unwrap();
        second.await.unwrap().unwrap();
        let report = report.unwrap();
        assert_eq!(got.len(), 2 * sent.len());
        assert_eq!(report.counters.restarts, 1);
        assert!(report.counters.reconnects >= 1, "{report:?}");
        assert_eq!(report.counters.frames, 2 * sent.len() as u64);
        check_session(Version::new(3, 1), &sent, &got[..sent.len()]);
        check_session(Version::new(3, 1), &sent, &got[sent.len()..]);
    });
}

/// Multicast needs a multicast route, and must never go out on a shared
/// network: so this runs in a private network namespace (`unshare -n`, with
/// loopback up and 224.0.0.0/4 routed to it, spec §10), re-running this test
/// binary inside it. Where no namespace can be created it says so and passes.
#[test]
fn multicast_inside_a_private_network_namespace() {
    if std::env::var_os("TREEMOCAP_IN_NETNS").is_some() {
        multicast_session();
        return;
    }
    let can = std::process::Command::new("unshare")
        .args(["-n", "true"])
        .status()
        .is_ok_and(|s| s.success());
    if !can {
        eprintln!("SKIPPED: cannot create a network namespace (unshare -n); multicast not tested");
        return;
    }
    let exe = std::env::current_exe().unwrap();
    let out = std::process::Command::new("unshare")
        .args([
            "-n",
            "sh",
            "-c",
            "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo && exec \"$0\" \"$1\" --exact --nocapture",
        ])
        .arg(&exe)
        // This test's full name in the one test binary (`it`).
        .arg(format!(
            "{}::multicast_inside_a_private_network_namespace",
            module_path!().trim_start_matches("it::")
        ))
        .env("TREEMOCAP_IN_NETNS", "1")
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success() && text.contains("1 passed"), "{text}");
}

fn multicast_session() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 11, 80, 30, 100.0);
    let rt = runtime();
    rt.block_on(async {
        // Default ports and group, as Motive: nothing else lives in here.
        for version in [Version::new(2, 9), Version::new(3, 1), Version::new(4, 1)] {
            let stats = Arc::new(ServerStats::default());
            let (server, _stop) = start_server(
                path.clone(),
                ServeOptions {
                    version,
                    speed: 4.0,
                    transport: Transport::Multicast,
                    stats: stats.clone(),
                    ..Default::default()
                },
            );
            command_port(&stats).await;
            // 2.x SERVERINFO does not say multicast: the client listens on both.
            let opts = NatNetSettings {
                interface: Interface::Address("127.0.0.1".parse().unwrap()),
                ..Default::default()
            };
            let (report, got) = collect(opts, sent.len(), Duration::from_secs(20)).await;
            report.unwrap();
            check_session(version, &sent, &got);
            server.await.unwrap().unwrap();
        }
        // A 2.x server on its own group and ports says neither: the
        // client must be told (issue: 0 frames, and still exit 0).
        let (group, data_port) = ("239.1.2.3".parse().unwrap(), free_port());
        let version = Version::new(2, 9);
        let stats = Arc::new(ServerStats::default());
        let (server, _stop) = start_server(
            path.clone(),
            ServeOptions {
                version,
                speed: 4.0,
                transport: Transport::Multicast,
                command_port: 0,
                data_port,
                multicast_group: group,
                stats: stats.clone(),
                ..Default::default()
            },
        );
        let opts = NatNetSettings {
            command_port: command_port(&stats).await,
            transport: TransportSetting::Multicast,
            interface: Interface::Name("lo".into()),
            multicast_group: Some(group),
            data_port: Some(data_port),
            ..Default::default()
        };
        let (report, got) = collect(opts, sent.len(), Duration::from_secs(20)).await;
        report.unwrap();
        check_session(version, &sent, &got);
        server.await.unwrap().unwrap();
    });
    record_on_a_custom_group(&path, sent.len());
}

/// `treemocap record` with the group, data port and interface (by name) on
/// the command line gets every frame; told the wrong group it gets none,
/// says so and exits 1.
fn record_on_a_custom_group(path: &std::path::Path, n: usize) {
    let bin = env!("CARGO_BIN_EXE_treemocap");
    let dir = tempfile::tempdir().unwrap();
    for (group, want) in [("239.1.2.4", Some(n)), ("239.1.2.5", None)] {
        let (cmd, data) = (free_port(), free_port());
        let mut server = std::process::Command::new(bin)
            .args([
                "serve",
                "--multicast",
                "--natnet-version",
                "2.9",
                "--speed",
                "4",
            ])
            .args(["--group", "239.1.2.4", "--interface", "127.0.0.1"])
            .args([
                "--command-port",
                &cmd.to_string(),
                "--data-port",
                &data.to_string(),
            ])
            .arg(path)
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(300));
        let out = dir.path().join(format!("{group}.log.csv"));
        let rec = std::process::Command::new(bin)
            .args([
                "record",
                "--natnet",
                &format!("127.0.0.1:{cmd}"),
                "--multicast",
            ])
            .args([
                "--group",
                group,
                "--data-port",
                &data.to_string(),
                "--interface",
                "lo",
            ])
            .args(["--seconds", "2"])
            .arg(&out)
            .output()
            .unwrap();
        let _ = server.kill();
        let _ = server.wait();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&rec.stdout),
            String::from_utf8_lossy(&rec.stderr)
        );
        match want {
            Some(n) => {
                assert!(rec.status.success(), "{text}");
                let frames = treemocap::app::open::open(&out).unwrap().count();
                assert_eq!(frames, n, "{text}");
            }
            None => {
                assert_eq!(rec.status.code(), Some(1), "{text}");
                assert!(text.contains("no frame came"), "{text}");
                assert!(!out.exists());
            }
        }
    }
}

/// Motive can stream Z up: asked (`up_axis = auto`), the server says so and
/// the client turns the stream Y up; told `y` it takes the axes as they come.
#[test]
fn a_z_up_stream_is_turned_y_up() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 13, 20, 4, 100.0);
    let rt = runtime();
    rt.block_on(async {
        for setting in [UpAxisSetting::Auto, UpAxisSetting::Z, UpAxisSetting::Y] {
            let stats = Arc::new(ServerStats::default());
            let (server, _stop) = start_server(
                path.clone(),
                ServeOptions {
                    up_axis: UpAxis::Z,
                    speed: 4.0,
                    ..loopback_server(&stats)
                },
            );
            let opts = NatNetSettings {
                command_port: command_port(&stats).await,
                up_axis: setting,
                ..Default::default()
            };
            let (report, got) = collect(opts, sent.len(), Duration::from_secs(10)).await;
            report.unwrap();
            server.await.unwrap().unwrap();
            if setting == UpAxisSetting::Y {
                // Taken as it comes: the height is in z.
                let (a, b) = (sent[0].markers[0].position, got[0].markers[0].position);
                assert_eq!(b.z, a.y as f32 as f64, "{a} {b}");
                assert_eq!(b.y, -(a.z as f32) as f64, "{a} {b}");
            } else {
                check_session(Version::new(3, 1), &sent, &got);
            }
        }
    });
}

/// A shipped Motive CSV take (read by `replay::open`) served and received:
/// every frame and marker as the reader produced them, f32 on the wire.
#[test]
fn a_motive_csv_take_is_served_exactly() {
    let path =
        std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/replays/maple-24.csv"));
    let sent: Vec<MarkerFrame> = treemocap::app::open::open(&path)
        .unwrap()
        .collect::<treemocap::Result<_>>()
        .unwrap();
    let rt = runtime();
    rt.block_on(async {
        let stats = Arc::new(ServerStats::default());
        let (server, _stop) = start_server(
            path.clone(),
            ServeOptions {
                version: Version::new(4, 1),
                speed: 40.0,
                bind: "127.0.0.1".parse().unwrap(),
                command_port: 0,
                data_port: 0,
                stats: stats.clone(),
                ..Default::default()
            },
        );
        let opts = NatNetSettings {
            command_port: command_port(&stats).await,
            ..Default::default()
        };
        let (report, got) = collect(opts, sent.len(), Duration::from_secs(30)).await;
        report.unwrap();
        check_session(Version::new(4, 1), &sent, &got);
        server.await.unwrap().unwrap();
    });
}

/// Opt-in discovery: no server address, a DISCOVERY datagram (sent to
/// 127.0.0.1 here instead of a broadcast address) finds the server.
#[test]
fn discovery_finds_the_server() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent) = session(dir.path(), 12, 20, 4, 100.0);
    let rt = runtime();
    rt.block_on(async {
        let stats = Arc::new(ServerStats::default());
        let (server, _stop) = start_server(path, loopback_server(&stats));
        let opts = NatNetSettings {
            discovery: true,
            discovery_address: "127.0.0.1".parse().unwrap(),
            command_port: command_port(&stats).await,
            ..Default::default()
        };
        let (report, got) = collect(opts, sent.len(), Duration::from_secs(10)).await;
        assert!(report.unwrap().server.contains("treemocap"));
        check_session(Version::new(3, 1), &sent, &got);
        server.await.unwrap().unwrap();
    });
}
