//! Where the frames are and how to read them: the header and parameters
//! reconciled into one description of the data section (spec/c3d.md §1).
//!
//! Real files disagree with themselves in known ways, so each field has a
//! rule for which source wins:
//! - points per frame: POINT:USED of any numeric type, else header word 2;
//! - scale and storage: POINT:SCALE, else the header float; negative = float;
//! - data start: header word 9, else POINT:DATA_START (Motive writes 0 there);
//! - frame count: the header's last − first + 1 unless a parameter
//!   (TRIAL:ACTUAL_END_FIELD, POINT:LONG_FRAMES, POINT:FRAMES) needs more
//!   than the header's 16 bits can say;
//! - analog values per frame: ANALOG:USED × (ANALOG:RATE / POINT:RATE) when
//!   that is a whole number, else ANALOG:USED × header word 10, else word 3.

use super::header::{Header, BLOCK};
use super::params::Params;
use super::processor::Processor;
use super::{FormatError, UpAxis};

/// How the point words of a frame are stored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Storage {
    /// int16 × scale (the scale is |POINT:SCALE|, in file units).
    Int16 {
        /// |POINT:SCALE|: file units per integer step.
        scale: f64,
    },
    /// float32, already in file units.
    Float32,
}

impl Storage {
    /// Bytes per coordinate or residual word: 2 for int16, 4 for float32.
    pub fn word_bytes(self) -> usize {
        match self {
            Storage::Int16 { .. } => 2,
            Storage::Float32 => 4,
        }
    }

    /// The storage's name in `inspect` and in error messages.
    pub fn name(self) -> &'static str {
        match self {
            Storage::Int16 { .. } => "int16",
            Storage::Float32 => "float32",
        }
    }
}

/// Everything needed to stream the frames of one file.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Byte order and float format (parameter-section byte 3).
    pub processor: Processor,
    /// int16 × scale or float32 (sign of POINT:SCALE).
    pub storage: Storage,
    /// Points per frame (POINT:USED).
    pub points: usize,
    /// Analog values per frame, over all channels; read past, never decoded.
    pub analog_values: usize,
    /// Byte offset of the first frame.
    pub data_offset: u64,
    /// Bytes per frame: points × 4 words + analog values.
    pub frame_bytes: usize,
    /// Frame number of the first frame.
    pub first_frame: i64,
    /// Frames the file declares.
    pub frames: u64,
    /// Frames per second.
    pub rate: f64,
    /// POINT:UNITS as written.
    pub units: String,
    /// File units to metres.
    pub metres_per_unit: f64,
    /// The file's up axis (frames are rotated to Y up).
    pub up: UpAxis,
    /// One name per point (POINT:LABELS, LABELS2, …; "Point i" where missing).
    pub labels: Vec<String>,
    /// MANUFACTURER:SOFTWARE (or COMPANY), when present.
    pub software: Option<String>,
}

/// What the caller asks about the up axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpChoice {
    /// From POINT:Y_SCREEN (then X_SCREEN); Z when neither says.
    Auto,
    /// The user's setting, whatever the file says.
    Fixed(UpAxis),
}

fn err(at: u64, msg: impl Into<String>) -> FormatError {
    FormatError {
        at,
        msg: msg.into(),
    }
}

/// Reconciles header and parameters. `file_len` bounds every pointer.
pub fn resolve(
    h: &Header,
    params: &Params,
    processor: Processor,
    file_len: u64,
    up: UpChoice,
    warnings: &mut Vec<String>,
) -> Result<Layout, FormatError> {
    let points = point_count(h, params, warnings)?;
    let storage = storage(h, params)?;
    let rate = frame_rate(h, params)?;
    let analog_values = analog_values(h, params, rate, warnings)?;
    let word = storage.word_bytes();
    let frame_bytes = points * 4 * word + analog_values * word;
    let (data_block, data_offset) = data_start(h, params, file_len, warnings)?;
    let (frames, first_frame) = frame_count(h, params, warnings)?;
    if frame_bytes == 0 && frames > u16::MAX as u64 {
        return Err(err(
            8,
            format!("{frames} frames of zero bytes each is not plausible"),
        ));
    }
    if frames > 0 && frame_bytes > 0 {
        let room = file_len.saturating_sub(data_offset);
        if room < frame_bytes as u64 {
            return Err(err(
                data_offset,
                format!(
                    "the data section (block {data_block}) holds {room} bytes, less than one frame of \
                     {points} points and {analog_values} analog values ({frame_bytes} bytes)"
                ),
            ));
        }
    }

    let (units, metres_per_unit) = units(params, warnings)?;
    let software = ["SOFTWARE", "COMPANY"]
        .iter()
        .filter_map(|n| params.get("MANUFACTURER", n))
        .flat_map(|p| p.strings())
        .find(|s| !s.is_empty());
    Ok(Layout {
        processor,
        storage,
        points,
        analog_values,
        data_offset,
        frame_bytes,
        first_frame,
        frames,
        rate,
        units,
        metres_per_unit,
        up: up_axis(params, up, warnings),
        labels: labels(params, points),
        software,
    })
}

