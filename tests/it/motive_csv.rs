//! The Motive CSV reader against two real exports and a hand-made file for
//! every quirk in spec/motive-csv.md. Expected values for the real exports were
//! read independently with Python's csv module, not from treemocap's output.

use std::path::{Path, PathBuf};

use treemocap::app::open as replay;
use treemocap::model::recording::{ChannelKind, Format, Recording};
use treemocap::{Error, MarkerFrame};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/motive")
        .join(name)
}

fn quirk(name: &str) -> PathBuf {
    fixture(&format!("quirks/{name}"))
}

fn read_all(path: &Path) -> (Box<dyn Recording>, Vec<MarkerFrame>) {
    let mut rec = replay::open(path).unwrap_or_else(|e| panic!("{e}"));
    let mut frames = Vec::new();
    for f in rec.by_ref() {
        frames.push(f.unwrap_or_else(|e| panic!("{e}")));
    }
    (rec, frames)
}

fn read_err(path: &Path) -> Error {
    match replay::open(path) {
        Err(e) => e,
        Ok(mut rec) => rec
            .find_map(|f| f.err())
            .unwrap_or_else(|| panic!("{} read without error", path.display())),
    }
}

fn assert_close(a: [f64; 3], b: [f64; 3]) {
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() < 1e-9, "{a:?} != {b:?}");
    }
}

#[test]
fn ha5dzs_v1_23_unlabeled_360hz_millimetres() {
    let (rec, frames) = read_all(&fixture("ha5dzs_test_markers_enabled_v1.23_unlabeled.csv"));
    let info = rec.info();
    assert_eq!(info.format, Format::MotiveCsv);
    assert_eq!(info.version, "1.23");
    assert_eq!(info.frame_rate, 360.0);
    assert_eq!(frames.len(), 1353);
    assert_eq!(frames[0].frame, 0);
    assert_eq!(frames.last().unwrap().frame, 1352);
    let counts: Vec<usize> = frames.iter().map(|f| f.markers.len()).collect();
    assert_eq!(*counts.iter().min().unwrap(), 15);
    assert_eq!(*counts.iter().max().unwrap(), 18);
    assert_eq!(counts.iter().sum::<usize>(), 22305);
    assert_eq!(frames[0].markers.len(), 15);
    let gaps: u64 = rec.channels().iter().map(|c| c.empty_cells).sum();
    assert_eq!(gaps, 6147);
    assert_eq!(rec.channels().len(), 18);
    assert!(rec
        .channels()
        .iter()
        .all(|c| c.kind == ChannelKind::Unlabeled));
    // Millimetres become metres.
    assert_close(
        frames[0].markers[0].position.to_array(),
        [2.659741943, -0.830793884, -2.86219165],
    );
    assert_close(
        frames[0].markers[1].position.to_array(),
        [2.030914551, 0.035370396, 0.724494568],
    );
    assert_close(
        frames
            .last()
            .unwrap()
            .markers
            .last()
            .unwrap()
            .position
            .to_array(),
        [-0.253554016, 1.443401001, 1.830059082],
    );
    // Time is frame / rate, not the millisecond-quantized Time column.
    assert_eq!(frames[3].time_s, 3.0 / 360.0);
    assert!(rec.warnings().is_empty(), "{:?}", rec.warnings());
}

#[test]
fn cmuphyscomp_v1_21_rigid_body_kept_apart() {
    let (rec, frames) = read_all(&fixture("cmuphyscomp_sample_take_v1.21.csv"));
    assert_eq!(rec.info().version, "1.21");
    assert_eq!(rec.info().frame_rate, 120.0);
    assert_eq!(frames.len(), 250);
    assert_eq!((frames[0].frame, frames[249].frame), (0, 249));
    // 9 Marker columns: 3 labeled + 6 unlabeled, 3 of which are always empty.
    let markers: Vec<_> = rec
        .channels()
        .iter()
        .filter(|c| c.kind.is_marker())
        .collect();
    assert_eq!(markers.len(), 9);
    assert_eq!(
        markers
            .iter()
            .filter(|c| c.kind == ChannelKind::Unlabeled)
            .count(),
        6
    );
    assert_eq!(markers.iter().filter(|c| c.present == 0).count(), 3);
    let kinds = |k| rec.channels().iter().filter(|c| c.kind == k).count();
    assert_eq!(kinds(ChannelKind::RigidBody), 1);
    assert_eq!(kinds(ChannelKind::RigidBodyMarker), 3);
    assert!(frames.iter().all(|f| f.markers.len() == 6));
    let gaps: u64 = markers.iter().map(|c| c.empty_cells).sum();
    assert_eq!(gaps, 2250);
    assert_close(
        frames[0].markers[0].position.to_array(),
        [-0.724127, 0.716956, 2.824065],
    );
    assert_close(
        frames[0].markers[1].position.to_array(),
        [-0.733624, 0.731344, 2.337087],
    );
    assert_close(
        frames[249].markers.last().unwrap().position.to_array(),
        [0.160351, 0.01916, 0.009576],
    );
}

