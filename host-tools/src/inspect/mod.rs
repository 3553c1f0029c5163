//! `dollop inspect`: measures a printed single-layer job from a top-view photo. The photo
//! is evened out and the print found (`photo`), registered to the job's footprint by its
//! outline (`register`), its materials told apart by colour (`classify`), and compared
//! with the design (`measure`): pattern error, boundary offsets along the path, bead
//! width. `picture` draws the result, `suggest` turns it into config corrections, `synth`
//! makes test photos from a simulated print. Slicing and simulating are other modules'.

pub mod classify;
pub mod design;
pub mod error;
pub mod frame;
pub mod markers;
pub mod measure;
pub mod photo;
pub mod picture;
pub mod register;
mod stages;
pub mod suggest;
pub mod synth;

pub use error::InspectError;

use design::Plan;
use dollop::Command;
use frame::DesignFrame;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// k-means runs from different seeds, the best kept (see `classify::kmeans_best`).
pub const KMEANS_RESTARTS: u64 = 4;

/// Spacing of the beads' sides read for the registration across the path, mm.
pub const EDGE_EVERY_MM: f64 = 0.1;

/// Photo pixels a millimetre under which the report warns that the pattern error reads
/// low. Measured on synthesized photos of a print whose slower valve thins the beads after
/// each switch (plant 4.51 %): 0.68 points low at 31.2 px/mm, 0.45 at 41.5.
pub const MIN_PX_PER_MM: f64 = 40.0;

/// How to inspect.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Resolution of the rectified design frame, px per mm.
    pub px_per_mm: f64,
    /// Largest photo, pixels.
    pub max_pixels: u64,
    /// Share of the paste seen in the design's area that the design cannot explain even
    /// with every boundary moved to where it was found, over which the photo is taken to
    /// show another job. (The plain pattern error cannot decide it: boundaries a millimetre
    /// late in 3 mm squares are wrong over a third of the area, two materials at random
    /// over half.)
    pub max_unexplained: f64,
    /// Register by the job's corner markers when the photo shows them (else, or when
    /// false, by the print's outline).
    pub use_markers: bool,
}

/// How the photo was registered to the design.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Registration {
    /// By the four corner markers.
    Markers,
    /// By the print's outline: the job has no markers.
    Outline,
    /// By the print's outline: the job has markers, but the photo does not show four
    /// regions that look like them.
    OutlineMarkersNotFound,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            px_per_mm: 40.0,
            max_pixels: photo::MAX_PIXELS,
            max_unexplained: 0.2,
            use_markers: true,
        }
    }
}

/// Offsets of one kind of switch (or all), mm.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OffsetStats {
    /// Boundaries measured.
    pub n: usize,
    /// Mean signed offset (positive: late).
    pub mean: f64,
    /// 95th percentile of |offset|.
    pub p95: f64,
    /// Largest |offset|.
    pub max: f64,
}

