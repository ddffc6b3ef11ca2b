//! A small RFC 4180 row reader that knows which line each row starts on.
//!
//! Why not the `csv` crate: its record positions skip blank lines and count
//! CRLF files differently, so an error would name the wrong line — and naming
//! the exact line is the point of an error in a 100 MB export. Quoted fields
//! (Motive quotes its IDs) and doubled quotes are handled; a quoted field may
//! run over a line end (a multi-line Take Notes) while `multiline` is on.
//!
//! Memory is bounded by the row, not the file: a row longer than
//! [`RowLimits::max_bytes`] or with more than [`RowLimits::max_fields`]
//! fields is refused as soon as the limit is passed, before it is read
//! whole, so a hostile file of one 100 MB line costs a few times the limit
//! at most, not gigabytes.

use std::io::{self, BufRead, Read};

/// How large a row may be. The defaults are far beyond any real export
/// (Motive's widest: a few thousand markers × 3 columns, a few hundred KB a
/// row) and small against the memory of any machine that runs treemocap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct RowLimits {
    /// Bytes of one row, continuation lines of a quoted field included.
    pub(crate) max_bytes: usize,
    /// Fields of one row.
    pub(crate) max_fields: usize,
}

impl Default for RowLimits {
    fn default() -> Self {
        RowLimits {
            max_bytes: 8 << 20,
            max_fields: 200_000,
        }
    }
}

/// Why a row could not be read.
#[derive(Debug)]
pub(crate) enum RowError {
    /// The OS refused to read.
    Io(io::Error),
    /// The row starting on `line` is longer than the limit.
    TooLong { line: u64, limit: usize },
    /// The row starting on `line` has more fields than the limit.
    TooManyFields { line: u64, limit: usize },
    /// A quoted field opened on `line`, column `column` (1-based field
    /// number) is not closed before the line ends, where the rows read
    /// allow no multi-line fields.
    UnterminatedQuote { line: u64, column: u64 },
}

impl From<io::Error> for RowError {
    fn from(e: io::Error) -> Self {
        RowError::Io(e)
    }
}

/// Reads rows one at a time into a reused buffer.
pub(crate) struct RowReader<R> {
    reader: R,
    limits: RowLimits,
    /// Whether a quoted field may run over a line end (header rows: a
    /// multi-line Take Notes) or not (data rows, which hold numbers only:
    /// there a lone quote is an error at its line, not a field that swallows
    /// the rest of the file).
    pub(crate) multiline: bool,
    /// Line number of the last line read (1-based).
    lines_read: u64,
    /// Line on which the current row starts.
    row_line: u64,
    /// Bytes the current row may still take (continuation lines of a
    /// quoted field count against the row's limit).
    budget_left: usize,
    raw: Vec<u8>,
    data: Vec<u8>,
    /// End of each field in `data`. u32: a row is far below 4 GB, and the
    /// ends are the largest part of a row of many short fields.
    ends: Vec<u32>,
}

impl<R: BufRead> RowReader<R> {
    pub(crate) fn new(reader: R, limits: RowLimits) -> Self {
        RowReader {
            reader,
            limits,
            multiline: true,
            lines_read: 0,
            row_line: 0,
            budget_left: 0,
            raw: Vec::with_capacity(4096),
            data: Vec::with_capacity(4096),
            ends: Vec::with_capacity(256),
        }
    }

    /// Reads one line into `raw` (replacing it), at most `budget` bytes;
    /// the number of bytes read, 0 at the end of the input.
    fn fill(&mut self, budget: usize) -> Result<usize, RowError> {
        self.raw.clear();
        let n = (&mut self.reader)
            .take(budget as u64 + 1)
            .read_until(b'\n', &mut self.raw)?;
        if n > budget {
            return Err(RowError::TooLong {
                line: self.row_line,
                limit: self.limits.max_bytes,
            });
        }
        Ok(n)
    }

    fn end_field(&mut self) -> Result<(), RowError> {
        if self.ends.len() == self.limits.max_fields {
            return Err(RowError::TooManyFields {
                line: self.row_line,
                limit: self.limits.max_fields,
            });
        }
        self.ends.push(self.data.len() as u32);
        Ok(())
    }

