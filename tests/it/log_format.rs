//! Our own recording format: exact round trips, crash-cut files, and reading
//! a file while it is still being written.

use std::io::Write;
use std::time::Duration;

use glam::DVec3;
use treemocap::app::open as replay;
use treemocap::format::log::{LogHeader, LogReader, LogWriter};
use treemocap::model::recording::{Format, Recording};
use treemocap::rng::Rng;
use treemocap::{Marker, MarkerFrame};

fn header() -> LogHeader {
    LogHeader {
        source: "test bench, seed 7".into(),
        frame_rate: 240.0,
    }
}

/// Frames with awkward values: negative zero, tiny and huge numbers, ids and
/// no ids, empty frames, jumps and a restart.
fn awkward_frames() -> Vec<MarkerFrame> {
    let mut rng = Rng::new(7);
    let mut frames = Vec::new();
    let numbers = [0i64, 1, 2, 5, 6, 7, 0, 1, -3];
    for (k, &n) in numbers.iter().enumerate() {
        let count = if k == 3 { 0 } else { rng.int(1, 12) as usize };
        let markers = (0..count)
            .map(|i| Marker {
                position: DVec3::new(
                    rng.normal() * 1e-7,
                    if i == 0 { -0.0 } else { rng.range(-3.0, 3.0) },
                    rng.normal() * 1e6,
                ),
                id: if i % 2 == 0 {
                    Some(i as i64 * 1000 - 5)
                } else {
                    None
                },
            })
            .collect();
        frames.push(MarkerFrame::new(n, n as f64 / 240.0 + k as f64, markers));
    }
    frames
}

fn read_all(reader: &mut LogReader) -> Vec<MarkerFrame> {
    reader.by_ref().map(|f| f.unwrap()).collect()
}

#[test]
fn round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("session.log.csv");
    let frames = awkward_frames();
    let mut w = LogWriter::create(&path, &header(), Duration::from_secs(1)).unwrap();
    for f in &frames {
        w.write_frame(f).unwrap();
    }
    w.finish().unwrap();

    assert_eq!(replay::detect(&path).unwrap(), Format::Log);
    let mut r = treemocap::app::open::log(&path).unwrap();
    assert_eq!(r.info().frame_rate, 240.0);
    assert_eq!(r.info().source, "test bench, seed 7");
    let back = read_all(&mut r);
    assert_eq!(back.len(), frames.len());
    for (a, b) in frames.iter().zip(&back) {
        assert_eq!(a.frame, b.frame);
        assert_eq!(a.time_s.to_bits(), b.time_s.to_bits());
        assert_eq!(a.markers.len(), b.markers.len());
        for (m, n) in a.markers.iter().zip(&b.markers) {
            assert_eq!(m.id, n.id);
            for k in 0..3 {
                assert_eq!(m.position[k].to_bits(), n.position[k].to_bits());
            }
        }
    }
    assert!(r.finish().is_empty());
}

#[test]
fn a_file_cut_mid_line_reads_up_to_its_last_whole_row() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("crash.csv");
    let frames = awkward_frames();
    let mut w = LogWriter::create(&path, &header(), Duration::from_secs(1)).unwrap();
    for f in &frames {
        w.write_frame(f).unwrap();
    }
    w.finish().unwrap();
    let full = std::fs::read(&path).unwrap();
    // Cut 5 bytes into the last row, as a crash during a write would.
    let last_row_start = full[..full.len() - 1]
        .iter()
        .rposition(|&b| b == b'\n')
        .unwrap()
        + 1;
    std::fs::write(&path, &full[..last_row_start + 5]).unwrap();

    let mut r = treemocap::app::open::log(&path).unwrap();
    let back = read_all(&mut r);
    let whole: usize = frames.iter().map(|f| f.markers.len().max(1)).sum::<usize>() - 1;
    let rows: usize = back.iter().map(|f| f.markers.len().max(1)).sum();
    assert_eq!(rows, whole, "every whole row and nothing else");
    let warnings = r.finish();
    assert_eq!(warnings.len(), 1);
    assert!(warnings[0].contains("crash.csv") && warnings[0].contains("cut off"));
}

#[test]
fn a_file_being_appended_can_be_followed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("live.csv");
    let frames = awkward_frames();
    let mut w = LogWriter::create(&path, &header(), Duration::from_secs(1)).unwrap();
    for f in &frames[..4] {
        w.write_frame(f).unwrap();
    }
    w.flush().unwrap();
    let mut r = treemocap::app::open::log(&path).unwrap();
    let first = read_all(&mut r);
    assert_eq!(first.len(), 4);

    // Half a row arrives: nothing new yet, and the half row is not misread.
    let mut raw = std::fs::OpenOptions::new()
        .append(true)
        .open(&path)
        .unwrap();
    raw.write_all(b"6,0.1,,1.5,2").unwrap();
    assert!(r.next().is_none());
    raw.write_all(b".5,3.5\n").unwrap();
    let f = r.next().unwrap().unwrap();
    assert_eq!((f.frame, f.markers.len()), (6, 1));
    assert_eq!(f.markers[0].position, DVec3::new(1.5, 2.5, 3.5));
    assert!(r.finish().is_empty());
}

#[test]
fn writer_flushes_within_the_interval_without_being_asked() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flush.csv");
    let mut w = LogWriter::create(&path, &header(), Duration::from_millis(50)).unwrap();
    let frame = MarkerFrame::new(0, 0.0, vec![Marker::new(DVec3::ONE)]);
    w.write_frame(&frame).unwrap();
    std::thread::sleep(Duration::from_millis(60));
    w.tick().unwrap();
    // Read while the writer is alive (as after a SIGKILL): the frame is there.
    let mut r = treemocap::app::open::log(&path).unwrap();
    assert_eq!(read_all(&mut r).len(), 1);
    drop(w);
}

#[test]
fn bad_rows_name_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.csv");
    std::fs::write(
        &path,
        "# treemocap log 1\n# frame_rate: 100\nframe,time_s,id,x,y,z\n0,0,,1,2,3\n1,0.01,,1,x,3\n",
    )
    .unwrap();
    let mut r = treemocap::app::open::log(&path).unwrap();
    let first = r.next().unwrap();
    assert!(first.is_ok(), "{first:?}");
    let e = r.next().unwrap().unwrap_err().to_string();
    assert!(
        e.contains("bad.csv") && e.contains("line 5, column 5"),
        "{e}"
    );

    std::fs::write(&path, "# treemocap log 1\nframe,time_s,id,x,y,z\n").unwrap();
    let e = treemocap::app::open::log(&path).err().unwrap().to_string();
    assert!(e.contains("frame_rate"), "{e}");
    std::fs::write(&path, "# treemocap log 9\n").unwrap();
    let e = treemocap::app::open::log(&path).err().unwrap().to_string();
    assert!(e.contains("version"), "{e}");
}
