//! Detectors and the tally a finished path is recorded into.
//!
//! All per-batch numbers live in one flat `Vec<f64>` whose layout ([`TallyLayout`]) is fixed by
//! the configuration, so batch statistics treat every estimate — scalars, spectrum bins, pixels —
//! the same way. Scalars come first ([`Scalar`]), then each detector's block: its detected power,
//! then a surface detector's parts in order ([`part`]: spectra, image, time, correlation, LDH) or
//! a lidar receiver's tallies. Each part declares its named outputs in the
//! [`crate::output::Registry`] as it lays them out ([`TallyLayout::new`]).

pub mod correlation;
pub mod image;
pub mod importance;
pub mod ldh;
pub mod lidar;
pub mod part;
pub mod spectrum;
pub mod tail;
pub mod time;
pub mod twin;
pub mod volume;

use glam::DVec3;

pub use correlation::{CorrelationLayout, CorrelationSpec};
pub use image::ImageSpec;
pub use ldh::{Detection, LdhLayout, LdhOptions, LdhSpec, RecordedLine, Roi, RoiLayout, SpeckleSpec};
pub use lidar::{Echo, LidarLayout, LidarSpec};
pub use part::{Part, Placed};
pub use spectrum::{SpectrumLayout, SpectrumSpec};
pub use time::{TimeLayout, TimeSpec};

use crate::SPEED_OF_LIGHT;
use crate::output::{Axis, Kind, Output, Registry, Slots};
use crate::stats::RunStats;

/// Which surface of the stack a detector watches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The `z = 0` surface (reflection).
    Top,
    /// Below the last finite layer (transmission).
    Bottom,
}

/// The sensitive area of a detector, in its plane (x, y in m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Area {
    /// The whole plane.
    All,
    Disk {
        center: [f64; 2],
        radius: f64,
    },
    Rect {
        min: [f64; 2],
        max: [f64; 2],
    },
    /// The ring `inner ≤ r ≤ outer` about `center`: a fibre ring at a source–detector separation
    /// (every point at the same distance from a beam at the centre, so a diffuse measurement
    /// collects all of them at once).
    Annulus {
        center: [f64; 2],
        inner: f64,
        outer: f64,
    },
}

impl Area {
    #[inline]
    pub fn contains(&self, x: f64, y: f64) -> bool {
        match *self {
            Area::All => true,
            Area::Disk { center, radius } => {
                let (dx, dy) = (x - center[0], y - center[1]);
                dx * dx + dy * dy <= radius * radius
            }
            Area::Rect { min, max } => min[0] <= x && x < max[0] && min[1] <= y && y < max[1],
            Area::Annulus { center, inner, outer } => {
                let (dx, dy) = (x - center[0], y - center[1]);
                let r2 = dx * dx + dy * dy;
                inner * inner <= r2 && r2 <= outer * outer
            }
        }
    }

    /// The distance (m) from (`x`, `y`) to the area: 0 over it.
    pub fn distance(&self, x: f64, y: f64) -> f64 {
        match *self {
            Area::All => 0.0,
            Area::Disk { center, radius } => ((x - center[0]).hypot(y - center[1]) - radius).max(0.0),
            Area::Rect { min, max } => {
                let dx = (min[0] - x).max(x - max[0]).max(0.0);
                let dy = (min[1] - y).max(y - max[1]).max(0.0);
                dx.hypot(dy)
            }
            Area::Annulus { center, inner, outer } => {
                let r = (x - center[0]).hypot(y - center[1]);
                (inner - r).max(r - outer).max(0.0)
            }
        }
    }

    /// Bounding rectangle (`None` for the whole plane).
    pub fn bounds(&self) -> Option<([f64; 2], [f64; 2])> {
        match *self {
            Area::All => None,
            Area::Disk { center, radius } => {
                Some(([center[0] - radius, center[1] - radius], [center[0] + radius, center[1] + radius]))
            }
            Area::Rect { min, max } => Some((min, max)),
            Area::Annulus { center, outer, .. } => {
                Some(([center[0] - outer, center[1] - outer], [center[0] + outer, center[1] + outer]))
            }
        }
    }
}

/// A detector: what the run records into its named outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct Detector {
    pub name: String,
    pub kind: DetectorKind,
}

/// The kinds of detector.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectorKind {
    /// A planar area parallel to the surface, with an angular acceptance: power, spectra, an
    /// image and, on a camera, LDH maps.
    Surface(Surface),
    /// A pulsed lidar receiver at the transceiver, scored only by its local estimate.
    Lidar(LidarSpec),
}

/// A planar detector parallel to the surface, with an angular acceptance.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    pub side: Side,
    /// Distance of the detector plane from its surface, m (outward, ≥ 0).
    pub distance: f64,
    pub area: Area,
    /// Unit vector: paths travelling within the acceptance cone about it are accepted.
    pub axis: DVec3,
    /// The receiver of a monostatic transceiver: `axis` is the reverse of the source's
    /// direction, and turns with it ([`crate::experiment::Experiment::pointed`]).
    pub monostatic: bool,
    /// Cosine of the acceptance half-angle.
    pub cos_acceptance: f64,
    /// Whether the specular reflection of the laser at the top surface is recorded.
    pub include_specular: bool,
    /// What it records, in the order declared ([`part`]): at most one part of each kind, and a
    /// part laid out on pixels after the image.
    pub parts: Vec<Part>,
    /// Scored by next-event estimation from every scattering vertex (a top detector with a
    /// narrow cone) rather than by the paths that happen to leave into its cone.
    pub next_event: bool,
    /// How its light is to be estimated, as configured (`estimator = "…"`). What a run uses is
    /// [`Surface::estimator`], never this: a run applies the pilot's decision of `"auto"`
    /// ([`crate::experiment::Experiment::decided`]).
    pub choice: EstimatorChoice,
    /// With `estimator = "footprints"`: the pixels whose light camera paths estimate
    /// ([`image::Footprints`]).
    pub footprints: Option<std::sync::Arc<image::Footprints>>,
}