    /// Reads the next row; `Ok(false)` at the end of the input.
    pub(crate) fn read(&mut self) -> Result<bool, RowError> {
        if !self.read_line()? {
            return Ok(false);
        }
        self.split()?;
        Ok(true)
    }

    /// Reads the next line without splitting it into fields; `Ok(false)`
    /// at the end of the input. [`Self::split`] makes fields of it.
    fn read_line(&mut self) -> Result<bool, RowError> {
        self.data.clear();
        self.ends.clear();
        self.row_line = self.lines_read + 1;
        let budget = self.limits.max_bytes;
        let n = self.fill(budget)?;
        if n == 0 {
            return Ok(false);
        }
        self.budget_left = budget - n;
        self.lines_read += 1;
        Ok(true)
    }

    /// Splits the line just read into fields; a quoted field running over
    /// the line end pulls in the following lines (while `multiline`).
    fn split(&mut self) -> Result<(), RowError> {
        self.data.clear();
        self.ends.clear();
        let mut budget = self.budget_left;
        let line_end = trim_eol(&self.raw);
        if !self.raw[..line_end].contains(&b'"') {
            // Every data row of an export: no quotes, so fields are the
            // slices between commas, copied whole rather than byte by byte.
            let mut start = 0;
            loop {
                let end = self.raw[start..line_end]
                    .iter()
                    .position(|&b| b == b',')
                    .map_or(line_end, |i| start + i);
                self.data.extend_from_slice(&self.raw[start..end]);
                self.end_field()?;
                if end == line_end {
                    break;
                }
                start = end + 1;
            }
            return Ok(());
        }
        let mut in_quotes = false;
        let mut quote_field = 0u64;
        let mut field_start = true;
        let mut pos = 0;
        loop {
            let line_end = trim_eol(&self.raw);
            while pos < line_end {
                let b = self.raw[pos];
                pos += 1;
                if in_quotes {
                    if b == b'"' {
                        if self.raw.get(pos) == Some(&b'"') && pos < line_end {
                            self.data.push(b'"');
                            pos += 1;
                        } else {
                            in_quotes = false;
                        }
                    } else {
                        self.data.push(b);
                    }
                } else if b == b',' {
                    self.end_field()?;
                    field_start = true;
                    continue;
                } else if b == b'"' && field_start {
                    in_quotes = true;
                    quote_field = self.ends.len() as u64 + 1;
                } else {
                    self.data.push(b);
                }
                field_start = false;
            }
            if !in_quotes {
                break;
            }
            if !self.multiline {
                return Err(RowError::UnterminatedQuote {
                    line: self.row_line,
                    column: quote_field,
                });
            }
            // A quoted field runs over the line end: keep the newline, go on.
            self.data.push(b'\n');
            pos = 0;
            let n = self.fill(budget)?;
            if n == 0 {
                break; // unterminated quote at EOF: take what there is
            }
            budget -= n;
            self.lines_read += 1;
        }
        self.end_field()?;
        self.budget_left = budget;
        Ok(())
    }

    /// The reader, positioned after the last line read (data rows are
    /// read in blocks once the header is known).
    pub(crate) fn into_inner(self) -> R {
        self.reader
    }

    /// The line the current row starts on.
    pub(crate) fn line(&self) -> u64 {
        self.row_line
    }

    /// Number of fields in the current row.
    pub(crate) fn len(&self) -> usize {
        self.ends.len()
    }

    /// Field `i` of the current row (empty if out of range).
    pub(crate) fn get(&self, i: usize) -> &[u8] {
        let Some(&end) = self.ends.get(i) else {
            return &[];
        };
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        &self.data[start as usize..end as usize]
    }

    /// Where field `i` lies in [`Self::data_buffer`] (empty if out of range).
    pub(crate) fn field_range(&self, i: usize) -> (usize, usize) {
        let Some(&end) = self.ends.get(i) else {
            return (0, 0);
        };
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        (start as usize, end as usize)
    }

    /// The fields of the current row, one after another (see [`Self::field_range`]).
    pub(crate) fn data_buffer(&self) -> &[u8] {
        &self.data
    }

    /// Field `i` as text (empty if out of range or not UTF-8).
    pub(crate) fn text(&self, i: usize) -> &str {
        std::str::from_utf8(self.get(i)).unwrap_or("")
    }

