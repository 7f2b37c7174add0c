//! The layered control variate of forward-estimated cameras (`run.control_variate`,
//! `ohd::detect::twin`): the estimate it gives equals the plain one within σ (pixels, ROI values
//! and spectrum bins) on a small retina with a moving vessel; where the vessel's medium equals its
//! layer's the twin is the path itself (`Λ ≡ 1`) and the image is the kernel's alone; it is the
//! same with any number of threads; and it is refused where it cannot apply.

use crate::support::run::{Run, experiment, roi_channel, roi_m0, run};
use crate::support::scenes;
use crate::support::stats::chi2_difference;

/// A 1 mm disk beam at normal incidence on a 300 µm retina (σs 15 /mm, g 0.9) over a 400 µm
/// choroid-like layer, a blood vessel (σs `blood_sigma_s` /mm, g 0.95, radius 80 µm, tilted 15°,
/// Poiseuille 16 mm/s on the axis) of medium `blood` in the retina, seen by a 12 × 12 LDH camera
/// of 1.2 mm at 15° with an ROI over the vessel.
fn retina(samples: u64, blood: &str, control_variate: &str) -> String {
    let header = scenes::header(samples, 5, 32);
    format!(
        r#"{header}control_variate = "{control_variate}"
[source]
wavelength_nm = 785
profile = "disk"
radius_mm = 1.0
position_mm = [0.05, -0.02, -1]
[ambient]
n_above = 1.336
n_below = 1.40
[media.tissue]
sigma_a_per_mm = 0.1
sigma_s_per_mm = 15
phase = {{ type = "hg", g = 0.9 }}
[media.choroid]
sigma_a_per_mm = 2
sigma_s_per_mm = 30
phase = {{ type = "hg", g = 0.9 }}
[media.blood]
{blood}
[[layers]]
name = "retina"
thickness_um = 300
n = 1.37
medium = "tissue"
[[layers]]
name = "choroid"
thickness_um = 400
n = 1.38
medium = "choroid"
[[regions]]
name = "vessel"
layer = "retina"
medium = "blood"
shape = {{ type = "cylinder", center_um = [0, 100, 150], axis = [0.96593, 0, 0.25882], radius_um = 80, length_mm = 0.8 }}
velocity = {{ type = "poiseuille", v_max_mm_per_s = 16 }}
{camera}[detectors.ldh]
frame_rate_khz = 39
window_samples = 64
window = "hann"
band_khz = [6, 18.3]
by_class = true
pixel_spectra = true
[[detectors.ldh.roi]]
name = "vessel"
center_um = [0, 100]
size_um = [500, 160]
"#,
        camera = scenes::camera(1.2, 15.0, 12)
    )
}

const BLOOD: &str = "sigma_a_per_mm = 0.4\nsigma_s_per_mm = 20\nphase = { type = \"hg\", g = 0.95 }";

/// An image output's values and standard errors.
fn image(r: &Run, name: &str) -> (Vec<f64>, Vec<f64>) {
    let reg = &r.out.layout.registry;
    let o = reg.outputs.iter().find(|o| o.name == name).unwrap_or_else(|| panic!("no {name}"));
    o.values(r.out.estimates.mean(), &r.out.estimates.stderr())
}

/// The first ROI's M0± of two runs agree within 4σ, and its four spectrum channels by χ².
fn assert_rois_agree(a: &Run, b: &Run) {
    let ((a_plus, sa_plus), (a_minus, sa_minus)) = roi_m0(a, 0, 0);
    let ((b_plus, sb_plus), (b_minus, sb_minus)) = roi_m0(b, 0, 0);
    for (what, x, sx, y, sy) in
        [("M0+", a_plus, sa_plus, b_plus, sb_plus), ("M0−", a_minus, sa_minus, b_minus, sb_minus)]
    {
        let z = (x - y) / sx.hypot(sy);
        assert!(z.abs() < 4.0, "ROI {what}: {x:.4e} ± {sx:.1e} against {y:.4e} ± {sy:.1e} (z = {z:.2})");
    }
    for channel in 0..4 {
        assert_roi_channel_agrees(a, b, channel);
    }
}

