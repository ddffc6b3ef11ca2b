//! A small software rasterizer for the pictures treemocap writes (tree.png,
//! track plots): anti-aliased thick lines, discs, rectangles and a 5×7
//! bitmap font, encoded with the `png` crate. Pictures let a user see a
//! result without a 3D viewer; this is all they need, and it keeps a
//! drawing stack out of the dependencies.

use std::path::Path;

use crate::error::{Error, Result};

/// A colour: red, green, blue, alpha (0–255).
pub type Rgba = [u8; 4];

/// An RGBA image being drawn on. Coordinates are pixels, x right, y down,
/// pixel centres at +0.5.
#[derive(Debug, Clone, PartialEq)]
pub struct Canvas {
    width: u32,
    height: u32,
    pixels: Vec<u8>,
}

impl Canvas {
    /// A white canvas.
    pub fn new(width: u32, height: u32) -> Canvas {
        Canvas {
            width,
            height,
            pixels: vec![255; width as usize * height as usize * 4],
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The colour at a pixel (None outside).
    pub fn pixel(&self, x: u32, y: u32) -> Option<Rgba> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 4;
        let p = &self.pixels[i..i + 4];
        Some([p[0], p[1], p[2], p[3]])
    }

    /// Blends `color` into a pixel with extra coverage `cover` (0–1).
    fn blend(&mut self, x: i64, y: i64, color: Rgba, cover: f64) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let a = cover.clamp(0.0, 1.0) * color[3] as f64 / 255.0;
        if a <= 0.0 {
            return;
        }
        let i = (y as usize * self.width as usize + x as usize) * 4;
        for (px, &c) in self.pixels[i..i + 3].iter_mut().zip(&color[..3]) {
            let old = *px as f64;
            *px = (old + (c as f64 - old) * a).round() as u8;
        }
        let old_a = self.pixels[i + 3] as f64;
        self.pixels[i + 3] = (old_a + (255.0 - old_a) * a).round() as u8;
    }

    /// Fills pixels in a bounding box by a signed-distance function
    /// (negative inside), anti-aliased over one pixel.
    fn shade(
        &mut self,
        (x0, y0, x1, y1): (f64, f64, f64, f64),
        color: Rgba,
        sdf: impl Fn(f64, f64) -> f64,
    ) {
        let clip = |v: f64, hi: u32| v.floor().clamp(0.0, hi as f64) as i64;
        let (xa, xb) = (clip(x0 - 1.0, self.width), clip(x1 + 1.0, self.width));
        let (ya, yb) = (clip(y0 - 1.0, self.height), clip(y1 + 1.0, self.height));
        for y in ya..yb {
            for x in xa..xb {
                let d = sdf(x as f64 + 0.5, y as f64 + 0.5);
                self.blend(x, y, color, 0.5 - d);
            }
        }
    }

    /// A line `width` pixels wide with round ends.
    pub fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, width: f64, color: Rgba) {
        if ![x0, y0, x1, y1, width].iter().all(|v| v.is_finite()) {
            return;
        }
        let h = 0.5 * width.max(0.5);
        let (dx, dy) = (x1 - x0, y1 - y0);
        let len2 = dx * dx + dy * dy;
        let bbox = (
            x0.min(x1) - h,
            y0.min(y1) - h,
            x0.max(x1) + h,
            y0.max(y1) + h,
        );
        self.shade(bbox, color, |px, py| {
            let t = if len2 > 0.0 {
                (((px - x0) * dx + (py - y0) * dy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (qx, qy) = (x0 + t * dx - px, y0 + t * dy - py);
            (qx * qx + qy * qy).sqrt() - h
        });
    }

    /// A filled disc.
    pub fn circle(&mut self, cx: f64, cy: f64, r: f64, color: Rgba) {
        if ![cx, cy, r].iter().all(|v| v.is_finite()) {
            return;
        }
        self.shade((cx - r, cy - r, cx + r, cy + r), color, |px, py| {
            ((px - cx).powi(2) + (py - cy).powi(2)).sqrt() - r
        });
    }

    /// A filled axis-aligned rectangle with its top-left corner at (x, y).
    pub fn rect(&mut self, x: f64, y: f64, w: f64, h: f64, color: Rgba) {
        if ![x, y, w, h].iter().all(|v| v.is_finite()) {
            return;
        }
        let (cx, cy, hx, hy) = (x + 0.5 * w, y + 0.5 * h, 0.5 * w.abs(), 0.5 * h.abs());
        self.shade((cx - hx, cy - hy, cx + hx, cy + hy), color, |px, py| {
            ((px - cx).abs() - hx).max((py - cy).abs() - hy)
        });
    }

    /// Text in a 5×7 pixel font scaled by `scale`, top-left at (x, y).
    /// Letters are drawn upper-case; characters without a glyph show as '?'.
    pub fn text(&mut self, x: f64, y: f64, s: &str, scale: u32, color: Rgba) {
        let scale = scale.max(1) as f64;
        for (i, ch) in s.chars().enumerate() {
            let rows = glyph(ch.to_ascii_uppercase());
            let ox = x + i as f64 * 6.0 * scale;
            for (r, bits) in rows.iter().enumerate() {
                for c in 0..5 {
                    if bits & (0b10000 >> c) != 0 {
                        let (px, py) = (ox + c as f64 * scale, y + r as f64 * scale);
                        for yy in 0..scale as i64 {
                            for xx in 0..scale as i64 {
                                self.blend(px as i64 + xx, py as i64 + yy, color, 1.0);
                            }
                        }
                    }
                }
            }
        }
    }

    /// The image as PNG bytes (RGBA, 8 bits).
    pub fn encode_png(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, self.width, self.height);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc
                .write_header()
                .map_err(|e| Error::Runtime(format!("PNG: {e}")))?;
            w.write_image_data(&self.pixels)
                .map_err(|e| Error::Runtime(format!("PNG: {e}")))?;
        }
        Ok(out)
    }

    /// Writes the image as a PNG file (atomically).
    pub fn save_png(&self, path: &Path) -> Result<()> {
        crate::output::write_atomic(path, &self.encode_png()?)
    }
}

