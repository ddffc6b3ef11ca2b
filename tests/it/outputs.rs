//! The outputs over real sockets: HTTP fetched by Python's urllib (a client we
//! did not write), the WebSocket by tokio-tungstenite, and a 10 000-node tree
//! sent over OSC to a UDP socket on 127.0.0.1, arriving whole.

use std::net::UdpSocket;
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use glam::DVec3;
use tokio::sync::watch;
use treemocap::protocol::live_frame::{self, LiveFrame, LiveTip, MarkerClass, TipState};
use treemocap::serve::http::{self, HttpState};
use treemocap::serve::live::LiveHub;
use treemocap::serve::osc::{tree_datagrams, OscSender};
use treemocap::serve::snapshot::{SnapshotNode, TreeSnapshot};

fn snapshot(version: u64, nodes: usize) -> TreeSnapshot {
    TreeSnapshot {
        version,
        time_s: 20.0,
        reason: "still phase".into(),
        glb: b"glTF\x02\x00\x00\x00fake".to_vec(),
        tree_json: "{\"nodes\":[]}".into(),
        tips_json: "{\"tips\":[]}".into(),
        nodes: (0..nodes)
            .map(|i| SnapshotNode {
                parent: i.checked_sub(1).map(|p| p as u32),
                position: DVec3::new(i as f64 * 1e-3, 1.0, -0.5),
                radius: 0.01,
            })
            .collect(),
        trees: Vec::new(),
        rig: None,
    }
}

/// `python3 -c` with urllib: the status code and the body.
fn python_http(method: &str, url: &str) -> (u16, Vec<u8>) {
    let (code, _, body) = python_http_headers(method, url);
    (code, body)
}

/// `python3 -c` with urllib: the status code, the headers (lower-case
/// names) and the body.
fn python_http_headers(method: &str, url: &str) -> (u16, Vec<(String, String)>, Vec<u8>) {
    let script = format!(
        "import sys, urllib.request, urllib.error\n\
         req = urllib.request.Request('{url}', method='{method}', data=b'' if '{method}'=='POST' else None)\n\
         try:\n    r = urllib.request.urlopen(req, timeout=10); code, h, body = r.status, r.headers, r.read()\n\
         except urllib.error.HTTPError as e:\n    code, h, body = e.code, e.headers, e.read()\n\
         sys.stdout.write(str(code) + '\\n')\n\
         for k, v in h.items(): sys.stdout.write(k.lower() + ': ' + v + '\\n')\n\
         sys.stdout.write('\\n'); sys.stdout.flush(); sys.stdout.buffer.write(body)\n"
    );
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let end = out.stdout.windows(2).position(|w| w == b"\n\n").unwrap();
    let head = std::str::from_utf8(&out.stdout[..end]).unwrap();
    let mut lines = head.lines();
    let code = lines.next().unwrap().parse().unwrap();
    let headers = lines
        .filter_map(|l| l.split_once(": "))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    (code, headers, out.stdout[end + 2..].to_vec())
}

fn header<'a>(headers: &'a [(String, String)], name: &str) -> Option<&'a str> {
    headers
        .iter()
        .find(|(k, _)| k == name)
        .map(|(_, v)| v.as_str())
}