impl OffsetStats {
    fn of(v: &[f64]) -> Self {
        let abs: Vec<f64> = v.iter().map(|x| x.abs()).collect();
        OffsetStats {
            n: v.len(),
            mean: v.iter().sum::<f64>() / v.len().max(1) as f64,
            p95: measure::quantile(&abs, 0.95),
            max: abs.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// What the photo showed.
pub struct Inspection {
    /// The photo.
    pub path: PathBuf,
    /// The plan it was compared with.
    pub plan: Plan,
    /// The frame it was rectified into.
    pub frame: DesignFrame,
    /// Per frame pixel: the material the photo shows, or `PLATE`.
    pub seen: Vec<u8>,
    /// Per frame pixel: the design's material, or `PLATE`.
    pub design: Vec<u8>,
    /// The photo rectified, for pictures.
    pub rectified: image::RgbImage,
    /// The photo's corners of the print, px, and the quarter turn that fitted.
    pub corners: [[f64; 2]; 4],
    /// Quarter turns from the photo's corner order to the design's.
    pub turn: usize,
    /// What registered the photo.
    pub registration: Registration,
    /// Learned colour of each material (index into the plan's materials), 0..1 RGB.
    pub colours: Vec<(u8, [f32; 3])>,
    /// Share of the design's area showing the wrong material or none.
    pub pattern_error: f64,
    /// Share of the paste seen inside the design's area that shows another material than
    /// the design with every found boundary moved to where it was found: what offsets
    /// along the path do not explain.
    pub unexplained: f64,
    /// Boundaries found.
    pub found: Vec<measure::Found>,
    /// Bead width samples: (bead, s, width mm).
    pub widths: Vec<(usize, f64, f64)>,
    /// Each material's bead width away from its switches.
    pub width_by_material: Vec<measure::MaterialWidth>,
    /// How finely the photo shows the print: photo pixels per millimetre of the design
    /// (the square root of the print's area in the photo over the design's).
    pub photo_px_per_mm: f64,
    /// Per axis (x, y): the offsets of boundaries running along it share a shift that
    /// nothing in the photo measured (see `measure::Drift::unpinned`); never with markers.
    pub unpinned: [bool; 2],
}

impl Inspection {
    /// Offsets of all found boundaries.
    pub fn offsets(&self) -> OffsetStats {
        OffsetStats::of(&self.found.iter().map(|f| f.offset).collect::<Vec<_>>())
    }

    /// Offsets of each switch direction (from, to) present.
    pub fn offsets_by_switch(&self) -> Vec<((u8, u8), OffsetStats)> {
        let mut keys: Vec<(u8, u8)> = self
            .found
            .iter()
            .map(|f| {
                let b = self.plan.boundaries[f.index];
                (b.from, b.to)
            })
            .collect();
        keys.sort_unstable();
        keys.dedup();
        keys.into_iter()
            .map(|k| {
                let v: Vec<f64> = self
                    .found
                    .iter()
                    .filter(|f| {
                        let b = self.plan.boundaries[f.index];
                        (b.from, b.to) == k
                    })
                    .map(|f| f.offset)
                    .collect();
                (k, OffsetStats::of(&v))
            })
            .collect()
    }

    /// The report `dollop inspect` prints.
    pub fn report(&self, names: &[String]) -> String {
        let name = |m: u8| {
            names
                .get(m as usize)
                .cloned()
                .unwrap_or_else(|| format!("material {m}"))
        };
        let mut s = String::new();
        self.report_registration(&mut s, &name);
        self.report_boundaries(&mut s, &name);
        self.report_widths(&mut s, &name);
        s
    }

    /// Where the print was found, how it was registered, the photo's resolution and
    /// colours, and the pattern error.
    fn report_registration(&self, s: &mut String, name: &dyn Fn(u8) -> String) {
        let _ = writeln!(
            s,
            "print found: corners at ({:.0}, {:.0}) ({:.0}, {:.0}) ({:.0}, {:.0}) ({:.0}, {:.0}) px; {} quarter turn(s) to the design",
            self.corners[0][0], self.corners[0][1], self.corners[1][0], self.corners[1][1],
            self.corners[2][0], self.corners[2][1], self.corners[3][0], self.corners[3][1], self.turn
        );
        let _ = writeln!(
            s,
            "registered by     {}",
            match self.registration {
                Registration::Markers => "the four corner markers",
                Registration::Outline => "the print's outline (the job has no corner markers)",
                Registration::OutlineMarkersNotFound =>
                    "the print's outline (the job has corner markers, but the photo does not show four)",
            }
        );
        let _ = writeln!(
            s,
            "photo resolution  {:.1} px/mm over the print{}",
            self.photo_px_per_mm,
            if self.photo_px_per_mm < MIN_PX_PER_MM {
                format!(
                    " (under {MIN_PX_PER_MM:.0}: plate showing between beads in slivers under {:.3} mm wide is read as paste, so the pattern error reads low; photograph closer)",
                    1.0 / self.photo_px_per_mm
                )
            } else {
                String::new()
            }
        );
        for (m, c) in &self.colours {
            let _ = writeln!(
                s,
                "colour of {}: #{:02x}{:02x}{:02x}",
                name(*m),
                (c[0] * 255.0) as u8,
                (c[1] * 255.0) as u8,
                (c[2] * 255.0) as u8
            );
        }
        let _ = writeln!(
            s,
            "pattern error     {:.2} % of the design's area shows the wrong material or none ({:.2} % of the paste differs with the boundaries where they landed)",
            100.0 * self.pattern_error,
            100.0 * self.unexplained
        );
    }

    /// The boundaries found and their offsets along the path, per switch.
    fn report_boundaries(&self, s: &mut String, name: &dyn Fn(u8) -> String) {
        let all = self.offsets();
        if all.n == 0 {
            let _ = writeln!(s, "boundaries        none found");
        } else {
            let _ = writeln!(
                s,
                "boundaries        {} of {} found; offset along the path mean {:+.3} mm, p95 {:.3} mm, max {:.3} mm",
                all.n,
                self.plan.boundaries.len(),
                all.mean,
                all.p95,
                all.max
            );
            for (axis, _) in self.unpinned.iter().enumerate().filter(|u| *u.1) {
                let _ = writeln!(
                    s,
                    "  caution: every switch direction runs one way along {}, so a shift of the photo along it looks like the switches' own offsets and the print's outline is all that places it (its bead ends, a few hundredths of a millimetre); slice with --markers to measure it",
                    ["x", "y"][axis]
                );
            }
            for ((a, b), st) in self.offsets_by_switch() {
                let _ = writeln!(
                    s,
                    "  {} -> {}: {} boundaries, mean {:+.3} mm, p95 {:.3} mm, max {:.3} mm",
                    name(a),
                    name(b),
                    st.n,
                    st.mean,
                    st.p95,
                    st.max
                );
            }
        }
    }

    /// Bead widths: the spread, the narrowest and widest, the median per material.
    fn report_widths(&self, s: &mut String, name: &dyn Fn(u8) -> String) {
        let w: Vec<f64> = self.widths.iter().map(|x| x.2).collect();
        if !w.is_empty() {
            let cap = 1.5 * self.plan.pitch;
            let touching = w.iter().filter(|&&x| x >= cap - 1e-9).count();
            let _ = writeln!(
                s,
                "bead width        mean {:.3} mm, p1 {:.3} mm, p99 {:.3} mm over {} samples (pitch {:.2} mm; {} where neighbours touch)",
                w.iter().sum::<f64>() / w.len() as f64,
                measure::quantile(&w, 0.01),
                measure::quantile(&w, 0.99),
                w.len(),
                self.plan.pitch,
                touching
            );
            let narrowest = self.widths.iter().min_by(|a, b| a.2.total_cmp(&b.2));
            let widest = self
                .widths
                .iter()
                .filter(|w| w.2 < cap - 1e-9)
                .max_by(|a, b| a.2.total_cmp(&b.2));
            for (what, w) in [("narrowest", narrowest), ("widest", widest)] {
                if let Some(&(bi, s_mm, x)) = w {
                    let (p, _) = self.plan.beads[bi].at(s_mm);
                    let _ = writeln!(
                        s,
                        "  {what} {x:.3} mm at ({:.2}, {:.2}) mm{}",
                        p[0],
                        p[1],
                        if what == "widest" {
                            " (of those under 1.5 pitch)"
                        } else {
                            ""
                        }
                    );
                }
            }
            let shown = |m: &measure::MaterialWidth| {
                if m.median >= cap - 1e-9 {
                    format!("{}: touching ({} samples)", name(m.material), m.samples)
                } else {
                    format!(
                        "{}: {:.3} mm ({} samples)",
                        name(m.material),
                        m.median,
                        m.samples
                    )
                }
            };
            if !self.width_by_material.is_empty() {
                let _ = writeln!(
                    s,
                    "  away from switches, median: {}",
                    self.width_by_material
                        .iter()
                        .map(shown)
                        .collect::<Vec<_>>()
                        .join("; ")
                );
            }
        }
    }
}

/// Bead width and corner radius of the machine in `config` (validated by the caller).
pub fn geometry(config: &dollop::config::Config) -> (f64, f64) {
    let radius = config
        .validate::<f64, { dollop::config::MAX_CONFIG_INLETS }>()
        .map_or(0.0, |m| m.corner_radius);
    (config.channel.line_pitch_mm as f64, radius)
}

/// Inspects the photo at `path` against `commands` (starting at `start_um`) printed on
/// the machine of `config`.
pub fn inspect(
    path: &Path,
    commands: &[Command],
    start_um: [i32; 3],
    config: &dollop::config::Config,
    o: &Options,
) -> Result<Inspection, InspectError> {
    let photo = photo::load(path, o.max_pixels)?;
    inspect_photo(path, photo, commands, start_um, config, o)
}

/// The frame's margin around the design, mm: two pitches of plate, and wide enough that
/// the picture shows the whole print with its corner markers. What the markers add is a
/// whole number of pixels, so the design's own pixels sample the photo at the same points
/// with or without them.
fn frame_margin(plan: &design::Plan, px_per_mm: f64) -> f64 {
    let (lo, hi) = plan.extent();
    let reach = [
        plan.lo[0] - lo[0],
        plan.lo[1] - lo[1],
        hi[0] - plan.hi[0],
        hi[1] - plan.hi[1],
    ]
    .into_iter()
    .fold(0.0f64, f64::max);
    2.0 * plan.pitch + (reach * px_per_mm).ceil() / px_per_mm
}

/// The resolutions, px per mm, the rectified picture is drawn at: below 2 a bead is a
/// pixel or two, above 200 a print's frame outgrows memory.
pub const PX_PER_MM: std::ops::RangeInclusive<f64> = 2.0..=200.0;

/// `inspect` on a photo already loaded.
pub fn inspect_photo(
    path: &Path,
    photo: photo::Photo,
    commands: &[Command],
    start_um: [i32; 3],
    config: &dollop::config::Config,
    o: &Options,
) -> Result<Inspection, InspectError> {
    let (pitch, corner_radius) = geometry(config);
    if !(o.px_per_mm.is_finite() && PX_PER_MM.contains(&o.px_per_mm)) {
        return Err(InspectError::Resolution {
            px_per_mm: o.px_per_mm,
            min: *PX_PER_MM.start(),
            max: *PX_PER_MM.end(),
        });
    }
    let bad = |message: String| InspectError::Photo {
        path: path.to_path_buf(),
        message,
    };
    let plan = design::plan(commands, start_um, pitch, corner_radius);
    let k = plan.materials.len();
    if plan.beads.is_empty() || k == 0 {
        return Err(InspectError::Job {
            path: path.to_path_buf(),
            message: "the job prints nothing to compare the photo with".into(),
        });
    }
    let frame = DesignFrame {
        lo: plan.lo,
        hi: plan.hi,
        px_per_mm: o.px_per_mm,
        margin_mm: frame_margin(&plan, o.px_per_mm),
    };
    let (fw, fh) = frame.size();
    if u64::from(fw) * u64::from(fh) > 100_000_000 {
        return Err(InspectError::FrameTooLarge { w: fw, h: fh });
    }
    // Register -> classify -> refine -> measure (see `stages`).
    let at = stages::register(&photo, &plan, &frame, o.use_markers).ok_or_else(|| {
        bad("the print's outline is not a quadrilateral that can be registered; photograph the whole print from above".into())
    })?;
    let palette = stages::palette(&photo, k).map_err(bad)?;
    let design = measure::paint(&plan, &frame);
    let turned = stages::classify(&photo, &frame, at, &palette, &design, &plan.materials)
        .ok_or_else(|| bad("the print's corners do not define a perspective".into()))?;
    let turn = turned.turn;
    let stages::Refined {
        seen,
        rectified,
        found,
        residual,
        names,
    } = stages::refine(&photo, &plan, &frame, &design, &palette, at, turned);
    let pattern_error = measure::pattern_error(&design, &seen);
    let moved = measure::moved(&plan, &found);
    let unexplained = stages::unexplained(&moved, &frame, &seen);
    if unexplained > o.max_unexplained {
        return Err(bad(format!(
            "the print does not match the job: even with its boundaries where they were found, {:.0} % of the paste shows another material than the design (over {:.0} %); is this the photo of this job?",
            100.0 * unexplained,
            100.0 * o.max_unexplained
        )));
    }
    if found.len() * 2 < plan.boundaries.len() {
        return Err(bad(format!(
            "the print does not match the job: only {} of its {} material boundaries were found; is this the photo of this job?",
            found.len(),
            plan.boundaries.len()
        )));
    }
    let (widths, width_by_material) = stages::widths(&plan, &moved, &frame, &seen, &found);
    let colours = stages::colours(&photo, &palette, &names);
    let photo_px_per_mm = stages::photo_px_per_mm(at.corners, &plan);
    let (corners, registration) = (at.corners, at.registration);
    Ok(Inspection {
        path: path.to_path_buf(),
        plan,
        frame,
        seen,
        design,
        rectified,
        corners,
        turn,
        registration,
        colours,
        pattern_error,
        unexplained,
        found,
        widths,
        photo_px_per_mm,
        width_by_material,
        unpinned: if registration == Registration::Markers {
            [false; 2]
        } else {
            residual.unpinned
        },
    })
}

/// Refuses a photo whose print shows clearly more, or fewer, distinct colours than the
/// job's `k` materials.
fn check_colour_count(
    samples: &[[f32; 3]],
    palette: &classify::Palette,
    k: usize,
) -> Result<(), String> {
    // Fewer: two learned colours nearly the same.
    for i in 0..k {
        for j in i + 1..k {
            let (a, b) = (palette.centres[i], palette.centres[j]);
            let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            if d < 0.08 {
                return Err(format!(
                    "the print shows fewer distinct colours than the job's {k} materials; is this the photo of this job, and are the pastes coloured apart?"
                ));
            }
        }
    }
    // More: one more cluster that is well apart, well populated and halves the spread.
    if k < 6 {
        let more = classify::kmeans_best(samples, k + 1, 11, KMEANS_RESTARTS);
        let mut count = vec![0usize; k + 1];
        for &s in samples {
            if let (Some(j), _) = classify::nearest(&more.centres, s) {
                count[j] += 1;
            }
        }
        let smallest =
            count.iter().copied().min().unwrap_or(0) as f64 / samples.len().max(1) as f64;
        if more.spread < 0.35 * palette.spread && smallest > 0.04 {
            return Err(format!(
                "the print shows more distinct colours than the job's {k} material(s); is this the photo of this job?"
            ));
        }
    }
    Ok(())
}
