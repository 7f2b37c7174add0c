//! Figures: every output drawn as a PNG with an SVG beside it (issue 22), with the plotters crate
//! and the DejaVu Sans font embedded in the binary (`media/fonts/`, no system font lookup).
//!
//! A figure is a value implementing [`Draw`]: line plots ([`lines::LinePlot`]: spectra with ±σ
//! bands and marked bands, profiles with error bars, log–log convergence) and image panels
//! ([`image::ImageFigure`]: axes in mm or any physical unit, a colour bar in the output's unit,
//! percentile scaling, a companion map). [`render`] draws it twice, into an RGB buffer (encoded
//! by the `png` crate) and into SVG text. Image cells are not drawn through plotters: each
//! [`Raster`] a figure returns is scaled (nearest cell) into the PNG and embedded in the SVG as
//! one `<image>` (a PNG of the cells), so that a 256² image is one element, not 65 536.
//! [`scale`] holds the colour maps, the robust ranges and the unit scaling.
//!
//! Orientation: image values arrive as every writer receives them, row 0 = the top row (largest
//! y), columns x ascending; they are drawn as they are stored.

pub mod image;
pub mod lines;
pub mod scale;

use plotters::coord::Shift;
use plotters::prelude::*;

/// The embedded font (DejaVu Sans; licence in media/fonts/LICENSE-DejaVu.txt).
static FONT: &[u8] = include_bytes!("../../../media/fonts/DejaVuSans.ttf");

/// The family name every figure asks for.
pub const FAMILY: &str = "sans-serif";

/// A drawing result on backend `DB`.
pub type DrawResult<T, DB> = Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Image cells to paint into the rectangle `[x0, x1) × [y0, y1)` (backend pixels): `nx × ny`
/// RGB cells, row 0 at the top.
#[derive(Debug, Clone)]
pub struct Raster {
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
    pub nx: usize,
    pub ny: usize,
    pub rgb: Vec<[u8; 3]>,
}

/// Something drawn as a figure.
pub trait Draw {
    /// Width and height, pixels (the SVG has the same size in user units).
    fn size(&self) -> (u32, u32);
    /// Draw on `root` (filled white already); returns the image cells to paint over it.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Vec<Raster>, DB>;
}

/// A figure as written: PNG bytes and SVG text.
#[derive(Debug, Clone)]
pub struct Figure {
    pub png: Vec<u8>,
    pub svg: String,
}

/// Register the embedded font once (plotters keeps a process-wide font table).
fn register_font() -> Result<(), String> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err("the embedded font does not load".into()) }
}

/// Draw `d` as PNG and SVG. An error is a drawing error of plotters (a message).
pub fn render(d: &impl Draw) -> Result<Figure, String> {
    register_font()?;
    let (w, h) = d.size();
    let mut rgb = vec![255u8; 3 * w as usize * h as usize];
    let rasters = {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let r = d.draw(&root).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
        r
    };
    for r in &rasters {
        paint(&mut rgb, w as usize, h as usize, r);
    }
    let png = encode_png(&rgb, w, h);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        d.draw(&root).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(Figure { png, svg: embed_rasters(svg, &rasters) })
}

/// Paint `r` into the `w × h` RGB buffer, each pixel the cell it falls in.
fn paint(rgb: &mut [u8], w: usize, h: usize, r: &Raster) {
    let (rw, rh) = ((r.x1 - r.x0).max(0) as usize, (r.y1 - r.y0).max(0) as usize);
    if rw == 0 || rh == 0 || r.rgb.len() != r.nx * r.ny || r.rgb.is_empty() {
        return;
    }
    for py in 0..rh {
        let y = r.y0 as i64 + py as i64;
        if y < 0 || y >= h as i64 {
            continue;
        }
        let iy = (py * r.ny / rh).min(r.ny - 1);
        for px in 0..rw {
            let x = r.x0 as i64 + px as i64;
            if x < 0 || x >= w as i64 {
                continue;
            }
            let ix = (px * r.nx / rw).min(r.nx - 1);
            let o = 3 * (y as usize * w + x as usize);
            rgb[o..o + 3].copy_from_slice(&r.rgb[iy * r.nx + ix]);
        }
    }
}

/// An 8-bit RGB PNG of `rgb` (`w × h`).
pub fn encode_png(rgb: &[u8], w: u32, h: u32) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        // Writing into a Vec cannot fail for a buffer of the declared size.
        let mut writer = enc.write_header().expect("PNG header into memory");
        writer.write_image_data(rgb).expect("PNG data into memory");
    }
    out
}

/// `svg` with each raster as an `<image>` (a PNG of its cells, drawn pixelated) before the
/// closing tag.
fn embed_rasters(mut svg: String, rasters: &[Raster]) -> String {
    let mut images = String::new();
    for r in rasters.iter().filter(|r| r.nx * r.ny == r.rgb.len() && !r.rgb.is_empty()) {
        let flat: Vec<u8> = r.rgb.iter().flatten().copied().collect();
        let png = encode_png(&flat, r.nx as u32, r.ny as u32);
        images.push_str(&format!(
            "<image x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" preserveAspectRatio=\"none\" \
             style=\"image-rendering:pixelated\" href=\"data:image/png;base64,{}\"/>\n",
            r.x0,
            r.y0,
            r.x1 - r.x0,
            r.y1 - r.y0,
            base64(&png)
        ));
    }
    match svg.rfind("</svg>") {
        Some(i) => svg.insert_str(i, &images),
        None => svg.push_str(&images),
    }
    svg
}

/// Standard base64 (RFC 4648, with padding).
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// (width, height, RGB bytes) of a PNG.
    pub(crate) fn decode(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().expect("PNG header");
        let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
        let info = reader.next_frame(&mut buf).expect("PNG frame");
        buf.truncate(info.buffer_size());
        (info.width as usize, info.height as usize, buf)
    }

    /// A figure's PNG has the declared size and its SVG is one document of that size.
    pub(crate) fn check_figure(f: &Figure, size: (u32, u32)) -> (usize, usize, Vec<u8>) {
        let img = decode(&f.png);
        assert_eq!((img.0 as u32, img.1 as u32), size);
        assert!(f.svg.starts_with("<svg") && f.svg.trim_end().ends_with("</svg>"), "{}", &f.svg[..80.min(f.svg.len())]);
        assert!(f.svg.contains(&format!("width=\"{}\"", size.0)) && f.svg.contains(&format!("height=\"{}\"", size.1)));
        img
    }

    #[test]
    fn base64_matches_the_rfc_examples() {
        for (i, o) in
            [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("foobar", "Zm9vYmFy")]
        {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }

    #[test]
    fn rasters_are_painted_by_nearest_cell() {
        let (w, h) = (10, 6);
        let mut rgb = vec![0u8; 3 * w * h];
        let r = Raster { x0: 2, y0: 1, x1: 6, y1: 5, nx: 2, ny: 2, rgb: vec![[1; 3], [2; 3], [3; 3], [4; 3]] };
        paint(&mut rgb, w, h, &r);
        let at = |x: usize, y: usize| rgb[3 * (y * w + x)];
        assert_eq!(
            [at(2, 1), at(5, 1), at(2, 4), at(5, 4), at(1, 1), at(6, 1), at(2, 0), at(2, 5)],
            [1, 2, 3, 4, 0, 0, 0, 0]
        );
        // Off the buffer, or malformed: nothing painted, no panic.
        paint(&mut rgb, w, h, &Raster { x0: -5, y0: -5, x1: 20, y1: 20, ..r.clone() });
        paint(&mut rgb, w, h, &Raster { nx: 3, ..r });
    }
}