/// The first ROI's spectrum channel `channel` of two runs agree by χ²: the static light, channel
/// 1, is at 0 Hz, one bin (its χ² is the z² of the ROI's static power); the total and the
/// Doppler-shifted light fill 30 bins or more.
fn assert_roi_channel_agrees(a: &Run, b: &Run, channel: usize) {
    let (x, y) = (roi_channel(a, 0, 0, channel), roi_channel(b, 0, 0, channel));
    let (chi2, dof, p) = chi2_difference((&x.values, &x.stderr), (&y.values, &y.stderr));
    let enough = if channel == 1 { dof == 1 } else { dof >= 30 };
    assert!(enough && p > 1e-4, "ROI spectrum channel {channel}: χ² = {chi2:.1} over {dof} bins (p = {p:.2e})");
}

/// The control variate's intensity image, ROI M0± and ROI spectrum equal the plain estimate's
/// within their standard errors (χ² of the differences), and its intensity image is far more
/// precise. Only the vessel moves here, so the twin (the stack without it) is static: it adds
/// nothing to the Doppler band, and on the plain run's streams the M0± maps, the per-pixel
/// spectra (which the control variate leaves plain, every path's line recorded in full) and the
/// ROI's Doppler-shifted channels are the plain run's bit for bit — a χ² of them was 0 over 144
/// pixels, a comparison that could not fail; they are compared as the identity they are. (Where
/// the twin moves, a belt under the stack, [`the_control_variate_equals_the_plain_estimate_with_surfaces`]
/// compares its M0± maps by χ².)
#[test]
fn the_control_variate_equals_the_plain_estimate() {
    let plain = run(&retina(600_000, BLOOD, "off"), &[]);
    let cv = run(&retina(600_000, BLOOD, "layered"), &[]);
    assert!(plain.out.layout.detectors[0].twin.is_none() && cv.out.layout.detectors[0].twin.is_some());
    let (a, b) = (image(&plain, "camera.image"), image(&cv, "camera.image"));
    let (chi2, dof, p) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
    assert!(dof == 144 && p > 1e-4, "camera.image: χ² = {chi2:.1} over {dof} pixels (p = {p:.2e})");
    for name in ["camera.m0_plus", "camera.m0_minus", "camera.m0_plus_multiple_doppler", "camera.pixel_spectra"] {
        let (a, b) = (image(&plain, name), image(&cv, name));
        assert!(a.0.iter().any(|v| *v != 0.0), "{name} is empty");
        assert!(a == b, "{name}: the static twin changed the Doppler band");
    }
    let ((a_plus, sa_plus), _) = roi_m0(&plain, 0, 0);
    let ((b_plus, sb_plus), _) = roi_m0(&cv, 0, 0);
    assert!(
        a_plus == b_plus && sa_plus == sb_plus,
        "ROI M0+: {a_plus:e} ± {sa_plus:e} against {b_plus:e} ± {sb_plus:e}"
    );
    for channel in [0, 1] {
        assert_roi_channel_agrees(&plain, &cv, channel);
    }
    for channel in [2, 3] {
        let (x, y) = (roi_channel(&plain, 0, 0, channel), roi_channel(&cv, 0, 0, channel));
        assert!(x.values == y.values && x.stderr == y.stderr, "ROI spectrum channel {channel} differs");
    }
    // Away from the vessel every path is pooled in the kernel: the median relative error of the
    // pixels outside the vessel's footprint falls several times (it keeps the corrections of the
    // paths that met the vessel, which here lies within a few transport lengths of every pixel).
    let mask = ohd::detect::image::region_mask(&cv.exp.scene, cv.exp.detectors[0].surface().unwrap().image().unwrap())
        .expect("the vessel is seen");
    // As written: row 0 at the largest y.
    let mask: Vec<bool> = mask.chunks(12).rev().flatten().copied().collect();
    let median_off_vessel = |(v, s): (Vec<f64>, Vec<f64>)| {
        let mut r: Vec<f64> =
            v.iter().zip(&s).zip(&mask).filter(|((v, _), m)| **v > 0.0 && !**m).map(|((v, s), _)| s / v).collect();
        r.sort_by(f64::total_cmp);
        r[r.len() / 2]
    };
    let (rp, rc) = (median_off_vessel(image(&plain, "camera.image")), median_off_vessel(image(&cv, "camera.image")));
    assert!(rc < rp / 4.0, "median relative error off the vessel: {rp:.4} plain, {rc:.4} with the control variate");
}

