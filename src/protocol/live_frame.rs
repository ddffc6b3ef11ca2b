//! The binary frame of the live view (`/live` WebSocket binary messages and
//! `treemocap view`'s `GET /frame/N`): one frame's raw markers, what the
//! tracker made of each, and the tips with their states.
//!
//! Binary because a display needs every marker of a frame: 1 000 markers at
//! 60 messages/s is 14 kB a message here against ~40 kB as JSON text, and the
//! browser reads it with a `DataView` and no parsing. Little-endian, f32
//! positions (metres, Y up; f32 resolves 1 µm at 10 m, finer than any rig):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `TMF1` (format 1) |
//! | 4 | 4 | reserved, 0 |
//! | 8 | 8 | frame number, i64 |
//! | 16 | 8 | frame time, f64 seconds |
//! | 24 | 4 | marker count M, u32 |
//! | 28 | 4 | tip count T, u32 |
//! | 32 | 12 M | markers: f32 x, y, z |
//! | … | M, padded to 4 | marker class, u8: 0 not classified, 1 a tip's marker, 2 noise |
//! | … | 20 T | tips: u32 marker id, u32 state (0 measured, 1 gap-filled, 2 not seen now), f32 x, y, z |
//!
//! Pure: no I/O, no clock.

use thiserror::Error;

/// Magic and format number at the start of every frame.
pub const MAGIC: [u8; 4] = *b"TMF1";

/// Bytes before the markers.
const HEADER: usize = 32;
/// Bytes per tip record.
const TIP: usize = 20;

/// What the tracker made of a raw marker, as the viewer colours it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum MarkerClass {
    /// Nothing known yet (no tips to compare with, before the first tree).
    #[default]
    Unclassified = 0,
    /// The marker of a tracked tip in this frame.
    Tip = 1,
    /// A marker the tracker treats as noise: no tip claims it.
    Noise = 2,
}

/// How a tip's position in a frame was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum TipState {
    /// A marker of this frame.
    Measured = 0,
    /// Filled across a gap (never a measurement).
    Filled = 1,
    /// Not seen now and not filled: the position is the last known one.
    Unseen = 2,
}

/// One tip in a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveTip {
    /// The tip's marker id (as in tips.json).
    pub marker: u32,
    /// Measured, filled or not seen now.
    pub state: TipState,
    /// Metres, Y up.
    pub position: [f32; 3],
}

/// One frame for the viewers.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LiveFrame {
    /// Frame number of the source.
    pub frame: i64,
    /// Session time (s) of the frame.
    pub time_s: f64,
    /// Every raw marker of the frame, metres, Y up.
    pub markers: Vec<[f32; 3]>,
    /// One class per marker, or empty when nothing is classified.
    pub classes: Vec<MarkerClass>,
    /// The tips, in marker-id order.
    pub tips: Vec<LiveTip>,
}

/// Why bytes are not a frame; names the field.
#[derive(Debug, Error, PartialEq)]
pub enum FrameError {
    /// Shorter than the header or than its counts say.
    #[error("live frame: {len} bytes, {need} needed for {field}")]
    Short {
        /// Bytes given.
        len: usize,
        /// Bytes the field needs.
        need: usize,
        /// The field that did not fit.
        field: &'static str,
    },
    /// Not `TMF1`.
    #[error("live frame: magic {0:?} is not TMF1")]
    Magic([u8; 4]),
    /// A marker class or tip state out of range.
    #[error("live frame: {field} {index} has the unknown value {value}")]
    Value {
        /// `marker class` or `tip state`.
        field: &'static str,
        /// Which marker or tip.
        index: usize,
        /// The value found.
        value: u32,
    },
}

fn padded(n: usize) -> usize {
    (n + 3) & !3
}

/// The encoded size of a frame with `m` markers and `t` tips.
pub fn encoded_len(m: usize, t: usize) -> usize {
    HEADER + 12 * m + padded(m) + TIP * t
}

