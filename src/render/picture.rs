//! tree.png: the reconstructed skeleton seen from the front (x–y) and the
//! side (z–y) at the same scale, branches drawn as thick as they are (at
//! least one pixel), captured tips as red dots, with a scale bar, so a user
//! can judge a result without a 3D viewer. With the captured motion, the
//! tree's two extreme poses along the main direction of the sway are drawn
//! lightly behind it, and each captured tip's path as a thin light line.

use glam::DVec3;

use crate::error::Result;
use crate::model::motion::TreeMotion;
use crate::model::tree::{Kind, Tree};
use crate::render::occlusion::{draw_top_down, Stroke};
use crate::render::raster::{Canvas, Rgb};

const WIDTH: u32 = 1400;
const HEIGHT: u32 = 820;
const MARGIN: f64 = 40.0;
const TOP: f64 = 70.0;
const BOTTOM: f64 = 60.0;

const TRUNK: Rgb = [74, 50, 32];
const BRANCH: Rgb = [122, 88, 58];
const TIP_FILL: Rgb = [220, 30, 30];
const TIP_EDGE: Rgb = [90, 0, 0];
const INK: Rgb = [30, 30, 30];
const GROUND: Rgb = [170, 170, 170];
/// The two extreme poses and the tips' paths: light, behind the tree.
const GHOST: [Rgb; 2] = [[214, 196, 178], [178, 198, 222]];
const PATH: Rgb = [236, 150, 150];

