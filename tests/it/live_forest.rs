//! Several trees sway live: `treemocap run` fed `replays/forest-3.csv`
//! (three trees, 8 s still then 10 s of wind) frame by frame over OSC. Every
//! tree gets its own pose events on `/live` (`tree_id`, `name`) and its own
//! `/treemocap/pose` datagrams (ending in the tree id); in each, the tree's
//! captured tips are displaced to the live tips the daemon sent over OSC for
//! that frame (within 1 mm); the live page loads the rigged forest and
//! sways every tree's tip joints. The one-tree messages are checked in
//! `live_view` (unchanged: no tree id).

use std::collections::HashMap;
use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rosc::{OscPacket, OscType};
use serde_json::Value;
use treemocap::config::Config;
use treemocap::model::frame::MarkerFrame;

use super::live_view::{
    free_port, http_get, listen_for_poses, osc_frame, root, status, Killed, Page, REAL_TIME_PAGE,
};

/// `/live` pose events by (tree version, tree id, frame): (name, d in µm).
type Poses = Arc<Mutex<HashMap<(u64, u64, i64), (String, Vec<i64>)>>>;

/// What the daemon sent over OSC: the live tips by frame (marker →
/// position) and the pose datagrams by (frame, tree id) (node → d, m).
#[derive(Default)]
struct OscOut {
    tips: HashMap<i64, HashMap<usize, [f64; 3]>>,
    poses: HashMap<(i64, i32), HashMap<usize, [f64; 3]>>,
}

/// One tree of the forest as `/trees/{id}.json` gives it: its captured
/// tips (marker, node, rest position).
type TreeTips = Vec<(usize, usize, [f64; 3])>;

fn forest_frames() -> Vec<MarkerFrame> {
    let config = Config::load(None, &[]).unwrap();
    treemocap::app::open::open_recording(&root().join("replays/forest-3.csv"), &config)
        .unwrap()
        .collect::<treemocap::Result<Vec<_>>>()
        .unwrap()
}

/// Every pose event of every tree: (tree version, tree id, frame) → (name, µm).
fn listen_to_poses(http_port: u16, stop: Arc<AtomicBool>) -> (Poses, JoinHandle<()>) {
    let poses: Poses = Arc::default();
    let keep = poses.clone();
    let thread = listen_for_poses(http_port, stop, move |v, d| {
        let key = (
            v["tree"].as_u64().unwrap(),
            v["tree_id"].as_u64().expect("a tree id in every pose"),
            v["frame"].as_i64().unwrap(),
        );
        let name = v["name"].as_str().expect("a name").to_string();
        keep.lock().unwrap().insert(key, (name, d));
    });
    (poses, thread)
}

/// Float arguments `[at, at + 3)` as a point.
fn xyz(args: &[OscType], at: usize) -> [f64; 3] {
    [0, 1, 2].map(|k| f64::from(args[at + k].clone().float().unwrap()))
}

/// Keeps the daemon's `/treemocap/tips` and `/treemocap/pose` until `stop`.
fn listen_to_osc(sock: UdpSocket, stop: Arc<AtomicBool>) -> (Arc<Mutex<OscOut>>, JoinHandle<()>) {
    let out: Arc<Mutex<OscOut>> = Arc::default();
    let keep = out.clone();
    sock.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let thread = std::thread::spawn(move || {
        let mut buf = vec![0u8; 65536];
        while !stop.load(Ordering::Relaxed) {
            let Ok(n) = sock.recv(&mut buf) else { continue };
            let Ok((_, OscPacket::Message(m))) = rosc::decoder::decode_udp(&buf[..n]) else {
                continue; // the tree's bundles
            };
            let a = &m.args;
            let mut o = keep.lock().unwrap();
            match m.addr.as_str() {
                "/treemocap/tips" => {
                    let frame = i64::from(a[0].clone().int().unwrap());
                    let tips = (2..a.len()).step_by(4).map(|k| {
                        let marker = a[k].clone().int().unwrap() as usize;
                        (marker, xyz(a, k + 1))
                    });
                    o.tips.insert(frame, tips.collect());
                }
                "/treemocap/pose" => {
                    let frame = i64::from(a[1].clone().int().unwrap());
                    let first = a[3].clone().int().unwrap() as usize;
                    let count = a[4].clone().int().unwrap() as usize;
                    assert_eq!(
                        a.len(),
                        6 + 3 * count,
                        "a forest pose ends with its tree id"
                    );
                    let tree = a[5 + 3 * count].clone().int().unwrap();
                    let nodes = o.poses.entry((frame, tree)).or_default();
                    for j in 0..count {
                        nodes.insert(first + j, xyz(a, 5 + 3 * j));
                    }
                }
                _ => {}
            }
        }
    });
    (out, thread)
}