/// Encodes a frame. Classes shorter than the markers count as unclassified.
pub fn encode(f: &LiveFrame) -> Vec<u8> {
    let m = f.markers.len();
    let mut out = Vec::with_capacity(encoded_len(m, f.tips.len()));
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&f.frame.to_le_bytes());
    out.extend_from_slice(&f.time_s.to_le_bytes());
    out.extend_from_slice(&(m as u32).to_le_bytes());
    out.extend_from_slice(&(f.tips.len() as u32).to_le_bytes());
    for p in &f.markers {
        for c in p {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in 0..padded(m) {
        out.push(f.classes.get(i).map_or(0, |c| *c as u8));
    }
    for t in &f.tips {
        out.extend_from_slice(&t.marker.to_le_bytes());
        out.extend_from_slice(&(t.state as u32).to_le_bytes());
        for c in t.position {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    out
}

fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_bits(u32_at(b, o))
}

fn xyz_at(b: &[u8], o: usize) -> [f32; 3] {
    [f32_at(b, o), f32_at(b, o + 4), f32_at(b, o + 8)]
}

/// Decodes a frame (the page does the same in JavaScript; this one is for
/// tests and tools). Classes come back as given, one per marker.
pub fn decode(b: &[u8]) -> Result<LiveFrame, FrameError> {
    let short = |need, field| FrameError::Short {
        len: b.len(),
        need,
        field,
    };
    if b.len() < HEADER {
        return Err(short(HEADER, "header"));
    }
    let magic = [b[0], b[1], b[2], b[3]];
    if magic != MAGIC {
        return Err(FrameError::Magic(magic));
    }
    let mut eight = [0u8; 8];
    eight.copy_from_slice(&b[8..16]);
    let frame = i64::from_le_bytes(eight);
    eight.copy_from_slice(&b[16..24]);
    let time_s = f64::from_le_bytes(eight);
    let m = u32_at(b, 24) as usize;
    let t = u32_at(b, 28) as usize;
    // Counts come from the wire: check the length (in u64, no overflow)
    // before allocating anything.
    let need = HEADER as u64 + 12 * m as u64 + ((m as u64 + 3) & !3) + TIP as u64 * t as u64;
    if (b.len() as u64) < need {
        let need = usize::try_from(need).unwrap_or(usize::MAX);
        return Err(short(need, "markers and tips"));
    }
    let markers = (0..m).map(|i| xyz_at(b, HEADER + 12 * i)).collect();
    let classes_at = HEADER + 12 * m;
    let classes = (0..m)
        .map(|i| match b[classes_at + i] {
            0 => Ok(MarkerClass::Unclassified),
            1 => Ok(MarkerClass::Tip),
            2 => Ok(MarkerClass::Noise),
            v => Err(FrameError::Value {
                field: "marker class",
                index: i,
                value: v as u32,
            }),
        })
        .collect::<Result<Vec<_>, _>>()?;
    let tips_at = classes_at + padded(m);
    let tips = (0..t)
        .map(|i| {
            let o = tips_at + TIP * i;
            let state = match u32_at(b, o + 4) {
                0 => TipState::Measured,
                1 => TipState::Filled,
                2 => TipState::Unseen,
                v => {
                    return Err(FrameError::Value {
                        field: "tip state",
                        index: i,
                        value: v,
                    })
                }
            };
            Ok(LiveTip {
                marker: u32_at(b, o),
                state,
                position: xyz_at(b, o + 8),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(LiveFrame {
        frame,
        time_s,
        markers,
        classes,
        tips,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> LiveFrame {
        LiveFrame {
            frame: -7,
            time_s: 12.345,
            markers: vec![[0.1, 1.5, -0.2], [1.0, 2.0, 3.0], [-4.5, 0.0, 9.25]],
            classes: vec![
                MarkerClass::Tip,
                MarkerClass::Noise,
                MarkerClass::Unclassified,
            ],
            tips: vec![
                LiveTip {
                    marker: 0,
                    state: TipState::Measured,
                    position: [0.1, 1.5, -0.2],
                },
                LiveTip {
                    marker: 9,
                    state: TipState::Filled,
                    position: [0.5, 1.0, 0.0],
                },
                LiveTip {
                    marker: 11,
                    state: TipState::Unseen,
                    position: [0.0, 1.0, 0.5],
                },
            ],
        }
    }

    #[test]
    fn round_trip() {
        let f = sample();
        let bytes = encode(&f);
        assert_eq!(bytes.len(), encoded_len(3, 3));
        assert_eq!(bytes.len() % 4, 0);
        assert_eq!(decode(&bytes), Ok(f));
        let empty = LiveFrame::default();
        assert_eq!(decode(&encode(&empty)), Ok(empty));
    }

    #[test]
    fn layout_is_the_documented_one() {
        let b = encode(&sample());
        assert_eq!(&b[0..4], b"TMF1");
        assert_eq!(i64::from_le_bytes(b[8..16].try_into().unwrap()), -7);
        assert_eq!(u32_at(&b, 24), 3);
        assert_eq!(f32_at(&b, 32 + 4), 1.5);
        assert_eq!(&b[68..72], &[1, 2, 0, 0]);
        assert_eq!(u32_at(&b, 72 + 20), 9);
        assert_eq!(u32_at(&b, 72 + 24), 1);
    }

    #[test]
    fn a_thousand_markers_fit_a_display_budget() {
        let f = LiveFrame {
            markers: vec![[0.0; 3]; 1000],
            ..LiveFrame::default()
        };
        // 60 messages/s of this stay under 1 MB/s per viewer.
        assert!(encode(&f).len() * 60 < 1_000_000);
    }

    #[test]
    fn bad_bytes_are_errors_not_panics() {
        let good = encode(&sample());
        for n in 0..good.len() {
            assert!(decode(&good[..n]).is_err(), "{n} bytes");
        }
        let mut b = good.clone();
        b[0] = b'X';
        assert!(matches!(decode(&b), Err(FrameError::Magic(_))));
        let mut b = good.clone();
        b[69] = 7;
        assert_eq!(
            decode(&b),
            Err(FrameError::Value {
                field: "marker class",
                index: 1,
                value: 7
            })
        );
        // Counts far beyond the bytes: an error, no allocation.
        let mut b = good;
        b[24..28].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(decode(&b), Err(FrameError::Short { .. })));
    }
}
