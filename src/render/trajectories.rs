//! The cleaned, labelled tip trajectories as files: C3D, CSV and TRC
//! (`treemocap export`). Every writer walks the session frame by frame with
//! one reader per tip, so memory does not grow with the take.
//!
//! What every format holds, per frame of the session (frames numbered as
//! the source numbered them) and per tip (`tip_01`, `tip_02`, … in the
//! order of `tips.json`'s markers):
//! - **measured** samples: the marker's position;
//! - **filled** samples (a gap filled from the neighbours or by PCHIP):
//!   the fill, flagged as such where the format can say so;
//! - **missing** samples: empty.
//!
//! Flags and ids per format (see docs/tracking.md):
//! - C3D (float, Intel, millimetres, Z up as is usual in C3D; POINT:Y_SCREEN
//!   says `+Z`): the fourth word of a point is its residual: `257` (0x0101:
//!   a residual of 1 × |SCALE| whichever byte a reader takes for it) for a
//!   measured sample, `0` for a filled one (the C3D convention for
//!   interpolated data), `−1` for a missing one (coordinates 0).
//!   POINT:LABELS are `tip_01`…, POINT:DESCRIPTIONS list each tip's marker
//!   ids.
//! - CSV (one header row, read by pandas with no options): `frame`,
//!   `time_s`, then per tip `tip_01_x_m`, `_y_m`, `_z_m` (metres, Y up),
//!   `tip_01_filled` (0 measured, 1 filled) and `tip_01_marker` (the source
//!   marker id of a measured sample); all empty when missing.
//! - TRC (OpenSim's marker format, tab separated, millimetres, Y up):
//!   positions only; a missing sample is empty; TRC cannot flag fills.

use std::fmt::Write as _;

use glam::DVec3;

use crate::model::tips::Tips;
use crate::model::trace::{Sample, SampleKind, Trace};

/// Label of tip `k` (0-based): `tip_01`, …, `tip_99`, `tip_100`.
pub fn tip_label(k: usize) -> String {
    format!("tip_{:02}", k + 1)
}

/// The source marker ids of a trace, distinct, in order of first use.
pub fn marker_ids(trace: &Trace) -> Vec<i64> {
    let mut out: Vec<i64> = Vec::new();
    for r in trace.sources() {
        if let Some(id) = r.id {
            if !out.contains(&id) {
                out.push(id);
            }
        }
    }
    out
}

/// One sample of one tip as the writers see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Point {
    /// A marker's position (m, Y up) and the source's id for it.
    Measured(DVec3, Option<i64>),
    /// A filled position (m, Y up).
    Filled(DVec3),
    /// No sample.
    Missing,
}

/// Walks a session frame by frame: for each internal frame, its source
/// frame number, time, and every tip's sample.
pub struct Frames<'a> {
    tips: &'a Tips,
    readers: Vec<Reader<'a>>,
    next: i64,
    row: Vec<Point>,
}

/// One tip's samples with the source id of each measurement.
struct Reader<'a> {
    samples: std::iter::Peekable<Box<dyn Iterator<Item = Sample> + 'a>>,
    runs: &'a [crate::model::trace::SourceRun],
    run: usize,
}

impl<'a> Frames<'a> {
    /// Starts at the session's first frame.
    pub fn new(tips: &'a Tips) -> Self {
        let readers = tips
            .tips
            .iter()
            .map(|t| {
                let it: Box<dyn Iterator<Item = Sample> + 'a> = Box::new(t.trace.samples());
                Reader {
                    samples: it.peekable(),
                    runs: t.trace.sources(),
                    run: 0,
                }
            })
            .collect();
        Frames {
            tips,
            readers,
            next: 0,
            row: vec![Point::Missing; tips.tips.len()],
        }
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.tips.timeline.len()
    }

