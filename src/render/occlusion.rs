//! Drawing from the top down: shapes handed over topmost first, each pixel
//! keeping the first colour it gets, which is the picture the usual
//! painter's order (bottom first, each shape over the last) makes.
//!
//! Why: a large tree's picture draws tens of thousands of thick capsules
//! that lie mostly under one another (every branch of the crown inside its
//! parents' width), so painting bottom first wrote each pixel of the crown
//! hundreds of times. From the top down each pixel is written once, and a
//! stripe of rows, then a row, that is already final wherever a capsule
//! could reach is skipped before the row's exact arithmetic. The spans are the very ones `Canvas::line`
//! computes, and rows do not depend on one another, so the pixels are the
//! same as painting bottom first, whichever thread paints which rows.

use crate::render::raster::{fill, line_into, Canvas, Rgb, Spans};

/// Rows per stripe: the rows are dealt to the threads in stripes this
/// tall, taken in turn (the crown at the top and the trunk below cost
/// differently, so halves would not share the work evenly), and each
/// stripe keeps which 64-pixel words are final on all its rows.
const STRIPE: usize = 16;

/// Threads painting: the machines this runs on have 2 cores or more, and
/// more threads would mostly wait for memory.
const THREADS: usize = 2;

/// One line of a layer: a straight line `width` pixels wide from
/// (x0, y0) to (x1, y1), as [`Canvas::line`] draws it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stroke {
    /// [x0, y0, x1, y1] in pixels.
    pub ends: [f64; 4],
    /// Width in pixels (at least one is drawn).
    pub width: f64,
    /// Its colour.
    pub color: Rgb,
}

/// Draws `strokes`, topmost first, over `canvas`: each pixel takes the
/// colour of the first stroke covering it, and what no stroke covers stays
/// as it was. The same pixels as drawing them in reverse with
/// [`Canvas::line`], on [`THREADS`] threads.
pub fn draw_top_down(canvas: &mut Canvas, strokes: &[Stroke]) {
    let (width, height) = (canvas.width(), canvas.height());
    let stripe_bytes = STRIPE * width as usize * 3;
    let mut bands: Vec<Band<'_>> = (0..THREADS)
        .map(|index| Band::new(width, height, index))
        .collect();
    for (i, stripe) in canvas.pixels_mut().chunks_mut(stripe_bytes).enumerate() {
        bands[i % THREADS].stripes.push(stripe);
    }
    let paint = |mut band: Band<'_>| {
        for s in strokes {
            line_into(&mut band, s.ends, s.width, s.color);
        }
    };
    let first = bands.remove(0);
    std::thread::scope(|scope| {
        for band in bands {
            scope.spawn(move || paint(band));
        }
        paint(first);
    });
}

/// The rows one thread paints: every [`THREADS`]th stripe from `index`.
struct Band<'a> {
    /// The canvas's size in pixels.
    size: (u32, u32),
    /// Which of the threads' bands this is: its stripes are those whose
    /// number is `index` modulo [`THREADS`].
    index: usize,
    /// This band's stripes of the canvas's pixels, in order.
    stripes: Vec<&'a mut [u8]>,
    /// One bit per pixel, [`Band::words`] words a row, set once the pixel
    /// is final; the bits past the canvas's right edge and the rows past
    /// its bottom (up to a whole stripe) are set from the start, so a full
    /// word is `u64::MAX` everywhere. Other bands' rows stay clear. A
    /// span's test and its gaps are a few words, where a list of runs per
    /// row cost a search and a splice in memory the cache did not hold.
    done: Vec<u64>,
    /// Words of `done` per row.
    words: usize,
    /// Per stripe, one bit per word of a row: set once that word is full
    /// on every row of the stripe, so a capsule deep under the crown is
    /// skipped a stripe at a time, mostly without reading `done`.
    tiles: Vec<u64>,
    /// Words of `tiles` per stripe.
    tile_words: usize,
}

impl<'a> Band<'a> {
    /// The band `index` of a `width` × `height` canvas, nothing drawn.
    fn new(width: u32, height: u32, index: usize) -> Self {
        let rows = (height as usize).div_ceil(STRIPE) * STRIPE;
        let words = (width as usize).div_ceil(64);
        let mut done = vec![0; rows * words];
        let past_edge = match width % 64 {
            0 => 0,
            used => u64::MAX << used,
        };
        for row in done.chunks_exact_mut(words) {
            row[words - 1] = past_edge;
        }
        done[height as usize * words..].fill(u64::MAX);
        let tile_words = words.div_ceil(64);
        Band {
            size: (width, height),
            index,
            stripes: Vec::new(),
            done,
            words,
            tiles: vec![0; rows / STRIPE * tile_words],
            tile_words,
        }
    }

