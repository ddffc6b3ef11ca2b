//! Datagrams from an attacker on the lab network (issue 11): nesting deep
//! enough to overflow a stack on every OSC port, floods of garbage and of
//! senders outside the allow-list. The daemon must keep running, count each
//! kind on `/status` and `/metrics`, and log a few lines, not one per
//! datagram.

use std::io::{BufRead, BufReader, Read};
use std::net::UdpSocket;
use std::time::Duration;

use rosc::{encoder, OscMessage, OscPacket, OscType};

use crate::common::running::{free_udp, Daemon};

/// The deepest bundle nesting that fits in one UDP datagram: each level is
/// `#bundle\0`, an 8-byte time tag and a 4-byte size (20 bytes), so 65 507
/// bytes hold 3 274 levels around a message. (The "10 000 deep" does
/// not fit in a datagram; arrays do, at 2 bytes a level.)
fn deepest_bundle() -> Vec<u8> {
    let mut inner: Vec<u8> = b"/a\0\0,\0\0\0".to_vec();
    while inner.len() + 20 <= 65_507 {
        let mut b = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
        b.extend_from_slice(&(inner.len() as u32).to_be_bytes());
        b.extend_from_slice(&inner);
        inner = b;
    }
    inner
}

/// One message whose type tags nest `depth` arrays (`,[[[…]]]`).
fn nested_arrays(depth: usize) -> Vec<u8> {
    let mut b = b"/treemocap/rebuild\0\0,".to_vec();
    b.extend(std::iter::repeat_n(b'[', depth));
    b.extend(std::iter::repeat_n(b']', depth));
    b.push(0);
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    b
}

fn message(addr: &str, args: Vec<OscType>) -> Vec<u8> {
    encoder::encode(&OscPacket::Message(OscMessage {
        addr: addr.into(),
        args,
    }))
    .unwrap()
}

/// A `/treemocap/markers` frame with one marker.
fn frame(n: i32) -> Vec<u8> {
    use OscType::{Double, Float, Int};
    message(
        "/treemocap/markers",
        vec![
            Int(n),
            Double(n as f64 / 100.0),
            Float(0.5),
            Float(1.5),
            Float(-0.25),
        ],
    )
}

fn hostile() -> Vec<Vec<u8>> {
    vec![
        deepest_bundle(),
        nested_arrays(10_000),
        nested_arrays(32_000),
    ]
}

fn send_all(to: u16, datagrams: &[Vec<u8>]) {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    for d in datagrams {
        s.send_to(d, ("127.0.0.1", to)).unwrap();
    }
}