#[test]
fn v1_25_bom_crlf_parent_row_and_same_name_twice() {
    let (rec, frames) = read_all(&quirk("v1.25_bom_crlf_parent.csv"));
    assert_eq!(rec.info().version, "1.25");
    assert_eq!(rec.info().source, "Take 2025-03-01 Gaga");
    let ch = rec.channels();
    let kinds: Vec<_> = ch.iter().map(|c| c.kind).collect();
    assert_eq!(
        kinds,
        [
            ChannelKind::RigidBody,
            ChannelKind::RigidBodyMarker,
            ChannelKind::Marker,
            ChannelKind::Unlabeled
        ]
    );
    // `Box:Marker1` is both a rigid-body marker and a marker: only the latter is a tip candidate.
    assert_eq!(ch[1].name, "Box:Marker1");
    assert_eq!(ch[2].name, "Box:Marker1");
    assert_eq!(frames.len(), 3, "row 1 claims 17263 frames; the file has 3");
    assert_eq!(frames[0].markers.len(), 2);
    assert_close(
        frames[0].markers[0].position.to_array(),
        [0.111, 0.211, 0.311],
    );
    assert_eq!(frames[0].markers[0].id, Some(2));
    assert_eq!(frames[1].markers.len(), 1);
    assert_close(
        frames[1].markers[0].position.to_array(),
        [1.501, 2.502, -0.503],
    );
    assert_eq!(frames[2].markers.len(), 1);
}

#[test]
fn v1_24_timecode_column() {
    let (rec, frames) = read_all(&quirk("v1.24_timecode.csv"));
    assert_eq!(rec.channels().len(), 2);
    assert_eq!(frames.len(), 3);
    assert_close(frames[0].markers[0].position.to_array(), [1.0, 2.0, 3.0]);
    assert_close(frames[0].markers[1].position.to_array(), [-0.01, 1.5, 0.02]);
    assert_eq!(frames[1].markers.len(), 1);
    assert_close(
        frames[2].markers[1].position.to_array(),
        [-0.0125, 1.5025, 0.0225],
    );
}

#[test]
fn excel_resaved_file() {
    let (rec, frames) = read_all(&quirk("v1.23_excel_resaved.csv"));
    assert_eq!(rec.info().frame_rate, 120.0);
    assert_eq!(rec.channels().len(), 1);
    assert_eq!(rec.channels()[0].kind, ChannelKind::Marker);
    assert_eq!(frames.len(), 2);
    assert_close(frames[0].markers[0].position.to_array(), [0.0, 1.2, 0.005]);
    assert_close(
        frames[1].markers[0].position.to_array(),
        [0.0015, 1.201, 0.00525],
    );
    assert_eq!(frames[1].time_s, 1.0 / 120.0);
}

#[test]
fn centimetres_and_frames_that_start_late_and_jump() {
    let (_, frames) = read_all(&quirk("v1.23_centimeters_jumps.csv"));
    let numbers: Vec<i64> = frames.iter().map(|f| f.frame).collect();
    assert_eq!(numbers, [72210, 72211, 72215, 72300]);
    assert_eq!(frames[2].time_s, 72215.0 / 100.0);
    assert_close(frames[0].markers[0].position.to_array(), [0.1, 1.5, -0.2]);
    assert_close(
        frames[3].markers[0].position.to_array(),
        [0.11, 1.51, -0.21],
    );
}

#[test]
fn take_without_assets_gives_empty_frames() {
    let (rec, frames) = read_all(&quirk("v1.23_empty_take.csv"));
    assert!(rec.channels().is_empty());
    assert_eq!(frames.len(), 3);
    assert!(frames.iter().all(|f| f.markers.is_empty()));
}

#[test]
fn row_typed_v1_1_is_rejected_clearly() {
    let e = read_err(&quirk("v1.1_row_typed.csv"));
    let msg = e.to_string();
    assert!(msg.contains("v1.1_row_typed.csv"), "{msg}");
    assert!(msg.contains("unsupported format version"), "{msg}");
}

