//! The Motive CSV reader's data rows read in blocks on worker threads
//! (issue 15) give what one thread gives: the same frames bit for bit, the
//! same counts, warnings and errors at the same lines, wherever the blocks
//! are cut. Block sizes here are tiny so that every file is many chunks and
//! rows run over block ends.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use treemocap::format::motive_csv::{MotiveCsvReader, ReadOptions};
use treemocap::model::recording::Recording;

/// A frame bit for bit: frame, time, markers (id, position) and the
/// reader's poses right after it.
type FrameBits = (i64, u64, Vec<(Option<i64>, [u64; 3])>, Vec<u64>);

/// Everything a user sees of a read.
#[derive(Debug, PartialEq)]
struct Outcome {
    frames: Vec<FrameBits>,
    error: Option<String>,
    /// (name, present, empty cells) per channel once reading ended.
    channels: Vec<(String, u64, u64)>,
    warnings: Vec<String>,
}

fn read_with(path: &Path, workers: usize, block_bytes: usize) -> Outcome {
    let file = std::fs::File::open(path).unwrap();
    let options = ReadOptions {
        workers,
        block_bytes,
    };
    let mut r = match MotiveCsvReader::from_file_with(file, path, 0.002, options) {
        Ok(r) => r,
        // A header refused: nothing of it depends on the data rows' reading.
        Err(e) => {
            return Outcome {
                frames: Vec::new(),
                error: Some(e.to_string()),
                channels: Vec::new(),
                warnings: Vec::new(),
            }
        }
    };
    let mut frames = Vec::new();
    let mut error = None;
    while let Some(f) = r.next() {
        match f {
            Ok(f) => {
                let markers = f
                    .markers
                    .iter()
                    .map(|m| (m.id, m.position.to_array().map(f64::to_bits)))
                    .collect();
                let poses = r
                    .poses()
                    .iter()
                    .flat_map(|(_, v)| v.iter().map(|x| x.to_bits()))
                    .collect();
                frames.push((f.frame, f.time_s.to_bits(), markers, poses));
            }
            Err(e) => {
                error = Some(e.to_string());
                assert!(r.next().is_none(), "nothing after an error");
                break;
            }
        }
    }
    let channels = r
        .channels()
        .iter()
        .map(|c| (c.name.clone(), c.present, c.empty_cells))
        .collect();
    let warnings = r.warnings().to_vec();
    Outcome {
        frames,
        error,
        channels,
        warnings,
    }
}

/// The single-threaded read of the whole file as one chunk: the reference.
fn reference(path: &Path) -> Outcome {
    read_with(path, 0, 1 << 30)
}