    /// True when every field is empty (a blank line or Excel's `,,,,`).
    pub(crate) fn is_blank(&self) -> bool {
        self.data.is_empty()
    }

    /// The current row as a compact copy (one buffer, one end per field),
    /// for header rows kept while the next ones are read.
    pub(crate) fn to_row(&self) -> Row {
        Row {
            data: self.data.clone(),
            ends: self.ends.clone(),
        }
    }
}

/// A copied row: the fields' bytes back to back and where each ends. A
/// header row of 200 000 columns costs its bytes plus 4 per field, where a
/// `Vec<String>` would cost 24 plus an allocation per field.
#[derive(Debug, Clone, Default)]
pub(crate) struct Row {
    data: Vec<u8>,
    ends: Vec<u32>,
}

impl Row {
    /// Number of fields.
    pub(crate) fn len(&self) -> usize {
        self.ends.len()
    }

    /// Field `i` as text (empty if out of range or not UTF-8).
    pub(crate) fn text(&self, i: usize) -> &str {
        let Some(&end) = self.ends.get(i) else {
            return "";
        };
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        std::str::from_utf8(&self.data[start as usize..end as usize]).unwrap_or("")
    }
}

/// Length of `raw` without its line end (`\n` or `\r\n`).
pub(crate) fn trim_eol(raw: &[u8]) -> usize {
    let mut n = raw.len();
    if n > 0 && raw[n - 1] == b'\n' {
        n -= 1;
        if n > 0 && raw[n - 1] == b'\r' {
            n -= 1;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(text: &str) -> Vec<(u64, Vec<String>)> {
        let mut r = RowReader::new(text.as_bytes(), RowLimits::default());
        let mut out = Vec::new();
        while r.read().unwrap() {
            out.push((
                r.line(),
                (0..r.len()).map(|i| r.text(i).to_string()).collect(),
            ));
        }
        out
    }

    #[test]
    fn lines_count_blank_rows_and_crlf() {
        let a = rows("a,b\r\n\r\nc,\"d\"\r\n");
        assert_eq!(a[0], (1, vec!["a".into(), "b".into()]));
        assert_eq!(a[1], (2, vec!["".into()]));
        assert_eq!(a[2], (3, vec!["c".into(), "d".into()]));
    }

    #[test]
    fn quotes_commas_and_multiline_fields() {
        let a = rows("\"x,y\",\"say \"\"hi\"\"\",,\n\"two\nlines\",z\nlast");
        assert_eq!(a[0].1, ["x,y", "say \"hi\"", "", ""]);
        assert_eq!(a[1], (2, vec!["two\nlines".into(), "z".into()]));
        assert_eq!(a[2], (4, vec!["last".into()]));
    }

    #[test]
    fn rows_beyond_the_limits_are_refused_at_their_line() {
        let limits = RowLimits {
            max_bytes: 64,
            max_fields: 5,
        };
        let read_all = |text: &str, multiline: bool| {
            let mut r = RowReader::new(text.as_bytes(), limits);
            r.multiline = multiline;
            loop {
                match r.read() {
                    Ok(true) => {}
                    Ok(false) => return None,
                    Err(e) => return Some(e),
                }
            }
        };
        let long = format!("a,b\n{}\n", "x".repeat(100));
        assert!(matches!(
            read_all(&long, true),
            Some(RowError::TooLong { line: 2, limit: 64 })
        ));
        assert!(matches!(
            read_all("a\n1,2,3,4,5,6\n", true),
            Some(RowError::TooManyFields { line: 2, limit: 5 })
        ));
        // A quote left open swallows lines only up to the byte limit...
        let open = format!("a\n\"{}", "1,2\n".repeat(40));
        assert!(matches!(
            read_all(&open, true),
            Some(RowError::TooLong { line: 2, .. })
        ));
        // ...and none at all where rows may not span lines.
        assert!(matches!(
            read_all("1,2\n3,\"4\n5,6\n", false),
            Some(RowError::UnterminatedQuote { line: 2, column: 2 })
        ));
        assert!(read_all("1,2\n3,\"4\"\n", false).is_none());
        // Exactly at the limits is fine.
        assert!(read_all("1,2,3,4,5\n", true).is_none());
    }
}
