//! Writes a synthetic session as a Motive 1.23 CSV export of unlabeled
//! markers, byte for byte the way Motive 2.x lays one out
//! (spec/motive-csv.md §1 and the ha5dzs fixture): row 1 key/value pairs,
//! an empty row 2, `Type`/`Name`/`ID` rows, the component row, the axis row,
//! then one row per frame with 6-decimal millimetres and empty cells for
//! gaps. Lines end in CRLF as in most real exports.
//!
//! Numbers are printed with Rust's own fixed-decimal formatting, which is
//! exact and platform independent, so the bytes depend only on the session.

use std::fmt::Write as _;
use std::io::{self, Write};

use super::motion::stream;
use super::Synthetic;
use crate::model::frame::MarkerFrame;
use crate::rng::Rng;

/// Stream label for the take's ID suffix.
const ID_SUFFIX: u64 = 0x1D;

/// The take start written in row 1. Fixed (**ours**): a wall-clock time
/// would make the bytes differ on every run.
const CAPTURE_START: &str = "2013-05-08 10.00.00.000 AM";

fn bad(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, msg)
}

/// Writes `syn` as a Motive 1.23 CSV. Every marker's `id` must name one of
/// `syn.columns`, and markers of a frame must come in column order.
pub fn write_motive_csv(syn: &Synthetic, out: &mut impl Write) -> io::Result<()> {
    let ncols = syn.columns.len();
    let mut line = String::with_capacity(64 + ncols * 40);
    key_value_rows(syn, &mut line)?;
    out.write_all(line.as_bytes())?;
    let suffix = id_suffix(syn);
    for (label, cell) in [("Type", 0), ("Name", 1), ("ID", 2), ("", 3)] {
        line.clear();
        descriptor_row(syn, label, cell, &suffix, &mut line);
        out.write_all(line.as_bytes())?;
    }
    line.clear();
    line.push_str("Frame,Time (Seconds)");
    for _ in 0..ncols {
        line.push_str(",X,Y,Z");
    }
    line.push_str("\r\n");
    out.write_all(line.as_bytes())?;
    for frame in &syn.frames {
        line.clear();
        data_row(frame, ncols, &mut line)?;
        out.write_all(line.as_bytes())?;
    }
    out.flush()
}

/// Row 1 (the take's keys and values) and the empty row 2. The take name
/// is written unquoted, so it may not hold CSV delimiters.
fn key_value_rows(syn: &Synthetic, line: &mut String) -> io::Result<()> {
    let truth = &syn.truth;
    let take = if truth.options.take_name.is_empty() {
        "synthetic"
    } else {
        truth.options.take_name.as_str()
    };
    if take.contains([',', '"', '\r', '\n']) {
        return Err(bad(format!(
            "take name '{take}' may not contain commas, quotes or line breaks"
        )));
    }
    let rate = format!("{:.6}", truth.frame_rate);
    let n = syn.frames.len();
    write!(
        line,
        "Format Version,1.23,Take Name,{take},Take Notes,,Capture Frame Rate,{rate},\
         Export Frame Rate,{rate},Capture Start Time,{CAPTURE_START},Total Frames in Take,{n},\
         Total Exported Frames,{n},Rotation Type,Quaternion,Length Units,Millimeters,\
         Coordinate Space,Global\r\n\r\n"
    )
    .ok();
    Ok(())
}

/// The per-take part of the marker IDs. Motive 2.x unlabeled IDs look like
/// "1A2A8F984BAAD11EE": a running number in hex followed by this suffix.
fn id_suffix(syn: &Synthetic) -> String {
    format!(
        "{:016X}",
        stream(&Rng::new(syn.truth.options.seed), ID_SUFFIX).next_u64()
    )
}

/// One of the `Type`, `Name`, `ID` and component rows (`cell` 0 to 3):
/// the same cell three times per column, for its X, Y and Z.
fn descriptor_row(syn: &Synthetic, label: &str, cell: u8, suffix: &str, line: &mut String) {
    write!(line, ",{label}").ok();
    for (c, col) in syn.columns.iter().enumerate() {
        for _ in 0..3 {
            match cell {
                0 => line.push_str(",Marker"),
                1 => {
                    line.push(',');
                    line.push_str(&col.name);
                }
                2 => {
                    write!(line, ",\"{:X}{suffix}\"", c + 1).ok();
                }
                _ => line.push_str(",Position"),
            }
        }
    }
    line.push_str("\r\n");
}

