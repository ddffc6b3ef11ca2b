//! Block 1 of a C3D file: the fixed 512-byte header (spec/c3d.md §1).
//!
//! Byte 0 (first parameter block) and byte 1 (the key 0x50) are single bytes
//! and readable before the processor type is known; every other field is a
//! 16-bit word or a float in the processor's byte order.

use super::processor::Processor;

/// Size of a C3D block ("record") in bytes.
pub const BLOCK: usize = 512;
/// Header byte 1 of every C3D file.
pub const KEY: u8 = 0x50;

/// The header fields treemocap uses. Parameters override most of them; the
/// header is the fallback and, for the data block, the first choice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header {
    /// Block number (1-based) of the first parameter block (byte 0).
    pub param_block: u8,
    /// 3D points per frame (word 2).
    pub points: u16,
    /// Analog samples per 3D frame over all channels (word 3).
    pub analog_total: u16,
    /// First frame number (word 4); 0 in Motive's zero-based exports.
    pub first_frame: u16,
    /// Last frame number (word 5); capped at 65535, so longer files need
    /// parameters.
    pub last_frame: u16,
    /// Largest gap the writer interpolated (word 6), informative only.
    pub max_gap: u16,
    /// POINT:SCALE as a float (words 7–8); negative means float storage.
    pub scale: f32,
    /// Block number (1-based) of the first data block (word 9).
    pub data_block: u16,
    /// Analog samples per 3D frame per channel (word 10).
    pub analog_per_channel: u16,
    /// 3D frame rate (words 11–12).
    pub frame_rate: f32,
}

fn w(b: &[u8; BLOCK], i: usize) -> [u8; 2] {
    [b[i], b[i + 1]]
}

fn f(b: &[u8; BLOCK], i: usize) -> [u8; 4] {
    [b[i], b[i + 1], b[i + 2], b[i + 3]]
}

impl Header {
    /// Reads the header fields in the byte order of `processor`.
    pub fn decode(b: &[u8; BLOCK], p: Processor) -> Header {
        Header {
            param_block: b[0],
            points: p.u16(w(b, 2)),
            analog_total: p.u16(w(b, 4)),
            first_frame: p.u16(w(b, 6)),
            last_frame: p.u16(w(b, 8)),
            max_gap: p.u16(w(b, 10)),
            scale: p.f32(f(b, 12)),
            data_block: p.u16(w(b, 16)),
            analog_per_channel: p.u16(w(b, 18)),
            frame_rate: p.f32(f(b, 20)),
        }
    }

    /// Writes the header block (no events) in the byte order of `processor`.
    pub fn encode(&self, p: Processor) -> [u8; BLOCK] {
        let mut b = [0u8; BLOCK];
        b[0] = self.param_block;
        b[1] = KEY;
        b[2..4].copy_from_slice(&p.put_u16(self.points));
        b[4..6].copy_from_slice(&p.put_u16(self.analog_total));
        b[6..8].copy_from_slice(&p.put_u16(self.first_frame));
        b[8..10].copy_from_slice(&p.put_u16(self.last_frame));
        b[10..12].copy_from_slice(&p.put_u16(self.max_gap));
        b[12..16].copy_from_slice(&p.put_f32(self.scale));
        b[16..18].copy_from_slice(&p.put_u16(self.data_block));
        b[18..20].copy_from_slice(&p.put_u16(self.analog_per_channel));
        b[20..24].copy_from_slice(&p.put_f32(self.frame_rate));
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let h = Header {
            param_block: 11,
            points: 36,
            analog_total: 16,
            first_frame: 0,
            last_frame: 65535,
            max_gap: 10,
            scale: -0.1,
            data_block: 300,
            analog_per_channel: 4,
            frame_rate: 120.0,
        };
        for p in [Processor::Intel, Processor::Dec, Processor::Mips] {
            let b = h.encode(p);
            assert_eq!(b[1], KEY);
            assert_eq!(Header::decode(&b, p), h);
        }
        // Word 2 in MIPS is big-endian.
        assert_eq!(&h.encode(Processor::Mips)[2..4], &[0, 36]);
    }
}
