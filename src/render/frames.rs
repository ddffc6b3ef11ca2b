//! Frames of the swaying tree: the crown seen from the front at several
//! keys of its motion, side by side, each over the rest pose drawn lightly,
//! at one scale, so that the sway can be seen without a 3D viewer (the
//! README's pictures). Only the crown is drawn (from a little below the
//! lowest captured tip up), where the motion is.

use glam::DVec3;

use crate::error::Result;
use crate::model::motion::TreeMotion;
use crate::model::tree::{Kind, Tree};
use crate::render::raster::{Canvas, Rgb};

const PANEL_W: f64 = 420.0;
const PANEL_H: f64 = 420.0;
const MARGIN: f64 = 20.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 40.0;
const REST: Rgb = [205, 205, 205];
const WOOD: Rgb = [110, 78, 50];
const TIP: Rgb = [220, 30, 30];
const INK: Rgb = [30, 30, 30];

/// The front view (x right, y up) of the crown at each of `keys`.
pub fn frames_png(tree: &Tree, motion: &TreeMotion, keys: &[usize]) -> Result<Vec<u8>> {
    let width = (MARGIN + keys.len() as f64 * (PANEL_W + MARGIN)).ceil() as u32;
    let height = (TOP + PANEL_H + BOTTOM).ceil() as u32;
    let mut canvas = Canvas::new(width.max(1), height);
    let captured_y = tree
        .nodes
        .iter()
        .filter(|n| matches!(n.kind, Kind::Captured { .. }))
        .map(|n| n.position.y)
        .fold(f64::INFINITY, f64::min);
    if !captured_y.is_finite() || motion.nodes != tree.nodes.len() {
        return canvas.encode_png();
    }
    let floor = captured_y - 0.2;
    let shown: Vec<usize> = (0..tree.nodes.len())
        .filter(|&i| tree.nodes[i].position.y >= floor && tree.nodes[i].parent.is_some())
        .collect();
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for &i in &shown {
        lo = lo.min(tree.nodes[i].position);
        hi = hi.max(tree.nodes[i].position);
    }
    // Room for the sway around the rest crown.
    lo -= DVec3::splat(0.08);
    hi += DVec3::splat(0.08);
    let scale = (PANEL_W / (hi.x - lo.x)).min(PANEL_H / (hi.y - lo.y));
    for (f, &k) in keys.iter().enumerate() {
        let left = MARGIN + f as f64 * (PANEL_W + MARGIN);
        let to_px = |p: DVec3| {
            (
                left + (p.x - lo.x) * scale,
                TOP + PANEL_H - (p.y - lo.y) * scale,
            )
        };
        let pose = motion.pose(k.min(motion.keys().saturating_sub(1)));
        let at = |n: usize| {
            pose.get(n)
                .map_or(tree.nodes[n].position, |p| DVec3::from(p.map(f64::from)))
        };
        for (layer, colour) in [(false, REST), (true, WOOD)] {
            for &i in &shown {
                let Some(p) = tree.nodes[i].parent else {
                    continue;
                };
                let (a, b) = if layer {
                    (at(i), at(p))
                } else {
                    (tree.nodes[i].position, tree.nodes[p].position)
                };
                let (x0, y0) = to_px(a);
                let (x1, y1) = to_px(b);
                let w = (2.0 * tree.nodes[i].radius * scale).max(1.0);
                canvas.line(x0, y0, x1, y1, w, colour);
            }
        }
        for c in &motion.captured {
            let (x, y) = to_px(at(c.node));
            canvas.circle(x, y, 3.0, TIP);
        }
        let t = motion.times.get(k).copied().unwrap_or(0.0) + motion.start_s;
        canvas.text_scaled(left, 12.0, &format!("T = {t:.2} S"), 2, INK);
    }
    // A 10 cm bar, the scale of the sway.
    let y = f64::from(height) - 18.0;
    canvas.line(MARGIN, y, MARGIN + 0.1 * scale, y, 3.0, INK);
    canvas.text_scaled(
        MARGIN + 0.1 * scale + 10.0,
        y - 7.0,
        "10 CM   REST POSE IN GREY",
        2,
        INK,
    );
    canvas.encode_png()
}