/// One frame's row: millimetres to 6 decimals in each marker's column,
/// empty cells for the columns without a marker.
fn data_row(frame: &MarkerFrame, ncols: usize, line: &mut String) -> io::Result<()> {
    write!(line, "{},{:.6}", frame.frame, frame.time_s).ok();
    let mut next = 0usize;
    for m in &frame.markers {
        let c =
            m.id.and_then(|id| usize::try_from(id).ok())
                .filter(|&c| c < ncols && c >= next)
                .ok_or_else(|| {
                    bad(format!(
                        "frame {}: marker id {:?} is not a column after {next} (of {ncols})",
                        frame.frame, m.id
                    ))
                })?;
        for _ in next..c {
            line.push_str(",,,");
        }
        let p = m.position * 1000.0;
        write!(line, ",{:.6},{:.6},{:.6}", p.x, p.y, p.z).ok();
        next = c + 1;
    }
    for _ in next..ncols {
        line.push_str(",,,");
    }
    line.push_str("\r\n");
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::model::frame::{Marker, MarkerFrame};
    use crate::sim::{generate, ColumnTruth, SynthOptions};

    fn column(name: &str, tip: Option<usize>) -> ColumnTruth {
        ColumnTruth {
            name: name.into(),
            tip,
            first_frame: 0,
            last_frame: 0,
        }
    }

    #[test]
    fn writes_motive_layout_by_hand() {
        let mut syn = generate(&SynthOptions {
            tips: 2,
            still_s: 0.02,
            wind_s: 0.0,
            gap_fraction: 0.0,
            spurious_per_s: 0.0,
            take_name: "hand".into(),
            ..SynthOptions::default()
        })
        .unwrap();
        syn.columns = vec![
            column("Unlabeled 1000", Some(0)),
            column("Unlabeled 1001", Some(1)),
            column("Unlabeled 1002", None),
        ];
        let m = |x: f64, y: f64, z: f64, id: i64| Marker {
            position: DVec3::new(x, y, z),
            id: Some(id),
        };
        syn.frames = vec![
            MarkerFrame::new(0, 0.0, vec![m(0.1, 1.5, -0.25, 0), m(-1.0, 2.0, 0.0005, 2)]),
            MarkerFrame::new(1, 0.01, vec![m(0.1000004, 1.5, -0.25, 1)]),
        ];
        let mut out = Vec::new();
        write_motive_csv(&syn, &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        let suffix = format!("{:016X}", stream(&Rng::new(1), ID_SUFFIX).next_u64());
        let expected = format!(
            "Format Version,1.23,Take Name,hand,Take Notes,,Capture Frame Rate,100.000000,\
             Export Frame Rate,100.000000,Capture Start Time,2013-05-08 10.00.00.000 AM,\
             Total Frames in Take,2,Total Exported Frames,2,Rotation Type,Quaternion,\
             Length Units,Millimeters,Coordinate Space,Global\r\n\
             \r\n\
             ,Type,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker\r\n\
             ,Name,Unlabeled 1000,Unlabeled 1000,Unlabeled 1000,Unlabeled 1001,Unlabeled 1001,\
             Unlabeled 1001,Unlabeled 1002,Unlabeled 1002,Unlabeled 1002\r\n\
             ,ID,\"1{s}\",\"1{s}\",\"1{s}\",\"2{s}\",\"2{s}\",\"2{s}\",\"3{s}\",\"3{s}\",\"3{s}\"\r\n\
             ,,Position,Position,Position,Position,Position,Position,Position,Position,Position\r\n\
             Frame,Time (Seconds),X,Y,Z,X,Y,Z,X,Y,Z\r\n\
             0,0.000000,100.000000,1500.000000,-250.000000,,,,-1000.000000,2000.000000,0.500000\r\n\
             1,0.010000,,,,100.000400,1500.000000,-250.000000,,,\r\n",
            s = suffix
        );
        assert_eq!(text, expected);
    }

    #[test]
    fn rejects_markers_out_of_column_order() {
        let mut syn = generate(&SynthOptions {
            tips: 2,
            still_s: 0.01,
            wind_s: 0.0,
            ..SynthOptions::default()
        })
        .unwrap();
        syn.frames[0].markers.reverse();
        let err = write_motive_csv(&syn, &mut Vec::new()).unwrap_err();
        assert!(err.to_string().contains("frame 0"), "{err}");
        syn.frames[0].markers = vec![Marker::new(DVec3::ZERO)];
        assert!(write_motive_csv(&syn, &mut Vec::new()).is_err());
    }
}