/// The current tree version and every tree's name and captured tips, read
/// while that version stays current.
fn forest_tips(base: &str) -> (u64, HashMap<u64, (String, TreeTips)>) {
    loop {
        let version = status(base)["tree_version"].as_u64().unwrap();
        let (code, body) = http_get(&format!("{base}/trees"));
        assert_eq!(code, 200);
        let list: Value = serde_json::from_slice(&body).unwrap();
        let list = list
            .as_array()
            .or_else(|| list["trees"].as_array())
            .unwrap()
            .clone();
        let mut trees = HashMap::new();
        for t in &list {
            let id = t["id"].as_u64().unwrap();
            let (code, body) = http_get(&format!("{base}/trees/{id}.json"));
            assert_eq!(code, 200);
            let j: Value = serde_json::from_slice(&body).unwrap();
            let nodes = j["nodes"].as_array().unwrap();
            let tips = j["markers"]
                .as_array()
                .unwrap()
                .iter()
                .enumerate()
                .filter_map(|(i, m)| {
                    let p = &nodes[i];
                    Some((
                        m.as_u64()? as usize,
                        i,
                        [0, 1, 2].map(|k| p[k].as_f64().unwrap()),
                    ))
                })
                .collect();
            let name = t["name"].as_str().unwrap().to_string();
            trees.insert(id, (name, tips));
        }
        if status(base)["tree_version"].as_u64() == Some(version) {
            return (version, trees);
        }
    }
}

/// Every tree's rest tips per tree version seen so far.
type Rests = HashMap<u64, HashMap<u64, (String, TreeTips)>>;

