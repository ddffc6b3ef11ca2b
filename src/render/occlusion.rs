//! Drawing from the top down: shapes handed over topmost first, each pixel
//! keeping the first colour it gets, which is the picture the usual
//! painter's order (bottom first, each shape over the last) makes.
//!
//! Why: a large tree's picture draws tens of thousands of thick capsules
//! that lie mostly under one another (every branch of the crown inside its
//! parents' width), so painting bottom first wrote each pixel of the crown
//! hundreds of times. From the top down each pixel is written once, and a
//! row that is already final across a capsule's whole width is skipped
//! before its arithmetic. The spans are the very ones `Canvas::line`
//! computes, and rows do not depend on one another, so the pixels are the
//! same as painting bottom first, whichever thread paints which rows.

use crate::render::raster::{fill, line_into, Canvas, Rgb, Spans};

/// Rows per stripe: the rows are dealt to the threads in stripes this
/// tall, taken in turn (the crown at the top and the trunk below cost
/// differently, so halves would not share the work evenly), and each
/// stripe keeps which pixels are final on all its rows.
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
    /// One bit per pixel of the canvas (other bands' rows stay clear),
    /// set once the pixel is final, [`Band::words`] words a row: a span's
    /// test and its gaps are a few words, where a list of runs per row
    /// cost a search and a splice in memory the cache did not hold.
    done: Vec<u64>,
    /// Words of `done` per row.
    words: usize,
    /// Per row, a run of pixels known final (empty as (1, 0)), as long
    /// as the spans painted allow: most rows of a crown are one long run
    /// and a few specks, and this flat array answers most "hidden?"
    /// before the bits.
    widest: Vec<(i64, i64)>,
    /// Per stripe, the pixels final on every row of it (the intersection
    /// of their `widest`): a tall capsule deep under the crown skips a
    /// stripe a test.
    solid: Vec<(i64, i64)>,
}

impl<'a> Band<'a> {
    /// The band `index` of a `width` × `height` canvas, nothing drawn.
    fn new(width: u32, height: u32, index: usize) -> Self {
        let rows = height as usize;
        let words = (width as usize).div_ceil(64);
        Band {
            size: (width, height),
            index,
            stripes: Vec::new(),
            done: vec![0; rows * words],
            words,
            widest: vec![(1, 0); rows],
            solid: vec![(1, 0); rows.div_ceil(STRIPE)],
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

    /// The whole run of final pixels on row `y` around `x0..=x1` (final
    /// itself): where the first clear bit lies on each side.
    fn run_around(&self, y: usize, x0: i64, x1: i64) -> (i64, i64) {
        let bits = &self.done[y * self.words..][..self.words];
        let end = (self.words * 64) as i64;
        let mut right = x1 + 1;
        while right < end {
            let (k, b) = ((right / 64) as usize, right % 64);
            // Set bits from b upwards.
            let ones = i64::from((!(bits[k] >> b)).trailing_zeros());
            right += ones;
            if ones < 64 - b {
                break;
            }
        }
        let mut left = x0 - 1;
        while left >= 0 {
            let (k, b) = ((left / 64) as usize, left % 64);
            // Set bits from b downwards.
            let ones = i64::from((!(bits[k] << (63 - b))).leading_zeros());
            left -= ones;
            if ones < b + 1 {
                break;
            }
        }
        (left + 1, right - 1)
    }

    /// Notes that `x0..=x1` of row `y` is final: the row's known run
    /// becomes the whole run around it when that is longer, and its
    /// stripe's common part follows.
    fn widen(&mut self, y: usize, x0: i64, x1: i64) {
        let widest = self.widest[y];
        let run = self.run_around(y, x0, x1);
        if run.1 - run.0 <= widest.1 - widest.0 {
            return;
        }
        self.widest[y] = run;
        let start = y - y % STRIPE;
        let rows = start..(start + STRIPE).min(self.widest.len());
        self.solid[y / STRIPE] = self.widest[rows]
            .iter()
            .fold((i64::MIN, i64::MAX), |s, w| (s.0.max(w.0), s.1.min(w.1)));
    }
}

impl Spans for Band<'_> {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn hidden_until(&self, y: i64, x0: i64, x1: i64) -> i64 {
        let holds = |(a, b): (i64, i64)| a <= x0 && x1 <= b;
        let mut y = y as usize;
        while y < self.widest.len() {
            if !self.owns(y) || (y.is_multiple_of(STRIPE) && holds(self.solid[y / STRIPE])) {
                y += STRIPE - y % STRIPE;
            } else if holds(self.widest[y]) {
                y += 1;
            } else {
                break;
            }
        }
        y as i64
    }

    fn span(&mut self, y: i64, x0: i64, x1: i64, color: Rgb) {
        let yu = y as usize;
        let (a, b) = self.widest[yu];
        if !self.owns(yu) || (a <= x0 && x1 <= b) {
            return;
        }
        let (first, last) = (x0 as usize / 64, x1 as usize / 64);
        for k in first..=last {
            // The bits of x0..=x1 in this word that are not final yet.
            let lo = if k == first { x0 as u32 % 64 } else { 0 };
            let hi = if k == last { x1 as u32 % 64 } else { 63 };
            let mask = (u64::MAX >> (63 - hi)) & (u64::MAX << lo);
            let word = &mut self.done[yu * self.words + k];
            let mut open = mask & !*word;
            *word |= mask;
            while open != 0 {
                let start = open.trailing_zeros();
                let len = (!(open >> start)).trailing_zeros();
                let from = (k * 64) as i64 + i64::from(start);
                fill(self.row(yu), from, from + i64::from(len) - 1, color);
                open &= !(u64::MAX >> (64 - len) << start);
            }
        }
        self.widen(yu, x0, x1);
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