/// Surfaces (issue 38): a rough top face and a Lambertian belt under a 150 µm choroid, running
/// at 3 mm/s along x — planar and laterally invariant, so the twin has them and shares their
/// reflections and shadow rays — and a rough copper ball moving in the choroid, which the twin has
/// not: it parts from its path where the path meets the ball and flies on. The images, ROI values
/// and spectra equal the plain estimate's within σ, and the intensity image is still several
/// times more precise. A rotating floor (whose Doppler shift depends on where) is refused.
///
/// (The thin choroid keeps the belt's M0+ off the plain estimate's tail: under the 400 µm one the
/// plain M0+ of 6·10⁵ paths had pixels 2·10⁻⁷ ± 0.6·10⁻⁷ where the control variate and a plain
/// run of 6·10⁶ paths gave 8·10⁻⁷ — χ² 1288 over 144 pixels against the first, 183 against the
/// second; the same with the layer's tissue moving and no surface at all, on the binary before
/// surfaces.)
#[test]
fn the_control_variate_equals_the_plain_estimate_with_surfaces() {
    let sets = [
        "detectors.0.next_event=true",
        "layers.0.roughness=0.2",
        "layers.1.thickness_um=150",
        "bottom={surface={type=\"lambertian\",albedo=0.5},velocity_mm_per_s=[3,0,0]}",
        "opaque=[{name=\"ball\",layer=\"retina\",shape={type=\"sphere\",center_um=[-350,-300,150],radius_um=110},surface={type=\"lambertian\",albedo=0.9},velocity_mm_per_s=[0,0,5]}]",
    ];
    let plain = run(&retina(600_000, BLOOD, "off"), &sets);
    let cv = run(&retina(600_000, BLOOD, "layered"), &sets);
    assert!(cv.exp.control_variate() && !plain.exp.control_variate());
    for name in ["camera.image", "camera.m0_plus", "camera.m0_minus"] {
        let (a, b) = (image(&plain, name), image(&cv, name));
        let (chi2, dof, p) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
        assert!(dof >= 100 && p > 1e-4, "{name}: χ² = {chi2:.1} over {dof} pixels (p = {p:.2e})");
    }
    // The ROI's M0± (its spectrum's bins are not compared: at 6·10⁵ paths their batch errors fall
    // short for either estimator here, surfaces or not — the control variate's against its own
    // run of 6·10⁶ paths gave χ² 168 over 65 bins without any surface, 69 between the two long runs).
    let ((a_plus, sa_plus), (a_minus, sa_minus)) = roi_m0(&plain, 0, 0);
    let ((b_plus, sb_plus), (b_minus, sb_minus)) = roi_m0(&cv, 0, 0);
    for (what, x, sx, y, sy) in
        [("M0+", a_plus, sa_plus, b_plus, sb_plus), ("M0−", a_minus, sa_minus, b_minus, sb_minus)]
    {
        let z = (x - y) / sx.hypot(sy);
        assert!(z.abs() < 4.0, "ROI {what}: {x:.4e} ± {sx:.1e} against {y:.4e} ± {sy:.1e} (z = {z:.2})");
    }
    let median = |(v, s): (Vec<f64>, Vec<f64>)| {
        let mut r: Vec<f64> = v.iter().zip(&s).filter(|(v, _)| **v > 0.0).map(|(v, s)| s / v).collect();
        r.sort_by(f64::total_cmp);
        r[r.len() / 2]
    };
    let (rp, rc) = (median(image(&plain, "camera.image")), median(image(&cv, "camera.image")));
    assert!(rc < rp / 2.0, "median relative error: {rp:.4} plain, {rc:.4} with the control variate");
    // Without the vessel and the ball every path is its twin, so the image is the kernel's alone:
    // the shadow rays from the rough face and the belt go to the kernel too. With them left out of
    // the twin (scored plain, unbiased) the median relative error was 0.0121 against 0.0066
    // (plain: 0.146).
    let alone = [&sets[..4], &["regions=[]", "detectors.0.ldh.roi=[]"]].concat();
    let plain = run(&retina(600_000, BLOOD, "off"), &alone);
    let cv = run(&retina(600_000, BLOOD, "layered"), &alone);
    let (rp, rc) = (median(image(&plain, "camera.image")), median(image(&cv, "camera.image")));
    assert!(
        rc < rp / 15.0,
        "without the vessel: median relative error {rp:.4} plain, {rc:.4} with the control variate"
    );
    let (a, b) = (image(&plain, "camera.image"), image(&cv, "camera.image"));
    let (chi2, dof, p) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
    assert!(dof == 144 && p > 1e-4, "without the vessel: χ² = {chi2:.1} over {dof} pixels (p = {p:.2e})");
    let text = retina(1000, BLOOD, "layered");
    let spin = [sets[3].replace("velocity_mm_per_s=[3,0,0]", "angular_velocity_rpm=[0,0,60]")];
    let err = ohd::config::load(&text, "test", &spin).unwrap_err().to_string();
    assert!(err.contains("run.control_variate") && err.contains("rotates"), "{err}");
}