/// The pilot's figures for `estimator = "auto"` ([`crate::pilot`]): the mean per-pixel relative
/// variance of the detector's main image × the work (collision steps) of a run by each estimator;
/// the lower is chosen ([`AutoChoice::chosen`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AutoChoice {
    pub forward: f64,
    pub camera: f64,
}

impl AutoChoice {
    /// The estimator these figures choose: camera-side where it is strictly cheaper, forward
    /// otherwise (a tie, or figures that are not numbers).
    pub fn chosen(self) -> Estimator {
        if self.camera < self.forward { Estimator::Camera } else { Estimator::Forward }
    }
}

/// The estimator a run uses for a surface detector's scattered light: decided, never "auto"
/// ([`Surface::estimator`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// The paths from the laser: their escapes into the cone and, with `next_event`, their
    /// shadow rays.
    Forward,
    /// Paths from the camera's pixels, connected to the laser at every scattering vertex.
    Camera,
    /// Camera paths from the pixels of the regions' footprints (and the ROIs,
    /// [`image::Footprints`]), the forward paths everywhere else.
    Footprints,
}

impl Estimator {
    /// The name in the configuration and the manifest.
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Forward => "forward",
            Estimator::Camera => "camera",
            Estimator::Footprints => "footprints",
        }
    }

    /// Whether forward paths score the detector (everywhere, or outside the footprints).
    pub fn forward(self) -> bool {
        self != Estimator::Camera
    }
}

/// A surface detector's configured estimator (`estimator = "forward" | "camera" | "footprints" |
/// "auto"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimatorChoice {
    Forward,
    Camera,
    Footprints,
    /// Either, whichever a pilot finds lower in variance × work ([`crate::pilot`]).
    Auto,
}

impl Surface {
    /// Solid angle of the acceptance cone, sr.
    pub fn solid_angle(&self) -> f64 {
        cone_solid_angle(self.cos_acceptance)
    }

    /// The estimator a run uses: the configured one — a run with a pilot's decision of
    /// `"auto"` has it applied here ([`crate::experiment::Experiment::decided`]) — and forward for
    /// an undecided `"auto"`, so that every reader (the paths traced, their weights, the
    /// manifest) sees one estimator.
    #[inline]
    pub fn estimator(&self) -> Estimator {
        match self.choice {
            EstimatorChoice::Forward | EstimatorChoice::Auto => Estimator::Forward,
            EstimatorChoice::Camera => Estimator::Camera,
            EstimatorChoice::Footprints => Estimator::Footprints,
        }
    }

    /// Scored by next-event estimation: shadow rays are traced to it, and the forward paths'
    /// escapes into its cone are weighted against them (a camera-estimated detector never is).
    #[inline]
    pub fn scored_by_next_event(&self) -> bool {
        self.next_event && self.estimator().forward()
    }

    /// Whether forward paths leave pixel `pixel` of the image (if any) to camera paths.
    #[inline]
    pub fn camera_pixel(&self, pixel: Option<usize>) -> bool {
        match (&self.footprints, pixel) {
            (Some(f), Some(p)) => f.mask[p],
            _ => false,
        }
    }
}

impl Detector {
    /// The planar detector, if this is one.
    pub fn surface(&self) -> Option<&Surface> {
        match &self.kind {
            DetectorKind::Surface(s) => Some(s),
            DetectorKind::Lidar(_) => None,
        }
    }

    /// The lidar receiver, if this is one.
    pub fn lidar(&self) -> Option<&LidarSpec> {
        match &self.kind {
            DetectorKind::Lidar(l) => Some(l),
            DetectorKind::Surface(_) => None,
        }
    }

    /// The LDH camera, if this is one.
    pub fn ldh(&self) -> Option<&LdhSpec> {
        self.surface()?.ldh()
    }

    /// Scored by next-event estimation (a lidar receiver always is; a camera-estimated detector
    /// never is).
    pub fn next_event(&self) -> bool {
        match &self.kind {
            DetectorKind::Surface(s) => s.scored_by_next_event(),
            DetectorKind::Lidar(_) => true,
        }
    }

    /// The surface it watches (a lidar receiver sits above the top surface).
    pub fn side(&self) -> Side {
        self.surface().map_or(Side::Top, |s| s.side)
    }
}

/// Solid angle (sr) of a cone of half-angle `α`, given `cos α`: `2π(1 − cos α)`.
pub fn cone_solid_angle(cos_acceptance: f64) -> f64 {
    std::f64::consts::TAU * (1.0 - cos_acceptance)
}

/// Global scalar tallies, in their slots at the start of the tally vector.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(usize)]
pub enum Scalar {
    ReflectanceSpecular = 0,
    ReflectanceDiffuse = 1,
    TransmittanceTotal = 2,
    TransmittanceUnscattered = 3,
    AbsorbedFraction = 4,
}

impl Scalar {
    pub const ALL: [Scalar; 5] = [
        Scalar::ReflectanceSpecular,
        Scalar::ReflectanceDiffuse,
        Scalar::TransmittanceTotal,
        Scalar::TransmittanceUnscattered,
        Scalar::AbsorbedFraction,
    ];

