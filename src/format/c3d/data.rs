//! Decoding one frame of the data section into markers (spec/c3d.md §1
//! "Data section" and "4th word").
//!
//! A point is missing when its fourth word is negative (−1 from most
//! writers, −32768 from Motive, which keeps stale coordinates) **or** any of
//! its words is not finite (ezc3d writes NaN coordinates with residual 0).
//! Nothing else: BTS float residuals of 247.0 are valid points. In float
//! files the fourth word is a float holding an integer; it is negative when
//! it is −1 or below (the cast to integer that the standard describes), and
//! a NaN there also makes the point missing, as in py-c3d.

use glam::DVec3;

use super::layout::{Layout, Storage};
use super::processor::Processor;
use super::UpAxis;
use crate::model::frame::Marker;

/// Turns frame bytes into markers in metres, Y up.
#[derive(Debug, Clone, Copy)]
pub struct FrameDecoder {
    processor: Processor,
    storage: Storage,
    points: usize,
    /// File value to metres: |POINT:SCALE| × unit for int16, unit for float.
    to_metres: f64,
    up: UpAxis,
}

impl FrameDecoder {
    /// A decoder for the storage, processor, scale and up axis of `layout`.
    pub fn new(layout: &Layout) -> FrameDecoder {
        let to_metres = match layout.storage {
            Storage::Int16 { scale } => scale.abs() * layout.metres_per_unit,
            Storage::Float32 => layout.metres_per_unit,
        };
        FrameDecoder {
            processor: layout.processor,
            storage: layout.storage,
            points: layout.points,
            to_metres,
            up: layout.up,
        }
    }

    /// Decodes the points of one frame (`buf` holds at least the point
    /// words; analog values after them are ignored), appending the valid
    /// ones to `out` with `id` = point index and counting them in `present`
    /// (one counter per point).
    pub fn decode(&self, buf: &[u8], out: &mut Vec<Marker>, present: &mut [u64]) {
        let p = self.processor;
        match self.storage {
            Storage::Int16 { .. } => {
                for (i, w) in buf.chunks_exact(8).take(self.points).enumerate() {
                    let r = p.i16([w[6], w[7]]);
                    if r < 0 {
                        continue;
                    }
                    let x = p.i16([w[0], w[1]]) as f64;
                    let y = p.i16([w[2], w[3]]) as f64;
                    let z = p.i16([w[4], w[5]]) as f64;
                    self.push(i, x, y, z, out, present);
                }
            }
            Storage::Float32 => {
                for (i, w) in buf.chunks_exact(16).take(self.points).enumerate() {
                    let r = p.f32([w[12], w[13], w[14], w[15]]);
                    let x = p.f32([w[0], w[1], w[2], w[3]]);
                    let y = p.f32([w[4], w[5], w[6], w[7]]);
                    let z = p.f32([w[8], w[9], w[10], w[11]]);
                    // A NaN residual fails `r > -1.0` too.
                    let valid = r > -1.0
                        && r.is_finite()
                        && x.is_finite()
                        && y.is_finite()
                        && z.is_finite();
                    if !valid {
                        continue;
                    }
                    self.push(i, x as f64, y as f64, z as f64, out, present);
                }
            }
        }
    }

    #[inline]
    fn push(&self, i: usize, x: f64, y: f64, z: f64, out: &mut Vec<Marker>, present: &mut [u64]) {
        let k = self.to_metres;
        let position = self.up.to_y_up(DVec3::new(x * k, y * k, z * k));
        out.push(Marker {
            position,
            id: Some(i as i64),
        });
        if let Some(c) = present.get_mut(i) {
            *c += 1;
        }
    }
}
