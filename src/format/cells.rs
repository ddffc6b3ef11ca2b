//! The fast path of reading a CSV data row: find the cells that hold
//! something and parse plain decimals, without touching the empty ones.
//!
//! Why: Motive adds a column every time an unlabeled marker reappears, so a
//! long take has tens of thousands of columns of which a few dozen hold a
//! number in any row. Splitting every field costs frames × columns; this
//! finds the commas sixteen bytes at a time (a row of commas is read at
//! memory speed) and costs per cell that holds a number. Numbers in the
//! form Motive writes (`-1234.567890`) are parsed eight digits at a time;
//! the result is the correctly rounded double, bit for bit what
//! `str::parse::<f64>` gives, which is the fallback for every other form.

/// Eight commas, for comparing a word of a row at once.
const COMMAS: u64 = u64::from_ne_bytes([b','; 8]);
const DOTS: u64 = u64::from_ne_bytes([b'.'; 8]);
const ZEROS: u64 = u64::from_ne_bytes([b'0'; 8]);
const LOW_BITS: u64 = 0x0101_0101_0101_0101;
const HIGH_BITS: u64 = 0x8080_8080_8080_8080;

/// What [`scan`] found in a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scan {
    /// Every cell was visited; the row has this many fields.
    Fields(usize),
    /// A cell starts with a quote: the row needs the full CSV reader.
    Quoted,
}

/// Calls `cell(column, start, end)` for every non-empty cell of an
/// unquoted row (`line` without its line end), in column order.
///
/// On x86-64 the row is read sixteen bytes at a time with SSE2 (part of
/// every x86-64 CPU): one compare gives the commas of sixteen bytes as the
/// bits of a mask, so a field costs one bit, not a byte-by-byte search.
/// Elsewhere, and from the first quote on, [`scan_from`] reads it.
#[cfg(target_arch = "x86_64")]
pub(crate) fn scan(line: &[u8], mut cell: impl FnMut(usize, usize, usize)) -> Scan {
    let n = line.len();
    let mut col = 0;
    // Where the current field starts.
    let mut start = 0;
    let mut base = 0;
    while base < n {
        let (mut commas, quotes) = masks16(line, base);
        if quotes != 0 {
            return scan_from(line, start, col, cell);
        }
        if commas == 0xFFFF && start == base {
            col += 16;
            start = base + 16;
            base += 16;
            continue;
        }
        while commas != 0 {
            let pos = base + commas.trailing_zeros() as usize;
            if pos > start {
                cell(col, start, pos);
            }
            col += 1;
            start = pos + 1;
            commas &= commas - 1;
        }
        base += 16;
    }
    if n > start {
        cell(col, start, n);
    }
    Scan::Fields(col + 1)
}

/// The commas and the quotes among the sixteen bytes of `line` at `base`
/// (fewer at the end of the line: the missing bytes count as neither), as
/// bit masks.
#[cfg(target_arch = "x86_64")]
#[inline]
fn masks16(line: &[u8], base: usize) -> (u32, u32) {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi8, _mm_loadu_si128, _mm_movemask_epi8, _mm_set1_epi8,
    };
    let mut tail = [0u8; 16];
    let bytes: &[u8] = match line.get(base..base + 16) {
        Some(b) => b,
        None => {
            let rest = &line[base..];
            tail[..rest.len()].copy_from_slice(rest);
            &tail
        }
    };
    // SAFETY: SSE2 is in the x86-64 baseline, so these intrinsics are
    // always available; the unaligned load reads exactly the sixteen bytes
    // of `bytes`.
    unsafe {
        let v = _mm_loadu_si128(bytes.as_ptr().cast::<__m128i>());
        let c = _mm_movemask_epi8(_mm_cmpeq_epi8(v, _mm_set1_epi8(b',' as i8)));
        let q = _mm_movemask_epi8(_mm_cmpeq_epi8(v, _mm_set1_epi8(b'"' as i8)));
        (c as u32, q as u32)
    }
}

/// As [`scan`], eight bytes at a time, on CPUs other than x86-64.
#[cfg(not(target_arch = "x86_64"))]
pub(crate) fn scan(line: &[u8], cell: impl FnMut(usize, usize, usize)) -> Scan {
    scan_from(line, 0, 0, cell)
}

/// [`scan`] from the start `p` of field `col` on, a word of eight bytes
/// at a time: runs of empty cells are skipped eight commas per step.
fn scan_from(
    line: &[u8],
    mut p: usize,
    mut col: usize,
    mut cell: impl FnMut(usize, usize, usize),
) -> Scan {
    let n = line.len();
    while p < n {
        // A run of empty cells: eight commas per step.
        while p + 8 <= n {
            let x = load(line, p) ^ COMMAS;
            if x != 0 {
                let k = first_set_byte(x);
                col += k;
                p += k;
                break;
            }
            col += 8;
            p += 8;
        }
        if p >= n {
            break;
        }
        match line[p] {
            b',' => {
                col += 1;
                p += 1;
            }
            b'"' => return Scan::Quoted,
            _ => {
                let start = p;
                p = field_end(line, p);
                cell(col, start, p);
                if p < n {
                    col += 1;
                    p += 1;
                }
            }
        }
    }
    Scan::Fields(col + 1)
}