    /// Name in the manifest's `estimates` (part of the scripting interface).
    pub fn name(self) -> &'static str {
        match self {
            Scalar::ReflectanceSpecular => "reflectance_specular",
            Scalar::ReflectanceDiffuse => "reflectance_diffuse",
            Scalar::TransmittanceTotal => "transmittance_total",
            Scalar::TransmittanceUnscattered => "transmittance_unscattered",
            Scalar::AbsorbedFraction => "absorbed_fraction",
        }
    }
}

/// Name of the scalar output of a box phantom (`[lateral]`): the fraction of the emitted power
/// that leaves through its side faces.
pub const LATERAL_SCALAR: &str = "transmittance_lateral";

/// How beat frequencies are computed from `l` and `dl/dt`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeatModel {
    /// `1/λ0`, m⁻¹.
    pub inv_wavelength: f64,
    /// `α/c = B/(T c)` for FMCW (Hz per metre of optical path), `None` for a single frequency.
    pub chirp_per_metre: Option<f64>,
}

impl BeatModel {
    pub fn new(wavelength: f64, chirp_slope: Option<f64>) -> Self {
        BeatModel { inv_wavelength: 1.0 / wavelength, chirp_per_metre: chirp_slope.map(|a| a / SPEED_OF_LIGHT) }
    }

    /// Lorentzian half-width at half maximum (Hz) of a path's line from its Brownian sum
    /// `b = Σ D_k n_k² |Δ_k|²`: the field correlation decays as `exp(−Σ D_k q_k² τ)` with
    /// `q_k = (2π/λ0) n_k |Δ_k|`, a Lorentzian of half-width `Σ D_k q_k² / 2π = 2π b/λ0²`
    /// (validation-values §4.10; Berne & Pecora 1976).
    #[inline(always)]
    pub fn brownian_hwhm(&self, b: f64) -> f64 {
        std::f64::consts::TAU * b * self.inv_wavelength * self.inv_wavelength
    }

    /// Number of spectra per detector: 1, or 2 (up, down) with a chirp.
    pub fn chirps(&self) -> usize {
        if self.chirp_per_metre.is_some() { 2 } else { 1 }
    }

    /// Beat frequency of chirp `c` (0 = up or single frequency, 1 = down).
    #[inline(always)]
    pub fn frequency(&self, chirp: usize, l: f64, dldt: f64) -> f64 {
        let doppler = dldt * self.inv_wavelength;
        match self.chirp_per_metre {
            None => doppler,
            Some(k) => {
                if chirp == 0 {
                    k * l + doppler
                } else {
                    k * l - doppler
                }
            }
        }
    }
}

/// The tally vector of an experiment: its [`Registry`] of named outputs, and the offsets each
/// detector records into (the same slots, in the form the recording code reads fastest).
#[derive(Debug, Clone, PartialEq)]
pub struct TallyLayout {
    pub registry: Registry,
    pub detectors: Vec<DetectorLayout>,
    /// The slot of `transmittance_lateral` (the weight leaving a box phantom through its side
    /// faces), declared only with `[lateral]` ([`TallyLayout::declare_lateral`]).
    pub lateral: Option<usize>,
    /// The sums of an importance pilot ([`importance`]; only in the pilot's own run,
    /// [`crate::experiment::Experiment::importance_table`]).
    pub importance: Option<importance::ImportanceLayout>,
    /// The slots of the `[volume]` grid's outputs ([`volume::VolumeGrid::declare`]; `None`
    /// without one).
    pub volume: Option<volume::VolumeSlots>,
}

/// Offsets of one detector's block.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorLayout {
    pub power: usize,
    /// Where each of its parts' tallies lie, in the order of its parts ([`Surface::parts`]).
    pub parts: Vec<Placed>,
    pub lidar: Option<LidarLayout>,
    /// Its layered control variate's kernels ([`twin`]; a forward-estimated camera in a scene of
    /// layers and regions, `run.control_variate`). Outside the tally vector: a batch's kernels
    /// are convolved into its images when it ends ([`TallyLayout::convolve_twins`]).
    pub twin: Option<twin::TwinLayout>,
    /// The histograms of its paths' scores into the regions' footprints ([`tail`]; a camera
    /// whose image sees regions). Declared after every other tally
    /// ([`TallyLayout::declare_tails`]).
    pub tail: Option<tail::TailLayout>,
}

impl TallyLayout {
    /// Lay out the scalar tallies, then each detector's block, declaring every output.
    pub fn new(detectors: &[Detector], beat: &BeatModel) -> Self {
        let mut reg = Registry::default();
        for s in Scalar::ALL {
            let slot = reg.take(1);
            debug_assert_eq!(slot, s as usize);
            reg.declare(Output {
                file: format!("/estimates/{}/value", s.name()),
                primary: true,
                ..Output::new(s.name().to_string(), Kind::Scalar, Slots::contiguous(slot, 1), Vec::new())
            });
        }
        let layouts = detectors.iter().enumerate().map(|(i, d)| d.declare(i, beat, &mut reg)).collect();
        TallyLayout { registry: reg, detectors: layouts, lateral: None, importance: None, volume: None }
    }

    /// The run's main output, whose error `ohd run --target-error` controls and the progress bar
    /// shows: the first detector's LDH M0+ image, else its lidar range–Doppler spectra, else its
    /// (up-chirp) total spectrum, else its image, else its power; without detectors the diffuse
    /// reflectance. Never g1, g2 or K: their values and σ exist only once the run's batches are
    /// all in ([`TallyLayout::finish_run`]), while this error is read off the batches as they
    /// come; a correlation detector's power is what their noise follows.
    pub fn main(&self) -> &Output {
        let slot = self.detectors.first().map_or(Scalar::ReflectanceDiffuse as usize, |d| {
            (d.ldh().map(|l| l.m0_plus))
                .or(d.lidar.as_ref().map(|l| l.spectra))
                .or(d.spectrum().map(|s| s.start))
                .or(d.image())
                .unwrap_or(d.power)
        });
        self.registry.at(slot)
    }

