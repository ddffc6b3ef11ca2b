//! The daemon's HTTP server under hostile clients (issue 11): silent and
//! slowloris connections are closed after the header timeout, a flood
//! beyond the connection cap cannot lock a user out of `/status`, clients
//! outside `daemon.http_allow` get 403, and `POST /rebuild` from a page of
//! another site is refused. The full loads (thousands of connections) are
//! in `examples/hostile.rs`; this runs a few hundred.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use crate::common::running::Daemon;

/// A TCP connection to `to` from the local address `from`.
fn connect_from(from: &str, to: SocketAddr) -> TcpStream {
    use socket2::{Domain, Socket, Type};
    let s = Socket::new(Domain::IPV4, Type::STREAM, None).unwrap();
    s.bind(&SocketAddr::new(from.parse().unwrap(), 0).into())
        .unwrap();
    s.connect(&to.into()).unwrap();
    s.into()
}

/// Sends a raw request and reads the whole answer (the server closes).
fn ask(mut s: TcpStream, request: &str) -> String {
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut answer = Vec::new();
    let _ = s.read_to_end(&mut answer);
    String::from_utf8_lossy(&answer).into_owned()
}

/// True once the server has closed `s` (a read returns end of file or an
/// error rather than timing out).
fn closed_by_server(s: &TcpStream) -> bool {
    s.set_read_timeout(Some(Duration::from_millis(20))).unwrap();
    let mut b = [0u8; 256];
    let mut s = s;
    loop {
        match s.read(&mut b) {
            Ok(0) => return true,
            Ok(_) => continue, // a 408 or similar before the close
            Err(e)
                if e.kind() == std::io::ErrorKind::WouldBlock
                    || e.kind() == std::io::ErrorKind::TimedOut =>
            {
                return false
            }
            Err(_) => return true,
        }
    }
}

#[test]
fn slowloris_and_idle_floods_are_cut_and_status_still_answers() {
    let dir = tempfile::tempdir().unwrap();
    let d = Daemon::start(
        &dir.path().join("out"),
        &[
            "daemon.http_header_timeout_s=1".into(),
            "daemon.http_idle_timeout_s=2".into(),
            "daemon.http_max_connections=100".into(),
        ],
    );
    // 150 connections that never send anything, 150 that send a header
    // line every 200 ms and never finish: three times the cap.
    let silent: Vec<TcpStream> = (0..150)
        .map(|_| TcpStream::connect(d.http).unwrap())
        .collect();
    let slow: Vec<TcpStream> = (0..150)
        .map(|_| {
            let mut s = TcpStream::connect(d.http).unwrap();
            let _ = s.write_all(b"GET /status HTTP/1.1\r\nHost: x\r\n");
            s
        })
        .collect();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let trickle = {
        let mut socks: Vec<TcpStream> = slow.iter().map(|s| s.try_clone().unwrap()).collect();
        let stop = stop.clone();
        std::thread::spawn(move || {
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                for s in &mut socks {
                    let _ = s.write_all(b"X-Slow: 1\r\n");
                }
                std::thread::sleep(Duration::from_millis(200));
            }
        })
    };

    // /status answers while they hang on.
    let mut ms = Vec::new();
    for _ in 0..20 {
        let t0 = Instant::now();
        let body = d.get("/status").expect("/status under load");
        ms.push(t0.elapsed().as_secs_f64() * 1000.0);
        assert!(body.contains("\"bad_input\""));
        std::thread::sleep(Duration::from_millis(50));
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "/status under 300 hostile connections: median {:.1} ms, max {:.1} ms",
        ms[10], ms[19]
    );
    assert!(ms[10] < 100.0, "median {} ms", ms[10]);
    assert!(ms[19] < 1000.0, "max {} ms", ms[19]);

    // After the header timeout every one of them has been closed.
    std::thread::sleep(Duration::from_millis(1500));
    let open_silent = silent.iter().filter(|s| !closed_by_server(s)).count();
    let open_slow = slow.iter().filter(|s| !closed_by_server(s)).count();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    trickle.join().unwrap();
    assert_eq!((open_silent, open_slow), (0, 0), "{}", d.log());
    let s = d.status();
    let incomplete = s["bad_input"]["http"]["incomplete"].as_u64().unwrap();
    assert!(incomplete >= 290, "{s:#}");

    // A keep-alive connection that goes quiet after its answer is closed too.
    let mut keep = TcpStream::connect(d.http).unwrap();
    keep.write_all(b"GET /status HTTP/1.1\r\nHost: x\r\n\r\n")
        .unwrap();
    let mut first = [0u8; 12];
    keep.read_exact(&mut first).unwrap();
    assert_eq!(&first, b"HTTP/1.1 200");
    std::thread::sleep(Duration::from_millis(1500));
    assert!(closed_by_server(&keep), "idle keep-alive still open");
}

#[test]
fn clients_outside_the_allow_list_and_cross_site_posts_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = Daemon::start(
        &dir.path().join("out"),
        &["daemon.http_allow=[\"127.0.0.1\"]".into()],
    );
    let get = "GET /status HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
    let post =
        "POST /rebuild HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\nConnection: close\r\n\r\n";
    for request in [get, post] {
        let answer = ask(connect_from("127.0.0.2", d.http), request);
        assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
        assert!(answer.contains("not in daemon.http_allow"), "{answer}");
    }
    // From an allowed address: a page of another site may not POST...
    let host = d.http.to_string();
    let cross = format!(
        "POST /rebuild HTTP/1.1\r\nHost: {host}\r\nOrigin: http://evil.example\r\n\
         Content-Length: 0\r\nConnection: close\r\n\r\n"
    );
    let answer = ask(connect_from("127.0.0.1", d.http), &cross);
    assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
    // ...our own page, a script or curl may.
    let own = cross.replace("http://evil.example", &format!("http://{host}"));
    let answer = ask(connect_from("127.0.0.1", d.http), &own);
    assert!(answer.starts_with("HTTP/1.1 202"), "{answer}");
    let answer = ask(connect_from("127.0.0.1", d.http), post);
    assert!(answer.starts_with("HTTP/1.1 202"), "{answer}");

    let s = d.status();
    assert_eq!(s["bad_input"]["http"]["not_allowed"], 2, "{s:#}");
    let (_, log) = d.stop();
    assert!(log.contains("not in daemon.http_allow"), "{log}");
}
