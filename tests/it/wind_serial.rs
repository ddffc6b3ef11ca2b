//! A wind sensor on a serial port, played by a pseudo-terminal pair: good and
//! bad NMEA sentences, plain lines and garbage, then the adapter unplugged and
//! plugged back in. The wind log and the status counters must agree with what
//! was sent.

use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};
use treemocap::daemon::wind_log::WindLog;
use treemocap::model::wind::WindEstimate;
use treemocap::source::wind_sensor::{spawn, SerialOptions, SerialStatus};

fn nmea(body: &str) -> String {
    let cs = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{cs:02X}\r\n")
}

/// A pseudo-terminal pair whose slave is reachable under a fixed path, as a
/// udev rule gives a USB adapter a stable name.
struct FakeSensor {
    master: TTYPort,
    _slave: TTYPort,
}

fn plug_in(link: &std::path::Path) -> FakeSensor {
    let (master, slave) = TTYPort::pair().expect("open a pseudo-terminal pair");
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(slave.name().unwrap(), link).unwrap();
    FakeSensor {
        master,
        _slave: slave,
    }
}

fn wait_for(what: &str, mut cond: impl FnMut() -> bool) {
    let start = Instant::now();
    while !cond() {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "timed out waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn sensor_lines_unplug_and_replug() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("ttyWIND");
    let mut sensor = plug_in(&link);

    let status = Arc::new(SerialStatus::default());
    let shutdown = Arc::new(AtomicBool::new(false));
    let got: Arc<Mutex<Vec<WindEstimate>>> = Arc::default();
    let log_path = dir.path().join("wind.csv");
    let log = Arc::new(Mutex::new(WindLog::create(&log_path).unwrap()));
    let start = Instant::now();
    let handle = spawn(
        SerialOptions {
            port: link.to_str().unwrap().into(),
            baud: 4800,
            heading_deg: 0.0,
            backoff_min: Duration::from_millis(20),
            backoff_max: Duration::from_millis(200),
        },
        Arc::new(move || start.elapsed().as_secs_f64()),
        {
            let got = got.clone();
            let log = log.clone();
            Box::new(move |e| {
                log.lock().unwrap().write(&e).unwrap();
                got.lock().unwrap().push(e);
            })
        },
        status.clone(),
        shutdown.clone(),
    );
    wait_for("connection", || status.connected.load(Ordering::Relaxed));

    let good = nmea("WIMWV,090.0,R,10.0,M,A");
    let mut corrupt = nmea("WIMWV,180.0,R,10.0,M,A");
    corrupt.replace_range(8..9, "7"); // the checksum no longer matches
    let lines = [
        good.clone(),
        corrupt,
        nmea("WIMWV,090.0,R,10.0,M,V"),
        nmea("WIXDR,C,21.5,C,TEMP"),
        "0,2.5\n".to_string(),
        "\u{1}\u{2}garbage\u{ff}\n".to_string(),
        nmea("IIMWV,270,T,36.0,K,A"),
    ];
    for l in &lines {
        sensor.master.write_all(l.as_bytes()).unwrap();
    }
    sensor.master.flush().unwrap();
    wait_for("three readings", || got.lock().unwrap().len() == 3);
    wait_for("garbage counted", || {
        status.invalid.load(Ordering::Relaxed) == 1
    });
    let s = status.snapshot("ttyWIND");
    assert_eq!(
        (s.readings, s.bad_checksum, s.not_valid, s.other_sentences),
        (3, 1, 1, 1)
    );

    // From 90° → blows towards 270°; from 0° → towards 180°; from 270° → towards 90°.
    let az: Vec<f64> = got
        .lock()
        .unwrap()
        .iter()
        .map(|e| e.azimuth_deg())
        .collect();
    for (a, want) in az.iter().zip([270.0, 180.0, 90.0]) {
        assert!((a - want).abs() < 1e-9, "{az:?}");
    }
    let speeds: Vec<f64> = got
        .lock()
        .unwrap()
        .iter()
        .map(|e| e.speed_m_s.unwrap())
        .collect();
    assert_eq!(speeds, [10.0, 2.5, 10.0]);

    // Unplug: the port vanishes.
    drop(sensor);
    std::fs::remove_file(&link).unwrap();
    wait_for("disconnect", || !status.connected.load(Ordering::Relaxed));
    assert!(status.snapshot("ttyWIND").last_error.is_some());
    std::thread::sleep(Duration::from_millis(300)); // several failed attempts

    // Replug: a new device under the same name.
    let mut sensor = plug_in(&link);
    wait_for("reconnection", || status.connected.load(Ordering::Relaxed));
    sensor.master.write_all(good.as_bytes()).unwrap();
    wait_for("reading after replug", || got.lock().unwrap().len() == 4);
    assert_eq!(status.snapshot("ttyWIND").reconnects, 1);

    shutdown.store(true, Ordering::Relaxed);
    handle.join().unwrap();

    // The wind log holds exactly the four readings, in order.
    let text = std::fs::read_to_string(&log_path).unwrap();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 4, "{text}");
    let logged: Vec<f64> = rows.iter().map(|r| r[2].parse().unwrap()).collect();
    assert_eq!(logged, [270.0, 180.0, 90.0, 270.0]);
    assert!(rows.iter().all(|r| r[1] == "sensor"));
    assert_eq!(rows[1][6], "2.500");
}