    /// Give every camera with a control variate (a forward-estimated top detector with an image
    /// over its whole rectangular area, and the footprint `fp`) its twin kernels.
    pub fn declare_twins(&mut self, detectors: &[Detector], fp: crate::source::Footprint) {
        for (d, lay) in detectors.iter().zip(&mut self.detectors) {
            if let Some(im) = twin_camera(d) {
                let mut blocks: Vec<usize> = lay.image().into_iter().collect();
                blocks.extend(lay.ldh().map_or(&[][..], |l| &l.blocks[..]));
                let skip = d.surface().and_then(|s| s.footprints.clone());
                let mut twin = twin::TwinLayout::new(im, fp, blocks);
                twin.skip = skip;
                lay.twin = Some(twin);
            }
        }
    }

    /// Empty kernels for one batch, one per detector.
    pub fn twin_kernels(&self) -> Vec<Vec<f64>> {
        self.detectors.iter().map(|d| d.twin.as_ref().map_or(Vec::new(), |t| vec![0.0; t.kernel_len()])).collect()
    }

    /// Convolve a finished batch's twin kernels into its images ([`twin`]).
    pub fn convolve_twins(&self, kernels: &[Vec<f64>], sums: &mut [f64]) {
        for (lay, k) in self.detectors.iter().zip(kernels) {
            if let Some(t) = &lay.twin {
                t.convolve(k, sums);
            }
        }
    }

    /// Declare the scalar `transmittance_lateral` of a box phantom in the next slot.
    pub fn declare_lateral(&mut self) {
        let slot = self.registry.take(1);
        let name = LATERAL_SCALAR;
        self.registry.declare(Output {
            file: format!("/estimates/{name}/value"),
            primary: true,
            ..Output::new(name.to_string(), Kind::Scalar, Slots::contiguous(slot, 1), Vec::new())
        });
        self.lateral = Some(slot);
    }

    /// Give every camera whose image sees regions (`mask_of` its image: the mask of their
    /// footprints, [`image::region_mask`]) the histograms of its paths' scores there ([`tail`]).
    pub fn declare_tails(&mut self, detectors: &[Detector], mask_of: impl Fn(&ImageSpec) -> Option<Vec<bool>>) {
        for (i, (d, lay)) in detectors.iter().zip(&mut self.detectors).enumerate() {
            let Some(mask) = d.surface().and_then(|s| s.image()).and_then(&mask_of) else { continue };
            let images = [lay.image(), lay.ldh().map(|l| l.m0_plus)];
            lay.tail = Some(tail::TailLayout::declare(i, &d.name, mask, images, &mut self.registry));
        }
    }

    /// Empty per-path scores for one batch, one per detector (none if no detector has a
    /// [`tail`] check).
    pub fn tail_scores(&self) -> Vec<[f64; tail::CHANNELS]> {
        let any = self.detectors.iter().any(|d| d.tail.is_some());
        if any { vec![[0.0; tail::CHANNELS]; self.detectors.len()] } else { Vec::new() }
    }

    /// Length of the tally vector.
    pub fn tallies(&self) -> usize {
        self.registry.len
    }

    /// Derive a finished batch's non-linear-in-layout outputs from its sums (the lidar gate
    /// spectra from their lag sums), so that they get batch statistics like everything else, and
    /// file its correlation sums under the group of batch number `batch` (the jackknife of
    /// [`finish_run`](Self::finish_run)).
    pub fn finish_batch(&self, detectors: &[Detector], sums: &mut [f64], batch: u64) {
        for (d, lay) in detectors.iter().zip(&self.detectors) {
            if let (Some(spec), Some(ll)) = (d.lidar(), &lay.lidar) {
                spec.finish_batch(ll, sums);
            }
        }
        for (placed, power) in self.parts() {
            placed.finish_batch(sums, power, batch);
        }
        self.registry.finish_batch(sums, batch);
    }

    /// Replace the run-level values of outputs that are non-linear in the tallies by the same
    /// function of the run's means (g1, g2 and K from the correlation sums), with their
    /// jackknife standard errors over groups of batches. Applied once, when a run's batches are
    /// all folded in ([`crate::experiment::Experiment::finish`]), whatever the threads, shards or
    /// resumes.
    pub fn finish_run(&self, estimates: &mut crate::stats::BatchAccumulator) {
        for (placed, power) in self.parts() {
            placed.finish_run(estimates, power);
        }
        self.registry.finish_run(estimates);
    }

    /// Every part of every surface detector, with its detector's power slot.
    pub fn parts(&self) -> impl Iterator<Item = (&Placed, usize)> {
        self.detectors.iter().flat_map(|lay| lay.parts.iter().map(move |p| (p, lay.power)))
    }
}

/// The image of `d` if the layered control variate can cover it ([`twin`]): a forward-estimated
/// top detector whose image spans exactly its rectangular area (a pixel is then on the area
/// wherever it lies, which the twin's shifted contributions need).
pub fn twin_camera(d: &Detector) -> Option<&ImageSpec> {
    let s = d.surface()?;
    let im = s.image()?;
    let fits = matches!(s.area, Area::Rect { min, max } if min == im.min && max == im.max);
    (s.side == Side::Top && s.estimator().forward() && fits).then_some(im)
}

/// An output of detector `i` with [`Output::new`]'s defaults, for struct update syntax.
pub(crate) fn detector_output(i: usize, name: String, kind: Kind, slots: Slots, shape: Vec<usize>) -> Output {
    Output { detector: Some(i), ..Output::new(name, kind, slots, shape) }
}

