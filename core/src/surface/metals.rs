//! Complex refractive indices `n + ik` of metals, for `surface = { type = "conductor", material =
//! "copper" }`: measured tables, interpolated linearly in wavelength (as refractiveindex.info
//! does) over the measured range, its end points included, and refused outside it.
//!
//! - Copper and gold: P. B. Johnson and R. W. Christy, "Optical constants of the noble metals",
//!   Phys. Rev. B 6, 4370–4379 (1972), room temperature, 0.4133–1.937 µm of their table.
//! - Aluminium: A. D. Rakić, "Algorithm for the determination of intrinsic optical constants of
//!   metal films: application to aluminum", Appl. Opt. 34, 4755–4767 (1995), 0.41328–4.1328 µm of
//!   the table.
//!
//! (Values as tabulated by the refractiveindex.info database, CC0.) At 1550 nm: copper
//! 0.716 + 10.66i, gold 0.524 + 10.74i, aluminium 1.578 + 15.66i.

use num_complex::Complex64;

/// A metal with a measured index table: `(wavelength µm, n, k)`, wavelengths increasing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metal {
    Copper,
    Gold,
    Aluminium,
}

/// A wavelength (m) in nm as a message shows it: to 10⁻⁴ nm, without trailing zeros (413.3, not
/// 413.29999999999995). Four decimals of a nanometre hold every table row exactly; the rest is
/// the µm → nm rounding.
pub fn nm_shown(wavelength: f64) -> String {
    let s = format!("{:.4}", wavelength * 1e9);
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

impl Metal {
    /// The names a configuration may use.
    pub const NAMES: [(&'static str, Metal); 4] = [
        ("copper", Metal::Copper),
        ("gold", Metal::Gold),
        ("aluminium", Metal::Aluminium),
        ("aluminum", Metal::Aluminium),
    ];

    pub fn from_name(name: &str) -> Option<Metal> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|&(_, m)| m)
    }

    pub fn name(self) -> &'static str {
        match self {
            Metal::Copper => "copper",
            Metal::Gold => "gold",
            Metal::Aluminium => "aluminium",
        }
    }

    /// The measurement the table comes from.
    pub fn reference(self) -> &'static str {
        match self {
            Metal::Copper | Metal::Gold => "Johnson & Christy, Phys. Rev. B 6, 4370 (1972)",
            Metal::Aluminium => "Rakić, Appl. Opt. 34, 4755 (1995)",
        }
    }

    fn table(self) -> &'static [(f64, f64, f64)] {
        match self {
            Metal::Copper => &COPPER,
            Metal::Gold => &GOLD,
            Metal::Aluminium => &ALUMINIUM,
        }
    }

    /// The measured range of wavelengths in nm, as the table's end points read (`"413.3"`,
    /// `"1937"`): the range [`Metal::index`] accepts, both ends included.
    pub fn range_nm(self) -> (String, String) {
        let t = self.table();
        (nm_shown(t[0].0 * 1e-6), nm_shown(t[t.len() - 1].0 * 1e-6))
    }

    /// `n + ik` at `wavelength` (m), if within the measured range, its end points included.
    pub fn index(self, wavelength: f64) -> Option<Complex64> {
        let t = self.table();
        let (first, last) = (t[0].0, t[t.len() - 1].0);
        // An end point written in nm (413.3 nm, 4132.8 nm) reaches µm through two roundings (nm →
        // m → µm) and may land an ulp outside: within 10⁻¹² of an end is that end.
        let um = wavelength * 1e6;
        let um = if (um - first).abs() <= 1e-12 * first {
            first
        } else if (um - last).abs() <= 1e-12 * last {
            last
        } else {
            um
        };
        let i = t.windows(2).position(|w| w[0].0 <= um && um <= w[1].0)?;
        let ((l0, n0, k0), (l1, n1, k1)) = (t[i], t[i + 1]);
        let f = (um - l0) / (l1 - l0);
        Some(Complex64::new(n0 + f * (n1 - n0), k0 + f * (k1 - k0)))
    }
}

const COPPER: [(f64, f64, f64); 20] = [
    (0.4133, 1.28, 2.207),
    (0.4305, 1.25, 2.305),
    (0.4509, 1.24, 2.397),
    (0.4714, 1.25, 2.483),
    (0.4959, 1.22, 2.564),
    (0.5209, 1.18, 2.608),
    (0.5486, 1.02, 2.577),
    (0.5821, 0.70, 2.704),
    (0.6168, 0.30, 3.205),
    (0.6595, 0.22, 3.747),
    (0.7045, 0.21, 4.205),
    (0.7560, 0.24, 4.665),
    (0.8211, 0.26, 5.180),
    (0.8920, 0.30, 5.768),
    (0.9840, 0.32, 6.421),
    (1.0880, 0.36, 7.217),
    (1.2160, 0.48, 8.245),
    (1.3930, 0.60, 9.439),
    (1.6100, 0.76, 11.12),
    (1.9370, 1.09, 13.43),
];

