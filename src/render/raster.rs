//! A small software rasterizer for the project's pictures (trace plots,
//! front and side views of a tree) written as PNG.
//!
//! Plotting crates draw text through the system's font libraries, which a
//! fresh lab machine may lack; lines, discs, rectangles and a built-in 5×7
//! bitmap font are all these pictures need, and are a few hundred lines.
//! Coordinates are pixels, x to the right and y down, as f64 so callers can
//! map data without rounding; everything outside the canvas is clipped.

use crate::error::Result;
use crate::render::error::RenderError;

/// An sRGB colour.
pub type Rgb = [u8; 3];

/// The canvas's background.
pub const WHITE: Rgb = [255, 255, 255];
/// Text and labels of the plots.
pub const BLACK: Rgb = [0, 0, 0];
/// Panel outlines of the plots.
pub const GREY: Rgb = [128, 128, 128];
/// Zero lines: visible, yet quieter than the data drawn over them.
pub const LIGHT_GREY: Rgb = [225, 225, 225];

/// An RGB image being drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    width: u32,
    height: u32,
    pixels: Vec<u8>,
}

impl Canvas {
    /// A white canvas (sizes are clamped to 1..=16384 pixels).
    pub fn new(width: u32, height: u32) -> Self {
        let (width, height) = (width.clamp(1, 16384), height.clamp(1, 16384));
        Canvas {
            width,
            height,
            pixels: vec![255; width as usize * height as usize * 3],
        }
    }

    /// Width in pixels (after clamping).
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels (after clamping).
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The colour at a pixel, or `None` outside the canvas.
    pub fn pixel(&self, x: i64, y: i64) -> Option<Rgb> {
        let i = self.index(x, y)?;
        Some([self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]])
    }

    fn index(&self, x: i64, y: i64) -> Option<usize> {
        if x < 0 || y < 0 || x >= i64::from(self.width) || y >= i64::from(self.height) {
            return None;
        }
        Some((y as usize * self.width as usize + x as usize) * 3)
    }

    /// Sets one pixel (ignored outside the canvas).
    pub fn set(&mut self, x: i64, y: i64, color: Rgb) {
        if let Some(i) = self.index(x, y) {
            self.pixels[i..i + 3].copy_from_slice(&color);
        }
    }

    /// A filled rectangle with its top-left corner at (x, y).
    pub fn rect(&mut self, x: f64, y: f64, w: f64, h: f64, color: Rgb) {
        if !(x.is_finite() && y.is_finite() && w.is_finite() && h.is_finite()) {
            return;
        }
        let x0 = x.round().max(0.0) as i64;
        let y0 = y.round().max(0.0) as i64;
        let x1 = (x + w).round().min(f64::from(self.width)) as i64;
        let y1 = (y + h).round().min(f64::from(self.height)) as i64;
        for yy in y0..y1 {
            for xx in x0..x1 {
                self.set(xx, yy, color);
            }
        }
    }

    /// A rectangle's outline, one pixel wide.
    pub fn rect_outline(&mut self, x: f64, y: f64, w: f64, h: f64, color: Rgb) {
        self.line(x, y, x + w, y, 1.0, color);
        self.line(x + w, y, x + w, y + h, 1.0, color);
        self.line(x + w, y + h, x, y + h, 1.0, color);
        self.line(x, y + h, x, y, 1.0, color);
    }

    /// A filled disc.
    pub fn circle(&mut self, cx: f64, cy: f64, r: f64, color: Rgb) {
        if !(cx.is_finite() && cy.is_finite() && r.is_finite()) || r < 0.0 {
            return;
        }
        let r = r.min(1e5);
        let (x0, x1) = ((cx - r).floor() as i64, (cx + r).ceil() as i64);
        let (y0, y1) = ((cy - r).floor() as i64, (cy + r).ceil() as i64);
        let r2 = (r + 0.5) * (r + 0.5);
        for yy in y0.max(0)..=y1.min(i64::from(self.height)) {
            for xx in x0.max(0)..=x1.min(i64::from(self.width)) {
                let (dx, dy) = (xx as f64 - cx, yy as f64 - cy);
                if dx * dx + dy * dy <= r2 {
                    self.set(xx, yy, color);
                }
            }
        }
    }

    /// A straight line `width` pixels wide.
    pub fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, width: f64, color: Rgb) {
        line_into(self, [x0, y0, x1, y1], width, color);
    }

    /// The pixels, row after row, 3 bytes each: for layers that paint
    /// rows on several threads (`occlusion`).
    pub(crate) fn pixels_mut(&mut self) -> &mut [u8] {
        &mut self.pixels
    }

    /// Text in the built-in 5×7 font, top-left at (x, y), one pixel per dot.
    /// Lower case is drawn as upper case; unknown characters as '?'.
    pub fn text(&mut self, x: f64, y: f64, text: &str, color: Rgb) {
        self.text_scaled(x, y, text, 1, color);
    }

    /// Text with each font dot drawn as `scale` × `scale` pixels.
    pub fn text_scaled(&mut self, x: f64, y: f64, text: &str, scale: u32, color: Rgb) {
        if !(x.is_finite() && y.is_finite()) {
            return;
        }
        let s = i64::from(scale.clamp(1, 16));
        let (mut cx, cy) = (x.round() as i64, y.round() as i64);
        for ch in text.chars() {
            let rows = glyph(ch);
            for (r, bits) in rows.iter().enumerate() {
                for c in 0..5 {
                    if bits & (0x10 >> c) != 0 {
                        for dy in 0..s {
                            for dx in 0..s {
                                self.set(cx + c * s + dx, cy + r as i64 * s + dy, color);
                            }
                        }
                    }
                }
            }
            cx += 6 * s;
        }
    }

    /// Width in pixels of `text` at `scale`.
    pub fn text_width(text: &str, scale: u32) -> f64 {
        (text.chars().count() as f64 * 6.0 - 1.0).max(0.0) * f64::from(scale.max(1))
    }

    /// Encodes the canvas as an 8-bit RGB PNG.
    pub fn encode_png(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        let err = RenderError::from;
        let mut encoder = png::Encoder::new(&mut out, self.width, self.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        // fdeflate's fast mode: 9 ms instead of 100 ms (`Balanced`) for a
        // large tree's picture, for a file 3× as large (58 kB instead of
        // 19 kB); the pixels are the same (docs/picture.md).
        encoder.set_compression(png::Compression::Fast);
        let mut writer = encoder.write_header().map_err(err)?;
        writer.write_image_data(&self.pixels).map_err(err)?;
        writer.finish().map_err(err)?;
        Ok(out)
    }
}

