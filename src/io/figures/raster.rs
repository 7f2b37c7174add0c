//! PNG previews of the simulator's images, drawn by a small raster of our own.
//!
//! * [`Canvas`]: an 8-bit RGB raster with clipped pixels, rectangles, lines and text in the
//!   public-domain 8×8 bitmap font of the `font8x8` crate (ASCII, Latin-1, Greek and a few symbols
//!   such as `−`, `≈`, `≤`, `→`; anything else is drawn as a box). [`Canvas::to_png`] encodes it.
//! * [`Colormap`]: grey, diverging blue–white–red and an approximation of viridis on `t ∈ [0, 1]`,
//!   with one fixed grey-magenta colour ([`NO_DATA`]) for NaN.
//! * [`image_png`]: a false-colour preview of one image, upscaled by an integer factor, with a title
//!   above it and a colour bar with tick labels in the value's units on its right.
//! * [`directional_png`]: the HoloDoppler-style directional composite of the power in the positive
//!   and negative halves of the Doppler spectrum (red = receding, blue = approaching).
//!
//! ## Orientation
//!
//! A [`Canvas`] is addressed like the PNG it becomes: `(x, y)` in pixels, `x` to the right and
//! row `y = 0` at the **top**.
//!
//! Data images are `ny × nx`, row-major, as written ([`crate::output::Output::values`]): data
//! row 0 = the largest `y` (`values[iy * nx + ix]`). Previews draw them with **y up**: data row 0
//! is the **top** row of the picture and data column 0 its left column, so a preview looks like a
//! plot of the `x`–`y` plane seen from `+z`, and like the `.npy` in `plt.imshow`. [`PreviewGeometry`] gives the exact placement (tests use it to find the
//! picture pixel of a data pixel).

use super::ticks::{nice_ticks, tick_label};

/// The colour of NaN and other "no data" pixels: a grey-magenta that no colour map produces.
pub const NO_DATA: [u8; 3] = [150, 110, 150];

const WHITE: [u8; 3] = [255, 255, 255];
const TEXT: [u8; 3] = [20, 20, 20];
const FRAME: [u8; 3] = [60, 60, 60];
const CAPTION: [u8; 3] = [110, 110, 110];

/// The box drawn for characters the font does not have.
const UNKNOWN_GLYPH: [u8; 8] = [0x00, 0x7E, 0x42, 0x42, 0x42, 0x42, 0x7E, 0x00];

/// Width in pixels of `s` drawn by [`Canvas::text`] at `scale` (8 × scale per character).
pub fn text_width(s: &str, scale: usize) -> usize {
    s.chars().count() * 8 * scale.max(1)
}

/// The 8×8 bitmap of `ch`: one byte per row (top first), bit 0 = leftmost pixel.
fn glyph(ch: char) -> [u8; 8] {
    use font8x8::legacy::{BASIC_LEGACY, GREEK_LEGACY, LATIN_LEGACY};
    let code = ch as u32;
    let g = match ch {
        ' ' | '\t' | '\u{A0}' => return [0; 8],
        '\u{20}'..='\u{7E}' => BASIC_LEGACY[code as usize],
        '\u{A1}'..='\u{FF}' => LATIN_LEGACY[(code - 0xA0) as usize],
        '\u{390}'..='\u{3C9}' => GREEK_LEGACY[(code - 0x390) as usize],
        // Minus sign, hyphen, en and em dash: the ASCII hyphen-minus.
        '\u{2010}' | '\u{2012}' | '\u{2013}' | '\u{2014}' | '\u{2212}' => BASIC_LEGACY[b'-' as usize],
        '\u{207B}' => [0x00, 0x00, 0x3C, 0x00, 0x00, 0x00, 0x00, 0x00], // superscript minus
        '\u{2192}' => [0x00, 0x10, 0x20, 0x7F, 0x20, 0x10, 0x00, 0x00], // →
        '\u{2190}' => [0x00, 0x08, 0x04, 0xFE, 0x04, 0x08, 0x00, 0x00], // ←
        '\u{2264}' => [0x30, 0x0C, 0x03, 0x0C, 0x30, 0x00, 0x3F, 0x00], // ≤
        '\u{2265}' => [0x03, 0x0C, 0x30, 0x0C, 0x03, 0x00, 0x3F, 0x00], // ≥
        '\u{2248}' => [0x00, 0x6E, 0x3B, 0x00, 0x6E, 0x3B, 0x00, 0x00], // ≈
        '\u{2026}' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x92, 0x00], // …
        _ => UNKNOWN_GLYPH,
    };
    if g == [0; 8] { UNKNOWN_GLYPH } else { g }
}

/// Clip the segment `p0–p1` to the rectangle `[xmin, xmax] × [ymin, ymax]` (Cohen–Sutherland:
/// clipped ends lie exactly on the boundary, so segments with far-away ends keep their precision).
/// `None` when nothing is inside or a coordinate is not finite.
pub(crate) fn clip_segment(p0: (f64, f64), p1: (f64, f64), rect: (f64, f64, f64, f64)) -> Option<[f64; 4]> {
    let (xmin, xmax, ymin, ymax) = rect;
    let code = |(x, y): (f64, f64)| {
        (x < xmin) as u8 | ((x > xmax) as u8) << 1 | ((y < ymin) as u8) << 2 | ((y > ymax) as u8) << 3
    };
    let (mut a, mut b) = (p0, p1);
    for _ in 0..8 {
        if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
            return None;
        }
        let (ca, cb) = (code(a), code(b));
        if ca | cb == 0 {
            return Some([a.0, a.1, b.0, b.1]);
        }
        if ca & cb != 0 {
            return None;
        }
        // Move the outside end onto the boundary it is beyond (the ratio is in [0, 1]: no overflow).
        let (out, other, c) = if ca != 0 { (a, b, ca) } else { (b, a, cb) };
        let along = |from: f64, to: f64, at: f64, o_from: f64, o_to: f64| {
            o_from + (o_to - o_from) * ((at - from) / (to - from))
        };
        let moved = if c & 8 != 0 {
            (along(out.1, other.1, ymax, out.0, other.0), ymax)
        } else if c & 4 != 0 {
            (along(out.1, other.1, ymin, out.0, other.0), ymin)
        } else if c & 2 != 0 {
            (xmax, along(out.0, other.0, xmax, out.1, other.1))
        } else {
            (xmin, along(out.0, other.0, xmin, out.1, other.1))
        };
        if ca != 0 { a = moved } else { b = moved }
    }
    None
}

/// An 8-bit RGB raster, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    pub width: usize,
    pub height: usize,
    /// `3 × width × height` bytes, row-major from the top row.
    pub rgb: Vec<u8>,
}

