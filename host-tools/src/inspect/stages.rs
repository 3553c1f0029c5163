//! The four stages `inspect_photo` runs in order: register (the print's corners in the
//! photo, by the job's markers or the print's outline), classify (the materials' colours
//! and the quarter turn whose labels agree best with the design), refine (the corners
//! moved by the drift the boundaries show, and the residual drift taken out) and measure
//! (the numbers of the `Inspection`, and the checks that the photo shows this job). Each
//! returns what the next takes; the refusals' words are the caller's to wrap.

use super::classify::{self, Palette, PLATE};
use super::design::Plan;
use super::frame::DesignFrame;
use super::measure::{self, Drift, Found, MaterialWidth};
use super::photo::Photo;
use super::{markers, register, Registration, EDGE_EVERY_MM, KMEANS_RESTARTS};

/// Where the photo shows the print.
#[derive(Clone, Copy)]
pub(super) struct Registered {
    /// The print's four corners in the photo, px.
    pub corners: [[f64; 2]; 4],
    /// What found them.
    pub registration: Registration,
}

/// The print's corners in the photo: by the job's markers when `use_markers` and the
/// photo shows them, else by the print's outline (`None` when the outline is not a
/// quadrilateral).
pub(super) fn register(
    photo: &Photo,
    plan: &Plan,
    frame: &DesignFrame,
    use_markers: bool,
) -> Option<Registered> {
    let by_markers = if use_markers {
        markers::register(photo, plan, frame)
    } else {
        None
    };
    match by_markers {
        Some(corners) => Some(Registered {
            corners,
            registration: Registration::Markers,
        }),
        None => {
            let corners = register::corners(&photo.print)?;
            let registration = if plan.markers.is_some() {
                Registration::OutlineMarkersNotFound
            } else {
                Registration::Outline
            };
            Some(Registered {
                corners,
                registration,
            })
        }
    }
}

/// The `k` materials' colours: k-means over the print's pixels (a sample of at most
/// 200 000), refused (`Err`, the reason) when the print shows clearly more or fewer.
pub(super) fn palette(photo: &Photo, k: usize) -> Result<Palette, String> {
    let every = ((photo.print_px / 200_000) as usize).max(1);
    let samples: Vec<[f32; 3]> = photo
        .rgb
        .iter()
        .zip(photo.print.pixels())
        .filter(|(_, m)| m[0] > 0)
        .map(|(c, _)| *c)
        .step_by(every)
        .collect();
    let palette = classify::kmeans_best(&samples, k, 7, KMEANS_RESTARTS);
    super::check_colour_count(&samples, &palette, k)?;
    Ok(palette)
}

/// The quarter turn whose colours agree best with the design.
pub(super) struct Turned {
    /// Quarter turns from the photo's corner order to the design's.
    pub turn: usize,
    /// Per frame pixel: the material seen, or `PLATE`.
    pub seen: Vec<u8>,
    /// Per palette cluster: the material it shows.
    pub names: Vec<u8>,
    /// The photo rectified at that turn.
    pub rectified: image::RgbImage,
}

/// Tries each quarter turn (only the first with markers: they leave no turn to decide)
/// and keeps the one whose labels agree best with `design`; `None` when no turn gives a
/// perspective.
pub(super) fn classify(
    photo: &Photo,
    frame: &DesignFrame,
    at: Registered,
    palette: &Palette,
    design: &[u8],
    materials: &[u8],
) -> Option<Turned> {
    let turns = if at.registration == Registration::Markers {
        0..1
    } else {
        0..4
    };
    // (agreement, the turn) of the best turn so far.
    let mut best: Option<(f64, Turned)> = None;
    for turn in turns {
        let Some(proj) = register::projection(at.corners, frame, turn) else {
            continue;
        };
        let (rgb, pic) = register::rectify(photo, frame, proj, None);
        let clusters: Vec<u8> = rgb
            .iter()
            .map(|&c| classify::label(&palette.centres, c).map_or(PLATE, |j| j as u8))
            .collect();
        let (names, agree) = classify::name_clusters(&clusters, design, materials);
        if best.as_ref().is_none_or(|b| agree > b.0) {
            let seen = clusters
                .iter()
                .map(|&c| if c == PLATE { PLATE } else { names[c as usize] })
                .collect();
            best = Some((
                agree,
                Turned {
                    turn,
                    seen,
                    names,
                    rectified: pic,
                },
            ));
        }
    }
    best.map(|(_, t)| t)
}

/// What refining the registration leaves.
pub(super) struct Refined {
    /// Per frame pixel: the material seen, or `PLATE`.
    pub seen: Vec<u8>,
    /// The photo rectified as `seen` was labelled.
    pub rectified: image::RgbImage,
    /// Boundaries found, their offsets with the residual drift taken out.
    pub found: Vec<Found>,
    /// The drift the corners could not take out.
    pub residual: Drift,
    /// Per palette cluster: the material it shows.
    pub names: Vec<u8>,
}

