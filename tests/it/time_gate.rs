//! The global time gate `run.time_gate_ns` (time of flight = optical path length / c from the
//! emission point): a gate wider than every path changes nothing, and a purely absorbing slab's
//! gated reflectance, transmittance and absorbed fraction against their closed forms.

use ohd::detect::Scalar;

use crate::support::run::{Run, run};
use crate::support::stats::assert_within_sigma;

const VDH: &str = include_str!("../../validation/vdh_slab.toml");

#[test]
fn a_gate_wider_than_every_path_changes_nothing() {
    // The gated walk tracks `l` and checks it, but draws the same numbers: every scalar equal.
    let sets = ["run.samples=50000", "layers.0.n=1.4"];
    let plain = run(VDH, &sets);
    let gated = run(VDH, &[sets[0], sets[1], "run.time_gate_ns=[0, 1e6]"]);
    assert!(gated.exp.needs_length() && !plain.exp.needs_length());
    for s in Scalar::ALL {
        assert_eq!(plain.scalar(s), gated.scalar(s), "{s:?}");
    }
}

/// The purely absorbing Fresnel slab of the closed forms below (σs = 0, σa = 2.5/mm, 0.2 mm,
/// n = 1.5 in air, no roulette), run with the gate override `gate`.
fn absorbing_slab(gate: &str) -> Run {
    run(
        VDH,
        &[
            "media.slab.sigma_s_per_cm=0",
            "media.slab.sigma_a_per_cm=25",
            "layers.0.n=1.5",
            "run.samples=400000",
            "run.roulette_threshold=0",
            gate,
        ],
    )
}

#[test]
fn gated_absorbing_slab_matches_its_closed_form() {
    // σs = 0, n = 1.5 in air, d = 0.2 mm, τ = σa d = 0.5, normal incidence. The light inside
    // crosses the slab at optical length n d = 0.3 mm per pass. A gate ending at l1 = c t1 =
    // 0.45 mm keeps: the specular reflection R0 = ((n−1)/(n+1))² (l = 0), the first pass's
    // transmission T = (1 − R0)² e^{−τ} (l = 0.3 mm; the next one leaves at 0.9 mm), no diffuse
    // reflection (the first leaves at 0.6 mm), and the absorption of the first pass plus that of
    // the first 0.1 mm of the way back after a reflection at the bottom:
    //   A = (1 − R0)(1 − e^{−τ}) + (1 − R0) e^{−τ} R0 (1 − e^{−τ/2}).
    let l1 = 0.45e-3;
    let t1_ns = l1 / ohd::SPEED_OF_LIGHT * 1e9;
    let gate = format!("run.time_gate_ns=[0, {t1_ns}]");
    let r = absorbing_slab(&gate);
    let (n, tau) = (1.5f64, 0.5f64);
    let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
    let t = (1.0 - r0).powi(2) * (-tau).exp();
    let a = (1.0 - r0) * (1.0 - (-tau).exp()) + (1.0 - r0) * (-tau).exp() * r0 * (1.0 - (-tau / 2.0).exp());
    let (rsp, _) = r.scalar(Scalar::ReflectanceSpecular);
    assert!((rsp - r0).abs() < 1e-12, "specular {rsp} vs {r0}");
    assert_eq!(r.scalar(Scalar::ReflectanceDiffuse).0, 0.0, "no diffuse reflection before 0.6 mm");
    let (tt, se_t) = r.scalar(Scalar::TransmittanceTotal);
    assert_within_sigma("gated T", tt, se_t, t, 4.0);
    let (ab, se_a) = r.scalar(Scalar::AbsorbedFraction);
    assert_within_sigma("gated A", ab, se_a, a, 4.0);
    // (The later passes add only R0² e^{−2τ} = 6e-4 of T here; the late gate below isolates them.)
}

#[test]
fn a_gate_starting_late_drops_the_early_light() {
    // Gate [l0, ∞) with l0 = 0.45 mm on the same slab: the first-pass transmission and the
    // specular reflection are dropped; the diffuse reflection (l = 0.6 mm) and the later
    // transmissions (0.9 mm, …) stay:
    //   Rd = (1 − R0)² R0 e^{−2τ} / (1 − R0² e^{−2τ}),  T = (1 − R0)² e^{−τ} R0² e^{−2τ} / (1 − R0² e^{−2τ}).
    let l0 = 0.45e-3;
    let t0_ns = l0 / ohd::SPEED_OF_LIGHT * 1e9;
    let gate = format!("run.time_gate_ns=[{t0_ns}, 1e6]");
    let r = absorbing_slab(&gate);
    let (n, tau) = (1.5f64, 0.5f64);
    let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
    let q = 1.0 - r0 * r0 * (-2.0 * tau).exp();
    assert_eq!(r.scalar(Scalar::ReflectanceSpecular).0, 0.0);
    let (rd, se_r) = r.scalar(Scalar::ReflectanceDiffuse);
    assert_within_sigma("late Rd", rd, se_r, (1.0 - r0).powi(2) * r0 * (-2.0 * tau).exp() / q, 4.0);
    let (tt, se_t) = r.scalar(Scalar::TransmittanceTotal);
    assert_within_sigma("late T", tt, se_t, (1.0 - r0).powi(2) * (-tau).exp() * r0 * r0 * (-2.0 * tau).exp() / q, 4.0);
}