impl Canvas {
    /// A `width × height` canvas filled with `background`.
    pub fn new(width: usize, height: usize, background: [u8; 3]) -> Self {
        let n = width.saturating_mul(height);
        let mut rgb = Vec::with_capacity(n.saturating_mul(3));
        for _ in 0..n {
            rgb.extend_from_slice(&background);
        }
        Canvas { width, height, rgb }
    }

    /// The colour at `(x, y)`, `None` outside the canvas.
    pub fn get(&self, x: usize, y: usize) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = 3 * (y * self.width + x);
        self.rgb.get(i..i + 3).map(|p| [p[0], p[1], p[2]])
    }

    /// Set one pixel; coordinates outside the canvas are ignored.
    pub fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x < 0 || y < 0 || x as u64 >= self.width as u64 || y as u64 >= self.height as u64 {
            return;
        }
        let i = 3 * (y as usize * self.width + x as usize);
        if let Some(p) = self.rgb.get_mut(i..i + 3) {
            p.copy_from_slice(&c);
        }
    }

    /// Fill the rectangle with corners `(x0, y0)` and `(x1, y1)`, both included, clipped.
    pub fn fill_rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: [u8; 3]) {
        let (xa, xb) = (x0.min(x1).max(0), x0.max(x1).min(self.width as i64 - 1));
        let (ya, yb) = (y0.min(y1).max(0), y0.max(y1).min(self.height as i64 - 1));
        for y in ya..=yb {
            for x in xa..=xb {
                self.set(x, y, c);
            }
        }
    }

    /// The outline of the rectangle with corners `(x0, y0)` and `(x1, y1)`, 1 px wide.
    pub fn rect_outline(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: [u8; 3]) {
        self.fill_rect(x0, y0, x1, y0, c);
        self.fill_rect(x0, y1, x1, y1, c);
        self.fill_rect(x0, y0, x0, y1, c);
        self.fill_rect(x1, y0, x1, y1, c);
    }

    /// A 1 px line from `(x0, y0)` to `(x1, y1)` (pixel centres at integer coordinates), clipped.
    /// Non-finite coordinates draw nothing.
    pub fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, c: [u8; 3]) {
        self.line_width(x0, y0, x1, y1, c, 1);
    }

    /// A line drawn with a square brush `width` pixels wide (1 = [`Canvas::line`]), clipped.
    pub fn line_width(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, c: [u8; 3], width: usize) {
        let width = width.clamp(1, 64) as i64;
        let pad = width as f64;
        let rect = (-pad, self.width as f64 + pad, -pad, self.height as f64 + pad);
        let Some([xa, ya, xb, yb]) = clip_segment((x0, y0), (x1, y1), rect) else {
            return;
        };
        let steps = (xb - xa).abs().max((yb - ya).abs()).ceil().max(1.0) as usize;
        let lo = -(width - 1) / 2;
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            let (x, y) = ((xa + t * (xb - xa)).round() as i64, (ya + t * (yb - ya)).round() as i64);
            self.fill_rect(x + lo, y + lo, x + lo + width - 1, y + lo + width - 1, c);
        }
    }

    /// Draw one glyph with its top-left corner at `(x, y)`; `rotate` turns it 90° counter-clockwise.
    fn glyph(&mut self, x: i64, y: i64, ch: char, c: [u8; 3], scale: i64, rotate: bool) {
        let g = glyph(ch);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..8 {
                if bits >> col & 1 == 0 {
                    continue;
                }
                // Unrotated: column → right, row → down. Rotated ccw: column → up, row → right.
                let (gx, gy) = if rotate { (row as i64, 7 - col as i64) } else { (col as i64, row as i64) };
                let (px, py) = (x.saturating_add(gx * scale), y.saturating_add(gy * scale));
                self.fill_rect(px, py, px.saturating_add(scale - 1), py.saturating_add(scale - 1), c);
            }
        }
    }

    /// Text with the top-left corner of its first character at `(x, y)`, each 8×8 glyph zoomed by
    /// the integer `scale` (0 counts as 1); `\n` starts a new line.
    pub fn text(&mut self, x: i64, y: i64, s: &str, c: [u8; 3], scale: usize) {
        let scale = scale.clamp(1, 64) as i64;
        let (mut cx, mut cy) = (x, y);
        for ch in s.chars() {
            if ch == '\n' {
                cx = x;
                cy = cy.saturating_add(10 * scale);
                continue;
            }
            if ch != ' ' {
                self.glyph(cx, cy, ch, c, scale, false);
            }
            cx = cx.saturating_add(8 * scale);
        }
    }

    /// Text rotated 90° counter-clockwise (read bottom to top, as a y-axis label). `(x, y)` is the
    /// top-left corner of its bounding box, which is `8 × scale` wide and [`text_width`] tall; the
    /// first character is at the bottom.
    pub fn text_vertical(&mut self, x: i64, y: i64, s: &str, c: [u8; 3], scale: usize) {
        let scale = scale.clamp(1, 64) as i64;
        let n = s.chars().count() as i64;
        for (i, ch) in s.chars().enumerate() {
            if ch != ' ' {
                self.glyph(x, y.saturating_add((n - 1 - i as i64) * 8 * scale), ch, c, scale, true);
            }
        }
    }

    /// The canvas encoded as an RGB8 PNG. An empty canvas (or one whose `rgb` does not have
    /// `3 × width × height` bytes) is encoded as a single white pixel.
    pub fn to_png(&self) -> Vec<u8> {
        let valid = self.width > 0
            && self.height > 0
            && self.width <= u32::MAX as usize
            && self.height <= u32::MAX as usize
            && Some(self.rgb.len()) == self.width.checked_mul(self.height).and_then(|n| n.checked_mul(3));
        let (w, h, data): (usize, usize, &[u8]) =
            if valid { (self.width, self.height, &self.rgb) } else { (1, 1, &WHITE) };
        crate::io::formats::png::encode_rgb8(w as u32, h as u32, data).unwrap_or_default()
    }
}

/// Colour maps on `t ∈ [0, 1]` (clamped; NaN → [`NO_DATA`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Colormap {
    /// Black (0) to white (1).
    Grey,
    /// Dark blue (0) – white (0.5) – dark red (1), for signed quantities with 0 at the middle.
    Diverging,
    /// Dark purple – blue – green – yellow, an approximation of matplotlib's viridis.
    Viridis,
}

/// Diverging anchors, evenly spaced: blue, light blue, white, light red, red.
const DIVERGING: [[u8; 3]; 7] =
    [[24, 48, 118], [48, 108, 180], [146, 192, 224], [255, 255, 255], [238, 160, 132], [196, 62, 52], [112, 8, 28]];