/// Where a line's pixels go, as runs of one row: straight onto a
/// [`Canvas`], or through a layer that keeps what is already drawn on top
/// (`occlusion`). Every run handed over is clipped to the canvas. The
/// rows come in blocks (a layer's stripes; a whole canvas is one block) so
/// a shape can ask once whether a block is hidden before any row's
/// arithmetic.
pub(crate) trait Spans {
    /// Width and height of the canvas, in pixels.
    fn size(&self) -> (u32, u32);
    /// The first row from `y` on that `span` paints (`y` itself when it
    /// paints every row). May be past the last row.
    fn next_row(&self, y: i64) -> i64 {
        y
    }
    /// The last row of `y`'s block.
    fn block_end(&self, _y: i64) -> i64 {
        i64::MAX
    }
    /// Whether pixels `x0..=x1` (clipped to the canvas) are final on every
    /// row `y0..=y1` of one block: nothing drawn there would show.
    fn covered_block(&self, _y0: i64, _y1: i64, _x0: i64, _x1: i64) -> bool {
        false
    }
    /// Whether pixels `x0..=x1` (clipped to the canvas) of row `y` are all
    /// final.
    fn covered(&self, _y: i64, _x0: i64, _x1: i64) -> bool {
        false
    }
    /// Paints pixels `x0..=x1` of row `y` (a layer that paints only some
    /// rows ignores the others).
    fn span(&mut self, y: i64, x0: i64, x1: i64, color: Rgb);
}

/// Whether the pixels `left..=right` of rows `top..=bottom` (clipped to
/// the canvas) that `out` paints are all final: a shape inside them would
/// change nothing.
fn hidden(out: &impl Spans, top: i64, bottom: i64, left: i64, right: i64) -> bool {
    let mut y = out.next_row(top);
    while y <= bottom {
        let end = out.block_end(y).min(bottom);
        if !out.covered_block(y, end, left, right) {
            return false;
        }
        y = out.next_row(end + 1);
    }
    true
}