/// Detector `i`'s output `name`: a `[layers][row][col]` stack of its image `im`, contiguous from
/// slot `start` (time-gated images, per-pixel speckle contrast).
pub(crate) fn image_stack_output(i: usize, name: String, im: &ImageSpec, layers: usize, start: usize) -> Output {
    detector_output(
        i,
        name,
        Kind::ImageStack { layers, nx: im.nx, ny: im.ny, min: im.min, max: im.max },
        Slots::contiguous(start, layers * im.nx * im.ny),
        vec![layers, im.ny, im.nx],
    )
}

impl Output {
    /// A stack ([`Kind::ImageStack`]) whose layers run along `layer` (its time or exposure axis).
    pub(crate) fn layered(mut self, layer: Axis) -> Self {
        if let Some(a) = self.axes.first_mut() {
            *a = layer;
        }
        self
    }
}

impl Detector {
    /// Lay out detector `i`'s tallies from `reg`'s end and declare its outputs.
    fn declare(&self, i: usize, beat: &BeatModel, reg: &mut Registry) -> DetectorLayout {
        let power = reg.take(1);
        reg.declare(Output {
            file: format!("/estimates/detectors/{}/detected_power/value", self.name),
            primary: true,
            ..detector_output(
                i,
                format!("{}.detected_power", self.name),
                Kind::Scalar,
                Slots::contiguous(power, 1),
                vec![],
            )
        });
        let mut lay = DetectorLayout { power, parts: Vec::new(), lidar: None, twin: None, tail: None };
        match &self.kind {
            DetectorKind::Surface(s) => {
                let at = Place { i, name: &self.name, image: s.image(), beat };
                lay.parts = s.parts.iter().map(|p| p.declare(&at, reg)).collect();
            }
            DetectorKind::Lidar(l) => lay.lidar = Some(l.declare(i, &self.name, reg)),
        }
        lay
    }
}

/// The state a path carries between events, and what it hands to the detectors when it leaves
/// the stack, sends a shadow ray or connects a camera path to the laser.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathState {
    pub pos: DVec3,
    /// Propagation direction (in the ambient medium, once it has left the stack).
    pub dir: DVec3,
    pub weight: f64,
    /// Optical path length from the emission point, m (only tracked when needed).
    pub l: f64,
    /// Rate of change of the optical path length, m/s.
    pub dldt: f64,
    /// Real scattering events so far.
    pub order: u32,
    /// Scattering events on moving particles so far.
    pub doppler_events: u32,
    /// `Σ D_k n_k² |dir_in − dir_out|²` over events on diffusing particles, m²/s; the Lorentzian
    /// half-width of the path's line is [`BeatModel::brownian_hwhm`] of it.
    pub brownian: f64,
}

impl PathState {
    /// A path at `pos` going along `dir` with `weight` and optical path length `l`, before any
    /// scattering event.
    #[inline(always)]
    pub fn new(pos: DVec3, dir: DVec3, weight: f64, l: f64) -> Self {
        PathState { pos, dir, weight, l, dldt: 0.0, order: 0, doppler_events: 0, brownian: 0.0 }
    }
}

/// Where a detector's parts are declared: its index and name, its pixel grid (if it has an
/// image) and the beat model.
#[derive(Debug, Clone, Copy)]
pub struct Place<'a> {
    pub i: usize,
    pub name: &'a str,
    pub image: Option<&'a ImageSpec>,
    pub beat: &'a BeatModel,
}

/// A path as the parts of a detector record it: arrived at `(x, y)` of the detector plane (in
/// image pixel `pixel`) with the optical path length `l` (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// The detector's index.
    pub detector: usize,
    pub x: f64,
    pub y: f64,
    pub pixel: Option<usize>,
    pub weight: f64,
    pub l: f64,
    /// m/s.
    pub dldt: f64,
    /// The Lorentzian half-width of its line, Hz ([`BeatModel::brownian_hwhm`]).
    pub gamma: f64,
    pub order: u32,
    pub doppler_events: u32,
}

/// What kind of escape a path's is, for the tallies ([`Recorder::escape`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// The laser's specular reflection at the top surface.
    Specular,
    /// Any other escape of the walk.
    Walked,
    /// An escape whose detectors' share is scored otherwise (the unscattered once-reflected
    /// escapes, with deterministic reflections, [`Recorder::reflection`]): the scalar tallies only.
    ScalarsOnly,
}

/// Which pixel a camera path scores into, where it starts, and the factor turning its
/// contributions into the batch's tally (see `transport::camera::start`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shot {
    pub detector: usize,
    pub pixel: usize,
    /// Its point on the detector plane, m.
    pub x: f64,
    pub y: f64,
    /// `A_pixel · Ω_cone · |cos θ0|` (the inverse density of the start, times the flux cosine)
    /// times the batch's weight of one path of this pixel.
    pub scale: f64,
}