/// Viridis at t = 0, 1/8, …, 1.
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 45, 123],
    [59, 82, 139],
    [44, 114, 142],
    [33, 145, 140],
    [40, 174, 128],
    [94, 201, 98],
    [173, 220, 48],
    [253, 231, 37],
];

/// Linear interpolation between evenly spaced anchor colours; `t` in [0, 1].
fn interpolate(anchors: &[[u8; 3]], t: f64) -> [u8; 3] {
    let pos = t * (anchors.len() - 1) as f64;
    let i = (pos.floor() as usize).min(anchors.len() - 2);
    let f = pos - i as f64;
    let (a, b) = (anchors[i], anchors[i + 1]);
    std::array::from_fn(|k| (a[k] as f64 + f * (b[k] as f64 - a[k] as f64)).round().clamp(0.0, 255.0) as u8)
}

impl Colormap {
    /// The colour of `t` (clamped to [0, 1]; NaN → [`NO_DATA`]).
    pub fn color(self, t: f64) -> [u8; 3] {
        if t.is_nan() {
            return NO_DATA;
        }
        let t = t.clamp(0.0, 1.0);
        match self {
            Colormap::Grey => {
                let g = (255.0 * t).round() as u8;
                [g, g, g]
            }
            Colormap::Diverging => interpolate(&DIVERGING, t),
            Colormap::Viridis => interpolate(&VIRIDIS, t),
        }
    }
}

/// HSV (`h` in degrees, any real; `s`, `v` clamped to [0, 1]) to RGB8. NaN counts as 0.
pub fn hsv_to_rgb(h: f64, s: f64, v: f64) -> [u8; 3] {
    let finite_or_zero = |x: f64| if x.is_finite() { x } else { 0.0 };
    let h = finite_or_zero(h).rem_euclid(360.0);
    let s = finite_or_zero(s).clamp(0.0, 1.0);
    let v = finite_or_zero(v).clamp(0.0, 1.0);
    let c = v * s;
    let hp = h / 60.0;
    let x = c * (1.0 - (hp.rem_euclid(2.0) - 1.0).abs());
    let (r, g, b) = match hp as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    let to_u8 = |f: f64| (255.0 * (f + m)).round().clamp(0.0, 255.0) as u8;
    [to_u8(r), to_u8(g), to_u8(b)]
}

/// The `q`-quantile (linear between order statistics) of an ascending, non-empty slice.
fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    let q = if q.is_nan() { 1.0 } else { q.clamp(0.0, 1.0) };
    let pos = q * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let j = (i + 1).min(sorted.len() - 1);
    sorted[i] + (pos - i as f64) * (sorted[j] - sorted[i])
}

/// Symmetric range `(−a, a)` for a diverging map: `a` = the `quantile` (e.g. 0.99) of `|v|` over
/// the finite values (the largest `|v|` if that quantile is 0); `(−1, 1)` if all are zero or none
/// is finite.
pub fn symmetric_range(values: &[f64], quantile: f64) -> (f64, f64) {
    let mut abs: Vec<f64> = values.iter().filter(|v| v.is_finite()).map(|v| v.abs()).collect();
    if abs.is_empty() {
        return (-1.0, 1.0);
    }
    abs.sort_by(f64::total_cmp);
    let mut a = quantile_sorted(&abs, quantile);
    if a <= 0.0 {
        a = abs[abs.len() - 1];
    }
    if a > 0.0 { (-a, a) } else { (-1.0, 1.0) }
}

/// Range `(lo, hi)` for a sequential map: `lo` = the smallest finite value, `hi` = the `quantile`
/// of the finite values (the largest if that quantile equals `lo`); `(0, 1)` if no value is finite
/// or all are equal.
pub fn sequential_range(values: &[f64], quantile: f64) -> (f64, f64) {
    let mut v: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if v.is_empty() {
        return (0.0, 1.0);
    }
    v.sort_by(f64::total_cmp);
    let lo = v[0];
    let mut hi = quantile_sorted(&v, quantile);
    if hi <= lo {
        hi = v[v.len() - 1];
    }
    if hi > lo { (lo, hi) } else { (0.0, 1.0) }
}

/// Where a preview draws its image: the top-left corner and size in pixels of the picture of the
/// `nx × ny` data. Picture pixel `(left + px, top + py)` shows data pixel
/// `ix = px · nx / width`, `iy = py · ny / height` (data row 0, the largest y, at the top).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PreviewGeometry {
    pub nx: usize,
    pub ny: usize,
    pub left: usize,
    pub top: usize,
    pub width: usize,
    pub height: usize,
}

/// The long side of a preview is at least this many pixels (integer upscaling) …
const PREVIEW_MIN_LONG: usize = 384;
/// … and at most about this many (integer subsampling of larger images).
const PREVIEW_MAX_LONG: usize = 2048;
/// A very thin image is stretched across its short side to at least this many pixels.
const PREVIEW_MIN_SHORT: usize = 32;
const MARGIN: usize = 16;
const TITLE_SCALE: usize = 2;
const LABEL_SCALE: usize = 1;
/// Height of the caption line under an image (with its gaps).
const CAPTION_H: usize = 8 * LABEL_SCALE + 10;
/// Top of the image: the margin, the title (8 × TITLE_SCALE px) and a gap.
const IMAGE_TOP: usize = MARGIN + 8 * TITLE_SCALE + 14;

impl PreviewGeometry {
    /// The geometry of a preview of an `nx × ny` image (both > 0): integer upscaling to at least
    /// 384 px on the long side, integer subsampling above 2048 px.
    pub fn new(nx: usize, ny: usize) -> Self {
        let (nx, ny) = (nx.max(1), ny.max(1));
        let long = nx.max(ny);
        let size = |n: usize| {
            if long <= PREVIEW_MIN_LONG {
                n * PREVIEW_MIN_LONG.div_ceil(long)
            } else if long <= PREVIEW_MAX_LONG {
                n
            } else {
                n.div_ceil(long.div_ceil(PREVIEW_MAX_LONG))
            }
        };
        let (mut width, mut height) = (size(nx), size(ny));
        if width < PREVIEW_MIN_SHORT {
            width *= PREVIEW_MIN_SHORT.div_ceil(width);
        }
        if height < PREVIEW_MIN_SHORT {
            height *= PREVIEW_MIN_SHORT.div_ceil(height);
        }
        PreviewGeometry { nx, ny, left: MARGIN, top: IMAGE_TOP, width, height }
    }