    /// Whether row `y` is this band's.
    fn owns(&self, y: usize) -> bool {
        (y / STRIPE) % THREADS == self.index
    }

    /// Row `y`'s pixels (a row of this band).
    fn row(&mut self, y: usize) -> &mut [u8] {
        let bytes = self.size.0 as usize * 3;
        let stripe = &mut self.stripes[y / STRIPE / THREADS];
        &mut stripe[(y % STRIPE) * bytes..][..bytes]
    }

    /// Whether word `k` is full on every row of `y`'s stripe.
    fn tile(&self, y: usize, k: usize) -> bool {
        self.tiles[y / STRIPE * self.tile_words + k / 64] >> (k % 64) & 1 == 1
    }

    /// Notes that word `k` of row `y` just filled: its tile is full once
    /// the word is full on the stripe's other rows too.
    fn word_filled(&mut self, y: usize, k: usize) {
        let start = y - y % STRIPE;
        let full = (start..start + STRIPE).all(|row| self.done[row * self.words + k] == u64::MAX);
        if full {
            self.tiles[y / STRIPE * self.tile_words + k / 64] |= 1 << (k % 64);
        }
    }
}

/// The bits of pixels `x0..=x1` in word `k` of a row whose pixels from
/// `first`*64 to `last`*64+63 are asked about.
fn word_mask(k: usize, (first, last): (usize, usize), x0: i64, x1: i64) -> u64 {
    let lo = if k == first { x0 as u32 % 64 } else { 0 };
    let hi = if k == last { x1 as u32 % 64 } else { 63 };
    (u64::MAX >> (63 - hi)) & (u64::MAX << lo)
}