/// The outline registers the print's edge, which sits where the outer beads' width puts
/// it: refines from the boundaries (see `measure::drift`), twice, then takes what the
/// corners cannot (a perspective the four corners misjudged) out of the offsets and the
/// labels.
pub(super) fn refine(
    photo: &Photo,
    plan: &Plan,
    frame: &DesignFrame,
    design: &[u8],
    palette: &Palette,
    at: Registered,
    turned: Turned,
) -> Refined {
    let Registered {
        corners,
        registration,
    } = at;
    let Turned {
        turn,
        mut seen,
        names,
        mut rectified,
    } = turned;
    let label = |rgb: &[[f32; 3]]| -> Vec<u8> {
        rgb.iter()
            .map(|&c| classify::label(&palette.centres, c).map_or(PLATE, |j| names[j]))
            .collect()
    };
    let mut targets = frame.corners();
    let design_corners = [
        [plan.lo[0], plan.hi[1]],
        [plan.hi[0], plan.hi[1]],
        [plan.hi[0], plan.lo[1]],
        [plan.lo[0], plan.lo[1]],
    ];
    // Along the path only the boundaries show a misregistration; across it the beads'
    // centre lines do (rows all along x leave y to them). The outline needs them: its
    // corners sit where the outer beads' width puts them. The markers' own centre lines
    // register across the path already, and on the calibration pattern (rows of
    // unequal width after every switch) the beads' centre lines measured worse.
    let drift_of = |seen: &[u8]| {
        let found = measure::boundaries(plan, frame, seen);
        let sides = if registration == Registration::Markers {
            Vec::new()
        } else {
            measure::edges(plan, frame, design, seen, EDGE_EVERY_MM)
        };
        (measure::drift(plan, &found, &sides, frame.px_per_mm), found)
    };
    let mut proj_now = register::projection(corners, frame, turn);
    for _ in 0..2 {
        let (d, _) = drift_of(&seen);
        for k in 0..4 {
            // The content for design corner q shows at q + d(q): aim the photo's corner
            // that much the other way (frame y runs down).
            let e = d.at(design_corners[k]);
            targets[k] = [
                targets[k][0] - e[0] * frame.px_per_mm,
                targets[k][1] + e[1] * frame.px_per_mm,
            ];
        }
        let Some(proj) = register::projection_to(corners, targets, turn) else {
            break;
        };
        let (rgb, pic) = register::rectify(photo, frame, proj, None);
        seen = label(&rgb);
        rectified = pic;
        proj_now = Some(proj);
    }
    // What the corners cannot take out (a perspective the four corners misjudged) is
    // taken out of the offsets themselves.
    let (residual, mut found) = drift_of(&seen);
    for f in &mut found {
        let b = plan.boundaries[f.index];
        // Beside a turn, seen where it landed (on the stretch between rows, or the next
        // row), along the path there.
        let (p, u) = if f.beside_turn {
            plan.beads[b.bead].at(b.s + f.offset)
        } else {
            (b.at, plan.beads[b.bead].at(b.s).1)
        };
        f.offset -= residual.along(p, u);
    }
    // The same residual, taken out of the labels: the photo sampled once more, straight
    // into the frame, each frame pixel where its content shows.
    if let Some(proj) = proj_now {
        let (rgb, pic) = register::rectify(photo, frame, proj, Some(&residual));
        seen = label(&rgb);
        rectified = pic;
    }
    Refined {
        seen,
        rectified,
        found,
        residual,
        names,
    }
}

/// Share of the paste seen that shows another material than `plan` with every found
/// boundary moved to where it was found (`moved`). Only where paste shows: gaps between
/// thin beads are not another job.
pub(super) fn unexplained(moved: &Plan, frame: &DesignFrame, seen: &[u8]) -> f64 {
    let want = measure::paint(moved, frame);
    let (mut n, mut bad) = (0u64, 0u64);
    for (&d, &s) in want.iter().zip(seen) {
        if d != PLATE && s != PLATE {
            n += 1;
            bad += u64::from(d != s);
        }
    }
    bad as f64 / n.max(1) as f64
}

/// The bead widths: every sample, and each material's away from its switches.
pub(super) fn widths(
    plan: &Plan,
    moved: &Plan,
    frame: &DesignFrame,
    seen: &[u8],
    found: &[Found],
) -> (Vec<(usize, f64, f64)>, Vec<MaterialWidth>) {
    let widths = measure::widths(plan, frame, seen, 0.5);
    let by_material = measure::width_by_material(plan, moved, found, &widths);
    (widths, by_material)
}

/// Each material's learned colour, 0..1 RGB (the evened palette times the plate's).
pub(super) fn colours(photo: &Photo, palette: &Palette, names: &[u8]) -> Vec<(u8, [f32; 3])> {
    names
        .iter()
        .zip(&palette.centres)
        .map(|(&m, c)| {
            (
                m,
                std::array::from_fn(|i| (c[i] * photo.plate[i]).clamp(0.0, 1.0)),
            )
        })
        .collect()
}

/// Photo pixels per millimetre of the design: the square root of the print's area in
/// the photo (the corners' quadrilateral) over the design's.
pub(super) fn photo_px_per_mm(corners: [[f64; 2]; 4], plan: &Plan) -> f64 {
    let area_px = (0..4)
        .map(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % 4]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        .abs()
        / 2.0;
    let area_mm = (plan.hi[0] - plan.lo[0]) * (plan.hi[1] - plan.lo[1]);
    (area_px / area_mm.max(1e-9)).sqrt()
}
