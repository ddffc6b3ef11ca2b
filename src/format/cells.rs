//! The fast path of reading a CSV data row: find the cells that hold
//! something and parse plain decimals, without touching the empty ones.
//!
//! Why: Motive adds a column every time an unlabeled marker reappears, so a
//! long take has tens of thousands of columns of which a few dozen hold a
//! number in any row. Splitting every field costs frames × columns; this
//! finds the commas 64 bytes at a time (a row of commas is read at
//! memory speed) and costs per cell that holds a number. Numbers in the
//! form Motive writes (`-1234.567890`) are parsed eight digits at a time,
//! with no search for the point; other plain decimals nearly as fast. The
//! result is the correctly rounded double, bit for bit what
//! `str::parse::<f64>` gives, which is the fallback for every other form.

/// Eight commas, for comparing a word of a row at once.
const COMMAS: u64 = u64::from_ne_bytes([b','; 8]);
const DOTS: u64 = u64::from_ne_bytes([b'.'; 8]);
const ZEROS: u64 = u64::from_ne_bytes([b'0'; 8]);
const LOW_BITS: u64 = 0x0101_0101_0101_0101;
const HIGH_BITS: u64 = 0x8080_8080_8080_8080;

/// What [`scan_row`] found in a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scan {
    /// Every cell was visited; the row has this many fields.
    Fields(usize),
    /// A cell starts with a quote: the row needs the full CSV reader.
    Quoted,
}

