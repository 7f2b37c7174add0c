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
