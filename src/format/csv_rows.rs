//! A small RFC 4180 row reader that knows which line each row starts on.
//!
//! Why not the `csv` crate: its record positions skip blank lines and count
//! CRLF files differently, so an error would name the wrong line — and naming
//! the exact line is the point of an error in a 100 MB export. Quoted fields
//! (Motive quotes its IDs) and doubled quotes are handled; a quoted field may
//! run over a line end (a multi-line Take Notes).

use std::io::{self, BufRead};

/// Reads rows one at a time into a reused buffer.
pub(crate) struct RowReader<R> {
    reader: R,
    /// Line number of the last line read (1-based).
    lines_read: u64,
    /// Line on which the current row starts.
    row_line: u64,
    raw: Vec<u8>,
    data: Vec<u8>,
    ends: Vec<usize>,
}

impl<R: BufRead> RowReader<R> {
    pub(crate) fn new(reader: R) -> Self {
        RowReader {
            reader,
            lines_read: 0,
            row_line: 0,
            raw: Vec::with_capacity(4096),
            data: Vec::with_capacity(4096),
            ends: Vec::with_capacity(256),
        }
    }

    /// Reads the next row; `Ok(false)` at the end of the input.
    pub(crate) fn read(&mut self) -> io::Result<bool> {
        if !self.read_line()? {
            return Ok(false);
        }
        self.split()?;
        Ok(true)
    }

    /// Reads the next line without splitting it into fields (see [`Self::line_bytes`]);
    /// `Ok(false)` at the end of the input. Data rows are read this way and
    /// scanned in place; [`Self::split`] makes fields of the line when needed.
    pub(crate) fn read_line(&mut self) -> io::Result<bool> {
        self.data.clear();
        self.ends.clear();
        self.raw.clear();
        if self.reader.read_until(b'\n', &mut self.raw)? == 0 {
            return Ok(false);
        }
        self.lines_read += 1;
        self.row_line = self.lines_read;
        Ok(true)
    }

    /// The line just read by [`Self::read_line`], without its line end.
    pub(crate) fn line_bytes(&self) -> &[u8] {
        &self.raw[..trim_eol(&self.raw)]
    }

    /// The line just read with its line end: word-at-a-time readers may look
    /// a few bytes past a field's end.
    pub(crate) fn line_buffer(&self) -> &[u8] {
        &self.raw
    }

    /// Splits the line just read into fields; a quoted field running over
    /// the line end pulls in the following lines.
    pub(crate) fn split(&mut self) -> io::Result<()> {
        self.data.clear();
        self.ends.clear();
        let line_end = trim_eol(&self.raw);
        if !self.raw[..line_end].contains(&b'"') {
            // Every data row of an export: no quotes, so fields are the
            // slices between commas, copied whole rather than byte by byte.
            for field in self.raw[..line_end].split(|&b| b == b',') {
                self.data.extend_from_slice(field);
                self.ends.push(self.data.len());
            }
            return Ok(());
        }
        let mut in_quotes = false;
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
                    self.ends.push(self.data.len());
                    field_start = true;
                    continue;
                } else if b == b'"' && field_start {
                    in_quotes = true;
                } else {
                    self.data.push(b);
                }
                field_start = false;
            }
            if !in_quotes {
                break;
            }
            // A quoted field runs over the line end: keep the newline, go on.
            self.data.push(b'\n');
            self.raw.clear();
            pos = 0;
            if self.reader.read_until(b'\n', &mut self.raw)? == 0 {
                break; // unterminated quote at EOF: take what there is
            }
            self.lines_read += 1;
        }
        self.ends.push(self.data.len());
        Ok(())
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
        &self.data[start..end]
    }

    /// Where field `i` lies in [`Self::data_buffer`] (empty if out of range).
    pub(crate) fn field_range(&self, i: usize) -> (usize, usize) {
        let Some(&end) = self.ends.get(i) else {
            return (0, 0);
        };
        (if i == 0 { 0 } else { self.ends[i - 1] }, end)
    }

    /// The fields of the current row, one after another (see [`Self::field_range`]).
    pub(crate) fn data_buffer(&self) -> &[u8] {
        &self.data
    }

    /// Field `i` as text (empty if out of range or not UTF-8).
    pub(crate) fn text(&self, i: usize) -> &str {
        std::str::from_utf8(self.get(i)).unwrap_or("")
    }
}

fn trim_eol(raw: &[u8]) -> usize {
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
        let mut r = RowReader::new(text.as_bytes());
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
}
