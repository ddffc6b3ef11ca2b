//! The wind sensor's line protocol: NMEA 0183 `$--MWV` sentences (wind
//! speed and angle) and plain `angle_deg,speed_m_s` lines. Pure: a line of
//! text in, a reading or the reason there is none out.
//!
//! Both line kinds give the angle the wind comes *from*, relative to the
//! sensor's 0° mark (the vessel's bow, for a marine sensor).

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
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LineError {
    /// `*hh` did not match the XOR of the sentence.
    #[error("checksum *{found} does not match (computed {expected:02X})")]
    Checksum {
        /// The XOR of the sentence's characters.
        expected: u8,
        /// The checksum the sentence carries (at most 8 characters of it).
        found: String,
    },
    /// A field is missing or not what MWV allows.
    #[error("field {field}: invalid '{value}'")]
    Invalid {
        /// Which field.
        field: &'static str,
        /// Its text (at most 40 characters of it).
        value: String,
    },
    /// MWV status `V`: the sensor itself says the data are not valid.
    #[error("status V (sensor reports data not valid)")]
    NotValid,
    /// Another NMEA sentence (not wind): ignored.
    #[error("not a wind sentence ({0})")]
    Other(String),
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
}