const GOLD: [(f64, f64, f64); 20] = [
    (0.4133, 1.46, 1.958),
    (0.4305, 1.45, 1.948),
    (0.4509, 1.38, 1.914),
    (0.4714, 1.31, 1.849),
    (0.4959, 1.04, 1.833),
    (0.5209, 0.62, 2.081),
    (0.5486, 0.43, 2.455),
    (0.5821, 0.29, 2.863),
    (0.6168, 0.21, 3.272),
    (0.6595, 0.14, 3.697),
    (0.7045, 0.13, 4.103),
    (0.7560, 0.14, 4.542),
    (0.8211, 0.16, 5.083),
    (0.8920, 0.17, 5.663),
    (0.9840, 0.22, 6.350),
    (1.0880, 0.27, 7.150),
    (1.2160, 0.35, 8.145),
    (1.3930, 0.43, 9.519),
    (1.6100, 0.56, 11.21),
    (1.9370, 0.92, 13.78),
];

const ALUMINIUM: [(f64, f64, f64); 30] = [
    (0.41328, 0.52135, 5.0008),
    (0.44280, 0.60790, 5.3676),
    (0.47687, 0.72780, 5.7781),
    (0.51660, 0.87340, 6.2418),
    (0.56357, 1.0728, 6.7839),
    (0.61993, 1.3660, 7.4052),
    (0.65225, 1.5724, 7.7354),
    (0.68881, 1.8301, 8.0601),
    (0.72932, 2.1606, 8.3565),
    (0.77491, 2.6154, 8.4914),
    (0.79478, 2.7675, 8.3866),
    (0.81569, 2.7668, 8.2573),
    (0.83774, 2.6945, 8.1878),
    (0.88561, 2.2802, 8.1134),
    (0.91166, 1.9739, 8.3058),
    (0.93928, 1.6784, 8.5970),
    (0.96863, 1.4867, 9.0655),
    (0.99988, 1.4359, 9.4939),
    (1.0332, 1.3998, 9.8914),
    (1.1271, 1.3281, 10.969),
    (1.2399, 1.3157, 12.245),
    (1.3776, 1.3899, 13.784),
    (1.5498, 1.5782, 15.656),
    (1.7712, 1.9205, 17.991),
    (2.0664, 2.4738, 20.982),
    (2.4797, 3.3372, 25.004),
    (2.7552, 3.9380, 27.580),
    (3.0996, 4.7097, 30.737),
    (3.4440, 5.4903, 33.814),
    (4.1328, 7.0796, 39.826),
];

#[cfg(test)]
mod tests {
    use super::*;

    /// The end points of each table are in its range, as written in nm (two roundings away from
    /// the table's µm), and give their rows; a tenth of a nm outside is refused.
    #[test]
    fn tables_take_their_end_points_and_refuse_just_outside() {
        for (m, lo_nm, hi_nm) in
            [(Metal::Copper, 413.3, 1937.0), (Metal::Gold, 413.3, 1937.0), (Metal::Aluminium, 413.28, 4132.8)]
        {
            let t = m.table();
            let (first, last) = (t[0], t[t.len() - 1]);
            assert_eq!(m.index(lo_nm * 1e-9), Some(Complex64::new(first.1, first.2)), "{} at {lo_nm} nm", m.name());
            assert_eq!(m.index(hi_nm * 1e-9), Some(Complex64::new(last.1, last.2)), "{} at {hi_nm} nm", m.name());
            assert_eq!(m.index((lo_nm - 0.1) * 1e-9), None, "{} at {} nm", m.name(), lo_nm - 0.1);
            assert_eq!(m.index((hi_nm + 0.1) * 1e-9), None, "{} at {} nm", m.name(), hi_nm + 0.1);
        }
    }

    #[test]
    fn tables_interpolate_and_refuse_outside_their_range() {
        // A tabulated wavelength gives its row exactly; 1550 nm lies between two rows.
        assert_eq!(Metal::Copper.index(1.393e-6), Some(Complex64::new(0.60, 9.439)));
        let cu = Metal::Copper.index(1.55e-6).unwrap();
        assert!((cu.re - 0.7158).abs() < 1e-3 && (cu.im - 10.656).abs() < 1e-2, "{cu}");
        let al = Metal::Aluminium.index(1.55e-6).unwrap();
        assert!((al.re - 1.578).abs() < 1e-3 && (al.im - 15.656).abs() < 1e-2, "{al}");
        assert!(Metal::Gold.index(0.3e-6).is_none() && Metal::Gold.index(2.5e-6).is_none());
        for (_, m) in Metal::NAMES {
            let t = m.table();
            assert!(t.windows(2).all(|w| w[0].0 < w[1].0 && w[1].1 > 0.0 && w[1].2 > 0.0), "{}", m.name());
        }
        // Metals reflect most of the near infrared at normal incidence.
        for (_, m) in Metal::NAMES {
            let r = super::super::conductor_reflectance(m.index(1.55e-6).unwrap(), 1.0);
            assert!(r > 0.95 && r < 1.0, "{}: R = {r}", m.name());
        }
    }
}