impl Spans for Canvas {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    fn span(&mut self, y: i64, x0: i64, x1: i64, color: Rgb) {
        let row = y as usize * self.width as usize * 3;
        fill(&mut self.pixels[row..], x0, x1, color);
    }
}

/// A straight line `width` pixels wide from (x0, y0) to (x1, y1), given
/// as `[x0, y0, x1, y1]`, as runs into `out`.
pub(crate) fn line_into(out: &mut impl Spans, ends: [f64; 4], width: f64, color: Rgb) {
    if !ends.iter().all(|v| v.is_finite()) {
        return;
    }
    let (w, h) = out.size();
    // Clip to a margin around the canvas so a wild coordinate cannot
    // make the loop below run for ever.
    let lim = 4.0 * f64::from(w.max(h));
    let [x0, y0, x1, y1] = ends.map(|v| v.clamp(-lim, lim));
    let half = (width.max(1.0) - 1.0) / 2.0;
    if half > 0.0 {
        capsule(out, [x0, y0, x1, y1], half + 0.5, color);
        return;
    }
    // One pixel per step along the longer axis. Steps move x by at most a
    // pixel and y one way, so the pixels of one row are one run:
    // handed over whole (the thin twigs of a large tree are most lines).
    // A pixel of margin: a step's rounding may land one past an end.
    let (top, bottom) = (y0.min(y1).round() as i64 - 1, y0.max(y1).round() as i64 + 1);
    let (left, right) = (x0.min(x1).round() as i64 - 1, x0.max(x1).round() as i64 + 1);
    let (top_c, bottom_c) = (top.max(0), bottom.min(i64::from(h) - 1));
    let (left_c, right_c) = (left.max(0), right.min(i64::from(w) - 1));
    if left_c > right_c || hidden(out, top_c, bottom_c, left_c, right_c) {
        // Off the canvas, or every row it would touch is final or not
        // `out`'s to paint.
        return;
    }
    let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as i64;
    let mut run: Option<(i64, i64, i64)> = None;
    let mut flush = |run: Option<(i64, i64, i64)>| {
        if let Some((y, lo, hi)) = run {
            let (lo, hi) = (lo.max(0), hi.min(i64::from(w) - 1));
            if (0..i64::from(h)).contains(&y) && lo <= hi {
                out.span(y, lo, hi, color);
            }
        }
    };
    for i in 0..=steps {
        let t = i as f64 / steps as f64;
        let (x, y) = (x0 + (x1 - x0) * t, y0 + (y1 - y0) * t);
        let (x, y) = (x.round() as i64, y.round() as i64);
        match &mut run {
            Some((row, lo, hi)) if *row == y => (*lo, *hi) = ((*lo).min(x), (*hi).max(x)),
            _ => {
                flush(run);
                run = Some((y, x, x));
            }
        }
    }
    flush(run);
}

/// Every pixel within `r` of the segment (x0, y0)–(x1, y1): a thick line
/// with round ends, filled row by row. Why not discs along the line: a
/// disc per pixel step costs length × width², which made the picture of
/// a large tree (thick trunk, 100 000 segments) slower than building it;
/// rows cost the pixels they fill. Most of a large crown's capsules lie
/// under others: a block of rows whose [`Reach`] `out` already has final
/// is skipped at once, then a row whose reach is final, before the row's
/// own arithmetic (square roots, divisions), which alone decides pixels.
fn capsule(out: &mut impl Spans, [x0, y0, x1, y1]: [f64; 4], r: f64, color: Rgb) {
    let (w, h) = out.size();
    let (w, h) = (f64::from(w), f64::from(h));
    let r = r.min(1e5);
    let top = floor(y0.min(y1) - r).max(0.0) as i64;
    let bottom = ceil(y0.max(y1) + r).min(h - 1.0) as i64;
    // The widest the capsule gets on any row, clipped, with a pixel of
    // margin for the rows' rounding.
    let left = (floor(x0.min(x1) - r) - 1.0).max(0.0) as i64;
    let right = (ceil(x0.max(x1) + r) + 1.0).min(w - 1.0) as i64;
    if left > right {
        return;
    }
    let (dx, dy) = (x1 - x0, y1 - y0);
    let len2 = dx * dx + dy * dy;
    let len = len2.sqrt();
    let reach = Reach::new([x0, y0, x1, y1], r, (left, right));
    let mut yy = out.next_row(top);
    while yy <= bottom {
        let end = out.block_end(yy).min(bottom);
        let (bl, br) = reach.columns(yy, end);
        if !out.covered_block(yy, end, bl, br) {
            for y in yy..=end {
                let (rl, rr) = reach.columns(y, y);
                if !out.covered(y, rl, rr) {
                    capsule_row(out, [x0, y0, x1, y1], (len2, len), r, y, color);
                }
            }
        }
        yy = out.next_row(end + 1);
    }
}

