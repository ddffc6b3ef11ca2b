//! Trace plots like the paper's Figure 9: for each marker, its x, y and z
//! over time as displacement from the rest position, with the rest window
//! shaded, filled stretches drawn in a paler tone and gaps marked in red.
//!
//! Each panel draws, per pixel column, the range of the samples that fall
//! into it, so an hour-long session costs one pass over the traces and the
//! picture stays readable.

use super::raster::{Canvas, Rgb, BLACK, GREY, LIGHT_GREY};
use crate::error::Result;
use crate::model::tips::{Tip, Tips};
use crate::model::trace::SampleKind;

const PANEL_W: f64 = 420.0;
const PANEL_H: f64 = 130.0;
const MARGIN_L: f64 = 70.0;
const MARGIN_T: f64 = 22.0;
const GAP_X: f64 = 30.0;
const GAP_Y: f64 = 36.0;
const COLUMNS: usize = 3;
/// x, y, z in the usual axis colours; fills in paler versions.
const AXIS: [Rgb; 3] = [[210, 40, 40], [30, 150, 50], [40, 70, 210]];
const AXIS_FILLED: [Rgb; 3] = [[240, 170, 170], [160, 215, 170], [170, 185, 240]];
const GAP: Rgb = [255, 215, 215];
const REST: Rgb = [235, 240, 250];

/// Draws every tip's trace into one picture.
pub fn render(tips: &Tips) -> Canvas {
    let n = tips.tips.len().max(1);
    let rows = n.div_ceil(COLUMNS);
    let cols = n.min(COLUMNS);
    let width = MARGIN_L + cols as f64 * (PANEL_W + GAP_X + MARGIN_L) - MARGIN_L;
    let height = 40.0 + rows as f64 * (PANEL_H + GAP_Y + MARGIN_T);
    let mut c = Canvas::new(width as u32, height as u32);
    let title = format!(
        "{}: displacement from rest (mm) over time (s); x red, y green, z blue; pale = filled, red band = gap, blue band = rest window",
        tips.source
    );
    c.text(10.0, 10.0, &title, BLACK);
    let timeline = &tips.timeline;
    let (t0, t1) = (timeline.time(0), timeline.time(timeline.len() as i64 - 1));
    for (k, tip) in tips.tips.iter().enumerate() {
        let panel = Panel {
            px: MARGIN_L + (k % COLUMNS) as f64 * (PANEL_W + GAP_X + MARGIN_L),
            py: 40.0 + MARGIN_T + (k / COLUMNS) as f64 * (PANEL_H + GAP_Y + MARGIN_T),
            t0,
            t1,
            max_d: largest_displacement(tip),
        };
        panel.draw(&mut c, tips, tip);
    }
    if tips.tips.is_empty() {
        c.text(MARGIN_L, 60.0, "no tips found", BLACK);
    }
    c
}

/// Per pixel column and axis, the (min, max, last) displacement of the
/// measured (index 0) and filled (index 1) samples that fall into it.
type Columns = Vec<[[Option<(f64, f64, f64)>; 3]; 2]>;

/// The vertical scale of a panel: the largest displacement, at least 1 mm.
fn largest_displacement(tip: &Tip) -> f64 {
    let mut max_d: f64 = 0.001;
    for s in tip.trace.samples() {
        if s.kind != SampleKind::Missing {
            let d = (s.position - tip.rest).abs().max_element();
            if d.is_finite() {
                max_d = max_d.max(d);
            }
        }
    }
    max_d
}

/// One tip's panel: where it stands and its scales.
struct Panel {
    px: f64,
    py: f64,
    t0: f64,
    t1: f64,
    max_d: f64,
}

impl Panel {
    fn to_x(&self, time: f64) -> f64 {
        self.px + (time - self.t0) / (self.t1 - self.t0).max(1e-9) * PANEL_W
    }

    fn to_y(&self, d: f64) -> f64 {
        self.py + PANEL_H / 2.0 - d / self.max_d * (PANEL_H / 2.0 - 2.0)
    }

    fn column(&self, time: f64, columns: usize) -> usize {
        ((self.to_x(time) - self.px).round().max(0.0) as usize).min(columns - 1)
    }

