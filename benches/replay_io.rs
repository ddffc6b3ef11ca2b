//! Reading Motive CSV exports and writing our own log: samples per second.
//! Targets: reading ≥ 2 million marker samples/s, log writing ≥ 1 million/s;
//! a wide export (thousands of mostly empty columns, as Motive writes
//! unlabeled markers) costs per cell holding a number, not per column
//! (issue 15: compare bytes/s with the dense file's).

use std::io::Write;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::DVec3;
use treemocap::format::log::{LogHeader, LogWriter};
use treemocap::format::motive_csv::{MotiveCsvReader, ReadOptions, DEFAULT_TIME_TOLERANCE_S};
use treemocap::{Marker, MarkerFrame};

const MARKERS: usize = 35;
const FRAMES: usize = 4000;

/// A 1.23 export in millimetres with 35 unlabeled markers and ~5 % gaps,
/// formatted like Motive (6 decimals, CRLF).
fn write_export(path: &std::path::Path) -> usize {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    write!(f, "Format Version,1.23,Take Name,bench,Take Notes,,Capture Frame Rate,100.000000,Export Frame Rate,100.000000,Capture Start Time,2026-01-01 01.00.00.000 PM,Total Frames in Take,{FRAMES},Total Exported Frames,{FRAMES},Rotation Type,Quaternion,Length Units,Millimeters,Coordinate Space,Global\r\n\r\n").unwrap();
    let row = |f: &mut dyn Write, label: &str, cell: &dyn Fn(usize) -> String| {
        write!(f, ",{label}").unwrap();
        for m in 0..MARKERS {
            for _ in 0..3 {
                write!(f, ",{}", cell(m)).unwrap();
            }
        }
        write!(f, "\r\n").unwrap();
    };
    row(&mut f, "Type", &|_| "Marker".into());
    row(&mut f, "Name", &|m| format!("Unlabeled {}", 1000 + m));
    row(&mut f, "ID", &|m| format!("\"{:X}A2A8F984BAAD11EE\"", m));
    row(&mut f, "", &|_| "Position".into());
    write!(f, "Frame,Time (Seconds)").unwrap();
    for _ in 0..MARKERS {
        write!(f, ",X,Y,Z").unwrap();
    }
    write!(f, "\r\n").unwrap();
    let mut samples = 0;
    for i in 0..FRAMES {
        write!(f, "{i},{:.6}", i as f64 / 100.0).unwrap();
        for m in 0..MARKERS {
            if (i * 7 + m * 13) % 20 == 0 {
                write!(f, ",,,").unwrap();
            } else {
                samples += 1;
                let t = i as f64 * 0.01 + m as f64;
                write!(
                    f,
                    ",{:.6},{:.6},{:.6}",
                    1000.0 * t.sin(),
                    1500.0 + m as f64 * 10.0,
                    -200.0 * t.cos()
                )
                .unwrap();
            }
        }
        write!(f, "\r\n").unwrap();
    }
    samples
}

fn read_motive_csv(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bench.csv");
    let samples = write_export(&path);
    let mut g = c.benchmark_group("motive_csv");
    g.throughput(Throughput::Elements(samples as u64));
    g.sample_size(20);
    g.bench_function("read_35_markers_4000_frames", |b| {
        b.iter(|| {
            let reader = treemocap::app::open::motive_csv(&path).unwrap();
            let n: usize = reader.map(|f| f.unwrap().markers.len()).sum();
            assert_eq!(n, samples);
        })
    });
    g.finish();
}