/// Rows of a 5×7 glyph, bit 4 = leftmost pixel.
fn glyph(c: char) -> [u8; 7] {
    match c {
        'A' => [14, 17, 17, 31, 17, 17, 17],
        'B' => [30, 17, 17, 30, 17, 17, 30],
        'C' => [14, 17, 16, 16, 16, 17, 14],
        'D' => [30, 17, 17, 17, 17, 17, 30],
        'E' => [31, 16, 16, 30, 16, 16, 31],
        'F' => [31, 16, 16, 30, 16, 16, 16],
        'G' => [14, 17, 16, 23, 17, 17, 15],
        'H' => [17, 17, 17, 31, 17, 17, 17],
        'I' => [14, 4, 4, 4, 4, 4, 14],
        'J' => [7, 2, 2, 2, 2, 18, 12],
        'K' => [17, 18, 20, 24, 20, 18, 17],
        'L' => [16, 16, 16, 16, 16, 16, 31],
        'M' => [17, 27, 21, 21, 17, 17, 17],
        'N' => [17, 17, 25, 21, 19, 17, 17],
        'O' => [14, 17, 17, 17, 17, 17, 14],
        'P' => [30, 17, 17, 30, 16, 16, 16],
        'Q' => [14, 17, 17, 17, 21, 18, 13],
        'R' => [30, 17, 17, 30, 20, 18, 17],
        'S' => [15, 16, 16, 14, 1, 1, 30],
        'T' => [31, 4, 4, 4, 4, 4, 4],
        'U' => [17, 17, 17, 17, 17, 17, 14],
        'V' => [17, 17, 17, 17, 17, 10, 4],
        'W' => [17, 17, 17, 21, 21, 21, 10],
        'X' => [17, 17, 10, 4, 10, 17, 17],
        'Y' => [17, 17, 10, 4, 4, 4, 4],
        'Z' => [31, 1, 2, 4, 8, 16, 31],
        '0' => [14, 17, 19, 21, 25, 17, 14],
        '1' => [4, 12, 4, 4, 4, 4, 14],
        '2' => [14, 17, 1, 2, 4, 8, 31],
        '3' => [31, 2, 4, 2, 1, 17, 14],
        '4' => [2, 6, 10, 18, 31, 2, 2],
        '5' => [31, 16, 30, 1, 1, 17, 14],
        '6' => [6, 8, 16, 30, 17, 17, 14],
        '7' => [31, 1, 2, 4, 8, 8, 8],
        '8' => [14, 17, 17, 14, 17, 17, 14],
        '9' => [14, 17, 17, 15, 1, 2, 12],
        ' ' => [0; 7],
        '.' => [0, 0, 0, 0, 0, 12, 12],
        ',' => [0, 0, 0, 0, 12, 4, 8],
        '-' => [0, 0, 0, 31, 0, 0, 0],
        '+' => [0, 4, 4, 31, 4, 4, 0],
        '=' => [0, 0, 31, 0, 31, 0, 0],
        ':' => [0, 12, 12, 0, 12, 12, 0],
        '(' => [2, 4, 8, 8, 8, 4, 2],
        ')' => [8, 4, 2, 2, 2, 4, 8],
        '/' => [1, 2, 2, 4, 8, 8, 16],
        '_' => [0, 0, 0, 0, 0, 0, 31],
        '%' => [24, 25, 2, 4, 8, 19, 3],
        _ => [14, 17, 1, 2, 4, 0, 4],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLACK: Rgba = [0, 0, 0, 255];

    #[test]
    fn shapes_cover_the_right_pixels() {
        let mut c = Canvas::new(40, 20);
        c.line(5.0, 10.0, 35.0, 10.0, 4.0, BLACK);
        assert_eq!(c.pixel(20, 10), Some(BLACK));
        assert_eq!(c.pixel(20, 9), Some(BLACK));
        assert_eq!(c.pixel(20, 3), Some([255, 255, 255, 255]));
        c.circle(5.0, 5.0, 3.0, [255, 0, 0, 255]);
        assert_eq!(c.pixel(5, 5), Some([255, 0, 0, 255]));
        assert_eq!(c.pixel(39, 0), Some([255, 255, 255, 255]));
        c.rect(30.0, 0.0, 5.0, 4.0, [0, 0, 255, 255]);
        assert_eq!(c.pixel(32, 2), Some([0, 0, 255, 255]));
        assert_eq!(c.pixel(36, 2), Some([255, 255, 255, 255]));
        // Out of range drawing is clipped, never a panic.
        c.line(-1e9, -5.0, 1e9, 500.0, 3.0, BLACK);
        c.line(f64::NAN, 0.0, 1.0, 1.0, 1.0, BLACK);
    }

    #[test]
    fn text_and_png_round_trip() {
        let mut c = Canvas::new(64, 16);
        c.text(1.0, 1.0, "T1", 1, BLACK);
        // 'T' top row is 5 pixels wide.
        for x in 1..6 {
            assert_eq!(c.pixel(x, 1), Some(BLACK));
        }
        assert_eq!(c.pixel(3, 2), Some(BLACK));
        assert_eq!(c.pixel(2, 2), Some([255, 255, 255, 255]));
        let bytes = c.encode_png().unwrap();
        let dec = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size().unwrap()];
        let info = r.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (64, 16));
        assert_eq!(&buf[..], &c.pixels[..]);
    }
}
