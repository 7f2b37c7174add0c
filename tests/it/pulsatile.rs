//! Pulsatile flows (`[cardiac]`): one transport run gives every window of an acquisition over the
//! cardiac cycle, each equal to a steady run with the velocities frozen at that window's time;
//! a steady waveform changes nothing.

use crate::support::run::{Run, run};
use crate::support::stats::chi2_difference;

const FIXTURE: &str = include_str!("../configs/good/pulsatile_vessel.toml");

/// A point detector over the vessel (laser Doppler flowmetry): its spectrum, and with
/// `acquisition` its spectra in 20 ms windows every 100 ms over the cycle (each window's lines
/// integrated over the bins as the steady spectrum's: equal to the frozen run's to rounding).
fn probe(acquisition: bool) -> String {
    let windows = if acquisition { "[detectors.spectrum.acquisition]\nwindow_ms = 20\nhop_ms = 100\n" } else { "" };
    format!(
        "\n[[detectors]]\nname = \"probe\"\narea = {{ type = \"disk\", radius_mm = 0.3 }}\n\
         acceptance_half_angle_deg = 20\ninclude_specular = false\n\
         [detectors.spectrum]\nf_min_khz = -40\nf_max_khz = 40\nbins = 160\n{windows}"
    )
}

/// Output `name` of a run as written (values, standard errors).
fn output(r: &Run, name: &str) -> (Vec<f64>, Vec<f64>) {
    let layout = r.exp.output_layout();
    let o = layout.registry.get(name).unwrap_or_else(|| panic!("no output {name}"));
    o.values(r.out.estimates.mean(), &r.out.estimates.stderr())
}

/// The fixture without its acquisition (a steady run refuses one).
fn without_acquisition() -> String {
    let (head, _) = FIXTURE.split_once("[detectors.ldh.acquisition]").expect("an acquisition");
    head.to_string()
}