    /// The data pixel shown at picture offset `(px, py)` from the image's top-left corner.
    pub fn data_index(&self, px: usize, py: usize) -> (usize, usize) {
        let ix = (px * self.nx / self.width).min(self.nx - 1);
        let iy = (py * self.ny / self.height).min(self.ny - 1);
        (ix, iy)
    }

    /// The canvas pixel at the centre of the block showing data pixel `(ix, iy)`.
    pub fn pixel_center(&self, ix: usize, iy: usize) -> (usize, usize) {
        let col = |i: usize, n: usize, size: usize| (i * size).div_ceil(n) + size / n / 2;
        let x = self.left + col(ix.min(self.nx - 1), self.nx, self.width);
        let y = self.top + col(iy.min(self.ny - 1), self.ny, self.height);
        (x, y)
    }

    /// The grey caption under the image: the data size and the orientation.
    fn caption(&self, canvas: &mut Canvas) {
        let text = format!("{} \u{d7} {} pixels, y up", self.nx, self.ny);
        canvas.text(self.left as i64, (self.top + self.height + 6) as i64, &text, CAPTION, LABEL_SCALE);
    }

    /// Paint the data pixels, coloured by `color(ix, iy)`, and a thin frame around them.
    fn paint(&self, canvas: &mut Canvas, color: impl Fn(usize, usize) -> [u8; 3]) {
        for py in 0..self.height {
            for px in 0..self.width {
                let (ix, iy) = self.data_index(px, py);
                canvas.set((self.left + px) as i64, (self.top + py) as i64, color(ix, iy));
            }
        }
        let (l, t) = (self.left as i64, self.top as i64);
        canvas.rect_outline(l - 1, t - 1, l + self.width as i64, t + self.height as i64, FRAME);
    }
}

/// A canvas sized for the title and `content_w × content_h` pixels of content below it.
fn titled_canvas(title: &str, content_w: usize, content_h: usize) -> Canvas {
    let width = (MARGIN + content_w + MARGIN).max(2 * MARGIN + text_width(title, TITLE_SCALE));
    let mut canvas = Canvas::new(width, IMAGE_TOP + content_h + MARGIN, WHITE);
    canvas.text(MARGIN as i64, MARGIN as i64, title, TEXT, TITLE_SCALE);
    canvas
}

/// The preview drawn when the data do not fit the stated shape: the title and an empty frame.
fn no_data_png(title: &str, why: &str) -> Vec<u8> {
    let side = PREVIEW_MIN_LONG;
    let mut canvas = titled_canvas(title, side, side);
    let (l, t) = (MARGIN as i64, IMAGE_TOP as i64);
    canvas.rect_outline(l, t, l + side as i64 - 1, t + side as i64 - 1, FRAME);
    let msg = format!("no data ({why})");
    let x = l + (side as i64 - text_width(&msg, LABEL_SCALE) as i64) / 2;
    canvas.text(x.max(l + 4), t + side as i64 / 2 - 4, &msg, TEXT, LABEL_SCALE);
    canvas.to_png()
}

/// Check that an `nx × ny` image has `len` values.
fn check_shape(len: usize, nx: usize, ny: usize) -> Result<(), String> {
    match nx.checked_mul(ny) {
        Some(n) if n == len && n > 0 => Ok(()),
        Some(0) => Err(format!("{nx} x {ny} image")),
        _ => Err(format!("{len} values for {nx} x {ny}")),
    }
}

/// A false-colour preview of a `ny × nx` image stored row-major with row 0 = largest y, drawn
/// with y up (data row 0 at the top), upscaled by an integer factor to at least 384 px on its
/// long side, with `title` above and a vertical colour bar on the right whose 3–5 tick labels are
/// in the value's units (`colorbar_label`, e.g. "M0+ (fraction of emitted power)"). `range = (lo,
/// hi)` maps `lo` → 0 and `hi` → 1 (a degenerate or non-finite range is widened around its
/// finite end). Non-finite values get the [`NO_DATA`] colour, listed under the colour bar when
/// present. A `values.len()` that is not `nx · ny` draws an empty "no data" frame with the title.
pub fn image_png(
    values: &[f64],
    nx: usize,
    ny: usize,
    cmap: Colormap,
    range: (f64, f64),
    title: &str,
    colorbar_label: &str,
) -> Vec<u8> {
    if let Err(why) = check_shape(values.len(), nx, ny) {
        return no_data_png(title, &why);
    }
    let (lo, hi) = usable_range(range);
    let to_t = |v: f64| if v.is_finite() { (v - lo) / (hi - lo) } else { f64::NAN };
    let geo = PreviewGeometry::new(nx, ny);

    const BAR_GAP: usize = 16;
    let bar_h = geo.height.max(160);
    let bar = ColorBar::new(cmap, (lo, hi), colorbar_label, bar_h);
    let has_no_data = values.iter().any(|v| !v.is_finite());
    let no_data_h = if has_no_data { 8 * LABEL_SCALE + 14 } else { 0 };

    let bar_x = geo.left + geo.width + BAR_GAP;
    let content_w = bar_x + bar.width() - MARGIN;
    let content_h = (geo.height + CAPTION_H).max(geo.height.max(bar_h).max(bar.unit_len) + no_data_h);
    let mut canvas = titled_canvas(title, content_w, content_h);
    geo.caption(&mut canvas);

    geo.paint(&mut canvas, |ix, iy| cmap.color(to_t(values[iy * nx + ix])));
    bar.draw(&mut canvas, bar_x, geo.top);
    if has_no_data {
        ColorBar::draw_no_data(&mut canvas, bar_x, geo.top + geo.height.max(bar_h).max(bar.unit_len) + 10);
    }
    canvas.to_png()
}

/// A vertical colour bar: the colour ramp (low at the bottom), tick marks with 3–5 labels in the
/// value's units on its right, and a rotated unit label right of those.
pub(crate) struct ColorBar<'a> {
    cmap: Colormap,
    /// The value range mapped to the ramp's bottom and top (finite, non-empty).
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
    labels: Vec<String>,
    label_w: usize,
    unit: &'a str,
    unit_scale: usize,
    /// Length in pixels of the rotated unit label.
    pub unit_len: usize,
    /// Height of the ramp in pixels.
    pub height: usize,
}

impl<'a> ColorBar<'a> {
    /// Width of the ramp, px.
    pub const BAR_W: usize = 18;
    const TICK_LEN: usize = 4;
    /// Offset of the tick labels from the bar's left edge, px.
    pub const LABEL_OFFSET: usize = Self::BAR_W + Self::TICK_LEN + 4;