/// Reads `path` one way and several parallel ways; all must agree.
fn assert_same_everywhere(path: &Path, block_sizes: &[usize]) -> Outcome {
    let want = reference(path);
    for &workers in &[0, 1, 2, 3] {
        for &block in block_sizes {
            let got = read_with(path, workers, block);
            assert!(
                got == want,
                "{} with {workers} workers, blocks of {block} B: {:?} frames vs {:?}, error {:?} vs {:?}",
                path.display(),
                got.frames.len(),
                want.frames.len(),
                got.error,
                want.error
            );
        }
    }
    want
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

#[test]
fn shipped_replays_and_fixtures_read_the_same_in_parallel() {
    for name in ["pine-35.csv", "maple-24.csv", "forest-3.csv"] {
        let out = assert_same_everywhere(&repo("replays").join(name), &[4096, 100_000]);
        assert!(out.error.is_none() && out.frames.len() >= 900, "{name}");
    }
    let mut files = Vec::new();
    for dir in ["tests/fixtures/motive", "tests/fixtures/motive/quirks"] {
        for e in std::fs::read_dir(repo(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "csv") && !p.ends_with("v1.1_row_typed.csv") {
                files.push(p);
            }
        }
    }
    assert!(files.len() >= 10);
    for p in &files {
        assert_same_everywhere(p, &[64, 1000]);
    }
    // The fixture with a rigid body: its poses follow every frame.
    let rb = reference(&repo(
        "tests/fixtures/motive/cmuphyscomp_sample_take_v1.21.csv",
    ));
    assert!(rb.frames.iter().any(|f| !f.3.is_empty()));
}

/// A sparse export as Motive writes unlabeled markers: `channels` marker
/// channels, of which 20 hold a value in any row, the 20 moving along the
/// columns as markers vanish and reappear under new names.
fn sparse(channels: usize, rows: usize) -> String {
    let mut t = String::from(
        "Format Version,1.23,Take Name,t,Capture Frame Rate,240,Export Frame Rate,240,Length Units,Millimeters\r\n\r\n,Type",
    );
    t += &",Marker".repeat(3 * channels);
    t += "\r\n,Name";
    for c in 0..channels {
        write!(t, ",Unlabeled {c},Unlabeled {c},Unlabeled {c}").unwrap();
    }
    t += "\r\n,ID";
    for c in 0..channels {
        write!(t, ",{c},{c},{c}").unwrap();
    }
    t += "\r\n,";
    t += &",Position".repeat(3 * channels);
    t += "\r\nFrame,Time (Seconds)";
    t += &",X,Y,Z".repeat(channels);
    for i in 0..rows {
        write!(t, "\r\n{i},{:.6}", i as f64 / 240.0).unwrap();
        let first = i * (channels - 20) / rows;
        for c in 0..channels {
            if c < first || c >= first + 20 || (i + c) % 23 == 0 {
                t += ",,,";
            } else {
                let v = ((i * 7 + c) as f64).sin() * 987.654321;
                write!(t, ",{v:.6},{:.6},{:.6}", v * 0.5, -v).unwrap();
            }
        }
    }
    t + "\r\n"
}

#[test]
fn a_sparse_export_of_thousands_of_columns_reads_the_same_in_parallel() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sparse.csv");
    std::fs::write(&path, sparse(1500, 1000)).unwrap();
    let out = assert_same_everywhere(&path, &[4096, 65_536]);
    assert!(out.error.is_none(), "{:?}", out.error);
    assert_eq!(out.frames.len(), 1000);
    assert_eq!(out.channels.len(), 1500);
    let empty: u64 = out.channels.iter().map(|c| c.2).sum();
    let present: u64 = out.channels.iter().map(|c| c.1).sum();
    assert!(present > 18 * 1000, "{present} markers");
    assert_eq!(empty, 1000 * 4500 - 3 * present);
}

/// A dense export of 3 markers in millimetres, `rows` data rows (lines 8…),
/// values with 6 decimals as Motive writes them.
fn dense(rows: usize) -> Vec<String> {
    let mut lines = vec![
        "Format Version,1.23,Take Name,t,Capture Frame Rate,100,Export Frame Rate,100,Length Units,Millimeters".to_string(),
        String::new(),
        ",Type,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker".into(),
        ",Name,a,a,a,b,b,b,c,c,c".into(),
        ",ID,1,1,1,2,2,2,3,3,3".into(),
        ",,Position,Position,Position,Position,Position,Position,Position,Position,Position".into(),
        "Frame,Time,X,Y,Z,X,Y,Z,X,Y,Z".into(),
    ];
    for i in 0..rows {
        let mut l = format!("{i},{:.6}", i as f64 / 100.0);
        for m in 0..3 {
            if (i + m) % 17 == 0 {
                l.push_str(",,,");
                continue;
            }
            for k in 0..3 {
                let v = ((i * 31 + m * 7 + k) as f64 * 0.618034).sin() * 1234.5;
                write!(l, ",{v:.6}").unwrap();
            }
        }
        lines.push(l);
    }
    lines
}

fn write_lines(path: &Path, lines: &[String], crlf: bool) {
    let eol = if crlf { "\r\n" } else { "\n" };
    std::fs::write(path, lines.join(eol) + eol).unwrap();
}