/// The same equality (on 4 × 4 pixels, for power on the image's scale) in a vessel below a first
/// layer, of two populations far more and far less forward than the tissue (`Λ` leaves its band
/// within a few collisions in it): a collision's likelihood ratio is the media's, whichever
/// population the path scattered on (over the population's own σs the image was 19 % low,
/// χ² 57), and the twin walks on from the layer it parted in (from the first layer's bounds it
/// gave χ² 36, p = 3·10⁻³: a weak check, the twins' own walks carry little here).
#[test]
fn the_control_variate_equals_the_plain_estimate_below_a_first_layer_on_two_populations() {
    let blood = "populations = [\"cells\", \"haze\"]\n\
        [media.cells]\nsigma_a_per_mm = 0.4\nsigma_s_per_mm = 14\nphase = { type = \"hg\", g = 0.99 }\n\
        velocity = { type = \"poiseuille\", v_max_mm_per_s = 16 }\n\
        [media.haze]\nsigma_a_per_mm = 0.0\nsigma_s_per_mm = 6\nphase = { type = \"hg\", g = 0.6 }";
    let below = |cv: &str| {
        retina(600_000, blood, cv)
            .replacen("pixels = [12, 12]", "pixels = [4, 4]", 1)
            .replacen("length_mm = 0.8 }\nvelocity = { type = \"poiseuille\", v_max_mm_per_s = 16 }", "length_mm = 0.8 }", 1)
            .replacen(
            "[[layers]]\nname = \"retina\"",
            "[[layers]]\nname = \"ilm\"\nthickness_um = 40\nn = 1.37\nmedium = \"tissue\"\n[[layers]]\nname = \"retina\"",
            1,
        )
    };
    let (plain, cv) = (run(&below("off"), &[]), run(&below("layered"), &[]));
    assert!(cv.exp.scene.regions[0].layer == 1, "the vessel is in the second layer");
    assert_equal_on_4x4("below a first layer", &plain, &cv);
}

/// The 4 × 4 images (intensity, M0±) of `plain` and `cv` equal within σ (χ²), and their ROI M0+
/// within 4σ.
fn assert_equal_on_4x4(what: &str, plain: &Run, cv: &Run) {
    for name in ["camera.image", "camera.m0_plus", "camera.m0_minus"] {
        let (a, b) = (image(plain, name), image(cv, name));
        let (chi2, dof, p) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
        assert!(dof == 16 && p > 1e-4, "{what}, {name}: χ² = {chi2:.1} over {dof} pixels (p = {p:.2e})");
    }
    let ((a, sa), _) = roi_m0(plain, 0, 0);
    let ((b, sb), _) = roi_m0(cv, 0, 0);
    let z = (a - b) / sa.hypot(sb);
    assert!(z.abs() < 4.0, "{what}: ROI M0+ {a:.4e} ± {sa:.1e} against {b:.4e} ± {sb:.1e} (z = {z:.2})");
}

/// The same equality with a density field in the vessel (a ramp along it, 0.2 to 1.5 of the
/// blood's σs), in scattering tissue and in a clear layer (whose twin never collides there):
/// the path and its twin are delta-tracked together through it and part at the first
/// tentative collision they disagree on (`transport::tracking::coupled_flight`).
#[test]
fn the_control_variate_equals_the_plain_estimate_through_a_density_region() {
    let ramp = "density = { type = \"ramp\", axis = \"x\", from_mm = -0.4, to_mm = 0.4, density_from = 0.2, density_to = 1.5 }";
    let blood = format!("{BLOOD}\n{ramp}");
    for fill in ["sigma_s_per_mm = 15", "sigma_s_per_mm = 0"] {
        let scene = |cv: &str| {
            retina(600_000, &blood, cv).replacen("pixels = [12, 12]", "pixels = [4, 4]", 1).replacen(
                "sigma_s_per_mm = 15",
                fill,
                1,
            )
        };
        let (plain, cv) = (run(&scene("off"), &[]), run(&scene("layered"), &[]));
        assert!(cv.out.layout.detectors[0].twin.is_some() && cv.exp.scene.layers[0].heterogeneous);
        assert_equal_on_4x4(fill, &plain, &cv);
    }
}