/// Largest distance (m) between a pose's captured tips (rest + d) and the
/// live tips of its frame, and how many tips were compared.
fn tips_vs_live(
    tips: &TreeTips,
    d: impl Fn(usize) -> [f64; 3],
    live: &HashMap<usize, [f64; 3]>,
) -> (f64, usize) {
    let mut worst: f64 = 0.0;
    let mut n = 0;
    for (marker, node, rest) in tips {
        let Some(p) = live.get(marker) else { continue };
        let d = d(*node);
        let e = (0..3)
            .map(|k| (rest[k] + d[k] - p[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        worst = worst.max(e);
        n += 1;
    }
    (worst, n)
}

/// The daemon on the forest replay, over OSC in and out and HTTP.
fn start(out: &std::path::Path, osc_in: u16, osc_out: u16, http: u16) -> Killed {
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .arg("run")
        .arg("--out")
        .arg(out)
        .args(["--set", "daemon.source=osc", "--set"])
        .arg(format!("osc.bind=127.0.0.1:{osc_in}"))
        .arg("--set")
        .arg(format!("daemon.http=127.0.0.1:{http}"))
        .arg("--set")
        .arg(format!("daemon.osc_targets=[\"127.0.0.1:{osc_out}\"]"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let daemon = Killed(child);
    let start = Instant::now();
    while http_get(&format!("http://127.0.0.1:{http}/status")).0 != 200 {
        assert!(start.elapsed() < Duration::from_secs(30), "no daemon");
        std::thread::sleep(Duration::from_millis(100));
    }
    daemon
}

#[test]
fn every_tree_of_a_forest_sways_live_with_its_own_tips() {
    let _one_at_a_time = REAL_TIME_PAGE.lock().unwrap_or_else(|e| e.into_inner());
    let out_dir = tempfile::tempdir().unwrap();
    let (osc_in, http_port) = (free_port(true), free_port(false));
    let osc_out = UdpSocket::bind("127.0.0.1:0").unwrap();
    let out_port = osc_out.local_addr().unwrap().port();
    let base = format!("http://127.0.0.1:{http_port}");
    let _daemon = start(out_dir.path(), osc_in, out_port, http_port);
    let stop = Arc::new(AtomicBool::new(false));
    let (osc, osc_thread) = listen_to_osc(osc_out, stop.clone());
    let (poses, ws_thread) = listen_to_poses(http_port, stop.clone());
    let frames = forest_frames();
    let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
    let send = |f: &MarkerFrame| {
        sock.send_to(&osc_frame(f), ("127.0.0.1", osc_in)).unwrap();
    };
    // The still phase (8 s) at 4× speed, then the first forest (built in
    // seconds on a busy machine); a few more still frames if the analysis
    // waits for them.
    for f in &frames[..400] {
        send(f);
        std::thread::sleep(Duration::from_millis(5));
    }
    let mut next = 400;
    let start = Instant::now();
    while status(&base)["trees"].as_u64() == Some(0) {
        assert!(start.elapsed() < Duration::from_secs(90), "no tree");
        std::thread::sleep(Duration::from_millis(500));
        if start.elapsed() > Duration::from_secs(5) && next < 440 {
            send(&frames[next]);
            next += 1;
        }
    }
    let mut page = Page::open(&format!("{base}/"));
    let mut rests = Rests::new();
    let (version, trees) = forest_tips(&base);
    assert_eq!(trees.len(), 3, "{trees:?}");
    rests.insert(version, trees);
    let loaded = format!("treemocap.tree?.version >= {version}");
    assert!(page.wait(&loaded, 30_000).is_some(), "{}", page.state());
    // The wind phase in real time (20 ms a frame) while the page is probed.
    let sending = frames[next..].to_vec();
    let sender = std::thread::spawn(move || {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        for f in &sending {
            s.send_to(&osc_frame(f), ("127.0.0.1", osc_in)).unwrap();
            std::thread::sleep(Duration::from_millis(20));
        }
    });
    let mut probes = Vec::new();
    // Often: the page and this test are two viewers, each sent the latest
    // pose when it is ready for one, so under load they see different
    // frames and only some probes name a frame this test received too.
    while !sender.is_finished() {
        std::thread::sleep(Duration::from_millis(50));
        let v = page.eval("treemocap.swayProbe()");
        // The wind may rebuild the forest: each version's tips are read
        // while it is current.
        let current = status(&base)["tree_version"].as_u64().unwrap();
        if !rests.contains_key(&current) {
            let (version, trees) = forest_tips(&base);
            rests.entry(version).or_insert(trees);
        }
        if !v["pose"].is_null() {
            probes.push(v);
        }
    }
    sender.join().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    stop.store(true, Ordering::Relaxed);
    ws_thread.join().unwrap();
    osc_thread.join().unwrap();
    let poses = poses.lock().unwrap().clone();
    let osc = std::mem::take(&mut *osc.lock().unwrap());
    check_poses(&rests, &poses, &osc);
    check_page(&rests, &poses, &osc, &probes);
    assert_eq!(page.errors(), serde_json::json!([]), "console errors");
}

/// Every tree of every version seen has pose events on `/live` and over
/// OSC, its tips where the live tips are.
fn check_poses(rests: &Rests, poses: &HashMap<(u64, u64, i64), (String, Vec<i64>)>, osc: &OscOut) {
    let mut checked = 0;
    for (&version, trees) in rests {
        for (&id, (name, tips)) in trees {
            let mine: Vec<_> = poses
                .iter()
                .filter(|((v, t, _), _)| *v == version && *t == id)
                .collect();
            if mine.is_empty() {
                continue;
            }
            let (mut worst, mut compared, mut moved) = (0.0f64, 0, 0.0f64);
            let mut osc_whole = 0;
            for ((_, _, frame), (n, d)) in &mine {
                assert_eq!(n, name);
                let Some(live) = osc.tips.get(frame) else {
                    continue;
                };
                let um = |node: usize| [0, 1, 2].map(|k| d[3 * node + k] as f64 * 1e-6);
                let (w, c) = tips_vs_live(tips, um, live);
                worst = worst.max(w);
                compared += c;
                for (_, node, _) in tips {
                    moved = moved.max(um(*node).iter().map(|x| x * x).sum::<f64>().sqrt());
                }
                // The OSC pose of the same frame and tree says the same (UDP
                // under load may lose a datagram of it: what came is checked).
                if let Some(o) = osc.poses.get(&(*frame, id as i32)) {
                    osc_whole += usize::from(o.len() * 3 == d.len());
                    for (node, x) in o {
                        assert!(3 * node < d.len(), "tree {id}: OSC node {node}");
                        for k in 0..3 {
                            let ws = d[3 * node + k] as f64 * 1e-6;
                            assert!((x[k] - ws).abs() < 2e-6, "tree {id} node {node}: {x:?}");
                        }
                    }
                }
            }
            eprintln!(
                "forest sway: tree {id} ({name}) v{version}: {} poses ({osc_whole} whole over OSC), {compared} tips compared, worst {:.4} mm, largest tip displacement {:.1} mm",
                mine.len(),
                worst * 1e3,
                moved * 1e3
            );
            assert!(
                worst < 1e-3,
                "tree {id}: a tip {:.3} mm from the live tip",
                worst * 1e3
            );
            assert!(compared > 0, "tree {id}: no tip compared");
            assert!(osc_whole > 0, "tree {id}: no whole pose over OSC");
            checked += 1;
        }
    }
    let last = rests.keys().max().unwrap();
    assert!(checked >= rests[last].len(), "poses for {checked} trees");
}

/// The page's tip joints of every tree at rest + the displacement of the
/// pose it shows for that tree (1 mm), for every tree at least once.
fn check_page(
    rests: &Rests,
    poses: &HashMap<(u64, u64, i64), (String, Vec<i64>)>,
    osc: &OscOut,
    probes: &[Value],
) {
    let mut shown: HashMap<String, usize> = HashMap::new();
    // Each tree version's node count, from any of its WebSocket poses.
    let nodes: HashMap<(u64, u64), usize> = poses
        .iter()
        .map(|(&(version, id, _), (_, d))| ((version, id), d.len() / 3))
        .collect();
    for p in probes {
        let Some(trees) = p["tree"].as_u64().and_then(|v| rests.get(&v)) else {
            continue;
        };
        let version = p["tree"].as_u64().unwrap();
        for (&id, (name, tips)) in trees {
            let Some(frame) = p["frames"][name].as_i64() else {
                continue;
            };
            // The pose this test got over WebSocket for that frame, or else
            // its whole OSC pose (sent for every frame due, never thinned)
            // when it has as many nodes as this tree's version.
            let from_osc = || {
                let n = *nodes.get(&(version, id))?;
                let o = osc.poses.get(&(frame, id as i32))?;
                (o.len() == n).then(|| {
                    (0..n)
                        .flat_map(|node| o[&node].map(|x| (x * 1e6).round() as i64))
                        .collect::<Vec<i64>>()
                })
            };
            let Some(d) = poses
                .get(&(version, id, frame))
                .map(|(_, d)| d.clone())
                .or_else(from_osc)
            else {
                continue;
            };
            for (marker, node, rest) in tips {
                let joint = &p["tips"][format!("tip_{marker:02}")];
                let at = [0, 1, 2].map(|k| joint[k].as_f64().unwrap());
                let e = (0..3)
                    .map(|k| (rest[k] + d[3 * node + k] as f64 * 1e-6 - at[k]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                assert!(
                    e < 1e-3,
                    "page: tree {name} tip {marker} {:.3} mm from its pose",
                    e * 1e3
                );
            }
            *shown.entry(name.clone()).or_default() += 1;
        }
    }
    eprintln!("forest sway on the page: probes matched per tree {shown:?}");
    assert_eq!(
        shown.len(),
        3,
        "every tree swayed on the page: {shown:?}; {} probes, the last {:?}",
        probes.len(),
        probes.last().map(|p| (
            &p["pose"],
            &p["frames"],
            &p["tree"],
            p["tips"].as_object().map(|t| t.len())
        ))
    );
}