impl Spans for Band<'_> {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn next_row(&self, y: i64) -> i64 {
        let mut y = y as usize;
        while y < self.size.1 as usize && !self.owns(y) {
            y += STRIPE - y % STRIPE;
        }
        y as i64
    }

    fn block_end(&self, y: i64) -> i64 {
        y - y % STRIPE as i64 + STRIPE as i64 - 1
    }

    fn covered_block(&self, y0: i64, y1: i64, x0: i64, x1: i64) -> bool {
        if x0 > x1 {
            return true;
        }
        let ends = (x0 as usize / 64, x1 as usize / 64);
        (ends.0..=ends.1).all(|k| {
            let mask = word_mask(k, ends, x0, x1);
            self.tile(y0 as usize, k)
                || (y0..=y1).all(|y| self.done[y as usize * self.words + k] & mask == mask)
        })
    }

    fn covered(&self, y: i64, x0: i64, x1: i64) -> bool {
        if x0 > x1 {
            return true;
        }
        let ends = (x0 as usize / 64, x1 as usize / 64);
        let row = &self.done[y as usize * self.words..];
        (ends.0..=ends.1).all(|k| {
            let mask = word_mask(k, ends, x0, x1);
            row[k] & mask == mask
        })
    }

    fn span(&mut self, y: i64, x0: i64, x1: i64, color: Rgb) {
        let yu = y as usize;
        if !self.owns(yu) {
            return;
        }
        let ends = (x0 as usize / 64, x1 as usize / 64);
        for k in ends.0..=ends.1 {
            // The bits of x0..=x1 in this word that are not final yet.
            let mask = word_mask(k, ends, x0, x1);
            let word = &mut self.done[yu * self.words + k];
            let mut open = mask & !*word;
            if open == 0 {
                continue;
            }
            *word |= mask;
            if *word == u64::MAX {
                self.word_filled(yu, k);
            }
            while open != 0 {
                let start = open.trailing_zeros();
                let len = (!(open >> start)).trailing_zeros();
                let from = (k * 64) as i64 + i64::from(start);
                fill(self.row(yu), from, from + i64::from(len) - 1, color);
                open &= !(u64::MAX >> (64 - len) << start);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::raster::{BLACK, GREY, WHITE};

    /// Shapes drawn top first through the layer give, pixel for pixel, the
    /// canvas that painting them bottom first gives.
    #[test]
    fn top_down_paints_what_bottom_up_paints() {
        // Thin and thick, steep and flat, some past the edges, over several
        // stripes and bitmap words.
        let shapes: Vec<([f64; 4], f64, Rgb)> = (0..300)
            .map(|i| {
                let f = f64::from(i);
                let ends = [
                    (f * 37.3) % 220.0 - 10.0,
                    (f * 23.7) % 140.0 - 10.0,
                    (f * 11.1) % 210.0,
                    (f * 53.9) % 125.0,
                ];
                let width = [1.0, 0.5, 2.5, 7.0, 15.0, 30.0, 1.0][i as usize % 7];
                let colour = [BLACK, GREY, [200, 10, 10], [10, 120, 200]][i as usize % 4];
                (ends, width, colour)
            })
            .collect();
        let mut painter = Canvas::new(200, 120);
        for &([x0, y0, x1, y1], w, c) in &shapes {
            painter.line(x0, y0, x1, y1, w, c);
        }
        let strokes: Vec<Stroke> = shapes
            .iter()
            .rev()
            .map(|&(ends, width, color)| Stroke { ends, width, color })
            .collect();
        let mut top_down = Canvas::new(200, 120);
        draw_top_down(&mut top_down, &strokes);
        assert_eq!(painter, top_down);
        // Not a blank canvas that trivially equals another.
        let white = (0..120)
            .flat_map(|y| (0..200).map(move |x| (x, y)))
            .filter(|&(x, y)| painter.pixel(x, y) == Some(WHITE))
            .count();
        assert!(white < 200 * 120 / 2, "{white} white pixels");
    }

    /// A random tree like a reconstructed crown (each branch splits into
    /// thinner ones, most lying under their neighbours), drawn thickest
    /// last through the layer, gives the canvas that painting it thickest
    /// first gives: the skipped blocks and rows (whole stripes full,
    /// words full, rows' reach full) hide nothing that would show.
    #[test]
    fn a_dense_random_crown_top_down_is_the_painters_crown() {
        let mut rng = crate::rng::Rng::new(0x5EED_CAFE);
        let mut random = move || rng.f64();
        // (x0, y0, x1, y1, width): a trunk, then branches from the ends.
        let mut segments = vec![(150.0, 235.0, 151.3, 150.0, 24.0)];
        let mut k = 0;
        while segments.len() < 4000 {
            let (_, _, x, y, w): (f64, f64, f64, f64, f64) = segments[k];
            k += 1;
            for _ in 0..3 {
                let angle = -std::f64::consts::FRAC_PI_2 + (random() - 0.5) * 2.4;
                let len = 8.0 + random() * 30.0;
                let (ex, ey) = (x + len * angle.cos(), y + len * angle.sin());
                segments.push((x, y, ex, ey, (w * (0.5 + 0.3 * random())).max(1.0)));
            }
        }
        // Thickest first, as picture.rs sorts them (ties in order).
        let mut order: Vec<usize> = (0..segments.len()).collect();
        order.sort_by(|&a, &b| segments[b].4.total_cmp(&segments[a].4).then(a.cmp(&b)));
        let colour = |i: usize| [(i * 7 % 200) as u8, (i * 13 % 200) as u8, 90];
        let mut painter = Canvas::new(300, 250);
        for &i in &order {
            let (x0, y0, x1, y1, w) = segments[i];
            painter.line(x0, y0, x1, y1, w, colour(i));
        }
        let strokes: Vec<Stroke> = order
            .iter()
            .rev()
            .map(|&i| {
                let (x0, y0, x1, y1, width) = segments[i];
                Stroke {
                    ends: [x0, y0, x1, y1],
                    width,
                    color: colour(i),
                }
            })
            .collect();
        let mut top_down = Canvas::new(300, 250);
        draw_top_down(&mut top_down, &strokes);
        assert_eq!(painter, top_down);
        let drawn = (0..250)
            .flat_map(|y| (0..300).map(move |x| (x, y)))
            .filter(|&(x, y)| painter.pixel(x, y) != Some(WHITE))
            .count();
        assert!(drawn > 300 * 250 / 4, "{drawn} pixels drawn");
    }

    /// What the layer paints goes over what the canvas held before it;
    /// what it does not touch stays.
    #[test]
    fn the_layer_covers_the_canvas_below_only_where_it_draws() {
        let mut c = Canvas::new(30, 20);
        c.rect(0.0, 0.0, 30.0, 20.0, GREY);
        let stroke = |ends, width, color| Stroke { ends, width, color };
        draw_top_down(
            &mut c,
            &[
                stroke([5.0, 10.0, 25.0, 10.0], 5.0, BLACK),
                stroke([0.0, 10.0, 29.0, 10.0], 9.0, WHITE),
            ],
        );
        assert_eq!(c.pixel(15, 10), Some(BLACK));
        assert_eq!(c.pixel(15, 13), Some(WHITE));
        assert_eq!(c.pixel(15, 1), Some(GREY));
    }
}