/// A vessel whose medium is its layer's (moving, so that it is a region of its own): the twin is
/// the path (`Λ = 1`, the same shadow rays), so the intensity image is the kernel's alone and
/// equals, to rounding, that of the same run without the vessel; the M0 images still carry the
/// vessel's Doppler shift.
#[test]
fn a_region_of_the_layers_medium_leaves_the_kernel_alone() {
    let tissue = "sigma_a_per_mm = 0.1\nsigma_s_per_mm = 15\nphase = { type = \"hg\", g = 0.9 }";
    let with = run(&retina(60_000, tissue, "layered"), &[]);
    let still = run(&retina(60_000, tissue, "layered"), &["regions.0.velocity.v_max_mm_per_s=0"]);
    let (a, b) = (image(&with, "camera.image"), image(&still, "camera.image"));
    for (i, (x, y)) in a.0.iter().zip(&b.0).enumerate() {
        assert!((x - y).abs() <= 1e-9 * x.abs(), "pixel {i}: {x:e} with the flow, {y:e} without");
    }
    let (m_with, m_still) = (image(&with, "camera.m0_plus"), image(&still, "camera.m0_plus"));
    let (s_with, s_still): (f64, f64) = (m_with.0.iter().sum(), m_still.0.iter().sum());
    assert!(s_with > 10.0 * s_still, "M0+ with the flow {s_with:e}, without {s_still:e}");
}

/// Threads change nothing: the kernels are per batch.
#[test]
fn the_control_variate_is_the_same_on_any_number_of_threads() {
    let text = retina(20_000, BLOOD, "layered");
    let one = run(&text, &["run.threads=1"]);
    let two = run(&text, &["run.threads=2"]);
    assert_eq!(one.out.estimates.mean(), two.out.estimates.mean());
    assert_eq!(one.out.estimates.stderr(), two.out.estimates.stderr());
}

/// Asked for where it cannot apply (a tilted beam), the run is refused naming the key and why.
#[test]
fn the_control_variate_is_refused_where_it_cannot_apply() {
    let text = retina(1000, BLOOD, "layered");
    let err = ohd::config::load(&text, "test", &["source.direction=[0.1, 0, 1]".to_string()]).unwrap_err().to_string();
    assert!(err.contains("run.control_variate") && err.contains("tilted"), "{err}");
    // `auto` there runs the plain estimate.
    let e = experiment(&text, &["source.direction=[0.1, 0, 1]", "run.control_variate=\"auto\""]);
    assert!(!e.control_variate());
}

/// Launches near the regions (`run.launches = "near_regions"`) weight each path by the profile's
/// density over the mixture's: the images, ROI values and spectra equal those of launches from
/// the profile within σ, with and without the control variate.
#[test]
fn launches_near_the_regions_equal_launches_from_the_profile() {
    let near = ["run.launches=\"near_regions\"", "run.launch_margin_um=150", "run.launch_profile_share=0.4"];
    for cv in ["off", "layered"] {
        let plain = run(&retina(400_000, BLOOD, cv), &[]);
        let biased = run(&retina(400_000, BLOOD, cv), &near);
        let l = biased.exp.plan.walk.launches.expect("near_regions").launches(&biased.exp.scene, &biased.exp.source);
        let p = l.expect("the vessel holds part of the profile").p_near;
        assert!(p > 0.05 && p < 0.6, "share of the profile near the vessel: {p}");
        for name in ["camera.image", "camera.m0_plus", "camera.m0_minus"] {
            let (a, b) = (image(&plain, name), image(&biased, name));
            let (chi2, dof, pv) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
            assert!(dof >= 100 && pv > 1e-4, "{cv}, {name}: χ² = {chi2:.1} over {dof} pixels (p = {pv:.2e})");
        }
        let ((a, sa), _) = roi_m0(&plain, 0, 0);
        let ((b, sb), _) = roi_m0(&biased, 0, 0);
        let z = (a - b) / sa.hypot(sb);
        assert!(z.abs() < 4.0, "{cv}: ROI M0+ {a:.4e} ± {sa:.1e} against {b:.4e} ± {sb:.1e} (z = {z:.2})");
    }
}