/// Window `m` of an acquisition run against a steady run frozen at the window's centre time (the
/// same seed, so the same paths: the harmonics are bookkeeping of the velocities each path met,
/// exact to rounding; the windows' band powers come from the tabulated kernel, within 10⁻⁸ of the
/// exact one, and their ROI spectra from drawn slots instead of the integrated lines of the
/// vessel's Brownian broadening: a χ² in the windows' errors, which hold the draws'). The same
/// paths read at systole and in diastole differ (the flow does pulse here).
#[test]
fn each_window_equals_the_steady_run_frozen_at_its_time() {
    let off = ["run.control_variate=\"off\"", "run.importance=\"off\"", "run.samples=200000"];
    let one = run(&format!("{FIXTURE}{}", probe(true)), &off);
    let acq = one.exp.detectors[0].ldh().and_then(|l| l.acquisition.clone()).expect("an acquisition");
    let windows = acq.times.len();
    assert_eq!(windows, 9);
    let (plus, minus) = (output(&one, "camera.m0_plus_windows"), output(&one, "camera.m0_minus_windows"));
    let (roi_plus, _) = output(&one, "camera.roi_vessel.m0_plus_windows");
    let (roi_spectra, roi_spectra_err) = output(&one, "camera.roi_vessel.spectrum_windows");
    let bins = roi_spectra.len() / windows;
    let probe_acq = one.exp.detectors[1].surface().and_then(|s| s.spectrum()).and_then(|s| s.acquisition.clone());
    let probe_times = probe_acq.expect("the probe's acquisition").times;
    assert_eq!(probe_times.len(), 9);
    let (probe_windows, probe_errors) = output(&one, "probe.spectrum_windows");
    let mut frozen_roi = Vec::new();
    // The first window (late diastole), the systolic one (the arterial peak at 12 % of the
    // cycle, 0.10 s) and one in diastole.
    for m in [0, 1, 5] {
        let t = format!("cardiac.frozen_at_s={:e}", acq.times[m]);
        let frozen = run(&format!("{}{}", without_acquisition(), probe(false)), &[off[0], off[1], off[2], &t]);
        for (name, series) in [("camera.m0_plus", &plus), ("camera.m0_minus", &minus)] {
            let (f, _) = output(&frozen, name);
            let scale = f.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let worst = f.iter().enumerate().map(|(p, v)| (series.0[p * windows + m] - v).abs()).fold(0.0, f64::max);
            eprintln!(
                "window {m} (t = {:.4} s), {name}: largest difference {:.2e} of the image's largest value",
                acq.times[m],
                worst / scale
            );
            assert!(scale > 0.0 && worst <= 1e-6 * scale, "window {m}, {name}: {worst:e} against {scale:e}");
        }
        let (spectra, errs) = output(&frozen, "camera.roi_vessel.spectrum");
        // The total channel against the window's spectrum (drawn slots against integrated lines).
        let row = m * bins..(m + 1) * bins;
        let (stat, dof, p) =
            chi2_difference((&roi_spectra[row.clone()], &roi_spectra_err[row]), (&spectra[..bins], &errs[..bins]));
        eprintln!("window {m}: ROI spectrum χ² = {stat:.1} over {dof} bins (p = {p:.2e})");
        assert!(dof >= 20 && p > 1e-4, "window {m}: ROI spectrum χ² = {stat:.1} over {dof} bins");
        // The point detector's window m (centred at 10 ms + m·100 ms) against a run frozen then.
        let t_probe = format!("cardiac.frozen_at_s={:e}", probe_times[m]);
        let frozen_probe =
            run(&format!("{}{}", without_acquisition(), probe(false)), &[off[0], off[1], off[2], &t_probe]);
        let (ps, _) = output(&frozen_probe, "probe.spectrum");
        let pb = ps.len();
        let scale = ps.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let worst = (0..pb).map(|k| (probe_windows[m * pb + k] - ps[k]).abs()).fold(0.0, f64::max);
        eprintln!("window {m}: point detector's spectrum, largest difference {:.2e} of its peak", worst / scale);
        assert!(scale > 0.0 && worst <= 1e-9 * scale, "window {m}: point spectrum {worst:e} against {scale:e}");
        assert!(probe_errors[m * pb..(m + 1) * pb].iter().any(|e| *e > 0.0));
        let (v, e) = output(&frozen, "camera.roi_vessel.m0_plus");
        assert!((roi_plus[m] - v[0]).abs() <= 1e-6 * v[0].abs(), "window {m}: ROI M0+ {} vs {}", roi_plus[m], v[0]);
        assert!(e[0] > 0.0);
        frozen_roi.push(v[0]);
    }
    let (first, systole, diastole) = (frozen_roi[0], frozen_roi[1], frozen_roi[2]);
    eprintln!("ROI M0+ of the same paths: first window {first:e}, systole {systole:e}, diastole {diastole:e}");
    for other in [first, diastole] {
        assert!((systole - other).abs() > 0.2 * systole, "the flow should pulse: {frozen_roi:?}");
    }
}

/// A waveform without harmonics (`s ≡ 1`) is the steady flow: the run is the steady scene's
/// byte for byte (the same walk; the layered control variate applies to both).
#[test]
fn a_steady_waveform_reproduces_the_steady_run() {
    let text = without_acquisition();
    let steady_waves = text
        .replace("shape = \"artery\"", "fourier = [[0, 0], [0, 0]]")
        .replace("shape = \"choroid\"", "fourier = [[0, 0]]");
    let (head, _) = text.split_once("[cardiac]").expect("a [cardiac] section");
    let tail = &text[text.find("[[detectors]]").expect("detectors")..];
    let plain = format!("{head}{tail}")
        .replace(", waveform = \"artery\", womersley = true", "")
        .replace(", waveform = \"bed\"", "");
    let (a, b) = (run(&steady_waves, &[]), run(&plain, &[]));
    assert!(a.exp.scene.cycle.is_none());
    assert_eq!(a.out.estimates.mean(), b.out.estimates.mean());
    assert_eq!(a.out.estimates.stderr(), b.out.estimates.stderr());
}