#[test]
fn parallel_values_are_the_standard_parse_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dense.csv");
    let lines = dense(3000);
    write_lines(&path, &lines, true);
    let out = read_with(&path, 2, 4096);
    assert!(out.error.is_none(), "{:?}", out.error);
    let want = read_independently(&lines);
    let got: Vec<_> = out.frames.iter().map(|f| (f.0, f.2.clone())).collect();
    assert_eq!(got, want);
}

/// Reads with small blocks on two workers; the error and the frames before it.
fn deep_error(path: &Path) -> (usize, String) {
    let out = read_with(path, 2, 4096);
    (out.frames.len(), out.error.expect("an error"))
}

#[test]
fn errors_deep_in_a_later_chunk_name_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.csv");
    let bad = 17_000; // line number; data starts at line 8
                      // (what, field spoiled, what it becomes; None drops it, the last one)
    let cases = [
        (
            "not a number",
            2,
            Some("abc"),
            format!("line {bad}, column 3: \"abc"),
        ),
        (
            "open quote",
            3,
            Some("\""),
            format!("line {bad}, column 4: a quote opened here is not closed"),
        ),
        (
            "short row",
            10,
            None,
            format!("line {bad}, column 11: row has 10 fields, the header has 11"),
        ),
    ];
    for crlf in [false, true] {
        for (what, field, prefix, want) in &cases {
            let mut lines = dense(20_000);
            let mut fields: Vec<String> = lines[bad - 1].split(',').map(String::from).collect();
            match prefix {
                Some(p) => fields[*field].insert_str(0, p),
                None => drop(fields.remove(*field)),
            }
            lines[bad - 1] = fields.join(",");
            write_lines(&path, &lines, crlf);
            let (frames, e) = deep_error(&path);
            assert!(e.contains(want.as_str()), "{what}: {e}");
            assert_eq!(frames, bad - 8, "{what}: frames before the error");
            assert_eq!(reference(&path).error.as_deref(), Some(e.as_str()));
        }
    }
}

#[test]
fn rows_past_8_mib_are_refused_at_their_line_deep_in_the_file() {
    const MAX: usize = 8 << 20;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("long.csv");
    let bad = 5_000;
    // (content bytes of the long row, a line end after it, refused?)
    for (content, eol, refused) in [
        (MAX - 1, true, false), // MAX with its line end: the largest row
        (MAX, true, true),
        (MAX, false, false), // the last row, without a line end
        (MAX + 1, false, true),
        (3 * MAX, true, true),
    ] {
        let mut lines = dense(bad + 100);
        let row = "7".repeat(content);
        if eol {
            lines[bad - 1] = row;
        } else {
            lines.truncate(bad - 1);
            lines.push(row);
        }
        let text = lines.join("\n") + if eol { "\n" } else { "" };
        std::fs::write(&path, text).unwrap();
        let (frames, e) = deep_error(&path);
        assert_eq!(frames, bad - 8, "{content} {eol}: {e}");
        let too_long = format!("line {bad}: row is longer than 8 MiB");
        if refused {
            assert!(e.contains(&too_long), "{content} {eol}: {e}");
        } else {
            // Read, then refused for what it holds: one field.
            assert!(
                e.contains(&format!("line {bad}, column 2: row has 1 fields")),
                "{content} {eol}: {e}"
            );
        }
        assert_eq!(reference(&path).error.as_deref(), Some(e.as_str()));
    }
}

