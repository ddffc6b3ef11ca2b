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
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            return;
        }
        // Clip to a margin around the canvas so a wild coordinate cannot
        // make the loop below run for ever.
        let lim = 4.0 * f64::from(self.width.max(self.height));
        let (x0, y0, x1, y1) = (
            x0.clamp(-lim, lim),
            y0.clamp(-lim, lim),
            x1.clamp(-lim, lim),
            y1.clamp(-lim, lim),
        );
        let half = (width.max(1.0) - 1.0) / 2.0;
        if half > 0.0 {
            self.capsule(x0, y0, x1, y1, half + 0.5, color);
            return;
        }
        let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as i64;
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            let (x, y) = (x0 + (x1 - x0) * t, y0 + (y1 - y0) * t);
            self.set(x.round() as i64, y.round() as i64, color);
        }
    }

    /// Every pixel within `r` of the segment (x0, y0)–(x1, y1): a thick line
    /// with round ends, filled row by row. Why not discs along the line: a
    /// disc per pixel step costs length × width², which made the picture of
    /// a large tree (thick trunk, 100 000 segments) slower than building it;
    /// rows cost the pixels they fill.
    fn capsule(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, r: f64, color: Rgb) {
        let r = r.min(1e5);
        let top = (y0.min(y1) - r).floor().max(0.0) as i64;
        let bottom = (y0.max(y1) + r).ceil().min(f64::from(self.height) - 1.0) as i64;
        let (dx, dy) = (x1 - x0, y1 - y0);
        let len2 = dx * dx + dy * dy;
        let len = len2.sqrt();
        for yy in top..=bottom {
            let y = yy as f64;
            let mut span = disc_span(x0, y0, r, y);
            span = union(span, disc_span(x1, y1, r, y));
            if len > 0.0 {
                // The band between the ends: 0 ≤ (p − p0)·d ≤ |d|² and
                // |(p − p0) × d| ≤ r|d|, each linear in x on this row.
                let mut lo = f64::NEG_INFINITY;
                let mut hi = f64::INFINITY;
                let ry = y - y0;
                for (a, b, min, max) in
                    [(dx, ry * dy, 0.0, len2), (-dy, ry * dx, -r * len, r * len)]
                {
                    // min ≤ a·(x − x0) + b ≤ max
                    if a.abs() < 1e-12 {
                        if b < min || b > max {
                            lo = f64::INFINITY;
                        }
                        continue;
                    }
                    let (p, q) = ((min - b) / a + x0, (max - b) / a + x0);
                    lo = lo.max(p.min(q));
                    hi = hi.min(p.max(q));
                }
                if lo <= hi {
                    span = union(span, Some((lo, hi)));
                }
            }
            if let Some((lo, hi)) = span {
                self.fill_row(yy, lo.ceil(), hi.floor(), color);
            }
        }
    }

    /// Sets pixels `x0..=x1` of row `y`, clipped to the canvas.
    fn fill_row(&mut self, y: i64, x0: f64, x1: f64, color: Rgb) {
        if y < 0 || y >= i64::from(self.height) {
            return;
        }
        let x0 = x0.max(0.0);
        let x1 = x1.min(f64::from(self.width) - 1.0);
        if x0.is_nan() || x1.is_nan() || x0 > x1 {
            return;
        }
        let row = y as usize * self.width as usize * 3;
        let (a, b) = (row + x0 as usize * 3, row + x1 as usize * 3 + 3);
        for px in self.pixels[a..b].chunks_exact_mut(3) {
            px.copy_from_slice(&color);
        }
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
        let mut writer = encoder.write_header().map_err(err)?;
        writer.write_image_data(&self.pixels).map_err(err)?;
        writer.finish().map_err(err)?;
        Ok(out)
    }
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