    /// A bar `height` px tall (at least 2) for `range` (made usable: finite and non-empty).
    pub fn new(cmap: Colormap, range: (f64, f64), unit: &'a str, height: usize) -> Self {
        let (lo, hi) = usable_range(range);
        let (tmin, tmax) = (lo.min(hi), lo.max(hi));
        let mut ticks = colorbar_ticks(tmin, tmax);
        if ticks.len() < 2 {
            ticks = vec![tmin, tmax];
        }
        let step = (ticks[1] - ticks[0]).abs();
        let labels: Vec<String> = ticks.iter().map(|&v| tick_label(v, step)).collect();
        let label_w = labels.iter().map(|s| text_width(s, LABEL_SCALE)).max().unwrap_or(0);
        let height = height.max(2);
        let unit_scale = if text_width(unit, 2) <= height { 2 } else { 1 };
        let unit_len = text_width(unit, unit_scale);
        ColorBar { cmap, lo, hi, ticks, labels, label_w, unit, unit_scale, unit_len, height }
    }

    /// The value at the bottom of the ramp.
    pub fn lo(&self) -> f64 {
        self.lo
    }

    /// The value at the top of the ramp.
    pub fn hi(&self) -> f64 {
        self.hi
    }

    /// Total width: ramp, ticks, labels and the unit label, px.
    pub fn width(&self) -> usize {
        Self::LABEL_OFFSET + self.label_w + 10 + 8 * self.unit_scale
    }

    /// Draw with the ramp's top-left corner at `(x, top)`.
    pub fn draw(&self, canvas: &mut Canvas, x: usize, top: usize) {
        let (lo, hi, bar_h) = (self.lo, self.hi, self.height);
        let bar_top = top as i64;
        let bar_bottom = bar_top + bar_h as i64 - 1;
        for y in bar_top..=bar_bottom {
            let t = (bar_bottom - y) as f64 / (bar_h - 1) as f64;
            canvas.fill_rect(x as i64, y, (x + Self::BAR_W - 1) as i64, y, self.cmap.color(t));
        }
        canvas.rect_outline(x as i64 - 1, bar_top - 1, (x + Self::BAR_W) as i64, bar_bottom + 1, FRAME);
        let label_x = x + Self::LABEL_OFFSET;
        for (&v, label) in self.ticks.iter().zip(&self.labels) {
            let t = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
            let y = (bar_bottom as f64 - t * (bar_h - 1) as f64).round() as i64;
            let x0 = (x + Self::BAR_W) as i64;
            canvas.fill_rect(x0, y, x0 + Self::TICK_LEN as i64 - 1, y, FRAME);
            let ty = (y - 4 * LABEL_SCALE as i64).clamp(bar_top - 4, bar_bottom + 4 - 8 * LABEL_SCALE as i64);
            canvas.text(label_x as i64, ty, label, TEXT, LABEL_SCALE);
        }
        let unit_x = label_x + self.label_w + 10;
        let unit_y = bar_top + (bar_h as i64 - self.unit_len as i64) / 2;
        canvas.text_vertical(unit_x as i64, unit_y.max(bar_top), self.unit, TEXT, self.unit_scale);
    }

    /// The "no data" swatch and label, its top-left corner at `(x, y)` (8 px tall).
    pub fn draw_no_data(canvas: &mut Canvas, x: usize, y: usize) {
        let (x, y) = (x as i64, y as i64);
        canvas.fill_rect(x, y, x + Self::BAR_W as i64 - 1, y + 7, NO_DATA);
        canvas.rect_outline(x - 1, y - 1, x + Self::BAR_W as i64, y + 8, FRAME);
        canvas.text(x + Self::LABEL_OFFSET as i64, y, "no data", TEXT, LABEL_SCALE);
    }
}

/// Nice ticks inside `[lo, hi]`: the most of them up to 5 (at least 3 when the nice steps allow).
fn colorbar_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let eps = 1e-9 * (hi - lo);
    let mut best: Vec<f64> = Vec::new();
    for target in 3..=12 {
        let inside: Vec<f64> =
            nice_ticks(lo, hi, target).into_iter().filter(|&v| v >= lo - eps && v <= hi + eps).collect();
        if inside.len() <= 5 && inside.len() > best.len() {
            best = inside;
        }
    }
    best
}

/// A finite, non-empty value range: a non-finite end is replaced, an empty range widened.
fn usable_range((lo, hi): (f64, f64)) -> (f64, f64) {
    let (lo, hi) = match (lo.is_finite(), hi.is_finite()) {
        (true, true) => (lo, hi),
        (true, false) => (lo, lo + 1.0),
        (false, true) => (hi - 1.0, hi),
        (false, false) => (0.0, 1.0),
    };
    if hi != lo && (hi - lo).is_finite() {
        return (lo, hi);
    }
    if (hi - lo).is_finite() {
        let d = if lo == 0.0 { 1.0 } else { 0.5 * lo.abs() };
        (lo - d, hi + d)
    } else {
        (lo / 2.0, hi / 2.0)
    }
}