/// An export of `channels` unlabeled marker channels of which only the 35
/// of the current "generation" hold numbers in any row (Motive gives a
/// marker a new column after every occlusion), like a long take.
fn write_wide_export(path: &std::path::Path, channels: usize) -> usize {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    write!(f, "Format Version,1.23,Take Name,wide,Capture Frame Rate,100.000000,Export Frame Rate,100.000000,Length Units,Millimeters\r\n\r\n").unwrap();
    let row = |f: &mut dyn Write, label: &str, cell: &dyn Fn(usize) -> String| {
        write!(f, ",{label}").unwrap();
        for m in 0..channels {
            let v = cell(m);
            write!(f, ",{v},{v},{v}").unwrap();
        }
        write!(f, "\r\n").unwrap();
    };
    row(&mut f, "Type", &|_| "Marker".into());
    row(&mut f, "Name", &|m| format!("Unlabeled {}", 1000 + m));
    row(&mut f, "", &|_| "Position".into());
    write!(f, "Frame,Time (Seconds){}\r\n", ",X,Y,Z".repeat(channels)).unwrap();
    let mut samples = 0;
    let mut line = String::new();
    for i in 0..FRAMES {
        line.clear();
        line.push_str(&format!("{i},{:.6}", i as f64 / 100.0));
        let generation = i * channels / FRAMES / MARKERS * MARKERS;
        for m in 0..channels {
            if m >= generation && m < generation + MARKERS {
                samples += 1;
                let t = i as f64 * 0.01 + m as f64;
                line.push_str(&format!(
                    ",{:.6},{:.6},{:.6}",
                    1000.0 * t.sin(),
                    1500.0,
                    -200.0 * t.cos()
                ));
            } else {
                line.push_str(",,,");
            }
        }
        line.push_str("\r\n");
        f.write_all(line.as_bytes()).unwrap();
    }
    samples
}

/// The export at `path`, its rows parsed by `workers` threads (`None`: the default).
fn open_with(path: &std::path::Path, workers: Option<usize>) -> MotiveCsvReader {
    let mut options = ReadOptions::default();
    if let Some(w) = workers {
        options.workers = w;
    }
    let file = std::fs::File::open(path).unwrap();
    MotiveCsvReader::from_file_with(file, path, DEFAULT_TIME_TOLERANCE_S, options).unwrap()
}

fn read_wide_motive_csv(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mut g = c.benchmark_group("motive_csv_bytes");
    g.sample_size(10);
    for (name, path, samples) in [
        ("dense_35_markers", dir.path().join("dense.csv"), 0),
        (
            "wide_3000_channels_35_present",
            dir.path().join("wide.csv"),
            1,
        ),
    ] {
        let samples = if samples == 0 {
            write_export(&path)
        } else {
            write_wide_export(&path, 3000)
        };
        g.throughput(Throughput::Bytes(std::fs::metadata(&path).unwrap().len()));
        // The default reader (rows parsed on worker threads) and the
        // single-threaded path, on the same file.
        for (suffix, workers) in [("", None), ("_1_thread", Some(0))] {
            g.bench_function(format!("{name}{suffix}"), |b| {
                b.iter(|| {
                    let n: usize = open_with(&path, workers)
                        .map(|f| f.unwrap().markers.len())
                        .sum();
                    assert_eq!(n, samples);
                })
            });
        }
    }
    g.finish();
}

fn write_log(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bench.log.csv");
    let frames: Vec<MarkerFrame> = (0..1000)
        .map(|i| {
            let markers = (0..MARKERS)
                .map(|m| {
                    Marker::new(DVec3::new(
                        i as f64 * 1e-3,
                        1.5 + m as f64 * 0.01,
                        -0.123456789,
                    ))
                })
                .collect();
            MarkerFrame::new(i, i as f64 / 100.0, markers)
        })
        .collect();
    let mut g = c.benchmark_group("log");
    g.throughput(Throughput::Elements((1000 * MARKERS) as u64));
    g.sample_size(20);
    g.bench_function("write_35_markers_1000_frames", |b| {
        b.iter(|| {
            let header = LogHeader {
                source: "bench".into(),
                frame_rate: 100.0,
            };
            let mut w = LogWriter::create(&path, &header, Duration::from_secs(1)).unwrap();
            for f in &frames {
                w.write_frame(f).unwrap();
            }
            w.flush().unwrap();
        })
    });
    g.finish();
}

criterion_group!(benches, read_motive_csv, read_wide_motive_csv, write_log);
criterion_main!(benches);