/// Points per frame: POINT:USED, or header word 2 when it is absent.
fn point_count(
    h: &Header,
    params: &Params,
    warnings: &mut Vec<String>,
) -> Result<usize, FormatError> {
    let used_param = params.get("POINT", "USED");
    let points = match used_param.and_then(|p| p.count()) {
        Some(n) => {
            if n != h.points as u64 {
                warnings.push(format!(
                    "POINT:USED is {n} but header word 2 says {}; using POINT:USED",
                    h.points
                ));
            }
            n
        }
        None => h.points as u64,
    };
    if points > u16::MAX as u64 {
        return Err(err(
            used_param.map_or(2, |p| p.offset),
            format!("POINT:USED = {points} is more than a C3D file can hold (65535)"),
        ));
    }
    Ok(points as usize)
}

/// Integers scaled by POINT:SCALE, or floats when the scale is negative.
fn storage(h: &Header, params: &Params) -> Result<Storage, FormatError> {
    let scale_param = params.get("POINT", "SCALE");
    let scale = match scale_param.and_then(|p| p.number(0)) {
        Some(s) if s.is_finite() && s != 0.0 => s,
        _ => h.scale as f64,
    };
    if !scale.is_finite() || scale == 0.0 {
        return Err(err(
            scale_param.map_or(12, |p| p.offset),
            format!("POINT:SCALE is {scale}; it must be a non-zero number"),
        ));
    }
    Ok(if scale < 0.0 {
        Storage::Float32
    } else {
        Storage::Int16 { scale }
    })
}

/// Frames per second: POINT:RATE, or header words 11-12.
fn frame_rate(h: &Header, params: &Params) -> Result<f64, FormatError> {
    let rate = params
        .get("POINT", "RATE")
        .and_then(|p| p.number(0))
        .filter(|r| r.is_finite() && *r > 0.0)
        .unwrap_or(h.frame_rate as f64);
    if !(rate.is_finite() && rate > 0.0) {
        return Err(err(
            20,
            format!("frame rate is {rate} (header words 11-12 and POINT:RATE)"),
        ));
    }
    Ok(rate)
}

/// Analog values stored with each frame (skipped, but they take room).
fn analog_values(
    h: &Header,
    params: &Params,
    rate: f64,
    warnings: &mut Vec<String>,
) -> Result<usize, FormatError> {
    let analog_used = params.get("ANALOG", "USED").and_then(|p| p.count());
    let analog_values = match analog_used {
        None => h.analog_total as u64,
        Some(0) => 0,
        Some(used) => {
            let ratio = params
                .get("ANALOG", "RATE")
                .and_then(|p| p.number(0))
                .map(|r| r / rate)
                .filter(|q| q.is_finite() && *q >= 0.0 && (q - q.round()).abs() < 1e-3);
            let per_channel = match ratio {
                Some(q) => q.round() as u64,
                None if h.analog_per_channel > 0 => h.analog_per_channel as u64,
                None => (h.analog_total as u64) / used,
            };
            let total = used.saturating_mul(per_channel);
            if total != h.analog_total as u64 {
                warnings.push(format!(
                    "analog values per frame: ANALOG:USED × rate ratio = {total}, header word 3 = {}; using {total}",
                    h.analog_total
                ));
            }
            total
        }
    };
    if analog_values > 1 << 24 {
        return Err(err(
            4,
            format!("{analog_values} analog values per frame is not plausible"),
        ));
    }
    Ok(analog_values as usize)
}

/// The data section's block and byte offset: header word 9 first (Motive's
/// POINT:DATA_START is 0), then POINT:DATA_START.
fn data_start(
    h: &Header,
    params: &Params,
    file_len: u64,
    warnings: &mut Vec<String>,
) -> Result<(u64, u64), FormatError> {
    let ds_param = params.get("POINT", "DATA_START").and_then(|p| p.count());
    let valid_block =
        |b: u64| b >= 2 && b != h.param_block as u64 && (b - 1) * BLOCK as u64 <= file_len;
    let data_block = if valid_block(h.data_block as u64) {
        h.data_block as u64
    } else if let Some(b) = ds_param.filter(|&b| valid_block(b)) {
        warnings.push(format!(
            "header word 9 (data block) is {}; using POINT:DATA_START = {b}",
            h.data_block
        ));
        b
    } else {
        return Err(err(
            16,
            format!(
                "data section block is {} (header word 9) and {} (POINT:DATA_START); neither is a block of this {file_len}-byte file",
                h.data_block,
                ds_param.map_or("absent".to_string(), |b| b.to_string())
            ),
        ));
    };
    Ok((data_block, (data_block - 1) * BLOCK as u64))
}

