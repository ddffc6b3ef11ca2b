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

/// What one line from the sensor says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorReading {
    /// Degrees the wind comes from, clockwise from the sensor's 0° mark.
    pub angle_deg: f64,
    /// MWV's reference: relative (`R`) or theoretical/true (`T`); plain lines
    /// carry none. A sensor fixed in the lab makes the two the same.
    pub reference: Option<char>,
    /// Metres per second, converted from the sentence's unit.
    pub speed_m_s: f64,
}

/// Why a line gave no reading. Each kind is counted separately in the status.
#[derive(Debug, Clone, PartialEq)]
pub enum LineError {
    /// `*hh` did not match the XOR of the sentence.
    Checksum { expected: u8, found: String },
    /// A field is missing or not what MWV allows.
    Invalid { field: &'static str, value: String },
    /// MWV status `V`: the sensor itself says the data are not valid.
    NotValid,
    /// Another NMEA sentence (not wind): ignored.
    Other(String),
}

impl std::fmt::Display for LineError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LineError::Checksum { expected, found } => {
                write!(
                    f,
                    "checksum *{found} does not match (computed {expected:02X})"
                )
            }
            LineError::Invalid { field, value } => write!(f, "field {field}: invalid '{value}'"),
            LineError::NotValid => write!(f, "status V (sensor reports data not valid)"),
            LineError::Other(s) => write!(f, "not a wind sentence ({s})"),
        }
    }
}

fn invalid(field: &'static str, value: &str) -> LineError {
    LineError::Invalid {
        field,
        value: value.chars().take(40).collect(),
    }
}

fn parse_angle(s: &str) -> Result<f64, LineError> {
    match s.trim().parse::<f64>() {
        Ok(a) if (0.0..=360.0).contains(&a) => Ok(a % 360.0),
        _ => Err(invalid("angle", s)),
    }
}

fn parse_speed(s: &str) -> Result<f64, LineError> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(invalid("speed", s)),
    }
}

/// Parses one line (without its line end). Empty lines give `Ok(None)`.
pub fn parse_line(line: &str) -> Result<Option<SensorReading>, LineError> {
    let line = line.trim();
    if line.is_empty() {
        return Ok(None);
    }
    if let Some(body) = line.strip_prefix('$') {
        return parse_nmea(body).map(Some);
    }
    let Some((angle, speed)) = line.split_once(',') else {
        return Err(invalid("line", line));
    };
    Ok(Some(SensorReading {
        angle_deg: parse_angle(angle)?,
        reference: None,
        speed_m_s: parse_speed(speed)?,
    }))
}