/// The tail check's histograms ([`ohd::detect::tail`]) hold every path's score into the vessel's
/// footprint: without the control variate the scores are the pixels' own contributions, so their
/// sum over the histogram is the footprint's pooled intensity and M0+ (times the paths), to
/// rounding; the slope of the largest is a power law's (finite: a bounded next-event weight), and
/// a slope below 3 is among the run's warnings.
#[test]
fn the_tail_histograms_add_up_to_the_footprints_pooled_values() {
    let plain = run(&retina(100_000, BLOOD, "off"), &[]);
    let (out, lay) = (&plain.out, &plain.out.layout.detectors[0]);
    let tail = lay.tail.as_ref().expect("the camera sees the vessel");
    let paths = (out.estimates.batches() as u64 * out.paths_per_batch) as f64;
    let mean = out.estimates.mean();
    let checks = out.tail_checks();
    for (c, image) in tail.images.iter().enumerate() {
        let start = image.expect("an intensity and an M0+ image");
        let pooled: f64 = tail.mask.iter().enumerate().filter(|(_, m)| **m).map(|(p, _)| mean[start + p]).sum();
        let [counts, _, sums] = tail.histogram(c, mean, paths);
        let (n, total): (f64, f64) = (counts.iter().sum(), sums.iter().sum());
        assert!(n > 1000.0 && n < paths, "channel {c}: {n} scores of {paths} paths");
        assert!(
            (total / (pooled * paths) - 1.0).abs() < 1e-9,
            "channel {c}: Σ scores {total:e}, pooled {:e}",
            pooled * paths
        );
        let slope = checks[&start].slope.expect("enough scores");
        assert!((1.0..=10.0).contains(&slope), "channel {c}: slope {slope}");
        // A slope below 3 is warned of, naming the image; one at or above it is not.
        let name = &out.layout.registry.outputs.iter().find(|o| o.slots.start == start).expect("the image").name;
        let warned = ohd::post::warnings::warnings(&plain.exp, out)
            .iter()
            .any(|w| w.code == "heavy_tail" && w.message.starts_with(&format!("{name}: ")));
        assert_eq!(warned, slope < ohd::post::warnings::TAIL_SLOPE, "channel {c} ({name}): slope {slope}");
    }
}

/// Weight windows (`run.importance = "windows"`), and windows with guided directions
/// (`"guided"`), on top of the control variate: the copies a split makes carry the path's twin, a
/// guided continuation weighs path and twin alike, so the M0± maps, ROI M0± and ROI spectra still
/// equal the plain estimate's within σ. Not the intensity image pixel by pixel: its control-variate pixels share
/// the kernel's error (one convolved estimate), which a χ² of independent pixels does not allow for
/// once the two runs' paths differ (a control variate alone on other streams than the plain run's
/// gives χ² 201 and 271 over 144 pixels; the first test passes on shared streams). Its total agrees:
/// 4 seeds of 1.6·10⁶ paths, plain 4.3439·10⁻³ ± 1.5·10⁻⁵, windows 4.3385·10⁻³ ± 2.1·10⁻⁶.
#[test]
fn the_control_variate_with_weight_windows_equals_the_plain_estimate() {
    let plain = run(&retina(400_000, BLOOD, "off"), &[]);
    for importance in ["windows", "guided"] {
        let windowed = run(&retina(400_000, BLOOD, "layered"), &[&format!("run.importance = \"{importance}\"")]);
        for name in ["camera.m0_plus", "camera.m0_minus"] {
            let (a, b) = (image(&plain, name), image(&windowed, name));
            let (chi2, dof, p) = chi2_difference((&a.0, &a.1), (&b.0, &b.1));
            assert!(dof >= 100 && p > 1e-4, "{importance}: {name}: χ² = {chi2:.1} over {dof} pixels (p = {p:.2e})");
        }
        assert_rois_agree(&plain, &windowed);
    }
}
