//! An analog Monte Carlo tracer of one homogeneous slab, written for the tests apart from
//! `ohd::transport` (it shares no code with the library: its own generator, Fresnel formula,
//! Henyey–Greenstein draw and geometry), as the independent reference of the estimator-equality
//! tests ([`crate::estimators`]).
//!
//! A photon of weight 1 enters at normal incidence at a point of a uniform disk on the top face
//! (z = 0; +z is depth), is reflected or refracted at each face with the unpolarised Fresnel
//! probability (total internal reflection past the critical angle), flies by delta tracking
//! against the largest σt (the slab's medium, or a sphere of another medium inside it), is
//! absorbed at a real collision with probability σa/σt and otherwise scattered by the local
//! Henyey–Greenstein phase function, until it is absorbed or leaves. Nothing is weighted, split or
//! rouletted: each photon's escape is one draw of the escape distribution.

/// A medium: coefficients per mm and the Henyey–Greenstein asymmetry.
#[derive(Debug, Clone, Copy)]
pub struct Medium {
    pub sigma_a: f64,
    pub sigma_s: f64,
    pub g: f64,
}

impl Medium {
    fn sigma_t(&self) -> f64 {
        self.sigma_a + self.sigma_s
    }
}

/// A sphere of another medium inside the slab (mm).
#[derive(Debug, Clone, Copy)]
pub struct Sphere {
    pub center: [f64; 3],
    pub radius: f64,
    pub medium: Medium,
}

/// The slab (mm) and what is around it.
#[derive(Debug, Clone, Copy)]
pub struct Slab {
    pub thickness: f64,
    pub n: f64,
    pub n_above: f64,
    pub n_below: f64,
    pub medium: Medium,
    pub sphere: Option<Sphere>,
}

/// Where and how a photon left the slab.
#[derive(Debug, Clone, Copy)]
pub struct Escape {
    /// Through the top face (else the bottom one).
    pub top: bool,
    /// Whether it entered the slab (else it is the beam's specular reflection at the top face).
    pub entered: bool,
    /// The point on the face (mm).
    pub x: f64,
    pub y: f64,
    /// The direction of travel outside (unit, refracted into the ambient medium).
    pub dir: [f64; 3],
}

/// xoshiro256++ (Blackman & Vigna 2019), seeded by SplitMix64.
pub struct Rng([u64; 4]);

impl Rng {
    pub fn new(seed: u64) -> Self {
        let mut z = seed;
        let mut next = || {
            z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            x ^ (x >> 31)
        };
        Rng([next(), next(), next(), next()])
    }

    /// A uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        let s = &mut self.0;
        let out = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        (out >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Unpolarised Fresnel reflectance from index `n1` into `n2` at incidence `cos_i`, and the
/// refracted cosine (reflectance 1 past the critical angle).
fn fresnel(n1: f64, n2: f64, cos_i: f64) -> (f64, f64) {
    let sin_t = n1 / n2 * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return (1.0, 0.0);
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let s = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let p = (n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i);
    (0.5 * (s * s + p * p), cos_t)
}

/// A new direction at angle θ from `d` (cos θ drawn from Henyey–Greenstein of asymmetry `g`),
/// uniform in azimuth about it.
fn scatter(d: [f64; 3], g: f64, rng: &mut Rng) -> [f64; 3] {
    let u = rng.uniform();
    let c = if g.abs() < 1e-9 {
        2.0 * u - 1.0
    } else {
        let f = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        ((1.0 + g * g - f * f) / (2.0 * g)).clamp(-1.0, 1.0)
    };
    let s = (1.0 - c * c).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * rng.uniform();
    let (sp, cp) = phi.sin_cos();
    // Any unit vector a not along d, then two axes normal to d.
    let a = if d[2].abs() < 0.9 { [0.0, 0.0, 1.0] } else { [1.0, 0.0, 0.0] };
    let mut e1 = [a[1] * d[2] - a[2] * d[1], a[2] * d[0] - a[0] * d[2], a[0] * d[1] - a[1] * d[0]];
    let len = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]).sqrt();
    e1 = [e1[0] / len, e1[1] / len, e1[2] / len];
    let e2 = [d[1] * e1[2] - d[2] * e1[1], d[2] * e1[0] - d[0] * e1[2], d[0] * e1[1] - d[1] * e1[0]];
    let mut w = [0.0; 3];
    for k in 0..3 {
        w[k] = c * d[k] + s * (cp * e1[k] + sp * e2[k]);
    }
    let len = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    [w[0] / len, w[1] / len, w[2] / len]
}

impl Slab {
    /// The medium at `p`.
    fn medium_at(&self, p: [f64; 3]) -> Medium {
        match self.sphere {
            Some(s) => {
                let d2: f64 = (0..3).map(|k| (p[k] - s.center[k]).powi(2)).sum();
                if d2 < s.radius * s.radius { s.medium } else { self.medium }
            }
            None => self.medium,
        }
    }

    /// Trace `photons` photons of a normal beam uniform over a disk of `beam_radius` (mm; 0: a
    /// pencil at the origin) from `seed`, handing every escape to `tally`.
    pub fn trace(&self, beam_radius: f64, photons: u64, seed: u64, mut tally: impl FnMut(&Escape)) {
        let mut rng = Rng::new(seed);
        let majorant = self.sphere.map_or(0.0, |s| s.medium.sigma_t()).max(self.medium.sigma_t());
        for _ in 0..photons {
            let r = beam_radius * rng.uniform().sqrt();
            let phi = std::f64::consts::TAU * rng.uniform();
            let mut p = [r * phi.cos(), r * phi.sin(), 0.0];
            let (r0, _) = fresnel(self.n_above, self.n, 1.0);
            if rng.uniform() < r0 {
                tally(&Escape { top: true, entered: false, x: p[0], y: p[1], dir: [0.0, 0.0, -1.0] });
                continue;
            }
            let mut d = [0.0, 0.0, 1.0];
            loop {
                let s = -(1.0 - rng.uniform()).ln() / majorant;
                let to_face = if d[2] > 0.0 {
                    (self.thickness - p[2]) / d[2]
                } else if d[2] < 0.0 {
                    -p[2] / d[2]
                } else {
                    f64::INFINITY
                };
                if s >= to_face {
                    let top = d[2] < 0.0;
                    p = [p[0] + to_face * d[0], p[1] + to_face * d[1], if top { 0.0 } else { self.thickness }];
                    let n_out = if top { self.n_above } else { self.n_below };
                    let (r, cos_t) = fresnel(self.n, n_out, d[2].abs());
                    if rng.uniform() < r {
                        d[2] = -d[2];
                        continue;
                    }
                    let eta = self.n / n_out;
                    let dir = [eta * d[0], eta * d[1], if top { -cos_t } else { cos_t }];
                    tally(&Escape { top, entered: true, x: p[0], y: p[1], dir });
                    break;
                }
                p = [p[0] + s * d[0], p[1] + s * d[1], p[2] + s * d[2]];
                let m = self.medium_at(p);
                if rng.uniform() * majorant >= m.sigma_t() {
                    continue; // a null collision
                }
                if rng.uniform() * m.sigma_t() < m.sigma_a {
                    break;
                }
                d = scatter(d, m.g, &mut rng);
            }
        }
    }
}

/// A share of `n` photons counted `k` times, with its binomial standard error.
pub fn share(k: f64, n: f64) -> (f64, f64) {
    let p = k / n;
    (p, (p * (1.0 - p) / n).sqrt())
}