/// A view: title, the horizontal coordinate of a point, its lowest value
/// and its span.
type View = (&'static str, fn(DVec3) -> f64, f64, f64);

/// Renders the front and side views as PNG bytes, with the motion when
/// there is one.
pub fn tree_png(tree: &Tree, motion: Option<&TreeMotion>) -> Result<Vec<u8>> {
    render(tree, motion).encode_png()
}

/// The two keys whose poses lie furthest apart along the main direction of
/// the captured tips' sway (the first principal axis of their
/// displacements), that direction, and the largest tip displacement (m).
pub fn extremes(tree: &Tree, motion: &TreeMotion) -> Option<([usize; 2], DVec3, f64)> {
    let nodes: Vec<usize> = motion.captured.iter().map(|c| c.node).collect();
    if motion.keys() == 0 || nodes.is_empty() || motion.nodes != tree.nodes.len() {
        return None;
    }
    let disp =
        |k: usize, n: usize| DVec3::from(motion.pose(k)[n].map(f64::from)) - tree.nodes[n].position;
    let mut cov = glam::DMat3::ZERO;
    let mut largest: f64 = 0.0;
    for k in 0..motion.keys() {
        for &n in &nodes {
            let d = disp(k, n);
            cov += glam::DMat3::from_cols(d * d.x, d * d.y, d * d.z);
            largest = largest.max(d.length());
        }
    }
    // Power iteration from the axis with the largest variance.
    let diag = [cov.x_axis.x, cov.y_axis.y, cov.z_axis.z];
    let mut dir =
        [DVec3::X, DVec3::Y, DVec3::Z][(0..3).max_by(|&a, &b| diag[a].total_cmp(&diag[b]))?];
    for _ in 0..50 {
        dir = (cov * dir).try_normalize()?;
    }
    let score = |k: usize| nodes.iter().map(|&n| disp(k, n).dot(dir)).sum::<f64>();
    let (mut lo, mut hi) = (0, 0);
    for k in 0..motion.keys() {
        if score(k) < score(lo) {
            lo = k;
        }
        if score(k) > score(hi) {
            hi = k;
        }
    }
    Some(([lo, hi], dir, largest))
}

/// Several trees of one capture in one picture, each named above its
/// crown, each tree's captured tips in its own colour (docs/forest.md).
pub fn forest_png(trees: &[(&str, &Tree)]) -> Result<Vec<u8>> {
    render_trees(trees, true, None).encode_png()
}

/// Renders the front and side views.
pub fn render(tree: &Tree, motion: Option<&TreeMotion>) -> Canvas {
    render_trees(&[("", tree)], false, motion)
}

/// Fill and edge colour of each tree's captured tips: the first tree's red
/// as a tree alone has always had, then colours that stay apart.
const TIP_COLOURS: [(Rgb, Rgb); 6] = [
    (TIP_FILL, TIP_EDGE),
    ([30, 110, 230], [0, 30, 100]),
    ([245, 160, 20], [110, 60, 0]),
    ([40, 170, 70], [0, 70, 20]),
    ([160, 70, 210], [60, 0, 90]),
    ([20, 180, 190], [0, 70, 80]),
];

/// The views of `trees` (name, tree) at one scale; `labelled` writes each
/// name above its tree and a forest's counts at the bottom; `motion` is the
/// first tree's (a tree alone; several trees are drawn still).
fn render_trees(trees: &[(&str, &Tree)], labelled: bool, motion: Option<&TreeMotion>) -> Canvas {
    let mut canvas = Canvas::new(WIDTH, HEIGHT);
    let Some(first) = trees.iter().flat_map(|(_, t)| t.nodes.iter()).next() else {
        return canvas;
    };
    let extreme = motion.and_then(|m| Some((m, extremes(trees.first()?.1, m)?)));
    let (lo, hi) = bounds(trees, extreme.map(|(m, (keys, _, _))| (m, keys)));
    // The ground: under the lowest trunk base.
    let ground = trees
        .iter()
        .filter_map(|(_, t)| t.nodes.first())
        .map(|n| n.position)
        .fold(first.position, |a, b| if b.y < a.y { b } else { a });
    let span = (hi - lo).max(DVec3::splat(1e-6));
    let panel_w = (WIDTH as f64 - 3.0 * MARGIN) / 2.0;
    let panel_h = HEIGHT as f64 - TOP - BOTTOM;
    // One scale for both views so their sizes compare.
    let scale = (panel_w / span.x.max(span.z)).min(panel_h / span.y);

    let views: [View; 2] = [
        ("front (x right, y up)", |p| p.x, lo.x, span.x),
        ("side (z right, y up)", |p| p.z, lo.z, span.z),
    ];
    let segments = thickest_first(trees);
    for (v, (title, horizontal, h_lo, h_span)) in views.iter().enumerate() {
        let panel_left = MARGIN + v as f64 * (panel_w + MARGIN);
        let left = panel_left + 0.5 * (panel_w - h_span * scale);
        let base = HEIGHT as f64 - BOTTOM;
        let to_px = |p: DVec3| {
            (
                left + (horizontal(p) - h_lo) * scale,
                base - (p.y - lo.y) * scale,
            )
        };
        canvas.text_scaled(panel_left, 20.0, title, 2, INK);
        let (_, gy) = to_px(ground);
        canvas.line(panel_left, gy, panel_left + panel_w, gy, 1.0, GROUND);
        // The branches over the motion, drawn topmost first so each pixel
        // is written once (occlusion.rs: tens of thousands of capsules lie
        // under one another in a large crown).
        let mut strokes = Vec::new();
        branch_strokes(&mut strokes, trees, &segments, &to_px, scale);
        if let Some((m, (keys, _, _))) = extreme {
            motion_strokes(&mut strokes, trees[0].1, m, keys, &segments, &to_px, scale);
        }
        draw_top_down(&mut canvas, &strokes);
        for (k, (name, tree)) in trees.iter().enumerate() {
            let (fill, edge) = TIP_COLOURS[k % TIP_COLOURS.len()];
            for node in &tree.nodes {
                if let Kind::Captured { .. } = node.kind {
                    let (x, y) = to_px(node.position);
                    canvas.circle(x, y, 5.0, edge);
                    canvas.circle(x, y, 3.5, fill);
                }
            }
            if labelled {
                label(&mut canvas, tree, name, &to_px, edge);
            }
        }
    }
    footer(&mut canvas, trees, scale, labelled);
    if let Some((m, (_, dir, largest))) = extreme {
        let text = format!(
            "motion {:.1} s: extreme poses along ({:.2}, {:.2}, {:.2}) behind the tree, tip paths light red; largest tip displacement {:.0} mm",
            m.times.last().copied().unwrap_or(0.0),
            dir.x,
            dir.y,
            dir.z,
            largest * 1000.0
        );
        canvas.text_scaled(MARGIN, 48.0, &text, 1, INK);
    }
    canvas
}

/// The box holding every node with its radius, and the extreme poses of
/// the motion (so a swaying tree is not cut at the edge of the picture).
fn bounds(trees: &[(&str, &Tree)], extreme: Option<(&TreeMotion, [usize; 2])>) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for n in trees.iter().flat_map(|(_, t)| t.nodes.iter()) {
        lo = lo.min(n.position - DVec3::splat(n.radius));
        hi = hi.max(n.position + DVec3::splat(n.radius));
    }
    if let Some((m, keys)) = extreme {
        for k in keys {
            for p in m.pose(k) {
                let p = DVec3::from(p.map(f64::from));
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
    }
    (lo, hi)
}

/// Every segment (tree, child node) of every tree, thickest first, so thin
/// branches stay visible on top; ties in tree and node order.
fn thickest_first(trees: &[(&str, &Tree)]) -> Vec<(usize, usize)> {
    let mut segments: Vec<(usize, usize)> = trees
        .iter()
        .enumerate()
        .flat_map(|(k, (_, t))| {
            (0..t.nodes.len())
                .filter(|&i| t.nodes[i].parent.is_some())
                .map(move |i| (k, i))
        })
        .collect();
    let radius = |(k, i): (usize, usize)| trees[k].1.nodes[i].radius;
    segments.sort_by(|&a, &b| radius(b).total_cmp(&radius(a)).then(a.cmp(&b)));
    segments
}

/// The first tree's two extreme poses as ghosts behind it, and each
/// captured tip's path over the motion, as strokes under those already in
/// `out`. Topmost first: the paths (the last drawn on top), then the second
/// ghost, then the first.
fn motion_strokes(
    out: &mut Vec<Stroke>,
    tree: &Tree,
    m: &TreeMotion,
    keys: [usize; 2],
    segments: &[(usize, usize)],
    to_px: &dyn Fn(DVec3) -> (f64, f64),
    scale: f64,
) {
    for c in m.captured.iter().rev() {
        let at = |k: usize| to_px(DVec3::from(m.pose(k)[c.node].map(f64::from)));
        for k in (1..m.keys()).rev() {
            let ((x0, y0), (x1, y1)) = (at(k - 1), at(k));
            out.push(Stroke {
                ends: [x0, y0, x1, y1],
                width: 1.0,
                color: PATH,
            });
        }
    }
    for (g, k) in keys.into_iter().enumerate().rev() {
        let pose = m.pose(k);
        let at = |n: usize| DVec3::from(pose[n].map(f64::from));
        for &(_, i) in segments.iter().rev().filter(|s| s.0 == 0) {
            let Some(p) = tree.nodes[i].parent else {
                continue;
            };
            let (x0, y0) = to_px(at(i));
            let (x1, y1) = to_px(at(p));
            let width = (2.0 * tree.nodes[i].radius * scale).max(1.0);
            out.push(Stroke {
                ends: [x0, y0, x1, y1],
                width,
                color: GHOST[g],
            });
        }
    }
}

/// The branches at rest, as wide as they are thick, the trunk in its
/// colour, as strokes under those already in `out`: thinnest first, as
/// they lie on top.
fn branch_strokes(
    out: &mut Vec<Stroke>,
    trees: &[(&str, &Tree)],
    segments: &[(usize, usize)],
    to_px: &dyn Fn(DVec3) -> (f64, f64),
    scale: f64,
) {
    for &(k, i) in segments.iter().rev() {
        let tree = trees[k].1;
        let node = &tree.nodes[i];
        let Some(parent) = node.parent.and_then(|p| tree.nodes.get(p)) else {
            continue;
        };
        let (x0, y0) = to_px(node.position);
        let (x1, y1) = to_px(parent.position);
        let colour = if node.kind == Kind::Trunk {
            TRUNK
        } else {
            BRANCH
        };
        out.push(Stroke {
            ends: [x0, y0, x1, y1],
            width: (2.0 * node.radius * scale).max(1.0),
            color: colour,
        });
    }
}

/// `name` centred above the highest node of `tree`.
fn label(
    canvas: &mut Canvas,
    tree: &Tree,
    name: &str,
    to_px: &dyn Fn(DVec3) -> (f64, f64),
    colour: Rgb,
) {
    let Some(top) = tree
        .nodes
        .iter()
        .map(|n| n.position)
        .reduce(|a, b| if b.y > a.y { b } else { a })
    else {
        return;
    };
    let (x, y) = to_px(top);
    let w = Canvas::text_width(name, 2);
    canvas.text_scaled(x - 0.5 * w, (y - 26.0).max(TOP - 30.0), name, 2, colour);
}

/// The scale bar and the counts.
fn footer(canvas: &mut Canvas, trees: &[(&str, &Tree)], scale: f64, forest: bool) {
    // Scale bar: the largest of 1, 0.5, 0.2, 0.1 m that fits in 200 px.
    let bar = [1.0, 0.5, 0.2, 0.1, 0.05]
        .into_iter()
        .find(|m| m * scale <= 200.0)
        .unwrap_or(0.05);
    let y = HEIGHT as f64 - 25.0;
    canvas.line(MARGIN, y, MARGIN + bar * scale, y, 3.0, INK);
    canvas.text_scaled(
        MARGIN + bar * scale + 10.0,
        y - 7.0,
        &format!("{bar} M"),
        2,
        INK,
    );
    let all = || trees.iter().flat_map(|(_, t)| t.nodes.iter());
    let captured = all()
        .filter(|n| matches!(n.kind, Kind::Captured { .. }))
        .count();
    let tips = all().filter(|n| n.kind.is_tip()).count();
    let nodes = all().count();
    let forced: usize = trees.iter().map(|(_, t)| t.forced_joins).sum();
    let info = if forest {
        format!(
            "trees {}   captured tips {captured}   all tips {tips}   nodes {nodes}   forced joins {forced}",
            trees.len()
        )
    } else {
        let steps = trees.first().map_or(0, |(_, t)| t.steps);
        format!(
            "captured tips {captured} (red)   all tips {tips}   nodes {nodes}   steps {steps}   forced joins {forced}"
        )
    };
    canvas.text_scaled(MARGIN + 330.0, y - 7.0, &info, 2, INK);
}