/// Records paths into one batch's tally.
pub struct Recorder<'a> {
    pub detectors: &'a [Detector],
    pub layout: &'a TallyLayout,
    pub beat: BeatModel,
    pub acc: &'a mut [f64],
    pub stats: &'a mut RunStats,
    /// Paths detected in LDH regions of interest, kept when speckle is asked for (else `None`).
    pub lines: Option<&'a mut Vec<RecordedLine>>,
    /// Scratch space of one record: the lidar receiver's pulse samples, an acquisition's rates
    /// per window.
    pub scratch: Vec<f64>,
    /// This batch's twin kernels, one per detector (empty for those without a control variate).
    pub kernels: Vec<Vec<f64>>,
    /// The current path's scores into each detector's regions' footprints, per [`tail`]
    /// channel (empty without a tail check, [`TallyLayout::tail_scores`]): a tally's sums over
    /// one path, filed when it ends ([`Recorder::end_path`]).
    pub path_scores: Vec<[f64; tail::CHANNELS]>,
    /// The current path's states and score, in an importance pilot ([`importance`]): the pilot's
    /// tally over one path, filed when it ends.
    pub trace: Option<importance::Trace>,
    /// While camera paths are recorded: the stream their broadened lines' slots are drawn from
    /// (`FrequencyAxis::drawn_slot`; a camera path adds a line per connection, tens per path).
    pub line_draws: Option<crate::sampling::PathRng>,
    /// In a scene whose flows pulse: the harmonic Doppler components `F_k` of the contribution
    /// being recorded ([`crate::flow::pulse`]), set by the estimator before each record; empty
    /// otherwise.
    pub pulse: Vec<num_complex::Complex64>,
    /// In a scene whose flows pulse: the stream the acquisition windows' broadened lines' slots
    /// are drawn from ([`ldh::LdhSpec::record_windows`]), one per batch.
    pub window_draws: Option<crate::sampling::PathRng>,
}

/// Where a path entered the stack (its layered twin's launch point, `TwinPath::launch`), m.
pub type Launch = (f64, f64);

/// What a contribution's layered twin scores ([`Recorder::escape`], [`Recorder::next_event`],
/// [`Recorder::reflection`]), with the launch point of the path carrying it (the twin kernels'
/// offsets are from it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Twin {
    /// No control variate for this path: the contribution alone.
    Off,
    /// The path's own state (`Λ = 1`, the same Doppler shift and transmittance): its share of the
    /// pixels cancels, it goes to the kernels only.
    Same(Launch),
    /// A state of its own.
    Other(PathState, Launch),
    /// The contribution is the twin's alone (its own walk after parting from its path): out of
    /// the covered pixels it meets, into the kernels; nothing else records it.
    Only(Launch),
}

impl Twin {
    /// The launch point of the path whose twin this is (`None`: no twin).
    #[inline]
    pub fn launch(&self) -> Option<Launch> {
        match *self {
            Twin::Off => None,
            Twin::Same(l) | Twin::Other(_, l) | Twin::Only(l) => Some(l),
        }
    }
}