#[test]
fn a_truncated_last_row_is_read_as_it_always_was() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.csv");
    let lines = dense(300);
    let full = lines.join("\r\n");
    let last = lines.len(); // the last row's line number
    let last_start = full.len() - lines[last - 1].len();
    // Every cut of the last row, and the complete file without its line end.
    for cut in last_start + 1..=full.len() {
        std::fs::write(&path, &full[..cut]).unwrap();
        let want = reference(&path);
        for (workers, block) in [(2, 4096), (1, 333), (0, 4096)] {
            assert_eq!(read_with(&path, workers, block), want, "cut at {cut}");
        }
        let fields = full[last_start..cut].split(',').count();
        match &want.error {
            None => assert_eq!(fields, 11, "cut at {cut}"),
            Some(e) if fields < 11 => assert!(
                e.contains(&format!(
                    "line {last}, column {}: row has {fields} fields",
                    fields + 1
                )),
                "cut at {cut}: {e}"
            ),
            // A cell cut to `-` is not a number: refused at its line too.
            Some(e) => assert!(
                e.contains(&format!("line {last}, column")),
                "cut at {cut}: {e}"
            ),
        }
        let frames = want.frames.len() + usize::from(want.error.is_some());
        assert_eq!(frames, last - 7, "cut at {cut}");
    }
}

/// Cells in every form a number may take in an export (Motive's six
/// decimals with 1 to 9 integer digits, fewer and more decimals, none, an
/// exponent, very long digit strings, negative zero, leading zeros) and
/// empty ones, so that rows of every length cross the scan's 64-byte steps.
fn every_form(rows: usize) -> Vec<String> {
    let forms: [fn(f64) -> String; 12] = [
        |v| format!("{v:.6}"),
        |v| format!("{:.6}", v * 1e5),
        |v| format!("{:.6}", -v * 1e-4),
        |v| format!("{v:.3}"),
        |v| format!("{v:.9}"),
        |v| format!("{:.0}", v * 10.0),
        |v| format!("{v:e}"),
        |v| format!("{v:E}"),
        |v| format!("{v:.20}"),
        |v| format!("{v}"),
        |v| format!("{:.6}", -v * 0.0),
        |v| format!("000{:.6}", v.abs()),
    ];
    let mut lines = dense(0);
    for i in 0..rows {
        let mut l = format!("{i},{:.6}", i as f64 / 100.0);
        for m in 0..3 {
            if (i + m) % 13 == 0 {
                l.push_str(",,,");
                continue;
            }
            for k in 0..3 {
                let v = ((i * 31 + m * 7 + k) as f64 * 0.618034).sin() * 1234.5;
                l.push(',');
                l.push_str(&forms[(i * 5 + m * 3 + k) % forms.len()](v));
            }
        }
        lines.push(l);
    }
    lines
}

#[test]
fn every_form_of_number_is_the_standard_parse_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for crlf in [false, true] {
        let path = dir.path().join("forms.csv");
        let lines = every_form(2000);
        write_lines(&path, &lines, crlf);
        let want = read_independently(&lines);
        for (workers, block) in [(0, 1 << 30), (2, 1000), (2, 4096)] {
            let out = read_with(&path, workers, block);
            assert!(out.error.is_none(), "{:?}", out.error);
            let got: Vec<_> = out.frames.iter().map(|f| (f.0, f.2.clone())).collect();
            assert!(
                got == want,
                "crlf {crlf}, {workers} workers, {block} B blocks"
            );
        }
    }
}

/// The frames of a three-marker export read independently of the reader:
/// split on commas, `str::parse`, millimetres to metres, as f64 bits.
#[allow(clippy::type_complexity)]
fn read_independently(lines: &[String]) -> Vec<(i64, Vec<(Option<i64>, [u64; 3])>)> {
    let mut want = Vec::new();
    for l in &lines[7..] {
        let cells: Vec<&str> = l.split(',').collect();
        let mut markers = Vec::new();
        for m in 0..3 {
            let xyz = &cells[2 + 3 * m..5 + 3 * m];
            if xyz.iter().all(|c| !c.is_empty()) {
                let p: [u64; 3] =
                    std::array::from_fn(|k| (xyz[k].parse::<f64>().unwrap() * 0.001).to_bits());
                markers.push((Some(m as i64), p));
            }
        }
        want.push((cells[0].parse::<i64>().unwrap(), markers));
    }
    want
}