    /// Whether the session has no frames.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The next frame: (source frame number, time in s, samples per tip).
    pub fn next_frame(&mut self) -> Option<(i64, f64, &[Point])> {
        let t = self.next;
        if t as usize >= self.tips.timeline.len() {
            return None;
        }
        self.next += 1;
        for (k, r) in self.readers.iter_mut().enumerate() {
            self.row[k] = Point::Missing;
            let Some(s) = r.samples.next_if(|s| s.frame <= t) else {
                continue;
            };
            if s.frame != t {
                continue;
            }
            self.row[k] = match s.kind {
                SampleKind::Measured => {
                    while r.runs.get(r.run + 1).is_some_and(|x| x.frame <= t) {
                        r.run += 1;
                    }
                    Point::Measured(s.position, r.runs.get(r.run).and_then(|x| x.id))
                }
                SampleKind::Filled => Point::Filled(s.position),
                SampleKind::Missing => Point::Missing,
            };
        }
        let frame = self.tips.timeline.source_frame(t).unwrap_or(t);
        Some((frame, self.tips.timeline.time(t), &self.row))
    }
}

/// CSV text (see the module comment).
pub fn to_csv(tips: &Tips) -> Vec<u8> {
    let mut out = String::from("frame,time_s");
    for k in 0..tips.tips.len() {
        let l = tip_label(k);
        let _ = write!(out, ",{l}_x_m,{l}_y_m,{l}_z_m,{l}_filled,{l}_marker");
    }
    out.push('\n');
    let mut frames = Frames::new(tips);
    while let Some((frame, time, row)) = frames.next_frame() {
        let _ = write!(out, "{frame},{time:.6}");
        for p in row {
            match *p {
                Point::Measured(v, id) => {
                    let _ = write!(out, ",{:.6},{:.6},{:.6},0,", v.x, v.y, v.z);
                    if let Some(id) = id {
                        let _ = write!(out, "{id}");
                    }
                }
                Point::Filled(v) => {
                    let _ = write!(out, ",{:.6},{:.6},{:.6},1,", v.x, v.y, v.z);
                }
                Point::Missing => out.push_str(",,,,,"),
            }
        }
        out.push('\n');
    }
    out.into_bytes()
}

/// TRC text for OpenSim (see the module comment). `name` goes in the first
/// header line.
pub fn to_trc(tips: &Tips, name: &str) -> Vec<u8> {
    let n = tips.timeline.len();
    let m = tips.tips.len();
    let rate = tips.frame_rate;
    let first = tips.timeline.source_frame(0).unwrap_or(0);
    let mut out = format!(
        "PathFileType\t4\t(X/Y/Z)\t{name}\n\
         DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
         {rate}\t{rate}\t{n}\t{m}\tmm\t{rate}\t{first}\t{n}\n\
         Frame#\tTime"
    );
    for k in 0..m {
        let _ = write!(out, "\t{}\t\t", tip_label(k));
    }
    out.push_str("\n\t");
    for k in 1..=m {
        let _ = write!(out, "\tX{k}\tY{k}\tZ{k}");
    }
    out.push_str("\n\n");
    let mut frames = Frames::new(tips);
    let mut i = 0;
    while let Some((_, time, row)) = frames.next_frame() {
        i += 1;
        let _ = write!(out, "{i}\t{time:.6}");
        for p in row {
            match *p {
                Point::Measured(v, _) | Point::Filled(v) => {
                    let _ = write!(
                        out,
                        "\t{:.3}\t{:.3}\t{:.3}",
                        v.x * 1000.0,
                        v.y * 1000.0,
                        v.z * 1000.0
                    );
                }
                Point::Missing => out.push_str("\t\t\t"),
            }
        }
        out.push('\n');
    }
    out.into_bytes()
}

/// Fourth word of a measured sample: 0x0101. Readers disagree on which
/// byte is the residual and which the camera mask (py-c3d: low byte
/// residual; ezc3d: high byte), so both bytes are 1: every reader sees a
/// residual of 1 × |POINT:SCALE| > 0.
pub const C3D_MEASURED: f32 = 257.0;
/// Residual of a filled sample: 0, the C3D convention for interpolated data.
pub const C3D_FILLED: f32 = 0.0;
/// Residual of a missing sample.
pub const C3D_MISSING: f32 = -1.0;

/// A tip's position in the C3D file: millimetres, Z up
/// ((x, y, z) Y up → (x, −z, y), the inverse of the reader's turn).
pub fn c3d_position(v: DVec3) -> [f64; 3] {
    [v.x * 1000.0, -v.z * 1000.0, v.y * 1000.0]
}