impl Recorder<'_> {
    /// Add `v` to the current path's score in channel `c` of `hit`'s detector's [`tail`] check,
    /// if its pixel is in the regions' footprints.
    #[inline(always)]
    pub fn tail_score(&mut self, hit: &Hit, c: usize, v: f64) {
        if !self.path_scores.is_empty() {
            self.add_tail_score(hit, c, v);
        }
    }

    fn add_tail_score(&mut self, hit: &Hit, c: usize, v: f64) {
        if self.layout.detectors[hit.detector].tail.as_ref().is_some_and(|t| t.covers(hit.pixel)) {
            self.path_scores[hit.detector][c] += v;
        }
    }

    /// A path has ended: its scores into the [`tail`] histograms, its states' values into an
    /// importance pilot's sums.
    #[inline(always)]
    pub fn end_path(&mut self) {
        if !self.path_scores.is_empty() {
            self.file_path_scores();
        }
        if let (Some(t), Some(lay)) = (self.trace.as_mut(), &self.layout.importance) {
            t.end(lay, self.acc);
        }
    }

    /// A state of the path after a scattering event in layer `li`, for an importance pilot.
    #[inline(always)]
    pub fn scattered(&mut self, li: usize, s: &PathState) {
        if let (Some(t), Some(lay)) = (self.trace.as_mut(), &self.layout.importance) {
            t.state(lay, li, s.pos, s.dir.z, s.weight);
        }
    }

    /// Weight `w` detected by detector `i`: into its power (and an importance pilot's score).
    #[inline(always)]
    fn detected(&mut self, i: usize, w: f64) {
        self.acc[self.layout.detectors[i].power] += w;
        if let (Some(t), Some(lay)) = (self.trace.as_mut(), &self.layout.importance)
            && lay.detector == i
        {
            t.scored(w);
        }
    }

    fn file_path_scores(&mut self) {
        for (lay, s) in self.layout.detectors.iter().zip(&mut self.path_scores) {
            if let Some(t) = &lay.tail
                && *s != [0.0; tail::CHANNELS]
            {
                t.record(self.acc, *s);
            }
            *s = [0.0; tail::CHANNELS];
        }
    }

    #[inline(always)]
    pub fn add(&mut self, s: Scalar, w: f64) {
        self.acc[s as usize] += w;
    }

    /// A path leaving a box phantom through a side face with weight `w`.
    #[inline]
    pub fn lateral(&mut self, w: f64) {
        if let Some(i) = self.layout.lateral {
            self.acc[i] += w;
        }
    }

    /// A path leaving the stack through `side` into ambient index `n_ambient` (`exit`: what kind
    /// of escape, for the tallies), carrying its layered twin `twin` (`None`: none) and, for the
    /// balance against next-event estimation's shadow rays, `direct`: the density of its last
    /// direction at its last vertex over `n_k² |cos θ_k|` there (`transport::nee`), `None` for an
    /// escape that is no direct connection from a vertex (unscattered, or reflected at a smooth
    /// face since), which no shadow ray covers.
    ///
    /// Inlined into the walk: the scalar tallies are a few adds, and where the walk does not
    /// track `l` or `dl/dt` their finiteness checks fold away. The detectors are an outlined
    /// call made only if there are any (measured: ~60 → ~15 instructions per escape without
    /// detectors).
    #[inline(always)]
    pub fn escape(
        &mut self,
        side: Side,
        e: PathState,
        exit: Exit,
        n_ambient: f64,
        twin: Option<&twin::TwinPath>,
        direct: Option<f64>,
    ) {
        debug_assert!(e.weight >= 0.0 || e.weight.is_nan(), "a negative contribution {}", e.weight);
        if !(e.weight.is_finite() && e.dldt.is_finite() && e.l.is_finite()) {
            self.stats.non_finite += 1;
            return;
        }
        let specular = exit == Exit::Specular;
        if twin.is_some_and(|t| t.only) {
            // A twin's own walk: the detectors' kernels alone.
            let e = PathState { ..e };
            self.detect(side, &e, specular, n_ambient, twin, direct);
            return;
        }
        match (side, specular) {
            (Side::Top, true) => self.add(Scalar::ReflectanceSpecular, e.weight),
            (Side::Top, false) => self.add(Scalar::ReflectanceDiffuse, e.weight),
            (Side::Bottom, _) => {
                self.add(Scalar::TransmittanceTotal, e.weight);
                if e.order == 0 {
                    self.add(Scalar::TransmittanceUnscattered, e.weight);
                }
            }
        }
        if exit != Exit::ScalarsOnly && !self.detectors.is_empty() {
            // A copy made here: taking `&e` directly made LLVM build `e` on the stack before the
            // first test, for every path (13 stores; measured 182.8M → 177.8M instructions).
            let e = PathState { ..e };
            self.detect(side, &e, specular, n_ambient, twin, direct);
        }
    }

    /// The laser's unscattered reflection `e` at an interface below the surface, leaving through
    /// it into the ambient index `n_ambient`, scored deterministically into the detectors (the
    /// scalar tallies count the walk's own, [`Exit::ScalarsOnly`]).
    #[inline(never)]
    pub fn reflection(&mut self, e: &PathState, twin: Twin, n_ambient: f64) {
        debug_assert!(e.weight >= 0.0 || e.weight.is_nan(), "a negative contribution {}", e.weight);
        if !(e.weight.is_finite() && e.l.is_finite()) {
            self.stats.non_finite += 1;
            return;
        }
        self.detect_with(Side::Top, e, false, n_ambient, twin, None);
    }

    /// A shadow ray of next-event estimation reaching detector `i` (already in its cone), and
    /// what the path's layered twin scores along it.
    #[inline(never)]
    pub fn next_event(&mut self, i: usize, e: &PathState, twin: Twin, n_ambient: f64) {
        debug_assert!(e.weight >= 0.0 || e.weight.is_nan(), "a negative contribution {}", e.weight);
        if !(e.weight.is_finite() && e.dldt.is_finite() && e.l.is_finite()) {
            self.stats.non_finite += 1;
            return;
        }
        if let (DetectorKind::Lidar(spec), Some(ll)) = (&self.detectors[i].kind, &self.layout.detectors[i].lidar) {
            self.detected(i, e.weight);
            let f = self.beat.frequency(0, e.l, e.dldt);
            spec.record(
                ll,
                self.acc,
                &mut self.scratch,
                Echo { weight: e.weight, length: e.l, frequency: f, order: e.order },
            );
            return;
        }
        self.detect_one(i, e, n_ambient, twin);
    }

    /// A camera path's connection `e` to the laser, scored into its pixel (`e.l` is the whole
    /// optical path length).
    #[inline(never)]
    pub fn camera(&mut self, shot: &Shot, e: &PathState) {
        if !(e.weight.is_finite() && e.dldt.is_finite() && e.l.is_finite()) {
            self.stats.non_finite += 1;
            return;
        }
        let i = shot.detector;
        if let DetectorKind::Surface(d) = &self.detectors[i].kind
            && d.footprints.is_some()
        {
            // (With the light field a camera path also scores its layered twin's light, negative.)
            let hit = self.hit(i, DVec3::new(shot.x, shot.y, 0.0), Some(shot.pixel), e.l, e);
            self.score_footprint(i, &hit);
            return;
        }
        debug_assert!(e.weight >= 0.0, "a negative contribution {}", e.weight);
        self.score(i, shot.x, shot.y, Some(shot.pixel), e.l, e);
    }

    /// The detectors' share of [`escape`](Self::escape) (a finite path); its twin is the path's
    /// [`twin::TwinPath`] state.
    #[inline(never)]
    fn detect(
        &mut self,
        side: Side,
        e: &PathState,
        specular: bool,
        n_ambient: f64,
        twin: Option<&twin::TwinPath>,
        direct: Option<f64>,
    ) {
        let twin = twin.map_or(Twin::Off, |t| t.share(e));
        self.detect_with(side, e, specular, n_ambient, twin, direct);
    }

    /// [`detect`](Self::detect) with the twin's contribution `twin`.
    fn detect_with(
        &mut self,
        side: Side,
        e: &PathState,
        specular: bool,
        n_ambient: f64,
        twin: Twin,
        direct: Option<f64>,
    ) {
        for (i, d) in self.detectors.iter().enumerate() {
            let DetectorKind::Surface(d) = &d.kind else { continue };
            if d.side != side
                || d.estimator() == Estimator::Camera
                || (specular && !d.include_specular)
                || e.dir.dot(d.axis) < d.cos_acceptance
            {
                continue;
            }
            if d.scored_by_next_event() {
                // A direct escape into a next-event detector's cone: the balance heuristic
                // against the shadow rays, which sample the same exit directions uniformly in
                // the cone (pdfs in exit solid angle: the phase function's, p·n0² cos θ0 /
                // (n_k² cos θ_k), and 1/Ω). Escapes after a smooth interface's reflection, and
                // unscattered ones, are not direct connections, which the shadow rays do not
                // cover: full weight (no `direct` density). A rough face's crossing is a vertex
                // of shadow rays, scattered or not.
                if let Some(q) = direct {
                    let p = q * n_ambient * n_ambient * e.dir.z.abs();
                    let w = p / (p + 1.0 / d.solid_angle());
                    let e = PathState { weight: e.weight * w, ..*e };
                    let twin = match twin {
                        Twin::Other(t, launch) => Twin::Other(PathState { weight: t.weight * w, ..t }, launch),
                        same_only_or_off => same_only_or_off,
                    };
                    self.detect_one(i, &e, n_ambient, twin);
                    continue;
                }
            }
            self.detect_one(i, e, n_ambient, twin);
        }
    }

    /// Record `e`, travelling in detector `i`'s cone, into it if it lands on its area; with a
    /// control variate, `twin`'s share too.
    fn detect_one(&mut self, i: usize, e: &PathState, n_ambient: f64, twin: Twin) {
        let (detectors, layout, beat) = (self.detectors, self.layout, self.beat);
        let DetectorKind::Surface(d) = &detectors[i].kind else { return };
        // Travel on to the detector plane.
        let dist = if d.distance > 0.0 { d.distance / e.dir.z.abs() } else { 0.0 };
        let p = e.pos + dist * e.dir;
        let l = e.l + n_ambient * dist;
        let pixel = || d.image().and_then(|im| im.pixel_at(p.x, p.y));
        let (Some(tl), Some(launch)) = (&layout.detectors[i].twin, twin.launch()) else {
            if d.area.contains(p.x, p.y) {
                let px = pixel();
                if d.camera_pixel(px) {
                    self.left_to_camera_paths(i, &self.hit(i, p, px, l, e));
                } else {
                    self.score(i, p.x, p.y, px, l, e);
                }
            }
            return;
        };
        let t = match twin {
            Twin::Other(t, _) => t,
            _ => *e,
        };
        let gamma = |b: f64| if b > 0.0 { beat.brownian_hwhm(b) } else { 0.0 };
        let hit = |s: &PathState, pixel: Option<usize>| Hit {
            detector: i,
            x: p.x,
            y: p.y,
            pixel,
            weight: s.weight,
            l,
            dldt: s.dldt,
            gamma: gamma(s.brownian),
            order: s.order,
            doppler_events: s.doppler_events,
        };
        let lay = &layout.detectors[i];
        let on_area = d.area.contains(p.x, p.y);
        let same = matches!(twin, Twin::Same(_));
        let px = if on_area { pixel() } else { None };
        // A camera pixel of `estimator = "footprints"`: the path's power and speckle records
        // only, its twin into the kernel only (whose convolution skips the camera pixels).
        let camera_px = d.camera_pixel(px);
        if camera_px && !matches!(twin, Twin::Only(_)) {
            self.left_to_camera_paths(i, &hit(e, px));
        } else if on_area && !matches!(twin, Twin::Only(_)) {
            // The path into every part (`Same`: its share of the covered parts cancels with its
            // twin's, the pixel spectra and speckle records keep it).
            let h = hit(e, px);
            self.detected(i, e.weight);
            for placed in &lay.parts {
                match (placed.varies(), same) {
                    (true, true) => placed.record_uncovered(self, &h),
                    _ => placed.record(self, &h),
                }
            }
        }
        // The twin into the kernels (wherever it met the plane: shifted, it may land on the area)
        // and the ROIs; out of the pixel and ROIs it met if it is not the path itself.
        let ht = hit(&t, px);
        let mut values = [0.0; 1 + ldh::MAX_BLOCKS];
        let mut n = 0;
        let (subtract, rois) = (on_area && !same && !camera_px, d.footprints.is_none());
        for placed in &lay.parts {
            n += placed.twin_values(self, &ht, launch, tl, subtract, rois, &mut values[n..]);
        }
        tl.record(&mut self.kernels[i], launch, (p.x, p.y), &values[..n]);
    }

    /// Record `e`, arrived at `(x, y)` of detector `i`'s plane (in image pixel `pixel`) with the
    /// optical path length `l`, into the detector's power and each of its parts.
    fn score(&mut self, i: usize, x: f64, y: f64, pixel: Option<usize>, l: f64, e: &PathState) {
        let hit = self.hit(i, DVec3::new(x, y, 0.0), pixel, l, e);
        self.detected(i, e.weight);
        for placed in &self.layout.detectors[i].parts {
            placed.record(self, &hit);
        }
    }

    /// `e`, arrived at `p` of detector `i`'s plane (in image pixel `pixel`) with the optical path
    /// length `l`, as its parts record it.
    fn hit(&self, i: usize, p: DVec3, pixel: Option<usize>, l: f64, e: &PathState) -> Hit {
        let gamma = if e.brownian > 0.0 { self.beat.brownian_hwhm(e.brownian) } else { 0.0 };
        Hit {
            detector: i,
            x: p.x,
            y: p.y,
            pixel,
            weight: e.weight,
            l,
            dldt: e.dldt,
            gamma,
            order: e.order,
            doppler_events: e.doppler_events,
        }
    }

    /// A forward path's `hit` on a camera pixel of `estimator = "footprints"`, whose light the
    /// camera paths estimate: into the detector's power (the forward paths' over the whole area)
    /// and the speckle records only.
    fn left_to_camera_paths(&mut self, i: usize, hit: &Hit) {
        self.detected(i, hit.weight);
        for placed in &self.layout.detectors[i].parts {
            placed.record_uncovered(self, hit);
        }
    }

    /// A camera path's connection `hit` into detector `i` with `estimator = "footprints"`: its
    /// pixel's maps and its ROIs (the power and the speckle records are the forward paths').
    fn score_footprint(&mut self, i: usize, hit: &Hit) {
        for placed in &self.layout.detectors[i].parts {
            placed.record_without_lines(self, hit);
        }
    }
}