/// Calls `cell(column, start, end)` for every non-empty cell of the
/// unquoted row at the start of `rest` (the rows after it may follow), in
/// column order; returns what it found and where the row's line feed is
/// (`rest.len()` for a last row without one). The cells exclude the line
/// end (`\n` or `\r\n`).
///
/// On x86-64 the row is read sixteen bytes at a time with SSE2 (part of
/// every x86-64 CPU), four at once: one compare per byte kind gives the
/// commas, quotes and line feeds of 64 bytes as the bits of three masks,
/// so a field costs one bit, and the row's end is found in the same pass
/// (no separate search for the line feed). Elsewhere, and from the first
/// quote on, [`scan_from`] reads it.
#[cfg(target_arch = "x86_64")]
pub(crate) fn scan_row(rest: &[u8], mut cell: impl FnMut(usize, usize, usize)) -> (Scan, usize) {
    let n = rest.len();
    let mut col = 0;
    // Where the current field starts.
    let mut start = 0;
    let mut base = 0;
    while base < n {
        let m = masks64(rest, base);
        // The bytes of this row in the block: those before its line feed.
        let row_bits = match m.newlines {
            0 => u64::MAX,
            nl => (1 << nl.trailing_zeros()) - 1,
        };
        if m.quotes & row_bits != 0 {
            let end = find_newline(rest, base).unwrap_or(n);
            let line = &rest[..content_end(rest, end)];
            return (scan_from(line, start, col, cell), end);
        }
        let mut commas = m.commas & row_bits;
        if commas == u64::MAX && start == base {
            // 64 empty cells (a wide export's usual run).
            col += 64;
            start = base + 64;
            base += 64;
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
        if m.newlines != 0 {
            let end = base + m.newlines.trailing_zeros() as usize;
            let content = content_end(rest, end);
            if content > start {
                cell(col, start, content);
            }
            return (Scan::Fields(col + 1), end);
        }
        base += 64;
    }
    if n > start {
        cell(col, start, n);
    }
    (Scan::Fields(col + 1), n)
}

/// The end of a row's content whose line feed is at `end` (`rest.len()`:
/// none): before the `\r` of a `\r\n`.
#[inline]
fn content_end(rest: &[u8], end: usize) -> usize {
    if end < rest.len() && end > 0 && rest[end - 1] == b'\r' {
        end - 1
    } else {
        end
    }
}

/// The commas, quotes and line feeds among 64 bytes, one bit a byte.
#[cfg(target_arch = "x86_64")]
struct Masks {
    commas: u64,
    quotes: u64,
    newlines: u64,
}

/// The [`Masks`] of the 64 bytes of `rest` at `base` (fewer at the end of
/// the buffer: the missing bytes count as none of the three).
#[cfg(target_arch = "x86_64")]
#[inline]
fn masks64(rest: &[u8], base: usize) -> Masks {
    use std::arch::x86_64::{
        __m128i, _mm_cmpeq_epi8, _mm_loadu_si128, _mm_movemask_epi8, _mm_set1_epi8,
    };
    let mut tail = [0u8; 64];
    let bytes: &[u8] = match rest.get(base..base + 64) {
        Some(b) => b,
        None => {
            let r = &rest[base..];
            tail[..r.len()].copy_from_slice(r);
            &tail
        }
    };
    let mut m = Masks {
        commas: 0,
        quotes: 0,
        newlines: 0,
    };
    // SAFETY: SSE2 is in the x86-64 baseline, so these intrinsics are
    // always available; each unaligned load reads sixteen of the 64 bytes
    // of `bytes`.
    unsafe {
        let (comma, quote, newline) = (
            _mm_set1_epi8(b',' as i8),
            _mm_set1_epi8(b'"' as i8),
            _mm_set1_epi8(b'\n' as i8),
        );
        for i in 0..4 {
            let v = _mm_loadu_si128(bytes.as_ptr().add(16 * i).cast::<__m128i>());
            let bits = |x| u64::from(_mm_movemask_epi8(_mm_cmpeq_epi8(v, x)) as u16) << (16 * i);
            m.commas |= bits(comma);
            m.quotes |= bits(quote);
            m.newlines |= bits(newline);
        }
    }
    m
}

/// As [`scan_row`], eight bytes at a time, on CPUs other than x86-64.
#[cfg(not(target_arch = "x86_64"))]
pub(crate) fn scan_row(rest: &[u8], cell: impl FnMut(usize, usize, usize)) -> (Scan, usize) {
    let end = find_newline(rest, 0).unwrap_or(rest.len());
    (scan_from(&rest[..content_end(rest, end)], 0, 0, cell), end)
}

/// [`scan_row`] from the start `p` of field `col` on, within `line` (a
/// row without its line end), a word of eight bytes at a time: runs of
/// empty cells are skipped eight commas per step.
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
/// Word at a time. On x86-64 [`scan_row`] finds a row's end in its own
/// pass; this serves the rows it hands to [`scan_from`] (a quote) and
/// every row elsewhere.
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
/// Motive writes every number with six decimals (`-1234.567890`): those
/// take [`six_decimals`], which needs no search for the point. Other plain
/// decimals of up to eight digits on each side of the point take
/// [`any_decimals`]; anything else (exponents, spaces, long digit strings)
/// goes to `str::parse`. Every path gives exactly the standard library's
/// answer, the correctly rounded double.
#[inline]
pub(crate) fn number(buf: &[u8], start: usize, end: usize) -> Option<f64> {
    match six_decimals(buf, start, end) {
        Some(v) => Some(v),
        None => any_decimals(buf, start, end),
    }
}

/// `buf[start..end]` if it is Motive's own form, an optional minus, one to
/// eight digits, a point and six digits; `None` for any other cell (which
/// may still be a number).
///
/// Why a path of its own: it is nearly every cell of an export, and
/// knowing where the point must be (seven bytes before the end) saves the
/// search for it; the integer digits and the decimals are each one word,
/// loaded at once. Both parts are exact integers, so `m / 10⁶` with
/// `m < 10¹⁴ < 2⁵³` is one correctly rounded division, as in
/// [`any_decimals`].
#[inline]
fn six_decimals(buf: &[u8], start: usize, end: usize) -> Option<f64> {
    if start + 16 > buf.len() || end < start + 8 {
        return None;
    }
    let neg = buf[start] == b'-';
    let s = start + usize::from(neg);
    // Integer digits: 1 to 8 (`wrapping_sub` makes 0 and negatives large).
    let int_len = end.wrapping_sub(s + 7);
    if int_len.wrapping_sub(1) >= 8 {
        return None;
    }
    // The last eight bytes: the last integer digit, the point, six decimals.
    let tail = load(buf, end - 8);
    // The integer digits moved to the top of the word; the bytes shifted in
    // are zeros, i.e. leading zero digits.
    let int = (load(buf, s) ^ ZEROS) << (8 * (8 - int_len));
    let frac = (tail ^ ZEROS) & !0xFFFF;
    if (tail >> 8) as u8 != b'.' || !all_digits(int) || !all_digits(frac) {
        return None;
    }
    let m = eight_digits(int) * 1_000_000 + eight_digits(frac);
    Some(with_sign(m as f64 / 1e6, neg))
}

/// `v` (not negative), negated if `neg`, without a branch: Motive's cells
/// are negative or not at random, and a mispredicted jump costs more than
/// the rest of the parse.
#[inline]
fn with_sign(v: f64, neg: bool) -> f64 {
    f64::from_bits(v.to_bits() | (u64::from(neg) << 63))
}

/// [`number`] for plain decimals of up to eight digits on each side of the
/// point, parsed with word arithmetic; the mantissa and the power of ten
/// are then both exact doubles, so one division gives the correctly
/// rounded result. Anything else goes to `str::parse`.
#[inline]
fn any_decimals(buf: &[u8], start: usize, end: usize) -> Option<f64> {
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
    Some(with_sign(v, neg))
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
        let (s, end) = scan_row(line.as_bytes(), |c, a, b| {
            out.push((c, line[a..b].to_string()))
        });
        assert_eq!(end, line.len());
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
    fn the_wide_scan_finds_the_cells_and_the_row_end_the_word_scan_finds() {
        // Rows of every length around the 64-byte steps, with runs of
        // empty cells, long cells and quotes anywhere, ending with `\n`,
        // `\r\n` or the end of the buffer, and another row after them.
        let mut rng = Rng::new(16);
        let pieces: [&[u8]; 8] = [
            b",",
            b",,,,,,,,,,,,,,,,",
            b"1",
            b"-12.345678",
            b"abcdefghijklmnopq",
            b"\"x\"",
            b"7,",
            b"\r",
        ];
        let endings: [&[u8]; 5] = [b"", b"\n", b"\r\n", b"\n1,\"2\",3\n", b"\r\n,,,,,4\r\n"];
        for _ in 0..20_000 {
            let mut line = Vec::new();
            for _ in 0..rng.int(0, 30) {
                let p = pieces[rng.int(0, 7) as usize];
                if p.starts_with(b"\"") && rng.int(0, 9) > 0 {
                    continue;
                }
                line.extend_from_slice(p);
            }
            let ending = endings[rng.int(0, 4) as usize];
            let mut buf = line.clone();
            buf.extend_from_slice(ending);
            let (mut wide, mut word) = (Vec::new(), Vec::new());
            let (a, end) = scan_row(&buf, |c, s, e| wide.push((c, s, e)));
            // What the rows were cut at before: the first line feed, the
            // line end trimmed, the word scan over the rest.
            let want_end = buf.iter().position(|&b| b == b'\n').unwrap_or(buf.len());
            let mut content = want_end;
            if want_end < buf.len() && want_end > 0 && buf[want_end - 1] == b'\r' {
                content -= 1;
            }
            let b = scan_from(&buf[..content], 0, 0, |c, s, e| word.push((c, s, e)));
            let text = String::from_utf8_lossy(&buf);
            assert_eq!(end, want_end, "{text}");
            assert_eq!(a, b, "{text}");
            assert_eq!(wide, word, "{text}");
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
            // The general path alone (most of these take six_decimals).
            assert_eq!(
                any_decimals(&buf, 0, end).map(f64::to_bits),
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

    #[test]
    fn motive_style_edge_cases_match_the_standard_parser() {
        // Every form a hand-edited or other-tool file may hold in a cell:
        // each must give exactly what `str::parse` gives, with room after
        // the cell for word loads and at the very end of the buffer.
        let cases = [
            "0.000000",
            "-0.000000",
            "1234.567890",
            "-1234.567890",
            "12",
            "-12",
            "0",
            "-0",
            "5.",
            "-5.",
            ".5",
            "-.5",
            "1.5e3",
            "-1.5E-3",
            "1e5",
            "123456.789012",
            "1234567.123456",
            "12345678.123456",
            "-12345678.1234567",
            "123456789012345.6",
            "1234567890123456.7",
            "0.123456789012345",
            "0.1234567890123456",
            "99999999.9999999",
            "9007199254740993.0",
            "-0.000001",
            "0.0000000000000001",
            "00001.500000",
            "1.000000000000000000001",
            "3.14159265358979323846",
            "-",
            ".",
            "-.",
            "",
            " 1.5",
            "1.5 ",
            "+1.5",
            "1.5.5",
            "1,5",
            "--1.5",
            "1.-5",
            "nan",
            "inf",
            "-inf",
            "1e400",
            "1.5\r",
            "\u{661}.5",
            "12345678.000000",
            "123456789.000000",
            "-99999999.999999",
            "1.00000",
            "1.0000000",
            "1 .000000",
            "1. 00000",
            "1.00000a",
            "a.000000",
            "1-.000000",
            "-1.00000-",
            "1..000000",
            "1.000.000",
        ];
        for text in cases {
            let want = text.trim().parse::<f64>().ok().filter(|v| v.is_finite());
            let mut buf = text.as_bytes().to_vec();
            let end = buf.len();
            assert_eq!(
                number(&buf, 0, end).map(f64::to_bits),
                want.map(f64::to_bits),
                "{text:?} at the end of the buffer"
            );
            for pad in [b',', b'.', b'7', b'-'] {
                buf.truncate(end);
                buf.extend_from_slice(&[pad; 20]);
                for (path, got) in [
                    ("number", number(&buf, 0, end)),
                    ("any_decimals", any_decimals(&buf, 0, end)),
                    // None = not its form, never a different value.
                    ("six_decimals", six_decimals(&buf, 0, end).or(want)),
                ] {
                    assert_eq!(
                        got.map(f64::to_bits),
                        want.map(f64::to_bits),
                        "{path}: {text:?} followed by {:?}",
                        pad as char
                    );
                }
            }
        }
    }
}
