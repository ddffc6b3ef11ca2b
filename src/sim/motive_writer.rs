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
    let truth = &syn.truth;
    let ncols = syn.columns.len();
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
    let mut line = String::with_capacity(64 + ncols * 40);
    write!(
        line,
        "Format Version,1.23,Take Name,{take},Take Notes,,Capture Frame Rate,{rate},\
         Export Frame Rate,{rate},Capture Start Time,{CAPTURE_START},Total Frames in Take,{n},\
         Total Exported Frames,{n},Rotation Type,Quaternion,Length Units,Millimeters,\
         Coordinate Space,Global\r\n\r\n"
    )
    .ok();
    out.write_all(line.as_bytes())?;

    // Motive 2.x unlabeled IDs look like "1A2A8F984BAAD11EE": a running
    // number in hex followed by a per-take suffix.
    let suffix = format!(
        "{:016X}",
        stream(&Rng::new(truth.options.seed), ID_SUFFIX).next_u64()
    );
    for (label, cell) in [("Type", 0), ("Name", 1), ("ID", 2), ("", 3)] {
        line.clear();
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
        out.write_all(line.as_bytes())?;
    }
    out.flush()
}