#[test]
fn http_routes_and_live_websocket() {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let (tree_tx, tree_rx) = watch::channel(None);
    let hub = Arc::new(LiveHub::default());
    let (stop_tx, stop_rx) = watch::channel(false);
    let rebuilds = Arc::new(AtomicUsize::new(0));
    let state = HttpState {
        tree: tree_rx,
        hub: hub.clone(),
        status: Arc::new(|| serde_json::json!({"markers": 24, "tips": 24})),
        metrics: Arc::new(|| {
            "# TYPE treemocap_frames_total counter\ntreemocap_frames_total 42\n".into()
        }),
        rebuild: {
            let r = rebuilds.clone();
            Some(Arc::new(move || {
                r.fetch_add(1, Ordering::SeqCst);
            }))
        },
        shutdown: stop_rx,
    };
    let listener = rt
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let addr = listener.local_addr().unwrap();
    let server = rt.spawn(http::serve(
        listener,
        state,
        treemocap::serve::limits::HttpLimits::default(),
        Arc::default(),
    ));
    let base = format!("http://{addr}");

    // Before the first tree: 404 with a reason.
    let (code, body) = python_http("GET", &format!("{base}/tree.glb"));
    assert_eq!(code, 404);
    assert!(String::from_utf8_lossy(&body).contains("no tree yet"));

    tree_tx.send(Some(Arc::new(snapshot(1, 3)))).unwrap();
    let (code, body) = python_http("GET", &format!("{base}/tree.glb"));
    assert_eq!((code, &body[..4]), (200, &b"glTF"[..]));
    assert_eq!(
        python_http("GET", &format!("{base}/tree.json")).1,
        b"{\"nodes\":[]}"
    );
    assert_eq!(
        python_http("GET", &format!("{base}/tips.json")).1,
        b"{\"tips\":[]}"
    );
    let (code, body) = python_http("GET", &format!("{base}/status"));
    let status: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!((code, status["tips"].as_i64()), (200, Some(24)));
    let (_, body) = python_http("GET", &format!("{base}/metrics"));
    assert!(String::from_utf8_lossy(&body).contains("treemocap_frames_total 42"));
    let (code, _) = python_http("POST", &format!("{base}/rebuild"));
    assert_eq!(code, 202);
    assert_eq!(rebuilds.load(Ordering::SeqCst), 1);
    assert_eq!(python_http("GET", &format!("{base}/nothing")).0, 404);

    // The page and its scripts, and CORS on the GET routes (not on POST).
    let (code, headers, page) = python_http_headers("GET", &format!("{base}/"));
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&page).contains("<title>treemocap live</title>"));
    assert_eq!(header(&headers, "access-control-allow-origin"), Some("*"));
    let (code, headers, js) = python_http_headers("GET", &format!("{base}/web/app.js"));
    assert_eq!(code, 200);
    assert!(header(&headers, "content-type")
        .unwrap()
        .starts_with("text/javascript"));
    assert!(String::from_utf8_lossy(&js).contains("decodeFrame"));
    let (code, headers, _) =
        python_http_headers("GET", &format!("{base}/web/three/three.module.js"));
    assert_eq!(code, 200);
    assert!(header(&headers, "content-type")
        .unwrap()
        .starts_with("text/javascript"));
    assert_eq!(python_http("GET", &format!("{base}/web/nothing.js")).0, 404);
    let (_, headers, _) = python_http_headers("GET", &format!("{base}/tree.glb"));
    assert_eq!(header(&headers, "access-control-allow-origin"), Some("*"));
    assert_eq!(header(&headers, "x-tree-version"), Some("1"));
    let (_, headers, _) = python_http_headers("GET", &format!("{base}/status"));
    assert_eq!(header(&headers, "access-control-allow-origin"), Some("*"));
    let (_, headers, _) = python_http_headers("POST", &format!("{base}/rebuild"));
    assert_eq!(header(&headers, "access-control-allow-origin"), None);

    // WebSocket: hello, the current tree and the status on connect; then
    // frames, thinned to the latest.
    rt.block_on(async {
        let (mut ws, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/live"))
            .await
            .unwrap();
        let mut kinds = Vec::new();
        while kinds.len() < 3 {
            let text = ws.next().await.unwrap().unwrap().into_text().unwrap();
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            if v["type"] == "tree" {
                assert_eq!(v["version"], 1);
            }
            if v["type"] == "status" {
                assert_eq!(v["status"]["tips"], 24);
            }
            kinds.push(v["type"].as_str().unwrap().to_string());
        }
        assert_eq!(kinds, ["hello", "tree", "status"]);
        while !hub.has_viewers() {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        let frame = |f: i64| LiveFrame {
            frame: f,
            time_s: f as f64 * 0.01,
            markers: vec![[0.1, 1.2, 0.3], [0.5, 0.5, 0.5]],
            classes: vec![MarkerClass::Tip, MarkerClass::Noise],
            tips: vec![LiveTip {
                marker: 0,
                state: TipState::Measured,
                position: [0.1, 1.2, 0.3],
            }],
        };
        // 200 frames as fast as the pipeline can publish: the viewer gets a
        // few (at most 60 a second), and the last it gets is the last one.
        for f in 0..200 {
            hub.publish_frame(frame(f));
        }
        let mut got = Vec::new();
        let quiet = Duration::from_millis(300);
        while let Ok(Some(msg)) = tokio::time::timeout(quiet, ws.next()).await {
            let msg = msg.unwrap();
            if msg.is_binary() {
                got.push(live_frame::decode(&msg.into_data()).unwrap());
            }
        }
        assert!(!got.is_empty() && got.len() < 10, "{} frames", got.len());
        assert_eq!(got.last().unwrap(), &frame(199));
        ws.send(tokio_tungstenite::tungstenite::Message::Close(None))
            .await
            .unwrap();

        // The JSON form for scripts: the latest frame at once.
        let (mut ws, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/live?format=json"))
            .await
            .unwrap();
        loop {
            let text = ws.next().await.unwrap().unwrap().into_text().unwrap();
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            if v["type"] == "frame" {
                assert_eq!(v["frame"], 199);
                assert_eq!(v["markers"][0][1].as_f64().unwrap() as f32, 1.2);
                assert_eq!(v["noise"], serde_json::json!([1]));
                assert_eq!(v["tips"][0]["state"], "measured");
                break;
            }
        }
    });

    // Shutdown ends the server promptly.
    stop_tx.send(true).unwrap();
    rt.block_on(async {
        tokio::time::timeout(Duration::from_secs(2), server)
            .await
            .expect("server stops within 2 s")
            .unwrap()
            .unwrap();
    });
}

#[test]
fn a_10000_node_tree_arrives_whole_over_osc() {
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let tree = snapshot(3, 10_000);
    let grams = tree_datagrams(&tree);
    let mut tx = OscSender::new(vec![rx.local_addr().unwrap()]).unwrap();
    let sender = std::thread::spawn(move || {
        tx.send_paced(&grams);
        tx.errors
    });
    let mut seen = vec![false; 10_000];
    let mut ended = false;
    let mut buf = vec![0u8; 65536];
    while !ended {
        let n = rx.recv(&mut buf).expect("datagram before timeout");
        let (_, packet) = rosc::decoder::decode_udp(&buf[..n]).unwrap();
        let rosc::OscPacket::Bundle(b) = packet else {
            panic!("not a bundle")
        };
        for p in b.content {
            let rosc::OscPacket::Message(m) = p else {
                panic!()
            };
            match m.addr.as_str() {
                "/treemocap/tree/node" => {
                    let id = m.args[0].clone().int().unwrap() as usize;
                    let parent = m.args[1].clone().int().unwrap();
                    assert_eq!(parent, id as i32 - 1);
                    assert_eq!(m.args[3].clone().float().unwrap(), 1.0);
                    seen[id] = true;
                }
                "/treemocap/tree/end" => {
                    assert_eq!(m.args[1].clone().int().unwrap(), 10_000);
                    ended = true;
                }
                "/treemocap/tree/begin" => assert_eq!(m.args[0].clone().int().unwrap(), 3),
                other => panic!("unexpected {other}"),
            }
        }
    }
    assert_eq!(sender.join().unwrap(), 0);
    assert!(seen.iter().all(|s| *s), "missing nodes");
}