/// Row `yy` of the capsule of radius `r` around (x0, y0)–(x1, y1), whose
/// |d|² and |d| are `lens`, into `out`.
fn capsule_row(
    out: &mut impl Spans,
    [x0, y0, x1, y1]: [f64; 4],
    (len2, len): (f64, f64),
    r: f64,
    yy: i64,
    color: Rgb,
) {
    let w = f64::from(out.size().0);
    let y = yy as f64;
    let mut span = disc_span(x0, y0, r, y);
    span = union(span, disc_span(x1, y1, r, y));
    // Below a nanopixel the discs are the whole shape, and the band's
    // tests lose their meaning (both slopes vanish: every x passes).
    if len > 1e-9 {
        span = union(
            span,
            band_span([x0, y0, x1 - x0, y1 - y0], len2, r * len, y),
        );
    }
    if let Some((lo, hi)) = span {
        let (lo, hi) = (ceil(lo).max(0.0), floor(hi).min(w - 1.0));
        if !lo.is_nan() && !hi.is_nan() && lo <= hi {
            out.span(yy, lo as i64, hi as i64, color);
        }
    }
}

/// Columns a capsule may touch on a range of rows, a little wider than
/// it does: every point of the capsule lies within `r` of a point of the
/// segment, so on rows `ya..=yb` it lies within `r` across of the part
/// of the segment between heights `ya − r` and `yb + r`, whose ends are
/// linear in the rows. No square root, no division per row: the cheap
/// test of whether anything on the rows can show. A pixel of margin
/// (`r` + 1) covers the rounding, so the columns always hold the row's
/// exact span.
struct Reach {
    /// The segment's first end, (x0, y0).
    start: (f64, f64),
    /// From the first end to the second, (dx, dy).
    d: (f64, f64),
    /// 1 / dy, or 0 for a segment (nearly) level, which every row's
    /// reach takes whole.
    inv_dy: f64,
    /// The capsule's radius plus the pixel of margin.
    r: f64,
    /// The capsule's columns on the canvas (its bounding box, clipped).
    clip: (i64, i64),
}

impl Reach {
    /// The reach of the capsule of radius `r` around (x0, y0)–(x1, y1),
    /// within the columns `clip`.
    fn new([x0, y0, x1, y1]: [f64; 4], r: f64, clip: (i64, i64)) -> Self {
        let dy = y1 - y0;
        Reach {
            start: (x0, y0),
            d: (x1 - x0, dy),
            inv_dy: if dy.abs() > 1e-9 { 1.0 / dy } else { 0.0 },
            r: r + 1.0,
            clip,
        }
    }

    /// The columns rows `ya..=yb` may touch, clipped (empty as `a > b`).
    fn columns(&self, ya: i64, yb: i64) -> (i64, i64) {
        let ((x0, y0), (dx, _)) = (self.start, self.d);
        let (mut t0, mut t1) = (0.0, 1.0);
        if self.inv_dy != 0.0 {
            let ta = (ya as f64 - self.r - y0) * self.inv_dy;
            let tb = (yb as f64 + self.r - y0) * self.inv_dy;
            t0 = ta.min(tb).max(0.0);
            t1 = ta.max(tb).min(1.0);
            if t0 > t1 {
                return (1, 0);
            }
        }
        let (xa, xb) = (x0 + t0 * dx, x0 + t1 * dx);
        // Truncation moves each end by less than a pixel, inside the
        // pixel of margin: no floor (a branch and two conversions each).
        // Finite ends and radius make finite columns.
        let lo = ((xa.min(xb) - self.r) as i64).max(self.clip.0);
        let hi = ((xa.max(xb) + self.r) as i64).min(self.clip.1);
        (lo, hi)
    }
}