#[test]
fn malformed_rows_name_line_and_column() {
    let e = read_err(&quirk("bad_short_row.csv")).to_string();
    assert!(
        e.contains("bad_short_row.csv") && e.contains("line 9"),
        "{e}"
    );
    assert!(e.contains("4 fields"), "{e}");

    let e = read_err(&quirk("bad_not_a_number.csv")).to_string();
    assert!(
        e.contains("line 9, column 4") && e.contains("\"abc\""),
        "{e}"
    );

    let e = read_err(&quirk("bad_missing_header_row.csv")).to_string();
    assert!(e.contains("line 7") && e.contains("header row"), "{e}");

    let e = read_err(&quirk("bad_no_units.csv")).to_string();
    assert!(e.contains("line 1") && e.contains("Length Units"), "{e}");
}

#[test]
fn frames_before_an_error_are_kept() {
    let mut rec = replay::open(&quirk("bad_not_a_number.csv")).unwrap();
    let first = rec.next().unwrap().unwrap();
    assert_eq!(first.markers.len(), 1);
    assert!(rec.next().unwrap().is_err());
    assert!(rec.next().is_none());
}

#[test]
fn every_cut_of_a_real_file_errors_or_reads_never_panics() {
    let bytes = std::fs::read(fixture("cmuphyscomp_sample_take_v1.21.csv")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.csv");
    for cut in (0..bytes.len()).step_by(97) {
        std::fs::write(&path, &bytes[..cut]).unwrap();
        if let Ok(rec) = replay::open(&path) {
            for f in rec {
                if f.is_err() {
                    break;
                }
            }
        }
    }
}

/// `treemocap inspect FILE` with its address space limited to `mib` MiB
/// (the shell's `ulimit -v`, so the limit binds the child only).
fn inspect_in(mib: u64, file: &Path) -> std::process::Output {
    std::process::Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {}; exec \"$0\" inspect \"$1\"",
            mib * 1024
        ))
        .arg(env!("CARGO_BIN_EXE_treemocap"))
        .arg(file)
        .output()
        .unwrap()
}

const ROW1: &str = "Format Version,1.23,Take Name,t,Capture Frame Rate,100,\
                    Export Frame Rate,100,Length Units,Meters";

/// Hostile first rows and absurd header rows are refused with one line
/// naming their line, in memory bounded by the longest row treemocap reads
/// (the 10 MB file of 5 million fields took 880 MB). A wide file of
/// real size reads under the same limit.
#[test]
fn absurd_rows_are_refused_in_bounded_memory() {
    const LIMIT_MIB: u64 = 256;
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let cases = [
        // 10 MB: the first row of 5 million fields.
        (
            write("row1.csv", &format!("{ROW1}{}\n", ",a".repeat(5_000_000))),
            "line 1: row is longer than 8 MiB",
        ),
        // 1 million one-byte fields, each a key: refused by count.
        (
            write("keys.csv", &format!("{ROW1}{}\n", ",k".repeat(1_000_000))),
            "line 1, column 200001: row has more than 200000 fields",
        ),
        // A Type row of 1 million columns.
        (
            write(
                "types.csv",
                &format!("{ROW1}\n\n,Type{}\n", ",Marker".repeat(1_000_000)),
            ),
            "line 3, column 200001: row has more than 200000 fields",
        ),
        // Header rows without end before `Frame,Time`.
        (
            write(
                "rows.csv",
                &format!("{ROW1}\n{}", ",Name,x\n".repeat(100_000)),
            ),
            "line 18: more than 16 header rows",
        ),
    ];
    for (file, expected) in &cases {
        let out = inspect_in(LIMIT_MIB, file);
        let e = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{}: {e}", file.display());
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(e.contains(expected), "{}: {e}", file.display());
    }

    // 20 000 markers (60 000 columns, rows of 600 KB): read, not refused.
    let n = 20_000;
    let mut t = format!("{ROW1}\n\n,Type");
    t += &",Marker".repeat(3 * n);
    t += "\n,Name";
    for i in 0..n {
        t += &format!(",M{i},M{i},M{i}");
    }
    t += "\n,ID";
    for i in 0..n {
        t += &format!(",{i},{i},{i}");
    }
    t += "\n,";
    t += &",Position".repeat(3 * n);
    t += "\nFrame,Time";
    t += &",X,Y,Z".repeat(n);
    for f in 0..3 {
        t += &format!("\n{f},{}", f as f64 / 100.0);
        t += &",0.123456,1.234567,-0.345678".repeat(n);
    }
    t += "\n";
    let wide = write("wide.csv", &t);
    let out = inspect_in(LIMIT_MIB, &wide);
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        s.contains("frames      3 ") && s.contains("20000 marker columns"),
        "{s}"
    );
}
