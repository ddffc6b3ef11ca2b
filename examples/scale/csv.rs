//! Motive CSV reading beside `cat` (the warm-cache read speed of the same
//! file) and pandas, on a dense export (fixed columns) and a sparse one
//! (unlabeled markers: a column per reappearance, thousands of them).

use std::io::Write;
use std::path::Path;

use treemocap::app::synth::write_session;
use treemocap::format::motive_csv::{MotiveCsvReader, ReadOptions};
use treemocap::sim::{CrownShape, SynthOptions};

use crate::util::{cat_seconds, mb_s, or_dash, peer_seconds, timed, Row, Scale};

/// A dense Motive 1.23 export: `markers` labeled markers in fixed columns,
/// about 5 % gaps, 6 decimals, CRLF, as Motive writes after labeling.
fn write_dense(path: &Path, frames: usize, markers: usize, rate: f64) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).expect("dense file"));
    let mut w = |s: &str| f.write_all(s.as_bytes()).expect("write");
    w(&format!("Format Version,1.23,Take Name,dense,Take Notes,,Capture Frame Rate,{rate:.6},Export Frame Rate,{rate:.6},Capture Start Time,2026-01-01 01.00.00.000 PM,Total Frames in Take,{frames},Total Exported Frames,{frames},Rotation Type,Quaternion,Length Units,Millimeters,Coordinate Space,Global\r\n\r\n"));
    let row = |label: &str, cell: &dyn Fn(usize) -> String| {
        let mut s = format!(",{label}");
        for m in 0..markers {
            for _ in 0..3 {
                s.push(',');
                s.push_str(&cell(m));
            }
        }
        s + "\r\n"
    };
    w(&row("Type", &|_| "Marker".into()));
    w(&row("Name", &|m| format!("tree:tip{m}")));
    w(&row("ID", &|m| format!("1:{m}")));
    w(&row("", &|_| "Position".into()));
    w(&format!(
        "Frame,Time (Seconds){}\r\n",
        ",X,Y,Z".repeat(markers)
    ));
    let mut line = String::new();
    for i in 0..frames {
        line.clear();
        line.push_str(&format!("{i},{:.6}", i as f64 / rate));
        for m in 0..markers {
            if (i * 7 + m * 13) % 20 == 0 {
                line.push_str(",,,");
            } else {
                let t = i as f64 / rate + m as f64;
                line.push_str(&format!(
                    ",{:.6},{:.6},{:.6}",
                    1000.0 * t.sin(),
                    1500.0 + m as f64 * 10.0,
                    -200.0 * t.cos()
                ));
            }
        }
        line.push_str("\r\n");
        w(&line);
    }
}

/// Reads the whole export with `options`; (seconds, marker samples, columns).
fn read_all(path: &Path, options: ReadOptions) -> (f64, u64, usize) {
    let ((samples, columns), s) = timed(|| {
        let file = std::fs::File::open(path).expect("open");
        let r = MotiveCsvReader::from_file_with(file, path, 0.002, options).expect("open");
        let columns = treemocap::format::Recording::channels(&r).len() * 3;
        let mut n = 0u64;
        for f in r {
            n += f.expect("frame").markers.len() as u64;
        }
        (n, columns)
    });
    (s, samples, columns)
}

/// One file: treemocap, cat and pandas on it.
fn measure(name: &str, path: &Path) -> Row {
    let bytes = std::fs::metadata(path).map_or(0, |m| m.len());
    let cat = cat_seconds(path);
    let best = |options: ReadOptions| {
        (0..3)
            .map(|_| read_all(path, options))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .expect("three runs")
    };
    let parallel = ReadOptions::default();
    let (ours, samples, columns) = best(parallel);
    let (one_thread, ..) = best(ReadOptions {
        workers: 0,
        ..parallel
    });
    let pandas = peer_seconds(&["pandas-motive", &path.to_string_lossy()]);
    println!(
        "csv {name}: {:.0} MB, {columns} columns, {samples} samples: treemocap {ours:.2} s \
         ({} workers; {one_thread:.2} s on one thread), cat {cat:.3} s, pandas {}",
        bytes as f64 / 1e6,
        parallel.workers,
        or_dash(pandas, |p| format!("{p:.2} s"))
    );
    Row::new(
        format!(
            "Motive CSV reading, {name} ({:.0} MB, {columns} columns)",
            bytes as f64 / 1e6
        ),
        "≥ 1/10 of `cat`",
        format!(
            "{:.0} MB/s = 1/{:.1} of cat ({:.0} MB/s); {:.1} M samples/s; \
             one thread: {:.0} MB/s = 1/{:.1} of cat",
            mb_s(bytes, ours),
            ours / cat,
            mb_s(bytes, cat),
            samples as f64 / ours / 1e6,
            mb_s(bytes, one_thread),
            one_thread / cat
        ),
        or_dash(pandas, |p| {
            format!(
                "pandas {:.0} MB/s ({:.1}× slower)",
                mb_s(bytes, p),
                p / ours
            )
        }),
    )
}

/// The dense and the sparse export.
pub fn reading(scale: &Scale) -> Vec<Row> {
    let minutes = if scale.quick { 1.0 } else { 10.0 };
    let dense = scale.path("dense.csv");
    write_dense(&dense, (minutes * 60.0 * 240.0) as usize, 70, 240.0);
    let sparse = scale.path("sparse.csv");
    let opts = SynthOptions {
        seed: 15,
        tips: 70,
        shape: CrownShape::Maple,
        frame_rate: 240.0,
        still_s: 30.0,
        wind_s: if scale.quick { 60.0 } else { 150.0 },
        ..Default::default()
    };
    write_session(&opts, &sparse).expect("sparse session");
    vec![
        measure(
            &format!("dense, {minutes} min at 240 Hz × 70 markers"),
            &dense,
        ),
        measure(
            &format!(
                "sparse, {} s at 240 Hz × 70 unlabeled",
                opts.still_s + opts.wind_s
            ),
            &sparse,
        ),
    ]
}