    fn draw(&self, c: &mut Canvas, tips: &Tips, tip: &Tip) {
        // Background: rest window, then gaps.
        let (ra, rb) = (
            self.to_x(tips.rest_window_s[0]),
            self.to_x(tips.rest_window_s[1]),
        );
        c.rect(ra, self.py, rb - ra, PANEL_H, REST);
        let (ranges, missing) = self.columns(tips, tip);
        for (col, m) in missing.iter().enumerate() {
            if *m && ranges[col][0][0].is_none() {
                let x = self.px + col as f64;
                c.rect(x, self.py + PANEL_H - 6.0, 1.0, 6.0, [220, 60, 60]);
                c.rect(x, self.py, 1.0, PANEL_H - 6.0, GAP);
            }
        }
        c.line(
            self.px,
            self.to_y(0.0),
            self.px + PANEL_W,
            self.to_y(0.0),
            1.0,
            LIGHT_GREY,
        );
        self.series(c, &ranges);
        self.labels(c, tip);
    }

    /// The samples binned by pixel column, and which columns are gaps
    /// (missing samples, or before the trace starts or after it ends).
    fn columns(&self, tips: &Tips, tip: &Tip) -> (Columns, Vec<bool>) {
        let timeline = &tips.timeline;
        let columns = PANEL_W as usize + 1;
        let mut ranges: Columns = vec![[[None; 3]; 2]; columns];
        let mut missing = vec![false; columns];
        for s in tip.trace.samples() {
            let col = self.column(timeline.time(s.frame), columns);
            let kind = match s.kind {
                SampleKind::Measured => 0,
                SampleKind::Filled => 1,
                SampleKind::Missing => {
                    missing[col] = true;
                    continue;
                }
            };
            let d = s.position - tip.rest;
            for (axis, v) in [d.x, d.y, d.z].into_iter().enumerate() {
                let slot = &mut ranges[col][kind][axis];
                *slot = Some(match *slot {
                    None => (v, v, v),
                    Some((lo, hi, _)) => (lo.min(v), hi.max(v), v),
                });
            }
        }
        let edge = |frame: i64| {
            ((self.to_x(timeline.time(frame)) - self.px).max(0.0) as usize).min(columns - 1)
        };
        let (first, last) = (edge(tip.trace.first_frame()), edge(tip.trace.last_frame()));
        for (col, m) in missing.iter_mut().enumerate() {
            if col < first || col > last {
                *m = true;
            }
        }
        (ranges, missing)
    }

    /// Each axis as a band per column joined to the next, filled first so
    /// that measured samples are drawn over them.
    fn series(&self, c: &mut Canvas, ranges: &Columns) {
        for kind in [1usize, 0] {
            for axis in 0..3 {
                let color = if kind == 0 {
                    AXIS[axis]
                } else {
                    AXIS_FILLED[axis]
                };
                let mut prev: Option<(f64, f64)> = None;
                for (col, r) in ranges.iter().enumerate() {
                    let x = self.px + col as f64;
                    match r[kind][axis] {
                        Some((lo, hi, last)) => {
                            c.line(x, self.to_y(lo), x, self.to_y(hi), 1.0, color);
                            if let Some((pxl, pyl)) = prev {
                                c.line(pxl, pyl, x, self.to_y((lo + hi) / 2.0), 1.0, color);
                            }
                            prev = Some((x, self.to_y(last)));
                        }
                        None => prev = None,
                    }
                }
            }
        }
    }

    fn labels(&self, c: &mut Canvas, tip: &Tip) {
        let (px, py) = (self.px, self.py);
        c.rect_outline(px, py, PANEL_W, PANEL_H, GREY);
        c.text(
            px,
            py - 12.0,
            &format!(
                "marker {}  rest ({:.3}, {:.3}, {:.3}) m  gaps {:.1} %",
                tip.marker,
                tip.rest.x,
                tip.rest.y,
                tip.rest.z,
                tip.gap_fraction * 100.0
            ),
            BLACK,
        );
        let label = format!("{:.1}", self.max_d * 1000.0);
        c.text(px - Canvas::text_width(&label, 1) - 4.0, py, &label, BLACK);
        c.text(px - 10.0, self.to_y(0.0) - 3.0, "0", BLACK);
        let label = format!("-{:.1}", self.max_d * 1000.0);
        c.text(
            px - Canvas::text_width(&label, 1) - 4.0,
            py + PANEL_H - 7.0,
            &label,
            BLACK,
        );
        c.text(px, py + PANEL_H + 4.0, &format!("{:.1}", self.t0), BLACK);
        let label = format!("{:.1} s", self.t1);
        c.text(
            px + PANEL_W - Canvas::text_width(&label, 1),
            py + PANEL_H + 4.0,
            &label,
            BLACK,
        );
    }
}

/// Renders the plot and writes it as PNG.
pub fn plot_traces(tips: &Tips) -> Result<Vec<u8>> {
    render(tips).encode_png()
}