/// Eight line feeds, for finding a row's end a word at a time.
const NEWLINES: u64 = u64::from_ne_bytes([b'\n'; 8]);

/// The index of the first line feed in `buf` at or after `from`.
///
/// Word at a time: rows of a dense export are a few KB, and this runs once
/// over every byte of the file, so it must cost far less than the scan.
#[inline]
pub(crate) fn find_newline(buf: &[u8], from: usize) -> Option<usize> {
    let n = buf.len();
    let mut p = from;
    while p + 8 <= n {
        if let Some(k) = first_zero_byte(load(buf, p) ^ NEWLINES) {
            return Some(p + k);
        }
        p += 8;
    }
    buf[p.min(n)..]
        .iter()
        .position(|&b| b == b'\n')
        .map(|k| p + k)
}

/// Little-endian word of eight bytes at `at` (the caller checked the length).
#[inline]
fn load(buf: &[u8], at: usize) -> u64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&buf[at..at + 8]);
    u64::from_le_bytes(b)
}

/// Index of the lowest non-zero byte of a non-zero word.
#[inline]
fn first_set_byte(x: u64) -> usize {
    (x.trailing_zeros() / 8) as usize
}

/// Index of the lowest zero byte of `x`, if any (the classic has-zero-byte
/// test: false positives can only lie above a true zero byte).
#[inline]
fn first_zero_byte(x: u64) -> Option<usize> {
    let z = x.wrapping_sub(LOW_BITS) & !x & HIGH_BITS;
    (z != 0).then(|| first_set_byte(z))
}

/// The end of the field starting at `p`: the next comma or the end of the line.
#[inline]
fn field_end(line: &[u8], mut p: usize) -> usize {
    let n = line.len();
    while p + 8 <= n {
        if let Some(k) = first_zero_byte(load(line, p) ^ COMMAS) {
            return p + k;
        }
        p += 8;
    }
    while p < n && line[p] != b',' {
        p += 1;
    }
    p
}

/// Powers of ten exactly representable as doubles (Clinger's fast path).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];
const POW10_INT: [u64; 9] = [
    1,
    10,
    100,
    1_000,
    10_000,
    100_000,
    1_000_000,
    10_000_000,
    100_000_000,
];

/// Eight digit values (0–9, the most significant in the lowest byte) as a number.
#[inline]
fn eight_digits(x: u64) -> u64 {
    let x = x.wrapping_mul(10).wrapping_add(x >> 8);
    (((x & 0x0000_00FF_0000_00FF).wrapping_mul(100 + (1_000_000 << 32)))
        .wrapping_add(((x >> 16) & 0x0000_00FF_0000_00FF).wrapping_mul(1 + (10_000 << 32))))
        >> 32
}

/// True when every byte of `x` (bytes XOR `'0'`) is a digit value 0–9.
#[inline]
fn all_digits(x: u64) -> bool {
    (x | x.wrapping_add(0x7676_7676_7676_7676)) & HIGH_BITS == 0
}

/// The finite number in `buf[start..end]`, or `None` if the cell is not one.
///
/// Plain decimals of up to eight digits on each side of the point are
/// parsed with word arithmetic; the mantissa and the power of ten are then
/// both exact doubles, so one division gives the correctly rounded result.
/// Anything else (exponents, spaces, long digit strings) goes to
/// `str::parse`, so every input gets exactly the standard library's answer.
#[inline]
pub(crate) fn number(buf: &[u8], start: usize, end: usize) -> Option<f64> {
    if end <= start || start + 18 > buf.len() || end - start > 18 {
        return slow(&buf[start..end]);
    }
    let neg = buf[start] == b'-';
    let s = start + usize::from(neg);
    let len = end - s;
    let a = load(buf, s);
    let Some(dot) = first_zero_byte(a ^ DOTS).filter(|&d| d < len) else {
        return slow(&buf[start..end]);
    };
    let k = len - dot - 1;
    if k > 8 || dot + k == 0 {
        return slow(&buf[start..end]);
    }
    let int = if dot == 0 {
        0
    } else {
        // The integer digits moved to the top of the word; the bytes shifted
        // in are zeros, i.e. leading zero digits.
        let x = (a ^ ZEROS) << (8 * (8 - dot));
        if !all_digits(x) {
            return slow(&buf[start..end]);
        }
        eight_digits(x)
    };
    let frac = if k == 0 {
        0
    } else {
        let x = (load(buf, s + dot + 1) ^ ZEROS) << (8 * (8 - k));
        if !all_digits(x) {
            return slow(&buf[start..end]);
        }
        eight_digits(x)
    };
    let m = int * POW10_INT[k] + frac;
    if m > 1 << 53 {
        return slow(&buf[start..end]);
    }
    let v = m as f64 / POW10[k];
    Some(if neg { -v } else { v })
}

