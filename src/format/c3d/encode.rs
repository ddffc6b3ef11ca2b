//! A small C3D writer: the encoder half of the codec. It writes what the
//! reader needs (header, POINT/ANALOG/TRIAL parameters, point and analog
//! data) in any processor and storage, with the layout quirks real files
//! have (moved parameter and data blocks, unpadded last block, LABELS2…),
//! so the round-trip tests, the benchmark and the fuzz seeds need no files.

use super::header::{Header, BLOCK};
use super::params::{self, Value};
use super::processor::Processor;

/// One point of one frame as written.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Coordinates in file units (int16 files: rounded to the scale).
    pub position: [f64; 3],
    /// The fourth word: negative = missing. Int16 files store it as an
    /// integer (−1, −32768, camera mask << 8 | residual).
    pub residual: f32,
}

/// What to write.
#[derive(Debug, Clone, PartialEq)]
pub struct WriteSpec {
    /// Byte order and float format of the whole file.
    pub processor: Processor,
    /// float32 storage (POINT:SCALE negative) instead of int16.
    pub float: bool,
    /// |POINT:SCALE|: file units per int16 step; also the float files' residual unit.
    pub scale: f32,
    /// Frames per second (header and POINT:RATE).
    pub rate: f32,
    /// POINT:UNITS ("mm", "m").
    pub units: String,
    /// POINT:LABELS (split into LABELS2… past 255); may be longer than the point count.
    pub labels: Vec<String>,
    /// POINT:DESCRIPTIONS (at most 255 are written), if any.
    pub descriptions: Vec<String>,
    /// POINT:Y_SCREEN ("+Z", "+Y"), if any.
    pub y_screen: Option<String>,
    /// Header first frame.
    pub first_frame: u16,
    /// Analog channels (ANALOG:USED).
    pub analog_channels: usize,
    /// Analog samples per channel per frame (ANALOG:RATE / POINT:RATE).
    pub analog_per_channel: usize,
    /// Block of the parameter section (≥ 2; blocks before it are blank).
    pub param_block: u8,
    /// Blank blocks between the parameters and the data.
    pub gap_blocks: usize,
    /// Pad the last block to 512 bytes (many writers do not).
    pub pad: bool,
    /// POINT:USED as a byte parameter (as ezc3d's FP_Type1 does).
    pub used_as_byte: bool,
    /// Frames × points.
    pub frames: Vec<Vec<Sample>>,
}

impl Default for WriteSpec {
    fn default() -> Self {
        WriteSpec {
            processor: Processor::Intel,
            float: false,
            scale: 0.1,
            rate: 100.0,
            units: "mm".into(),
            labels: Vec::new(),
            descriptions: Vec::new(),
            y_screen: Some("+Z".into()),
            first_frame: 1,
            analog_channels: 0,
            analog_per_channel: 0,
            param_block: 2,
            gap_blocks: 0,
            pad: true,
            used_as_byte: false,
            frames: Vec::new(),
        }
    }
}

/// Encodes `spec` as a complete C3D file.
pub fn encode(spec: &WriteSpec) -> Vec<u8> {
    let p = spec.processor;
    let points = spec.frames.first().map_or(spec.labels.len(), |f| f.len());
    let n = spec.frames.len();
    let last = spec.first_frame as u64 + n as u64 - 1;
    let mut list = point_and_analog_parameters(spec, points, n);
    list.extend(label_parameters(spec));
    if n > 65535 {
        list.extend(long_take_parameters(spec, n, last));
    }
    // The data block is only known once the section's size is, and
    // DATA_START is inside it; its size does not depend on the value.
    let probe = params::encode(&GROUPS, &list, p);
    let data_block = spec.param_block as usize + probe.len() / BLOCK + spec.gap_blocks;
    list[DATA_START_INDEX].2 = Value::Int16(vec![data_block as u16 as i16], vec![]);
    let section = params::encode(&GROUPS, &list, p);

    let header = Header {
        param_block: spec.param_block,
        points: points as u16,
        analog_total: (spec.analog_channels * spec.analog_per_channel) as u16,
        first_frame: spec.first_frame,
        last_frame: last.min(65535) as u16,
        max_gap: 0,
        scale: signed_scale(spec),
        data_block: data_block as u16,
        analog_per_channel: spec.analog_per_channel as u16,
        frame_rate: spec.rate,
    };
    let mut out = header.encode(p).to_vec();
    out.resize((spec.param_block as usize - 1) * BLOCK, 0);
    out.extend_from_slice(&section);
    out.resize((data_block - 1) * BLOCK, 0);
    encode_frames(spec, &mut out);
    if spec.pad {
        out.resize(out.len().div_ceil(BLOCK) * BLOCK, 0);
    }
    out
}

/// The groups every written file has, with their ids.
const GROUPS: [(u8, &str); 3] = [(1, "POINT"), (2, "ANALOG"), (3, "TRIAL")];

/// Where POINT:DATA_START is in [`point_and_analog_parameters`]' list: it
/// is filled in once the section's size is known.
const DATA_START_INDEX: usize = 4;

