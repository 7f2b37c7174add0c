//! The solver's accepted inputs ([`MieSolution::new`](super::MieSolution::new)), which its
//! errors ([`MieError`](super::MieError)) quote.

/// Smallest accepted size parameter. Below it `|a_n|²` of the terms that set g and Qext would
/// underflow; such spheres are Rayleigh scatterers.
pub const X_MIN: f64 = 1e-20;
/// Largest accepted size parameter (N ≈ 1.0002e5 terms).
pub const X_MAX: f64 = 1e5;
/// Smallest accepted real part of the relative index (far below any material's; it keeps `1/m²`
/// finite when k = 0).
pub const N_MIN: f64 = 1e-6;
/// Largest accepted real part of the relative index.
pub const N_MAX: f64 = 100.0;
/// Largest accepted imaginary part of the relative index.
pub const K_MAX: f64 = 100.0;
/// Largest accepted `|m|·x`: the downward recurrence runs `max(N, |m|x) + 16` steps (≈ 20 ms
/// here); memory stays `O(N)` regardless.
pub const MX_MAX: f64 = 1e7;
