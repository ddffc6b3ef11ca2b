//! A wind sensor on a serial port: NMEA 0183 `$--MWV` sentences or plain
//! `angle,speed` lines, read on a blocking thread that reconnects with
//! back-off when the port vanishes (a USB adapter unplugged).
//!
//! Both line kinds give the angle the wind comes *from*, relative to the
//! sensor's 0° mark (the vessel's bow, for a marine sensor).
//! `sensor_heading_deg` says where that mark points in capture coordinates, so
//! downwind azimuth = heading + angle + 180°.

use std::io::Read;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde::Serialize;

use crate::model::wind::{direction_of, WindEstimate, WindSource};
pub use crate::protocol::nmea::{parse_line, LineError, SensorReading};

/// A reading turned into capture coordinates.
pub fn to_estimate(reading: &SensorReading, heading_deg: f64, time_s: f64) -> WindEstimate {
    WindEstimate {
        time_s,
        source: WindSource::Sensor,
        direction: direction_of((heading_deg + reading.angle_deg + 180.0).rem_euclid(360.0)),
        speed_m_s: Some(reading.speed_m_s),
    }
}

/// Where and how to read the sensor.
#[derive(Debug, Clone)]
pub struct SerialOptions {
    /// Device path, e.g. `/dev/ttyUSB0`.
    pub port: String,
    /// Baud rate of the line (NMEA 0183 is 4800).
    pub baud: u32,
    /// Capture azimuth of the sensor's 0° mark (degrees).
    pub heading_deg: f64,
    /// First and longest wait between reconnection attempts.
    pub backoff_min: Duration,
    /// Longest wait between attempts: how late a replugged sensor is seen.
    pub backoff_max: Duration,
}

/// Live counters of the sensor thread, for `/status` and the log.
#[derive(Debug, Default)]
pub struct SerialStatus {
    /// The port is open right now.
    pub connected: AtomicBool,
    /// Lines that gave a wind estimate.
    pub readings: AtomicU64,
    /// NMEA sentences whose checksum did not match; skipped.
    pub bad_checksum: AtomicU64,
    /// Lines with a missing, malformed or unknown field; skipped.
    pub invalid: AtomicU64,
    /// MWV sentences flagged invalid by the sensor itself (status V); skipped.
    pub not_valid: AtomicU64,
    /// Well-formed sentences other than MWV (a multi-sensor's other data).
    pub other_sentences: AtomicU64,
    /// Successful opens after the first one.
    pub reconnects: AtomicU64,
    /// Why the port was last lost or could not be opened.
    pub last_error: Mutex<Option<String>>,
}

/// A copy of [`SerialStatus`] at one instant.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SerialStatusSnapshot {
    /// The device, so `/status` says which sensor it describes.
    pub port: String,
    /// The port was open.
    pub connected: bool,
    /// Lines that gave a wind estimate.
    pub readings: u64,
    /// Sentences with a wrong checksum.
    pub bad_checksum: u64,
    /// Lines with a missing or malformed field.
    pub invalid: u64,
    /// Sentences the sensor flagged invalid (status V).
    pub not_valid: u64,
    /// Sentences other than MWV.
    pub other_sentences: u64,
    /// Successful opens after the first one.
    pub reconnects: u64,
    /// Why the port was last lost or could not be opened.
    pub last_error: Option<String>,
}

impl SerialStatus {
    /// The counters now, for `/status` (each read on its own; they may be
    /// a few lines apart).
    pub fn snapshot(&self, port: &str) -> SerialStatusSnapshot {
        SerialStatusSnapshot {
            port: port.to_string(),
            connected: self.connected.load(Ordering::Relaxed),
            readings: self.readings.load(Ordering::Relaxed),
            bad_checksum: self.bad_checksum.load(Ordering::Relaxed),
            invalid: self.invalid.load(Ordering::Relaxed),
            not_valid: self.not_valid.load(Ordering::Relaxed),
            other_sentences: self.other_sentences.load(Ordering::Relaxed),
            reconnects: self.reconnects.load(Ordering::Relaxed),
            last_error: self.last_error.lock().map(|e| e.clone()).unwrap_or(None),
        }
    }

    fn set_error(&self, msg: String) {
        if let Ok(mut e) = self.last_error.lock() {
            *e = Some(msg);
        }
    }
}

/// Longest line kept while waiting for its end; longer is garbage.
const MAX_LINE: usize = 256;

