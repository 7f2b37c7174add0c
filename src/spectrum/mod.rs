//! Frequency axes and the histogram slots a beat frequency falls into.

/// An explicit signed frequency axis: `bins` equal bins over `[f_min, f_max)` (Hz), ascending.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrequencyAxis {
    pub f_min: f64,
    pub f_max: f64,
    pub bins: usize,
    inv_width: f64,
}

/// Where a frequency lands on an axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    Bin(usize),
    Below,
    Above,
    /// NaN or infinite: counted as non-finite, never binned.
    NonFinite,
}

impl FrequencyAxis {
    /// `None` unless `f_min < f_max` (both finite) and `bins ≥ 1`.
    pub fn new(f_min: f64, f_max: f64, bins: usize) -> Option<Self> {
        (f_min.is_finite() && f_max.is_finite() && f_min < f_max && bins >= 1).then(|| FrequencyAxis {
            f_min,
            f_max,
            bins,
            inv_width: bins as f64 / (f_max - f_min),
        })
    }

    /// Width of one bin, Hz.
    pub fn bin_width(&self) -> f64 {
        (self.f_max - self.f_min) / self.bins as f64
    }

    /// Centre frequency of bin `k`, Hz.
    pub fn center(&self, k: usize) -> f64 {
        self.f_min + (k as f64 + 0.5) * self.bin_width()
    }

    /// The slot of frequency `f`: bin `k` covers `[f_min + kΔ, f_min + (k+1)Δ)`.
    #[inline(always)]
    pub fn locate(&self, f: f64) -> Slot {
        if !f.is_finite() {
            return Slot::NonFinite;
        }
        if f < self.f_min {
            return Slot::Below;
        }
        let k = ((f - self.f_min) * self.inv_width) as usize;
        if f >= self.f_max {
            Slot::Above
        } else {
            // Rounding can put f just below f_max into bin `bins`; keep it in range.
            Slot::Bin(k.min(self.bins - 1))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_and_mirror_symmetry() {
        let a = FrequencyAxis::new(-10.0, 10.0, 5).unwrap();
        assert_eq!(a.locate(0.0), Slot::Bin(2)); // odd bin count: DC is the centre bin
        assert_eq!(a.locate(-10.0), Slot::Bin(0));
        assert_eq!(a.locate(10.0), Slot::Above);
        assert_eq!(a.locate(-10.000001), Slot::Below);
        assert_eq!(a.locate(f64::NAN), Slot::NonFinite);
        assert_eq!(a.locate(9.999999999), Slot::Bin(4));
        for &f in &[0.3, 1.9, 2.1, 5.5, 7.77] {
            match (a.locate(f), a.locate(-f)) {
                (Slot::Bin(i), Slot::Bin(j)) => assert_eq!(i + j, 4),
                other => panic!("{other:?}"),
            }
        }
        assert!((a.center(2)).abs() < 1e-15);
        assert!(FrequencyAxis::new(1.0, 1.0, 3).is_none());
        assert!(FrequencyAxis::new(0.0, 1.0, 0).is_none());
    }
}
