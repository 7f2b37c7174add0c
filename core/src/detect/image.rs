//! A surface detector's pixels and its intensity image: the detected power per pixel over the
//! bounding rectangle of its area (rows are `y`, row-major). The pixel grid is also the one the
//! time-gated images, the speckle-contrast image and an LDH camera's maps are laid out on.

use super::{Hit, Place, detector_output};
use crate::output::{Kind, Output, PER_PIXEL, Registry, Slots};

/// An intensity image over the bounding rectangle of the detector area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageSpec {
    pub nx: usize,
    pub ny: usize,
    pub min: [f64; 2],
    pub max: [f64; 2],
}

impl ImageSpec {
    /// The pixel (row-major index) holding the point `(x, y)` of the detector plane.
    #[inline]
    pub fn pixel_at(&self, x: f64, y: f64) -> Option<usize> {
        let fx = (x - self.min[0]) / (self.max[0] - self.min[0]);
        let fy = (y - self.min[1]) / (self.max[1] - self.min[1]);
        ((0.0..1.0).contains(&fx) && (0.0..1.0).contains(&fy)).then(|| {
            let ix = ((fx * self.nx as f64) as usize).min(self.nx - 1);
            let iy = ((fy * self.ny as f64) as usize).min(self.ny - 1);
            iy * self.nx + ix
        })
    }

    /// The kind of an image over this detector's pixels.
    pub fn kind(&self) -> Kind {
        Kind::Image { nx: self.nx, ny: self.ny, min: self.min, max: self.max }
    }

    /// `[ny, nx]`: rows are `y`.
    pub fn shape(&self) -> Vec<usize> {
        vec![self.ny, self.nx]
    }

    /// The key of detector `i` that its images' memory grows with.
    pub fn budget_key(&self, i: usize) -> (String, String) {
        (format!("detectors[{i}].image.pixels"), format!("= [{}, {}]", self.nx, self.ny))
    }

    /// Lay out the intensity image from `reg`'s end and declare it (`NAME_image.npy`); returns
    /// its first slot.
    pub fn declare(&self, at: &Place, reg: &mut Registry) -> usize {
        let (i, name) = (at.i, at.name);
        let n = self.nx * self.ny;
        let start = reg.take(n);
        reg.declare(Output {
            file: format!("{name}_image.npy"),
            units: PER_PIXEL,
            primary: true,
            budget_key: Some(self.budget_key(i)),
            ..detector_output(i, format!("{name}.image"), self.kind(), Slots::contiguous(start, n), self.shape())
        });
        start
    }

    /// Record `hit` into its pixel of the image at `start`.
    #[inline]
    pub fn record(start: usize, acc: &mut [f64], hit: &Hit) {
        if let Some(px) = hit.pixel {
            acc[start + px] += hit.weight;
        }
    }
}

/// The pixels of `im` (row-major, row 0 at the lowest `y`) whose centre's vertical line meets a
/// region of `scene` within its layer, and in a region of a density field meets some density
/// (by the field's majorant segments: within one majorant cell of it): the regions' footprints
/// as the camera sees them from straight above (a grid's vessels, not its box). `None` without
/// regions or if no pixel is in the mask.
pub fn region_mask(scene: &crate::medium::Scene, im: &ImageSpec) -> Option<Vec<bool>> {
    use crate::medium::density::{Density, Field};
    let (hx, hy) = ((im.max[0] - im.min[0]) / im.nx as f64, (im.max[1] - im.min[1]) / im.ny as f64);
    let mask: Vec<bool> = (0..im.ny)
        .flat_map(|j| (0..im.nx).map(move |i| (i, j)))
        .map(|(i, j)| {
            let (x, y) = (im.min[0] + (i as f64 + 0.5) * hx, im.min[1] + (j as f64 + 0.5) * hy);
            scene.regions.iter().any(|r| {
                let l = &scene.layers[r.layer];
                let top = glam::DVec3::new(x, y, l.z_top);
                r.shape.intersect(top, glam::DVec3::Z).is_some_and(|(a, b)| {
                    let (a, b) = (a.max(0.0), b.min(l.z_bottom - l.z_top));
                    b > a
                        && match scene.media[r.medium].density() {
                            None => true,
                            Some(Density::Ramp(f)) => f.segments(top, glam::DVec3::Z, a, b).any(|s| s.max > 0.0),
                            Some(Density::Grid(f)) => f.segments(top, glam::DVec3::Z, a, b).any(|s| s.max > 0.0),
                        }
                })
            })
        })
        .collect();
    mask.iter().any(|&m| m).then_some(mask)
}

/// The pixels of a camera (`estimator = "footprints"`) whose light camera paths estimate
/// ([`crate::transport::camera`]), the forward paths (with their control variate) estimating
/// every other pixel: the regions' footprints ([`region_mask`]) grown by a halo, and every
/// pixel an ROI touches. Fixed before the run, so each pixel's estimate is one unbiased
/// estimator's; an ROI lies wholly within camera pixels, so its values and spectra are the camera
/// paths' alone.
#[derive(Debug, Clone, PartialEq)]
pub struct Footprints {
    /// Per pixel (the image's order): estimated by camera paths.
    pub mask: Vec<bool>,
    /// The camera pixels, in order.
    pub pixels: Vec<u32>,
    /// The halo around the regions' footprints, m.
    pub halo: f64,
    /// Camera paths per forward path (spread evenly over the camera pixels).
    pub camera_paths: f64,
    /// Camera paths connect to the layered twin's light field below the regions, tabulated by
    /// this many forward paths (`light_field`, `crate::transport::field`); `None`: to the beam
    /// only.
    pub light_field: Option<u64>,
}