/// HoloDoppler-style directional composite of the power in the positive (`pos`) and negative
/// (`neg`) halves of the Doppler spectrum, `ny × nx` each, same layout and upscaling as
/// [`image_png`]. Each pixel is an HSV colour: hue red (0°) where `pos > neg`, blue (240°) where
/// `neg > pos`; saturation `|pos − neg|` / the image's largest `|pos − neg|` (0 if that is 0); value
/// `(pos + neg)/2` / the image's largest `(pos + neg)/2`, clamped to [0, 1]. Pixels with a
/// non-finite input get [`NO_DATA`]. A legend under the image names the two colours.
pub fn directional_png(pos: &[f64], neg: &[f64], nx: usize, ny: usize, title: &str) -> Vec<u8> {
    if let Err(why) = check_shape(pos.len(), nx, ny).and(check_shape(neg.len(), nx, ny)) {
        return no_data_png(title, &why);
    }
    let finite = |i: usize| pos[i].is_finite() && neg[i].is_finite();
    let (mut max_diff, mut max_mean) = (0.0_f64, 0.0_f64);
    for i in (0..pos.len()).filter(|&i| finite(i)) {
        max_diff = max_diff.max((pos[i] - neg[i]).abs());
        max_mean = max_mean.max(0.5 * (pos[i] + neg[i]));
    }
    let ratio = |a: f64, max: f64| if max > 0.0 && max.is_finite() { (a / max).clamp(0.0, 1.0) } else { 0.0 };
    let color = |i: usize| {
        if !finite(i) {
            return NO_DATA;
        }
        let hue = if pos[i] >= neg[i] { 0.0 } else { 240.0 };
        hsv_to_rgb(hue, ratio((pos[i] - neg[i]).abs(), max_diff), ratio(0.5 * (pos[i] + neg[i]), max_mean))
    };

    let geo = PreviewGeometry::new(nx, ny);
    let legend: [([u8; 3], &str); 2] = [([255, 0, 0], "positive (receding)"), ([0, 0, 255], "negative (approaching)")];
    let mut entries: Vec<([u8; 3], &str)> = legend.to_vec();
    if (0..pos.len()).any(|i| !finite(i)) {
        entries.push((NO_DATA, "no data"));
    }
    const ROW: usize = 8 * LABEL_SCALE + 7;
    const SWATCH: usize = 8 * LABEL_SCALE + 2;
    let legend_w = SWATCH + 8 + entries.iter().map(|(_, s)| text_width(s, LABEL_SCALE)).max().unwrap_or(0);
    let legend_top = geo.top + geo.height + CAPTION_H + 4;
    let content_h = geo.height + CAPTION_H + 4 + ROW * entries.len();
    let mut canvas = titled_canvas(title, geo.width.max(legend_w), content_h);
    geo.caption(&mut canvas);
    geo.paint(&mut canvas, |ix, iy| color(iy * nx + ix));
    for (k, (c, label)) in entries.iter().enumerate() {
        let y = (legend_top + k * ROW) as i64;
        let x = geo.left as i64;
        canvas.fill_rect(x, y - 1, x + SWATCH as i64 - 1, y + SWATCH as i64 - 2, *c);
        canvas.rect_outline(x, y - 1, x + SWATCH as i64 - 1, y + SWATCH as i64 - 2, FRAME);
        canvas.text(x + (SWATCH + 8) as i64, y, label, TEXT, LABEL_SCALE);
    }
    canvas.to_png()
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLACK: [u8; 3] = [0, 0, 0];

    /// Decode PNG bytes into (width, height, RGB8 bytes).
    pub(crate) fn decode(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().expect("PNG header");
        let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
        let info = reader.next_frame(&mut buf).expect("PNG frame");
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        buf.truncate(info.buffer_size());
        (info.width as usize, info.height as usize, buf)
    }

    fn pixel(img: &(usize, usize, Vec<u8>), x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * img.0 + x);
        [img.2[i], img.2[i + 1], img.2[i + 2]]
    }

    #[test]
    fn canvas_round_trips_through_png() {
        let mut c = Canvas::new(7, 5, [10, 20, 30]);
        c.set(6, 4, [255, 0, 0]);
        c.set(-1, 0, [0, 255, 0]);
        c.set(7, 0, [0, 255, 0]);
        c.set(i64::MAX, i64::MIN, [0, 255, 0]);
        let img = decode(&c.to_png());
        assert_eq!((img.0, img.1), (7, 5));
        assert_eq!(pixel(&img, 0, 0), [10, 20, 30]);
        assert_eq!(pixel(&img, 6, 4), [255, 0, 0]);
        assert_eq!(img.2, c.rgb);
    }

    #[test]
    fn drawing_is_clipped_and_never_panics() {
        let mut c = Canvas::new(20, 10, WHITE);
        c.fill_rect(-100, -100, 100, 2, BLACK);
        assert_eq!(c.get(19, 2), Some(BLACK));
        assert_eq!(c.get(0, 3), Some(WHITE));
        c.line(-1e300, 5.0, 1e300, 5.0, [1, 2, 3]);
        assert_eq!(c.get(10, 5), Some([1, 2, 3]));
        c.line(f64::NAN, 0.0, 3.0, 3.0, BLACK);
        c.line(f64::INFINITY, 0.0, 3.0, f64::NEG_INFINITY, BLACK);
        c.line_width(0.0, 9.0, 19.0, 9.0, [4, 5, 6], 3);
        c.text(-5, -3, "clipped ±µσ∑ text", BLACK, 3);
        c.text_vertical(15, -40, "vertical", BLACK, 0);
        c.text(i64::MAX - 3, i64::MIN + 1, "far\naway", BLACK, 64);
        c.text_vertical(i64::MIN, i64::MAX, "far away", BLACK, 64);
        c.fill_rect(i64::MIN, i64::MIN, i64::MAX, i64::MIN + 1, BLACK);
        c.line_width(0.0, 0.0, 1.0, 1.0, BLACK, usize::MAX);
        let empty = Canvas::new(0, 0, WHITE);
        assert_eq!(text_width("abc", 2), 48);
        assert_eq!(decode(&empty.to_png()).0, 1);
        // A diagonal line is continuous: every column between its ends has a pixel.
        let mut d = Canvas::new(30, 30, WHITE);
        d.line(2.0, 3.0, 27.0, 20.0, BLACK);
        for x in 2..=27 {
            assert!((0..30).any(|y| d.get(x, y) == Some(BLACK)), "column {x}");
        }
    }

    #[test]
    fn text_uses_the_font_and_boxes_unknown_characters() {
        let mut c = Canvas::new(16, 8, WHITE);
        c.text(0, 0, "I", BLACK, 1);
        // font8x8 'I' has a full-width top bar from column 2 to 5 in its first row (0x1E).
        let ink: Vec<bool> = (0..8).map(|x| c.get(x, 0) == Some(BLACK)).collect();
        assert!(ink.iter().filter(|&&b| b).count() >= 3, "{ink:?}");
        c.text(8, 0, "\u{4E00}", BLACK, 1);
        assert_eq!(c.get(9, 1), Some(BLACK), "unknown character is a box");
        assert_eq!(c.get(11, 3), Some(WHITE), "box is hollow");
        // Rotated text is 8 px wide and as tall as the text is long, read bottom to top.
        let mut v = Canvas::new(8, 24, WHITE);
        v.text_vertical(0, 0, "--.", BLACK, 1);
        let rows_with_ink = (0..24).filter(|&y| (0..8).any(|x| v.get(x, y) == Some(BLACK))).count();
        assert!(rows_with_ink >= 10, "{rows_with_ink}");
        // The '.' (last) is at the top: rows 0..8 hold only its short dot.
        let top_ink = (0..8).flat_map(|y| (0..8).map(move |x| (x, y))).filter(|&(x, y)| v.get(x, y) == Some(BLACK));
        assert!(top_ink.count() <= 4);
    }

    #[test]
    fn hsv_primaries_and_greys() {
        assert_eq!(hsv_to_rgb(0.0, 1.0, 1.0), [255, 0, 0]);
        assert_eq!(hsv_to_rgb(120.0, 1.0, 1.0), [0, 255, 0]);
        assert_eq!(hsv_to_rgb(240.0, 1.0, 1.0), [0, 0, 255]);
        assert_eq!(hsv_to_rgb(360.0, 1.0, 1.0), [255, 0, 0]);
        assert_eq!(hsv_to_rgb(-120.0, 1.0, 1.0), [0, 0, 255]);
        for h in [0.0, 77.0, 240.0, 359.9] {
            assert_eq!(hsv_to_rgb(h, 0.0, 0.5), [128, 128, 128]);
            assert_eq!(hsv_to_rgb(h, 0.0, 1.0), [255, 255, 255]);
            assert_eq!(hsv_to_rgb(h, 0.7, 0.0), [0, 0, 0]);
        }
        assert_eq!(hsv_to_rgb(f64::NAN, 2.0, f64::NAN), [0, 0, 0]);
    }

    #[test]
    fn colormaps_ends_middle_and_nan() {
        assert_eq!(Colormap::Grey.color(0.0), [0, 0, 0]);
        assert_eq!(Colormap::Grey.color(1.0), [255, 255, 255]);
        assert_eq!(Colormap::Grey.color(-3.0), [0, 0, 0]);
        assert_eq!(Colormap::Grey.color(f64::INFINITY), [255, 255, 255]);
        assert_eq!(Colormap::Diverging.color(0.5), [255, 255, 255]);
        let (blue, red) = (Colormap::Diverging.color(0.0), Colormap::Diverging.color(1.0));
        assert!(blue[2] > blue[0] && red[0] > red[2]);
        assert_eq!(Colormap::Viridis.color(0.0), [68, 1, 84]);
        assert_eq!(Colormap::Viridis.color(1.0), [253, 231, 37]);
        for m in [Colormap::Grey, Colormap::Diverging, Colormap::Viridis] {
            assert_eq!(m.color(f64::NAN), NO_DATA);
            for k in 0..=100 {
                assert_ne!(m.color(k as f64 / 100.0), NO_DATA);
            }
        }
        // Viridis brightens monotonically (sum of channels as a rough luminance).
        let lum = |c: [u8; 3]| c.iter().map(|&v| v as u32).sum::<u32>();
        for k in 0..20 {
            let (a, b) = (Colormap::Viridis.color(k as f64 / 20.0), Colormap::Viridis.color((k + 1) as f64 / 20.0));
            assert!(lum(b) >= lum(a), "{k}");
        }
    }

    #[test]
    fn ranges() {
        assert_eq!(symmetric_range(&[0.0, 0.0], 0.99), (-1.0, 1.0));
        assert_eq!(symmetric_range(&[], 0.99), (-1.0, 1.0));
        assert_eq!(symmetric_range(&[f64::NAN, f64::INFINITY], 0.99), (-1.0, 1.0));
        assert_eq!(symmetric_range(&[-4.0, 1.0, 2.0, f64::NAN], 1.0), (-4.0, 4.0));
        // 1% outliers do not set the 0.99 range.
        let mut v: Vec<f64> = (0..1000).map(|i| (i % 10) as f64 - 5.0).collect();
        v[3] = -1e6;
        let (lo, hi) = symmetric_range(&v, 0.99);
        assert_eq!(lo, -hi);
        assert!((4.0..=5.0).contains(&hi), "{hi}");
        // Mostly zeros: fall back to the largest |v|.
        let mut z = vec![0.0; 1000];
        z[0] = -2.0;
        assert_eq!(symmetric_range(&z, 0.99), (-2.0, 2.0));

        assert_eq!(sequential_range(&[], 0.99), (0.0, 1.0));
        assert_eq!(sequential_range(&[3.0, 3.0], 0.99), (0.0, 1.0));
        assert_eq!(sequential_range(&[1.0, f64::NAN, 3.0, 2.0], 1.0), (1.0, 3.0));
        let s: Vec<f64> = (0..=100).map(|i| i as f64).collect();
        assert_eq!(sequential_range(&s, 0.5), (0.0, 50.0));
    }

    #[test]
    fn grey_preview_puts_data_row_zero_at_the_top() {
        // Row 0 (top, the largest y): 0, 1/3; row 1 (bottom): 2/3, 1.
        let values = [0.0, 1.0, 2.0, 3.0];
        let png = image_png(&values, 2, 2, Colormap::Grey, (0.0, 3.0), "grey 2x2", "value (a.u.)");
        let img = decode(&png);
        let geo = PreviewGeometry::new(2, 2);
        assert_eq!((geo.width, geo.height), (384, 384));
        assert!(img.0 >= geo.left + geo.width && img.1 >= geo.top + geo.height);
        let at = |ix, iy| {
            let (x, y) = geo.pixel_center(ix, iy);
            pixel(&img, x, y)
        };
        assert_eq!(at(0, 0), [0, 0, 0], "value 0 black, top left");
        assert_eq!(at(1, 1), [255, 255, 255], "value 3 white, bottom right");
        assert_eq!(at(1, 0), Colormap::Grey.color(1.0 / 3.0));
        assert_eq!(at(0, 1), Colormap::Grey.color(2.0 / 3.0));
        // Top-left corner of the picture is data (0, 0); bottom-right is data (1, 1).
        assert_eq!(pixel(&img, geo.left, geo.top), [0, 0, 0]);
        assert_eq!(pixel(&img, geo.left + geo.width - 1, geo.top + geo.height - 1), [255, 255, 255]);
    }

    #[test]
    fn preview_geometry_scales_and_maps_back() {
        for (nx, ny) in [(1, 1), (2, 3), (64, 64), (100, 50), (385, 10), (5000, 3000), (1, 1000)] {
            let g = PreviewGeometry::new(nx, ny);
            assert!(g.width.max(g.height) >= PREVIEW_MIN_LONG.min(nx.max(ny) * 384), "{nx}x{ny}");
            assert!(g.width.max(g.height) <= PREVIEW_MAX_LONG, "{nx}x{ny}");
            assert!(g.width.min(g.height) >= PREVIEW_MIN_SHORT, "{nx}x{ny}");
            for (ix, iy) in [(0, 0), (nx - 1, ny - 1), (nx / 2, ny / 3)] {
                let (x, y) = g.pixel_center(ix, iy);
                let (dx, dy) = g.data_index(x - g.left, y - g.top);
                if nx.max(ny) <= PREVIEW_MAX_LONG {
                    assert_eq!((dx, dy), (ix, iy), "{nx}x{ny} at ({ix},{iy})");
                }
            }
        }
        let g = PreviewGeometry::new(64, 32);
        assert_eq!((g.width, g.height), (384, 192));
    }

    #[test]
    fn diverging_preview_and_nan() {
        let (nx, ny) = (40, 30);
        let values: Vec<f64> =
            (0..nx * ny).map(|i| if i == 5 { f64::NAN } else { ((i % nx) as f64 - 20.0) * 1e-7 }).collect();
        let range = symmetric_range(&values, 0.99);
        let img = decode(&image_png(&values, nx, ny, Colormap::Diverging, range, "signed", "M1 (Hz)"));
        let geo = PreviewGeometry::new(nx, ny);
        let (x, y) = geo.pixel_center(5, 0);
        assert_eq!(pixel(&img, x, y), NO_DATA);
        let (x, y) = geo.pixel_center(0, 10);
        let c = pixel(&img, x, y);
        assert!(c[2] > c[0], "negative values are blue: {c:?}");
        let (x, y) = geo.pixel_center(39, 10);
        let c = pixel(&img, x, y);
        assert!(c[0] > c[2], "positive values are red: {c:?}");
    }

    #[test]
    fn directional_composite_colours() {
        // Pixel 0: pos > neg (receding) → red; pixel 1: neg > pos → blue; pixel 2: equal → grey; 3: zero.
        let pos = [3.0, 1.0, 2.0, 0.0];
        let neg = [1.0, 3.0, 2.0, 0.0];
        let img = decode(&directional_png(&pos, &neg, 2, 2, "directional"));
        let geo = PreviewGeometry::new(2, 2);
        let at = |ix, iy| {
            let (x, y) = geo.pixel_center(ix, iy);
            pixel(&img, x, y)
        };
        assert_eq!(at(0, 0), [255, 0, 0], "max mean and max difference: pure red");
        assert_eq!(at(1, 0), [0, 0, 255]);
        assert_eq!(at(0, 1), [255, 255, 255], "no difference: grey at full value");
        assert_eq!(at(1, 1), [0, 0, 0]);
        // Weaker, partly directional pixels stay reddish / bluish.
        let pos = [1.0, 0.2, 0.5, f64::NAN];
        let neg = [0.2, 1.0, 0.4, 0.1];
        let img = decode(&directional_png(&pos, &neg, 4, 1, "weak"));
        let geo = PreviewGeometry::new(4, 1);
        let at = |ix| {
            let (x, y) = geo.pixel_center(ix, 0);
            pixel(&img, x, y)
        };
        let (r, b) = (at(0), at(1));
        assert!(r[0] > r[1] && r[0] > r[2], "{r:?}");
        assert!(b[2] > b[0] && b[2] > b[1], "{b:?}");
        let c = at(2);
        assert!(c[0] > c[2] && c[0] - c[2] < 100, "slightly receding: pale red {c:?}");
        assert_eq!(at(3), NO_DATA);
    }

    #[test]
    fn bad_inputs_do_not_panic() {
        let nan = [f64::NAN; 6];
        for bytes in [
            image_png(&[], 0, 0, Colormap::Grey, (0.0, 1.0), "", ""),
            image_png(&[1.0; 5], 2, 3, Colormap::Viridis, (0.0, 1.0), "mismatch", "x"),
            image_png(&[1.0; 6], usize::MAX, 2, Colormap::Viridis, (0.0, 1.0), "overflow", "x"),
            image_png(&nan, 2, 3, Colormap::Viridis, (f64::NAN, f64::INFINITY), "nan", "x"),
            image_png(&[2.0; 6], 3, 2, Colormap::Diverging, (2.0, 2.0), "equal", "x"),
            image_png(&[2.0; 6], 3, 2, Colormap::Diverging, (5.0, -5.0), "reversed", "x"),
            image_png(&[1e300, -1e300], 2, 1, Colormap::Grey, (-f64::MAX, f64::MAX), "huge", "x"),
            image_png(&[0.0; 6], 6, 1, Colormap::Grey, (0.0, 0.0), "zero", &"long label ".repeat(40)),
            directional_png(&[], &[], 0, 0, "empty"),
            directional_png(&[1.0; 6], &[1.0; 5], 2, 3, "mismatch"),
            directional_png(&nan, &nan, 3, 2, "nan"),
            directional_png(&[0.0; 6], &[0.0; 6], 3, 2, "zeros"),
            directional_png(&[-1.0; 6], &[f64::INFINITY; 6], 3, 2, "odd"),
        ] {
            let (w, h, _) = decode(&bytes);
            assert!(w > 0 && h > 0);
        }
    }

    /// Renders the example previews to `$OHD_PNG_DIR` (for looking at them), when set.
    #[test]
    fn render_examples_when_asked() {
        let Ok(dir) = std::env::var("OHD_PNG_DIR") else { return };
        let dir = std::path::Path::new(&dir);
        let (nx, ny) = (96, 64);
        let (mut m0, mut pos, mut neg, mut m1) = (vec![], vec![], vec![], vec![]);
        for iy in 0..ny {
            for ix in 0..nx {
                let (x, y) = (ix as f64 / nx as f64 - 0.5, iy as f64 / ny as f64 - 0.3);
                let vessel = (-((y - 0.25 * x).powi(2)) / 0.003).exp();
                let bg = 2e-5 * (1.0 - x * x);
                let flow = if x > 0.0 { 1.0 } else { 0.3 };
                pos.push(bg + 8e-5 * vessel * flow);
                neg.push(bg + 8e-5 * vessel * (1.3 - flow));
                m0.push(bg + 8e-5 * vessel);
                m1.push(if ix == 3 && iy == 60 { f64::NAN } else { 3e3 * vessel * (2.0 * flow - 1.3) });
            }
        }
        let r = sequential_range(&m0, 0.99);
        let png = image_png(&m0, nx, ny, Colormap::Viridis, r, "M0 (y up)", "M0+ (fraction of emitted power)");
        std::fs::write(dir.join("ohd_preview_m0.png"), png).unwrap();
        let r = symmetric_range(&m1, 0.99);
        let png = image_png(&m1, nx, ny, Colormap::Diverging, r, "M1 - mean Doppler shift", "M1 (Hz)");
        std::fs::write(dir.join("ohd_preview_m1.png"), png).unwrap();
        let png = directional_png(&pos, &neg, nx, ny, "Directional composite");
        std::fs::write(dir.join("ohd_preview_directional.png"), png).unwrap();
        let tall: Vec<f64> = (0..20 * 200).map(|i| (i / 20) as f64 / 199.0 + (i % 20) as f64 * 0.01).collect();
        let png = image_png(
            &tall,
            20,
            200,
            Colormap::Grey,
            (0.0, 1.0),
            "A tall 20 x 200 image, row 0 dark",
            "depth-resolved M0 (a.u.)",
        );
        std::fs::write(dir.join("ohd_preview_tall.png"), png).unwrap();
        std::fs::write(dir.join("ohd_preview_mismatch.png"), image_png(&m0, 7, 7, Colormap::Grey, r, "bad", ""))
            .unwrap();
    }
}