/// Row `y` of the band between a segment's ends: the points p with
/// 0 ≤ (p − p0)·d ≤ |d|² and |(p − p0) × d| ≤ r|d| (`rlen`), each linear
/// in x on the row. `seg` is [x0, y0, dx, dy], `len2` = |d|².
fn band_span([x0, y0, dx, dy]: [f64; 4], len2: f64, rlen: f64, y: f64) -> Option<(f64, f64)> {
    let mut lo = f64::NEG_INFINITY;
    let mut hi = f64::INFINITY;
    let ry = y - y0;
    for (a, b, min, max) in [(dx, ry * dy, 0.0, len2), (-dy, ry * dx, -rlen, rlen)] {
        // min ≤ a·(x − x0) + b ≤ max
        if a.abs() < 1e-12 {
            if b < min || b > max {
                return None;
            }
            continue;
        }
        let (p, q) = ((min - b) / a + x0, (max - b) / a + x0);
        lo = lo.max(p.min(q));
        hi = hi.min(p.max(q));
    }
    (lo <= hi).then_some((lo, hi))
}

/// Sets pixels `x0..=x1` of the row starting `row` (3 bytes a pixel); the
/// caller has clipped them to the canvas (`Spans` promises so).
pub(crate) fn fill(row: &mut [u8], x0: i64, x1: i64, color: Rgb) {
    debug_assert!(0 <= x0 && x0 <= x1);
    let (a, b) = (x0 as usize * 3, x1 as usize * 3 + 3);
    for px in row[a..b].chunks_exact_mut(3) {
        px.copy_from_slice(&color);
    }
}