impl Footprints {
    /// The footprints of `scene`'s regions on `im`, grown by `halo` (m: a pixel joins if its
    /// centre lies within `halo` of a footprint pixel's centre), and the pixels of the rectangles
    /// `rois` (`(min, max)`, m) touch. `None` if that is no pixel.
    pub fn new(
        scene: &crate::medium::Scene,
        im: &ImageSpec,
        halo: f64,
        rois: &[([f64; 2], [f64; 2])],
        camera_paths: f64,
    ) -> Option<Footprints> {
        let (nx, ny) = (im.nx, im.ny);
        let (hx, hy) = ((im.max[0] - im.min[0]) / nx as f64, (im.max[1] - im.min[1]) / ny as f64);
        let regions = region_mask(scene, im).unwrap_or_else(|| vec![false; nx * ny]);
        let mut mask = grown(&regions, (nx, ny), (hx, hy), halo);
        // Every pixel an ROI's rectangle overlaps (with an area: edges alone do not count).
        let cell = |v: f64, lo: f64, h: f64, n: usize| ((v - lo) / h).clamp(0.0, n as f64);
        for (min, max) in rois {
            let (i0, i1) =
                (cell(min[0], im.min[0], hx, nx).floor() as usize, cell(max[0], im.min[0], hx, nx).ceil() as usize);
            let (j0, j1) =
                (cell(min[1], im.min[1], hy, ny).floor() as usize, cell(max[1], im.min[1], hy, ny).ceil() as usize);
            for j in j0..j1 {
                for i in i0..i1 {
                    mask[j * nx + i] = true;
                }
            }
        }
        let pixels: Vec<u32> = (0..nx * ny).filter(|&p| mask[p]).map(|p| p as u32).collect();
        (!pixels.is_empty()).then_some(Footprints { mask, pixels, halo, camera_paths, light_field: None })
    }

    /// Camera paths per camera pixel in a batch of `paths_per_batch` forward paths: the share
    /// `camera_paths` of them spread evenly, rounded up to a whole number (at least one).
    pub fn paths_per_pixel(&self, paths_per_batch: u64) -> u64 {
        let total = (paths_per_batch as f64 * self.camera_paths).ceil();
        ((total / self.pixels.len() as f64).ceil() as u64).max(1)
    }
}

/// The pixels of an `nx × ny` grid of pitch `(hx, hy)` whose centre lies within `halo` of the
/// centre of a pixel of `mask` (row-major). From a mask row `dj` rows away, the pixels within the
/// disk's half-width there, read off the rows' running counts of mask pixels: O(pixels × (2·rows
/// + 1)).
pub fn grown(mask: &[bool], (nx, ny): (usize, usize), (hx, hy): (f64, f64), halo: f64) -> Vec<bool> {
    let mut out = mask.to_vec();
    let mut count = vec![0u32; (nx + 1) * ny];
    for j in 0..ny {
        for i in 0..nx {
            count[j * (nx + 1) + i + 1] = count[j * (nx + 1) + i] + u32::from(mask[j * nx + i]);
        }
    }
    let ry = ((halo / hy).floor() as usize).min(ny);
    for dj in 0..=ry {
        let reach = halo * halo - (dj as f64 * hy).powi(2);
        if reach < 0.0 {
            continue;
        }
        let w = ((reach.sqrt() / hx).floor() as usize).min(nx);
        for j in 0..ny {
            for src in [j.checked_sub(dj), (j + dj < ny).then_some(j + dj)].into_iter().flatten() {
                let row = &count[src * (nx + 1)..(src + 1) * (nx + 1)];
                for i in 0..nx {
                    if row[(i + w + 1).min(nx)] > row[i.saturating_sub(w)] {
                        out[j * nx + i] = true;
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod footprint_tests {
    use super::grown;

    /// The row-wise halo equals the brute-force one: every pixel within the distance, centre to
    /// centre, of a marked pixel (anisotropic pitch, marks at the edges, several radii).
    #[test]
    fn the_halo_is_every_pixel_within_its_distance() {
        let (nx, ny, hx, hy) = (23, 17, 1.0, 1.7);
        let mut mask = vec![false; nx * ny];
        for &(i, j) in &[(0, 0), (5, 8), (22, 16), (11, 3), (12, 3), (3, 15)] {
            mask[j * nx + i] = true;
        }
        for halo in [0.0, 0.9, 1.0, 2.5, 4.0, 7.3, 40.0] {
            let fast = grown(&mask, (nx, ny), (hx, hy), halo);
            for (p, &got) in fast.iter().enumerate() {
                let (i, j) = ((p % nx) as f64, (p / nx) as f64);
                let near = (0..nx * ny).filter(|&q| mask[q]).any(|q| {
                    let (a, b) = ((q % nx) as f64, (q / nx) as f64);
                    ((i - a) * hx).powi(2) + ((j - b) * hy).powi(2) <= halo * halo
                });
                assert_eq!(got, near, "halo {halo}, pixel {p}");
            }
        }
    }
}