/// `tips.json` with the trajectories (`tips --json --traces`): the usual
/// fields plus `frames`, `times_s` and, per tip, `label`, `marker_ids`,
/// `trace` (one `[x, y, z]` or `null` per frame) and `filled` (indices of
/// the filled entries). See docs/tracking.md.
pub fn tips_json_with_traces(tips: &Tips) -> String {
    let mut root: serde_json::Value =
        serde_json::from_str(&tips.to_json()).unwrap_or(serde_json::Value::Null);
    let n = tips.timeline.len();
    let m = tips.tips.len();
    let mut traces: Vec<Vec<serde_json::Value>> = vec![Vec::with_capacity(n); m];
    let mut filled: Vec<Vec<usize>> = vec![Vec::new(); m];
    let (mut frames_out, mut times) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut frames = Frames::new(tips);
    let mut i = 0;
    while let Some((frame, time, row)) = frames.next_frame() {
        frames_out.push(frame);
        times.push(time);
        for (k, p) in row.iter().enumerate() {
            traces[k].push(match *p {
                Point::Measured(v, _) => serde_json::json!([v.x, v.y, v.z]),
                Point::Filled(v) => {
                    filled[k].push(i);
                    serde_json::json!([v.x, v.y, v.z])
                }
                Point::Missing => serde_json::Value::Null,
            });
        }
        i += 1;
    }
    if let Some(obj) = root.as_object_mut() {
        obj.insert("frames".into(), serde_json::json!(frames_out));
        obj.insert("times_s".into(), serde_json::json!(times));
        if let Some(list) = obj.get_mut("tips").and_then(|t| t.as_array_mut()) {
            for (k, (entry, tip)) in list.iter_mut().zip(&tips.tips).enumerate() {
                if let Some(e) = entry.as_object_mut() {
                    e.insert("label".into(), serde_json::json!(tip_label(k)));
                    e.insert(
                        "marker_ids".into(),
                        serde_json::json!(marker_ids(&tip.trace)),
                    );
                    e.insert(
                        "trace".into(),
                        serde_json::Value::Array(std::mem::take(&mut traces[k])),
                    );
                    e.insert(
                        "filled".into(),
                        serde_json::json!(std::mem::take(&mut filled[k])),
                    );
                }
            }
        }
    }
    let mut text = serde_json::to_string(&root).unwrap_or_else(|_| "{}".into());
    text.push('\n');
    text
}

/// The C3D file (see the module comment).
pub fn to_c3d(tips: &Tips) -> Vec<u8> {
    use crate::format::c3d::encode::{encode, Sample as C3dSample, WriteSpec};
    let labels: Vec<String> = (0..tips.tips.len()).map(tip_label).collect();
    let descriptions: Vec<String> = tips
        .tips
        .iter()
        .map(|t| {
            let ids: Vec<String> = marker_ids(&t.trace).iter().map(|i| i.to_string()).collect();
            let mut d = format!("marker ids {}", ids.join(" "));
            d.truncate(120);
            d
        })
        .collect();
    let mut frames = Frames::new(tips);
    let mut rows = Vec::with_capacity(frames.len());
    while let Some((_, _, row)) = frames.next_frame() {
        rows.push(
            row.iter()
                .map(|p| match *p {
                    Point::Measured(v, _) => C3dSample {
                        position: c3d_position(v),
                        residual: C3D_MEASURED,
                    },
                    Point::Filled(v) => C3dSample {
                        position: c3d_position(v),
                        residual: C3D_FILLED,
                    },
                    Point::Missing => C3dSample {
                        position: [0.0; 3],
                        residual: C3D_MISSING,
                    },
                })
                .collect(),
        );
    }
    let spec = WriteSpec {
        float: true,
        scale: 0.1,
        rate: tips.frame_rate as f32,
        units: "mm".into(),
        labels,
        descriptions,
        y_screen: Some("+Z".into()),
        first_frame: 1,
        frames: rows,
        ..WriteSpec::default()
    };
    encode(&spec)
}
