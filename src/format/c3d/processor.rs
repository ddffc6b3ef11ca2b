//! The three C3D processor types and how each stores 16-bit integers and
//! 32-bit floats (spec/c3d.md §1 "Processor types").

use serde::Serialize;

/// Byte order and float format of a C3D file, from byte 3 of the parameter
/// section (83 + n).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Processor {
    /// Little-endian integers, IEEE floats (84).
    Intel,
    /// Little-endian integers, VAX-F floats (85).
    Dec,
    /// Big-endian integers and IEEE floats (86; SGI/MIPS).
    Mips,
}

impl Processor {
    /// The processor named by parameter-section byte 3, if it is one.
    pub fn from_code(code: u8) -> Option<Processor> {
        match code {
            84 => Some(Processor::Intel),
            85 => Some(Processor::Dec),
            86 => Some(Processor::Mips),
            _ => None,
        }
    }

    /// The code written to parameter-section byte 3.
    pub fn code(self) -> u8 {
        match self {
            Processor::Intel => 84,
            Processor::Dec => 85,
            Processor::Mips => 86,
        }
    }

    /// How users and vendors name it.
    pub fn name(self) -> &'static str {
        match self {
            Processor::Intel => "Intel",
            Processor::Dec => "DEC",
            Processor::Mips => "MIPS",
        }
    }

    /// A 16-bit signed word in this processor's byte order.
    #[inline]
    pub fn i16(self, b: [u8; 2]) -> i16 {
        match self {
            Processor::Mips => i16::from_be_bytes(b),
            _ => i16::from_le_bytes(b),
        }
    }

    /// A 16-bit unsigned word in this processor's byte order.
    #[inline]
    pub fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Processor::Mips => u16::from_be_bytes(b),
            _ => u16::from_le_bytes(b),
        }
    }

    /// A float in this processor's format (VAX F_floating for DEC).
    #[inline]
    pub fn f32(self, b: [u8; 4]) -> f32 {
        match self {
            Processor::Intel => f32::from_le_bytes(b),
            Processor::Mips => f32::from_be_bytes(b),
            Processor::Dec => vax_to_f32(b),
        }
    }

    /// The bytes of `v` in this processor's byte order (the encoder, `encode.rs`).
    pub fn put_i16(self, v: i16) -> [u8; 2] {
        match self {
            Processor::Mips => v.to_be_bytes(),
            _ => v.to_le_bytes(),
        }
    }

    /// The bytes of `v` in this processor's byte order (the encoder, `encode.rs`).
    pub fn put_u16(self, v: u16) -> [u8; 2] {
        match self {
            Processor::Mips => v.to_be_bytes(),
            _ => v.to_le_bytes(),
        }
    }

    /// The bytes of `v` in this processor's float format (the encoder, `encode.rs`).
    pub fn put_f32(self, v: f32) -> [u8; 4] {
        match self {
            Processor::Intel => v.to_le_bytes(),
            Processor::Mips => v.to_be_bytes(),
            Processor::Dec => f32_to_vax(v),
        }
    }
}

/// VAX-F as stored by DEC C3D files: the two 16-bit halves are swapped
/// relative to IEEE little-endian and the exponent bias is 2 higher (the
/// value is a quarter of the same bits read as IEEE).
///
/// Exponent 0 is VAX zero (sign 0) or a "reserved operand" (sign 1), which
/// has no value: it becomes NaN so the point is treated as missing. For
/// exponents above 2 the bias is removed exactly by subtracting 2 from the
/// exponent field (this also keeps VAX exponent 255 finite, as it is in VAX);
/// below that, dividing by 4 lands in IEEE subnormals.
#[inline]
fn vax_to_f32(b: [u8; 4]) -> f32 {
    let bits = u32::from_le_bytes([b[2], b[3], b[0], b[1]]);
    let exp = (bits >> 23) & 0xFF;
    if exp == 0 {
        if bits & 0x8000_0000 != 0 {
            f32::NAN
        } else {
            0.0
        }
    } else if exp > 2 {
        f32::from_bits(bits - (2 << 23))
    } else {
        f32::from_bits(bits) / 4.0
    }
}

/// The inverse of [`vax_to_f32`] for the values VAX-F can hold: zero and
/// IEEE subnormals become VAX zero, values too large for VAX saturate, NaN
/// becomes the reserved operand.
fn f32_to_vax(v: f32) -> [u8; 4] {
    let bits = if v.is_nan() {
        0x8000_0000
    } else {
        let b = v.to_bits();
        let exp = (b >> 23) & 0xFF;
        if exp == 0 {
            0
        } else if exp >= 254 {
            (b & 0x8000_0000) | 0x7FFF_FFFF
        } else {
            b + (2 << 23)
        }
    };
    let le = bits.to_le_bytes();
    [le[2], le[3], le[0], le[1]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vax_known_values() {
        // 1.0 in VAX-F is 0x4080 0x0000 (16-bit words, little-endian each).
        assert_eq!(vax_to_f32([0x80, 0x40, 0x00, 0x00]), 1.0);
        // -2.5: IEEE 0xC020_0000 -> VAX exponent +2 -> 0xC120_0000, halves swapped.
        assert_eq!(vax_to_f32([0x20, 0xC1, 0x00, 0x00]), -2.5);
        assert_eq!(vax_to_f32([0, 0, 0, 0]), 0.0);
        assert!(vax_to_f32([0x00, 0x80, 0x00, 0x00]).is_nan());
    }

    #[test]
    fn round_trip_all_processors() {
        for p in [Processor::Intel, Processor::Dec, Processor::Mips] {
            for v in [
                0.0f32,
                1.0,
                -1.0,
                1234.5678,
                -0.001,
                3.0e30,
                f32::MIN_POSITIVE * 8.0,
            ] {
                assert_eq!(p.f32(p.put_f32(v)), v, "{p:?} {v}");
            }
            for v in [0i16, 1, -1, i16::MIN, i16::MAX, 12345] {
                assert_eq!(p.i16(p.put_i16(v)), v);
            }
            assert_eq!(Processor::from_code(p.code()), Some(p));
        }
        assert_eq!(Processor::Mips.put_i16(1), [0, 1]);
        assert_eq!(Processor::Dec.put_i16(1), [1, 0]);
    }
}