/// Any other form of number, through the standard library.
fn slow(raw: &[u8]) -> Option<f64> {
    let v: f64 = std::str::from_utf8(raw).ok()?.trim().parse().ok()?;
    v.is_finite().then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn cells(line: &str) -> (Scan, Vec<(usize, String)>) {
        let mut out = Vec::new();
        let s = scan(line.as_bytes(), |c, a, b| {
            out.push((c, line[a..b].to_string()))
        });
        (s, out)
    }

    #[test]
    fn visits_only_cells_with_content_and_counts_fields() {
        let (s, c) = cells("1,0.5,,,,,,,,,,,,,,,,,,,x,,y");
        assert_eq!(s, Scan::Fields(23));
        assert_eq!(
            c,
            vec![
                (0, "1".into()),
                (1, "0.5".into()),
                (20, "x".into()),
                (22, "y".into())
            ]
        );
        assert_eq!(cells("").0, Scan::Fields(1));
        assert_eq!(cells(",,,,,,,,,,,,,,,,,").0, Scan::Fields(18));
        assert!(cells(",,,,,,,,,,,,,,,,,").1.is_empty());
        assert_eq!(
            cells("abcdefghijklmnop,").1,
            vec![(0, "abcdefghijklmnop".into())]
        );
        assert_eq!(cells("1,\"2\"").0, Scan::Quoted);
    }

    #[test]
    fn the_wide_scan_finds_the_cells_the_word_scan_finds() {
        // Rows of every length around the 16-byte steps, with runs of
        // empty cells, long cells and quotes anywhere.
        let mut rng = Rng::new(16);
        let pieces: [&[u8]; 7] = [
            b",",
            b",,,,,,,,,,,,,,,,",
            b"1",
            b"-12.345678",
            b"abcdefghijklmnopq",
            b"\"x\"",
            b"7,",
        ];
        for _ in 0..20_000 {
            let mut line = Vec::new();
            for _ in 0..rng.int(0, 12) {
                let p = pieces[rng.int(0, 6) as usize];
                if p.starts_with(b"\"") && rng.int(0, 9) > 0 {
                    continue;
                }
                line.extend_from_slice(p);
            }
            let (mut wide, mut word) = (Vec::new(), Vec::new());
            let a = scan(&line, |c, s, e| wide.push((c, s, e)));
            let b = scan_from(&line, 0, 0, |c, s, e| word.push((c, s, e)));
            assert_eq!(a, b, "{}", String::from_utf8_lossy(&line));
            assert_eq!(wide, word, "{}", String::from_utf8_lossy(&line));
        }
    }

    #[test]
    fn numbers_are_bit_identical_to_the_standard_parser() {
        let mut rng = Rng::new(15);
        for i in 0..200_000u32 {
            let v = (rng.f64() - 0.3) * 10f64.powi(rng.int(-3, 9) as i32);
            let text = match i % 5 {
                0 => format!("{v:.6}"),
                1 => format!("{v}"),
                2 => format!("{v:.3}"),
                3 => format!("{v:.8}"),
                _ => format!("{v:e}"),
            };
            let mut buf = text.clone().into_bytes();
            let end = buf.len();
            buf.extend_from_slice(b",,,,,,,,,,,,,,,,,,,,");
            let want = text.parse::<f64>().ok().filter(|v| v.is_finite());
            assert_eq!(
                number(&buf, 0, end).map(f64::to_bits),
                want.map(f64::to_bits),
                "{text}"
            );
            // At the very end of a line (no room for word loads).
            assert_eq!(
                number(text.as_bytes(), 0, end).map(f64::to_bits),
                want.map(f64::to_bits),
                "{text}"
            );
        }
        for bad in [
            "", "-", ".", "1.2.3", "12a.5", "nan", "inf", "1e999", "--1", "0x10",
        ] {
            let mut buf = bad.as_bytes().to_vec();
            let end = buf.len();
            buf.extend_from_slice(&[b','; 20]);
            assert_eq!(number(&buf, 0, end), None, "{bad}");
        }
        let mut buf = b" 12.5 ".to_vec();
        buf.extend_from_slice(&[b','; 20]);
        assert_eq!(number(&buf, 0, 6), Some(12.5));
        let mut buf = b"-0.000000".to_vec();
        buf.extend_from_slice(&[b','; 20]);
        assert_eq!(
            number(&buf, 0, 9).map(f64::to_bits),
            Some((-0.0f64).to_bits())
        );
    }
}