/// POINT:SCALE as written: negative for float storage.
fn signed_scale(spec: &WriteSpec) -> f32 {
    if spec.float {
        -spec.scale
    } else {
        spec.scale
    }
}

/// A character parameter value.
fn chars(strings: Vec<String>, array: bool) -> Value {
    Value::Chars { strings, array }
}

/// The POINT and ANALOG parameters every file has (DATA_START still 0),
/// then X_SCREEN/Y_SCREEN if the spec sets an up axis.
fn point_and_analog_parameters(
    spec: &WriteSpec,
    points: usize,
    n: usize,
) -> Vec<(u8, &'static str, Value)> {
    let used = if spec.used_as_byte {
        Value::Byte(vec![points as u8], vec![])
    } else {
        Value::Int16(vec![points as u16 as i16], vec![])
    };
    let analog_rate = spec.rate * spec.analog_per_channel as f32;
    let mut list = vec![
        (1, "USED", used),
        (1, "SCALE", Value::Float(vec![signed_scale(spec)], vec![])),
        (1, "RATE", Value::Float(vec![spec.rate], vec![])),
        (
            1,
            "FRAMES",
            Value::Int16(vec![n.min(65535) as u16 as i16], vec![]),
        ),
        (1, "DATA_START", Value::Int16(vec![0], vec![])),
        (1, "UNITS", chars(vec![spec.units.clone()], false)),
        (
            2,
            "USED",
            Value::Int16(vec![spec.analog_channels as i16], vec![]),
        ),
        (2, "RATE", Value::Float(vec![analog_rate], vec![])),
    ];
    if let Some(y) = &spec.y_screen {
        list.push((1, "X_SCREEN", chars(vec!["+X".into()], false)));
        list.push((1, "Y_SCREEN", chars(vec![y.clone()], false)));
    }
    list
}

/// POINT:LABELS split into LABELS2… every 255 labels, and at most 255
/// DESCRIPTIONS, as Vicon and Motive write them.
fn label_parameters(spec: &WriteSpec) -> Vec<(u8, &'static str, Value)> {
    const LABEL_NAMES: [&str; 8] = [
        "LABELS", "LABELS2", "LABELS3", "LABELS4", "LABELS5", "LABELS6", "LABELS7", "LABELS8",
    ];
    let mut list: Vec<(u8, &'static str, Value)> = spec
        .labels
        .chunks(255)
        .zip(LABEL_NAMES)
        .map(|(chunk, name)| (1, name, chars(chunk.to_vec(), true)))
        .collect();
    if !spec.descriptions.is_empty() {
        let descriptions = spec.descriptions.iter().take(255).cloned().collect();
        list.push((1, "DESCRIPTIONS", chars(descriptions, true)));
    }
    list
}

/// The parameters of a take longer than the header's 16-bit frame numbers:
/// POINT:LONG_FRAMES and TRIAL:ACTUAL_START_FIELD/ACTUAL_END_FIELD.
fn long_take_parameters(spec: &WriteSpec, n: usize, last: u64) -> Vec<(u8, &'static str, Value)> {
    let words = |v: u64| Value::Int16(vec![v as u16 as i16, (v >> 16) as u16 as i16], vec![2]);
    vec![
        (1, "LONG_FRAMES", Value::Float(vec![n as f32], vec![])),
        (3, "ACTUAL_START_FIELD", words(spec.first_frame as u64)),
        (3, "ACTUAL_END_FIELD", words(last)),
    ]
}

/// Appends the data section: each frame's points, then its analog values.
fn encode_frames(spec: &WriteSpec, out: &mut Vec<u8>) {
    let p = spec.processor;
    let analog_values = spec.analog_channels * spec.analog_per_channel;
    for (f, frame) in spec.frames.iter().enumerate() {
        for s in frame {
            encode_sample(spec, s, out);
        }
        // Analog values that look like points if misread: a reader that
        // miscounts them shifts every later frame.
        for a in 0..analog_values {
            let v = (f * 7 + a) as f32 - 1000.0;
            if spec.float {
                out.extend_from_slice(&p.put_f32(v));
            } else {
                out.extend_from_slice(&p.put_i16(v as i16));
            }
        }
    }
}

/// Appends one point: X, Y, Z and the residual word, as float32 or as
/// int16 steps of the scale.
fn encode_sample(spec: &WriteSpec, s: &Sample, out: &mut Vec<u8>) {
    let p = spec.processor;
    if spec.float {
        for v in s.position {
            out.extend_from_slice(&p.put_f32(v as f32));
        }
        out.extend_from_slice(&p.put_f32(s.residual));
    } else {
        for v in s.position {
            let q = (v / spec.scale as f64).round().clamp(-32768.0, 32767.0) as i16;
            out.extend_from_slice(&p.put_i16(q));
        }
        out.extend_from_slice(&p.put_i16(s.residual.clamp(-32768.0, 32767.0) as i16));
    }
}