/// `x.floor()` without the call into libm that the baseline x86-64 target
/// makes of it (5 % of a large tree's picture). Exact for |x| < 2⁶³; beyond
/// that (and for ±∞) it saturates, which the callers clamp to the canvas
/// anyway. NaN stays NaN.
fn floor(x: f64) -> f64 {
    if x.is_nan() {
        return x;
    }
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// `x.ceil()` as [`floor`] does it.
fn ceil(x: f64) -> f64 {
    -floor(-x)
}

/// The x-interval of row `y` inside the disc of radius `r` at (cx, cy).
fn disc_span(cx: f64, cy: f64, r: f64, y: f64) -> Option<(f64, f64)> {
    let dy = y - cy;
    let w2 = r * r - dy * dy;
    (w2 >= 0.0).then(|| {
        let w = w2.sqrt();
        (cx - w, cx + w)
    })
}

/// The smallest interval holding both (the pieces of a convex shape's row
/// overlap, so this is their union).
fn union(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// The 5×7 dot pattern of a character: seven rows, bit 4 is the left column.
fn glyph(ch: char) -> [u8; 7] {
    let ch = ch.to_ascii_uppercase();
    match ch {
        ' ' => [0; 7],
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        'A' => [0x0E, 0x11, 0x11, 0x11, 0x1F, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'D' => [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'H' => [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'Q' => [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04],
        'Z' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F],
        '.' => [0, 0, 0, 0, 0, 0x0C, 0x0C],
        ',' => [0, 0, 0, 0, 0x0C, 0x04, 0x08],
        '-' => [0, 0, 0, 0x1F, 0, 0, 0],
        '+' => [0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0],
        ':' => [0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0],
        ';' => [0, 0x0C, 0x0C, 0, 0x0C, 0x04, 0x08],
        '/' => [0, 0x01, 0x02, 0x04, 0x08, 0x10, 0],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '[' => [0x0E, 0x08, 0x08, 0x08, 0x08, 0x08, 0x0E],
        ']' => [0x0E, 0x02, 0x02, 0x02, 0x02, 0x02, 0x0E],
        '%' => [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
        '_' => [0, 0, 0, 0, 0, 0, 0x1F],
        '=' => [0, 0, 0x1F, 0, 0x1F, 0, 0],
        '<' => [0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02],
        '>' => [0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08],
        '\'' => [0x04, 0x04, 0x08, 0, 0, 0, 0],
        '#' => [0x0A, 0x0A, 0x1F, 0x0A, 0x1F, 0x0A, 0x0A],
        '±' => [0x04, 0x04, 0x1F, 0x04, 0x04, 0, 0x1F],
        _ => [0x0E, 0x11, 0x01, 0x02, 0x04, 0, 0x04],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_land_where_asked_and_clip() {
        let mut c = Canvas::new(40, 30);
        c.rect(2.0, 3.0, 4.0, 2.0, BLACK);
        assert_eq!(c.pixel(2, 3), Some(BLACK));
        assert_eq!(c.pixel(5, 4), Some(BLACK));
        assert_eq!(c.pixel(6, 4), Some(WHITE));
        c.line(0.0, 20.0, 39.0, 20.0, 3.0, GREY);
        assert_eq!(c.pixel(20, 21), Some(GREY));
        assert_eq!(c.pixel(20, 23), Some(WHITE));
        c.circle(30.0, 8.0, 3.0, [255, 0, 0]);
        assert_eq!(c.pixel(30, 10), Some([255, 0, 0]));
        // Far outside, NaN, huge: clipped, no panic.
        c.line(-1e300, 0.0, 1e300, 1e9, 2.0, BLACK);
        c.line(f64::NAN, 0.0, 1.0, 1.0, 1.0, BLACK);
        c.circle(1e12, 1e12, 1e12, BLACK);
        c.rect(-5.0, -5.0, 1e9, 1.0, BLACK);
        assert_eq!(c.pixel(-1, 0), None);
    }

    /// Thick lines are filled row by row now; they cover what the discs
    /// stamped along the line used to (all but the scallops' edge pixels).
    #[test]
    fn thick_lines_cover_what_discs_along_them_cover() {
        for (x0, y0, x1, y1, w) in [
            (5.0, 5.0, 50.0, 30.0, 7.0),
            (10.3, 40.0, 10.3, 5.0, 4.0),
            (3.0, 3.0, 3.0, 3.0, 9.0),
            (60.0, 10.0, 20.0, 12.5, 2.5),
            (-20.0, 70.0, 90.0, -5.0, 12.0),
        ] {
            let mut rows = Canvas::new(80, 60);
            rows.line(x0, y0, x1, y1, w, BLACK);
            let mut discs = Canvas::new(80, 60);
            let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as i64;
            for i in 0..=steps {
                let t = i as f64 / steps as f64;
                discs.circle(
                    x0 + (x1 - x0) * t,
                    y0 + (y1 - y0) * t,
                    (w - 1.0) / 2.0,
                    BLACK,
                );
            }
            let (mut differ, mut ink) = (0, 0);
            for y in 0..60 {
                for x in 0..80 {
                    differ += usize::from(rows.pixel(x, y) != discs.pixel(x, y));
                    ink += usize::from(discs.pixel(x, y) == Some(BLACK));
                }
            }
            assert!(
                ink > 0 && differ * 20 <= ink,
                "{differ} of {ink} pixels differ"
            );
        }
    }

    #[test]
    fn text_draws_the_font() {
        let mut c = Canvas::new(20, 10);
        c.text(0.0, 0.0, "1", BLACK);
        // '1': the top row has only the middle dot (column 2).
        assert_eq!(c.pixel(2, 0), Some(BLACK));
        assert_eq!(c.pixel(0, 0), Some(WHITE));
        assert_eq!(c.pixel(1, 6), Some(BLACK));
        assert_eq!(Canvas::text_width("ab", 2), 22.0);
    }

    #[test]
    fn png_decodes_back_to_the_pixels() {
        let mut c = Canvas::new(7, 5);
        c.set(3, 2, [10, 20, 30]);
        let bytes = c.encode_png().unwrap();
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (7, 5));
        let i = (2 * 7 + 3) * 3;
        assert_eq!(&buf[i..i + 3], &[10, 20, 30]);
        assert_eq!(&buf[0..3], &[255, 255, 255]);
    }
}