/// Reads the sensor until `shutdown` is set, calling `on_estimate` for every
/// good reading. Never returns early: a missing or vanished port is retried
/// with back-off and reported in `status`.
pub fn run_blocking(
    opts: &SerialOptions,
    clock: &dyn Fn() -> f64,
    on_estimate: &mut dyn FnMut(WindEstimate),
    status: &SerialStatus,
    shutdown: &AtomicBool,
) {
    let mut backoff = opts.backoff_min;
    let mut opened_before = false;
    let mut lines = LineReader {
        opts,
        clock,
        on_estimate,
        status,
        line: Vec::with_capacity(MAX_LINE),
        line_no: 0,
    };
    while !shutdown.load(Ordering::Relaxed) {
        let port = serialport::new(&opts.port, opts.baud)
            .timeout(Duration::from_millis(100))
            .open();
        let mut port = match port {
            Ok(p) => p,
            Err(e) => {
                status.connected.store(false, Ordering::Relaxed);
                status.set_error(format!("{}: {e}", opts.port));
                sleep_unless(shutdown, backoff);
                backoff = (backoff * 2).min(opts.backoff_max);
                continue;
            }
        };
        if opened_before {
            status.reconnects.fetch_add(1, Ordering::Relaxed);
        }
        opened_before = true;
        backoff = opts.backoff_min;
        status.connected.store(true, Ordering::Relaxed);
        tracing::info!("wind sensor on {} connected", opts.port);
        lines.read_port(&mut *port, shutdown);
        status.connected.store(false, Ordering::Relaxed);
        tracing::warn!("wind sensor on {} lost; reconnecting", opts.port);
    }
    status.connected.store(false, Ordering::Relaxed);
}

/// Splits the port's bytes into lines and turns each into a reading.
struct LineReader<'a> {
    opts: &'a SerialOptions,
    clock: &'a dyn Fn() -> f64,
    on_estimate: &'a mut dyn FnMut(WindEstimate),
    status: &'a SerialStatus,
    /// The line being read; a line longer than `MAX_LINE` is cut and refused.
    line: Vec<u8>,
    /// Lines read on this connection, for the warnings.
    line_no: u64,
}

impl LineReader<'_> {
    /// Reads until the port fails or closes, or the shutdown flag is set
    /// (checked after every read, which times out after 100 ms).
    fn read_port(&mut self, port: &mut dyn Read, shutdown: &AtomicBool) {
        // A new connection starts a new line count, and half a line from
        // before the port was lost is not the start of the next one.
        self.line.clear();
        self.line_no = 0;
        let mut buf = [0u8; 256];
        while !shutdown.load(Ordering::Relaxed) {
            let n = match port.read(&mut buf) {
                Ok(0) => {
                    self.status
                        .set_error(format!("{}: port closed", self.opts.port));
                    return;
                }
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    self.status.set_error(format!("{}: {e}", self.opts.port));
                    return;
                }
            };
            for &b in &buf[..n] {
                if b != b'\n' {
                    if self.line.len() < MAX_LINE {
                        self.line.push(b);
                    }
                    continue;
                }
                self.end_of_line();
            }
        }
    }

    fn end_of_line(&mut self) {
        self.line_no += 1;
        let (port, line_no, status) = (&self.opts.port, self.line_no, self.status);
        let text = String::from_utf8_lossy(&self.line).into_owned();
        let too_long = self.line.len() >= MAX_LINE;
        self.line.clear();
        if too_long {
            status.invalid.fetch_add(1, Ordering::Relaxed);
            tracing::warn!("{port}: line {line_no}: longer than {MAX_LINE} bytes");
            return;
        }
        match parse_line(&text) {
            Ok(Some(r)) => {
                status.readings.fetch_add(1, Ordering::Relaxed);
                (self.on_estimate)(to_estimate(&r, self.opts.heading_deg, (self.clock)()));
            }
            Ok(None) => {}
            Err(e) => {
                let counter = match e {
                    LineError::Checksum { .. } => &status.bad_checksum,
                    LineError::Invalid { .. } => &status.invalid,
                    LineError::NotValid => &status.not_valid,
                    LineError::Other(_) => &status.other_sentences,
                };
                counter.fetch_add(1, Ordering::Relaxed);
                if !matches!(e, LineError::Other(_)) {
                    tracing::warn!("{port}: line {line_no}: {e}");
                }
            }
        }
    }
}

fn sleep_unless(shutdown: &AtomicBool, total: Duration) {
    let step = Duration::from_millis(20);
    let mut left = total;
    while !left.is_zero() && !shutdown.load(Ordering::Relaxed) {
        let d = left.min(step);
        std::thread::sleep(d);
        left -= d;
    }
}

/// Starts [`run_blocking`] on its own thread.
pub fn spawn(
    opts: SerialOptions,
    clock: Arc<dyn Fn() -> f64 + Send + Sync>,
    mut on_estimate: Box<dyn FnMut(WindEstimate) + Send>,
    status: Arc<SerialStatus>,
    shutdown: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    std::thread::Builder::new()
        .name("wind-serial".into())
        .spawn(move || run_blocking(&opts, &*clock, &mut *on_estimate, &status, &shutdown))
        .expect("spawn wind sensor thread")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plain_lines_and_heading() {
        let r = parse_line("90,3.5").unwrap().unwrap();
        assert_eq!((r.angle_deg, r.speed_m_s), (90.0, 3.5));
        // Wind from the sensor's 90° mark; the mark points to capture azimuth 0:
        // it comes from azimuth 90 and blows towards 270.
        let e = to_estimate(&r, 0.0, 1.0);
        assert!((e.azimuth_deg() - 270.0).abs() < 1e-9);
        let e = to_estimate(&r, 100.0, 1.0);
        assert!((e.azimuth_deg() - 10.0).abs() < 1e-9);
    }
}