/// Sends `n` copies of `datagram` from `from`, paced so that the kernel's
/// receive queue never overflows (a lost datagram would not be counted).
fn flood(from: &str, to: u16, datagram: &[u8], n: usize) {
    let s = UdpSocket::bind((from, 0)).unwrap();
    for i in 0..n {
        s.send_to(datagram, ("127.0.0.1", to)).unwrap();
        if i % 200 == 199 {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

fn bad(status: &serde_json::Value, source: &str, kind: &str) -> u64 {
    status["bad_input"][source][kind]
        .as_u64()
        .unwrap_or(u64::MAX)
}

#[test]
fn nesting_beyond_any_stack_is_refused_on_every_daemon_osc_port() {
    let dir = tempfile::tempdir().unwrap();
    let (osc, control) = (free_udp(), free_udp());
    let mut d = Daemon::start(
        &dir.path().join("out"),
        &[
            "daemon.source=osc".into(),
            format!("osc.bind=127.0.0.1:{osc}"),
            format!("daemon.osc_control=127.0.0.1:{control}"),
        ],
    );
    let datagrams = hostile();
    let levels = deepest_bundle()
        .windows(8)
        .filter(|w| w == b"#bundle\0")
        .count();
    assert_eq!(levels, 3_274);
    send_all(osc, &datagrams);
    send_all(control, &datagrams);
    // Still there, and still working: a frame in, a rebuild request taken.
    send_all(osc, &[frame(1), frame(2)]);
    send_all(control, &[message("/treemocap/rebuild", vec![])]);
    // The control port is its own thread: wait for its count too, not only
    // for the frames (under load its last datagrams were still queued).
    let s = d.wait_status(10, "the frames and the refusals after the attack", |s| {
        s["frames"].as_u64() >= Some(2)
            && bad(s, "osc", "failed_decode") >= 3
            && bad(s, "osc_control", "failed_decode") >= 3
    });
    assert!(d.alive(), "{}", d.log());
    assert_eq!(bad(&s, "osc", "failed_decode"), 3, "{s:#}");
    assert_eq!(bad(&s, "osc_control", "failed_decode"), 3, "{s:#}");
    let (status, log) = d.stop();
    assert!(status.success(), "{status}: {log}");
    assert!(log.contains("nested more than 8 deep"), "{log}");
}

#[test]
fn nesting_beyond_any_stack_is_refused_by_record_osc() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec.log.csv");
    let port = free_udp();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_treemocap"))
        .args([
            "record",
            "--osc",
            &format!("127.0.0.1:{port}"),
            "--seconds",
            "3",
        ])
        .arg(&out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap());
    let mut stdout = String::new();
    while !stdout.contains("listening") {
        assert!(lines.read_line(&mut stdout).unwrap() > 0, "{stdout}");
    }
    send_all(port, &hostile());
    send_all(port, &[frame(7)]);
    lines.read_to_string(&mut stdout).unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("failed_decode 3"), "{stdout}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("\n7,0.07,,0.5,1.5,-0.25\n"), "{text}");
}

/// 20 000 garbage datagrams, 5 000 from a sender outside `osc.allow`,
/// 2 000 at the control port: every one counted by kind on both `/status`
/// and `/metrics`, and the log holds a handful of lines with the counts,
/// not one per datagram.
#[test]
fn floods_are_counted_by_kind_and_logged_in_a_few_lines() {
    let dir = tempfile::tempdir().unwrap();
    let (osc, control) = (free_udp(), free_udp());
    let d = Daemon::start(
        &dir.path().join("out"),
        &[
            "daemon.source=osc".into(),
            format!("osc.bind=127.0.0.1:{osc}"),
            "osc.allow=[\"127.0.0.1\"]".into(),
            format!("daemon.osc_control=127.0.0.1:{control}"),
        ],
    );
    // Sent in bursts, each waited for on /status: a burst larger than the
    // socket's receive buffer would be cut by the kernel on a busy machine,
    // before treemocap sees it.
    let counted = |source: &str, kind: &str, from: &str, port: u16, datagram: &[u8], n: u64| {
        let mut sent = 0;
        while sent < n {
            let burst = (n - sent).min(500);
            flood(from, port, datagram, burst as usize);
            sent += burst;
            d.wait_status(20, "every datagram counted", |s| {
                bad(s, source, kind) >= sent
            });
        }
    };
    counted(
        "osc",
        "failed_decode",
        "127.0.0.1",
        osc,
        b"hello, treemocap",
        20_000,
    );
    counted("osc", "not_allowed", "127.0.0.2", osc, &frame(1), 5_000);
    let wrong = message("/marker", vec![OscType::String("seven".into())]);
    counted("osc", "invalid", "127.0.0.1", osc, &wrong, 1_000);
    counted(
        "osc_control",
        "failed_decode",
        "127.0.0.1",
        control,
        b"not osc",
        2_000,
    );
    let s = d.wait_status(20, "every datagram counted", |_| true);
    assert_eq!(bad(&s, "osc", "failed_decode"), 20_000, "{s:#}");
    assert_eq!(bad(&s, "osc", "not_allowed"), 5_000, "{s:#}");
    assert_eq!(bad(&s, "osc", "invalid"), 1_000, "{s:#}");
    assert_eq!(bad(&s, "osc", "incomplete"), 0, "{s:#}");
    assert_eq!(bad(&s, "osc_control", "failed_decode"), 2_000, "{s:#}");
    let metrics = d.get("/metrics").unwrap();
    for line in [
        "treemocap_bad_input_total{source=\"osc\",kind=\"failed_decode\"} 20000",
        "treemocap_bad_input_total{source=\"osc\",kind=\"not_allowed\"} 5000",
        "treemocap_bad_input_total{source=\"osc\",kind=\"invalid\"} 1000",
        "treemocap_bad_input_total{source=\"osc_control\",kind=\"failed_decode\"} 2000",
    ] {
        assert!(metrics.lines().any(|l| l == line), "{line}\n{metrics}");
    }
    let (status, log) = d.stop();
    assert!(status.success(), "{status}");
    let total = log.lines().filter(|l| l.contains("WARN")).count();
    assert!(total <= 16, "{total} warnings:\n{log}");
    // Each warning written, plus the counts of those held back, is every
    // datagram: nothing is dropped from the account, only from the log.
    for (first, summary, sent) in [
        (
            "osc: garbage from",
            "osc: datagrams that are not OSC: … and ",
            20_000,
        ),
        (
            "osc: dropping datagrams from 127.0.0.2",
            "osc: senders not in osc.allow: … and ",
            5_000,
        ),
        (
            "osc control: from 127.0.0.1",
            "osc control: datagrams that are not OSC: … and ",
            2_000,
        ),
    ] {
        let written = log.lines().filter(|l| l.contains(first)).count() as u64;
        let held: u64 = log
            .lines()
            .filter_map(|l| l.split(summary).nth(1))
            .map(|rest| {
                assert!(rest.ends_with(" more like this in the last 10 s"), "{rest}");
                rest.split(' ').next().unwrap().parse::<u64>().unwrap()
            })
            .sum();
        assert!((1..=3).contains(&written), "{first}: {written}\n{log}");
        assert_eq!(written + held, sent, "{summary}\n{log}");
    }
}