/// Frames in the file and the first frame's number: the header's range, or
/// the parameters that hold counts beyond 65535 (TRIAL fields, POINT:FRAMES,
/// POINT:LONG_FRAMES).
fn frame_count(
    h: &Header,
    params: &Params,
    warnings: &mut Vec<String>,
) -> Result<(u64, i64), FormatError> {
    let trial = |name: &str| {
        params
            .get("TRIAL", name)
            .and_then(|p| match (p.number(0), p.number(1)) {
                (Some(lo), Some(hi)) if p.kind == super::params::ParamType::Int16 => {
                    Some(lo as u64 + ((hi as u64) << 16))
                }
                (Some(v), _) if (0.0..4.0e9).contains(&v) => Some(v as u64),
                _ => None,
            })
    };
    let header_count =
        (h.last_frame >= h.first_frame).then(|| (h.last_frame - h.first_frame) as u64 + 1);
    let mut first_frame = h.first_frame as i64;
    let mut param_counts: Vec<(u64, &str)> = Vec::new();
    if let (Some(s), Some(e)) = (trial("ACTUAL_START_FIELD"), trial("ACTUAL_END_FIELD")) {
        if e >= s {
            param_counts.push((e - s + 1, "TRIAL:ACTUAL_END_FIELD"));
        }
    }
    for name in ["LONG_FRAMES", "FRAMES"] {
        if let Some(n) = params.get("POINT", name).and_then(|p| p.count()) {
            param_counts.push((
                n,
                if name == "FRAMES" {
                    "POINT:FRAMES"
                } else {
                    "POINT:LONG_FRAMES"
                },
            ));
        }
    }
    let long = param_counts
        .iter()
        .filter(|(n, _)| *n > u16::MAX as u64)
        .max_by_key(|(n, _)| *n);
    let frames = match (long, header_count) {
        (Some(&(n, from)), _) => {
            if let Some(s) = trial("ACTUAL_START_FIELD").filter(|_| from.starts_with("TRIAL")) {
                first_frame = s as i64;
            }
            n
        }
        (None, Some(n)) => n,
        (None, None) => match param_counts.iter().max_by_key(|(n, _)| *n) {
            Some(&(n, from)) => {
                warnings.push(format!(
                    "header last frame {} is before first frame {}; using {from} = {n}",
                    h.last_frame, h.first_frame
                ));
                n
            }
            None => {
                return Err(err(
                    8,
                    format!(
                        "header last frame {} is before first frame {} and no parameter gives the frame count",
                        h.last_frame, h.first_frame
                    ),
                ))
            }
        },
    };
    Ok((frames, first_frame))
}

/// POINT:UNITS and metres per unit.
fn units(params: &Params, warnings: &mut Vec<String>) -> Result<(String, f64), FormatError> {
    let units = params
        .get("POINT", "UNITS")
        .and_then(|p| p.strings().into_iter().next())
        .unwrap_or_default();
    let metres_per_unit = match units.to_ascii_lowercase().as_str() {
        "mm" | "millimeters" | "millimetres" => 0.001,
        "cm" | "centimeters" | "centimetres" => 0.01,
        "m" | "meters" | "metres" => 1.0,
        "" => {
            warnings.push("POINT:UNITS is missing; assuming mm".into());
            0.001
        }
        other => {
            return Err(err(
                params.get("POINT", "UNITS").map_or(0, |p| p.offset),
                format!(
                    "POINT:UNITS \"{}\" is not a length treemocap knows (mm, cm, m)",
                    crate::error::excerpt(other)
                ),
            ))
        }
    };
    Ok((units, metres_per_unit))
}

/// The up axis: the setting, or POINT:Y_SCREEN when it is `auto`.
fn up_axis(params: &Params, up: UpChoice, warnings: &mut Vec<String>) -> UpAxis {
    let screen = |name: &str| {
        params
            .get("POINT", name)
            .and_then(|p| p.strings().into_iter().next())
            .map(|s| s.to_ascii_uppercase())
    };
    match up {
        UpChoice::Fixed(a) => a,
        UpChoice::Auto => match (screen("Y_SCREEN").as_deref(), screen("X_SCREEN").as_deref()) {
            (Some("+Y" | "Y"), _) => UpAxis::Y,
            (Some("+Z" | "Z"), _) => UpAxis::Z,
            (Some(y), x) => {
                warnings.push(format!(
                    "POINT:Y_SCREEN is \"{}\" (X_SCREEN \"{}\"); only +Y and +Z are understood, assuming Z up \
                     (set c3d.up_axis to override)",
                    crate::error::excerpt(y),
                    crate::error::excerpt(x.unwrap_or("absent"))
                ));
                UpAxis::Z
            }
            // Without Y_SCREEN, C3D's usual Z up.
            (None, _) => UpAxis::Z,
        },
    }
}

/// Labels: LABELS, LABELS2, LABELS3, … in order, the first `points` of them,
/// with a name made up for every empty or missing one.
fn labels(params: &Params, points: usize) -> Vec<String> {
    let mut labels: Vec<String> = Vec::new();
    for i in 1.. {
        let name = if i == 1 {
            "LABELS".to_string()
        } else {
            format!("LABELS{i}")
        };
        match params.get("POINT", &name) {
            Some(p) => labels.extend(p.strings()),
            None => break,
        }
        if labels.len() >= points {
            break;
        }
    }
    labels.truncate(points);
    for (i, l) in labels.iter_mut().enumerate() {
        if l.is_empty() {
            *l = format!("Point {i}");
        }
    }
    while labels.len() < points {
        labels.push(format!("Point {}", labels.len()));
    }
    labels
}