fn parse_nmea(body: &str) -> Result<SensorReading, LineError> {
    let (data, checksum) = match body.split_once('*') {
        Some((d, c)) => (d, Some(c)),
        None => (body, None),
    };
    // The checksum is optional in NMEA 0183, but when present it must match.
    if let Some(found) = checksum {
        let expected = data.bytes().fold(0u8, |a, b| a ^ b);
        match u8::from_str_radix(found.trim(), 16) {
            Ok(v) if v == expected && found.trim().len() == 2 => {}
            _ => {
                return Err(LineError::Checksum {
                    expected,
                    found: found.trim().chars().take(8).collect(),
                })
            }
        }
    }
    let fields: Vec<&str> = data.split(',').collect();
    let id = fields[0];
    if id.len() != 5 || !id.is_ascii() {
        return Err(invalid("sentence id", id));
    }
    if &id[2..] != "MWV" {
        return Err(LineError::Other(id.to_string()));
    }
    if fields.len() < 6 {
        return Err(invalid("field count", &fields.len().to_string()));
    }
    let angle = parse_angle(fields[1])?;
    let reference = match fields[2] {
        "R" => 'R',
        "T" => 'T',
        other => return Err(invalid("reference", other)),
    };
    let speed = parse_speed(fields[3])?;
    let factor = match fields[4] {
        "M" => 1.0,
        "K" => 1.0 / 3.6,
        "N" => 1852.0 / 3600.0,
        "S" => 0.44704,
        other => return Err(invalid("speed unit", other)),
    };
    match fields[5] {
        "A" => {}
        "V" => return Err(LineError::NotValid),
        other => return Err(invalid("status", other)),
    }
    Ok(SensorReading {
        angle_deg: angle,
        reference: Some(reference),
        speed_m_s: speed * factor,
    })
}

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
        let mut line = Vec::with_capacity(MAX_LINE);
        let mut buf = [0u8; 256];
        let mut line_no = 0u64;
        while !shutdown.load(Ordering::Relaxed) {
            let n = match port.read(&mut buf) {
                Ok(0) => {
                    status.set_error(format!("{}: port closed", opts.port));
                    break;
                }
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    status.set_error(format!("{}: {e}", opts.port));
                    break;
                }
            };
            for &b in &buf[..n] {
                if b != b'\n' {
                    if line.len() < MAX_LINE {
                        line.push(b);
                    }
                    continue;
                }
                line_no += 1;
                let text = String::from_utf8_lossy(&line).into_owned();
                let too_long = line.len() >= MAX_LINE;
                line.clear();
                if too_long {
                    status.invalid.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(
                        "{}: line {line_no}: longer than {MAX_LINE} bytes",
                        opts.port
                    );
                    continue;
                }
                match parse_line(&text) {
                    Ok(Some(r)) => {
                        status.readings.fetch_add(1, Ordering::Relaxed);
                        on_estimate(to_estimate(&r, opts.heading_deg, clock()));
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
                            tracing::warn!("{}: line {line_no}: {e}", opts.port);
                        }
                    }
                }
            }
        }
        status.connected.store(false, Ordering::Relaxed);
        tracing::warn!("wind sensor on {} lost; reconnecting", opts.port);
    }
    status.connected.store(false, Ordering::Relaxed);
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

    fn nmea(body: &str) -> String {
        let cs = body.bytes().fold(0u8, |a, b| a ^ b);
        format!("${body}*{cs:02X}")
    }

    #[test]
    fn mwv_sentences() {
        let r = parse_line(&nmea("WIMWV,270.0,R,10.0,N,A"))
            .unwrap()
            .unwrap();
        assert_eq!(r.angle_deg, 270.0);
        assert_eq!(r.reference, Some('R'));
        assert!((r.speed_m_s - 5.144444).abs() < 1e-5);
        let r = parse_line(&nmea("IIMWV,045,T,36,K,A")).unwrap().unwrap();
        assert!((r.speed_m_s - 10.0).abs() < 1e-12);
        let r = parse_line(&nmea("WIMWV,10,R,4.5,M,A")).unwrap().unwrap();
        assert_eq!(r.speed_m_s, 4.5);
        let r = parse_line(&nmea("WIMWV,10,R,10,S,A")).unwrap().unwrap();
        assert!((r.speed_m_s - 4.4704).abs() < 1e-12);
        // Without a checksum: accepted (NMEA makes it optional for MWV).
        assert!(parse_line("$WIMWV,10,R,4.5,M,A").unwrap().is_some());
    }

    #[test]
    fn bad_sentences_are_told_apart() {
        let good = nmea("WIMWV,270.0,R,10.0,N,A");
        let bad = format!("{}00", &good[..good.len() - 2]);
        assert!(matches!(parse_line(&bad), Err(LineError::Checksum { .. })));
        assert_eq!(
            parse_line(&nmea("WIMWV,270.0,R,10.0,N,V")),
            Err(LineError::NotValid)
        );
        assert!(matches!(
            parse_line(&nmea("WIMWV,400,R,10.0,N,A")),
            Err(LineError::Invalid { field: "angle", .. })
        ));
        assert!(matches!(
            parse_line(&nmea("WIMWV,40,R,10.0,X,A")),
            Err(LineError::Invalid {
                field: "speed unit",
                ..
            })
        ));
        assert!(matches!(
            parse_line(&nmea("WIXDR,C,20,C")),
            Err(LineError::Other(_))
        ));
        assert!(matches!(
            parse_line("garbage"),
            Err(LineError::Invalid { .. })
        ));
        assert!(matches!(parse_line("$"), Err(LineError::Invalid { .. })));
        assert!(matches!(
            parse_line("12,-3"),
            Err(LineError::Invalid { field: "speed", .. })
        ));
    }

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
