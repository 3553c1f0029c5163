//! `dollop calibrate rheology|flow|lag|camera|syringe`: parses the arguments, runs the
//! calibration from `crate::calibrate`, prints its report and fragment, and writes the
//! fragment (`--out`) and plot (`--plot`). The measuring and fitting live in the library.

use crate::calibrate::camera::edges::Roi;
use crate::calibrate::camera::frames;
use crate::calibrate::camera::{parse_roi, parse_window};
use crate::calibrate::flow::RateUnit;
use crate::calibrate::lag::{InletKind, TimeUnit};
use crate::calibrate::output::{self, load_config, StagedFiles};
use crate::calibrate::rheology::Kind;
use crate::calibrate::{camera, flow, lag, rheology, syringe, table, CalError, CalOption};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Arguments of `dollop calibrate`.
#[derive(clap::Args, Debug)]
#[command(
    about = "Turn measurements into config values: fits with 95 % confidence intervals, \
             verdicts, a TOML fragment (--out) and a PNG of data against fits (--plot)"
)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(clap::Subcommand, Debug)]
enum What {
    /// Flow curve (shear rate 1/s, shear stress Pa) or oscillatory sweep (angular frequency
    /// rad/s, |G*| Pa) -> `rheology = { .. }`. Fits Newtonian, power law, Herschel-Bulkley
    /// and (oscillatory) the weak gel G* = A w^(1/z); picks the model by AICc.
    Rheology(RheologyArgs),
    /// Supply pressure (kPa) against flow (mm3/s, ml/min, mg/s, g/s or g/min; an optional
    /// third column names the material) -> channel resistance, and with --config the
    /// effective rheology in this channel and the pressure for the configured bead.
    Flow(FlowArgs),
    /// Time after valve open or extruder start against cumulative mass -> Weibull
    /// M(t) = M_inf (1 - exp(-k t^n)), t_lag = (ln 0.1 / -k)^(1/n), and the valve dead time
    /// and pressure rise (or the syringe's lag_k/lag_n).
    Lag(LagArgs),
    /// Side-view frames of the filament leaving the nozzle -> extrusion speed (optical
    /// flow), filament width (Canny edges), die swell and the feed-forward nozzle speed
    /// V_n = V_ex (D_ex / D_t)^2 for a target width.
    Camera(CameraArgs),
    /// Syringe geometry or a measured mass per step -> steps per mm^3, the line width at a
    /// print speed, and `syringe = { steps_per_mm3, lag_k, lag_n }`.
    Syringe(SyringeArgs),
}

#[derive(clap::Args, Debug)]
struct Output {
    /// Write the TOML config fragment here (atomically).
    #[arg(long, value_name = "FRAGMENT.toml")]
    out: Option<PathBuf>,
    /// Draw data against fits into this PNG.
    #[arg(long, value_name = "OUT.png")]
    plot: Option<PathBuf>,
}

/// Limits on a measurement CSV (see `calibrate::table::Limits`).
#[derive(clap::Args, Debug)]
struct CsvLimits {
    /// Most data rows read from a CSV; more are refused.
    #[arg(long, value_name = "N", default_value_t = table::MAX_ROWS)]
    max_rows: usize,
    /// Largest CSV file, MiB; larger is refused before it is read.
    #[arg(long, value_name = "MIB", default_value_t = table::MAX_CSV_MIB)]
    max_csv_mb: u64,
}

impl CsvLimits {
    fn get(&self) -> table::Limits {
        table::Limits {
            max_rows: self.max_rows,
            max_mib: self.max_csv_mb,
        }
    }
}

#[derive(clap::Args, Debug)]
struct RheologyArgs {
    /// CSV: shear rate, stress (or angular frequency, |G*|); header optional.
    data: PathBuf,
    /// What the columns hold (default: read from the header; rotational without one).
    #[arg(long, value_enum)]
    kind: Option<Kind>,
    #[command(flatten)]
    limits: CsvLimits,
    #[command(flatten)]
    output: Output,
}

#[derive(clap::Args, Debug)]
struct FlowArgs {
    /// CSV: pressure kPa, flow, [material].
    data: PathBuf,
    /// Unit of the flow column (default: read from its header).
    #[arg(long, value_enum)]
    rate_unit: Option<RateUnit>,
    /// Paste density, g/ml (for mass flows).
    #[arg(long, value_name = "G_PER_ML")]
    density: Option<f64>,
    /// Machine config: channel geometry, bead and print speed.
    #[arg(long, value_name = "MACHINE.toml")]
    config: Option<PathBuf>,
    /// Print speed for the target pressure, mm/s (default: the config's).
    #[arg(long, value_name = "MM_S")]
    speed: Option<f64>,
    /// Material name when the CSV has no material column (default: the file name).
    #[arg(long)]
    material: Option<String>,
    #[command(flatten)]
    limits: CsvLimits,
    #[command(flatten)]
    output: Output,
}

#[derive(clap::Args, Debug)]
struct LagArgs {
    /// CSV: time after the start, cumulative mass.
    data: PathBuf,
    /// Unit of the time column (default: ms if its header says so, else s).
    #[arg(long, value_enum)]
    time_unit: Option<TimeUnit>,
    /// Which inlet the curve belongs to: the fragment holds valve timings or the
    /// syringe's Weibull lag.
    #[arg(long, value_enum, default_value_t = InletKind::Valve)]
    inlet: InletKind,
    /// The syringe's steps per mm^3 (from `calibrate syringe`), for a complete
    /// `syringe = { .. }` table.
    #[arg(long)]
    steps_per_mm3: Option<f64>,
    #[command(flatten)]
    limits: CsvLimits,
    #[command(flatten)]
    output: Output,
}

#[derive(clap::Args, Debug)]
struct CameraArgs {
    /// Folder of frames (.png/.jpg/.bmp, in file-name order), filament moving down.
    frames: PathBuf,
    /// Frames per second.
    #[arg(long)]
    fps: f64,
    /// Image scale, mm per pixel (photograph a ruler or the nozzle).
    #[arg(long, value_name = "MM")]
    mm_per_px: f64,
    /// Target line width D_t, mm: gives the feed-forward nozzle speed and the fragment.
    #[arg(long, value_name = "MM")]
    target_width: Option<f64>,
    /// Nozzle bore for the die swell, mm (default: the config's).
    #[arg(long, value_name = "MM")]
    nozzle_diameter: Option<f64>,
    /// Machine config (nozzle bore, print-speed cap).
    #[arg(long, value_name = "MACHINE.toml")]
    config: Option<PathBuf>,
    /// Measure only inside this rectangle, px (e.g. below the nozzle tip).
    #[arg(long, value_name = "X,Y,W,H", value_parser = parse_roi)]
    roi: Option<Roi>,
    /// Savitzky-Golay window, frames (odd, 3 to 101).
    #[arg(long, default_value_t = 7, value_parser = parse_window)]
    window: usize,
    /// Most frames read from the folder; more are refused.
    #[arg(long, value_name = "N", default_value_t = frames::MAX_FRAMES)]
    max_frames: usize,
    /// Most pixels over all frames (width x height x frames), checked from the image
    /// headers before any frame is decoded.
    #[arg(long, value_name = "N", default_value_t = frames::MAX_PIXELS)]
    max_pixels: u64,
    #[command(flatten)]
    output: Output,
}

#[derive(clap::Args, Debug)]
struct SyringeArgs {
    /// Syringe barrel inner diameter, mm.
    #[arg(long, value_name = "MM")]
    diameter: Option<f64>,
    /// Lead screw lead (plunger travel per screw turn), mm.
    #[arg(long, value_name = "MM")]
    lead: Option<f64>,
    /// Full steps per motor turn.
    #[arg(long, default_value_t = 200.0)]
    steps_per_rev: f64,
    /// Microsteps per full step.
    #[arg(long, default_value_t = 16.0)]
    microsteps: f64,
    /// Motor turns per screw turn (gearing).
    #[arg(long, default_value_t = 1.0)]
    gear_ratio: f64,
    /// Measured paste mass per microstep, mg (weigh the output of many steps).
    #[arg(long, value_name = "MG")]
    mg_per_step: Option<f64>,
    /// Paste density, g/ml.
    #[arg(long, value_name = "G_PER_ML")]
    density: Option<f64>,
    /// Print speed v for the line width, mm/s (default: the config's).
    #[arg(long, value_name = "MM_S")]
    speed: Option<f64>,
    /// Flow Q for the line width, mm^3/s (default: the config's bead at its speed).
    #[arg(long, value_name = "MM3_S")]
    flow: Option<f64>,
    /// Plunger step rate for the line width, steps/s (instead of --flow).
    #[arg(long, value_name = "HZ", conflicts_with = "flow")]
    step_rate: Option<f64>,
    /// Bead shape factor c in a = sqrt(4/(pi c)) sqrt(Q/v): the bead's cross-section
    /// over the circle of its width, pi a^2 / 4. 1 = round filament; h/a for an
    /// elliptical bead of height h; 4h/(pi a) for a flat, rectangular one.
    #[arg(long, value_name = "C", default_value_t = 1.0)]
    shape: f64,
    /// Lag measurement (CSV as for `calibrate lag`); without it lag_k = 20, lag_n = 1.
    #[arg(long, value_name = "LAG.csv")]
    lag: Option<PathBuf>,
    /// Unit of the lag file's time column.
    #[arg(long, value_enum)]
    lag_time_unit: Option<TimeUnit>,
    /// Machine config (print speed, bead, step-rate limit).
    #[arg(long, value_name = "MACHINE.toml")]
    config: Option<PathBuf>,
    #[command(flatten)]
    limits: CsvLimits,
    #[command(flatten)]
    output: Output,
}

/// Runs `dollop calibrate`: the report goes out before any file is written, so a failed
/// `--out` or `--plot` still leaves the numbers on screen.
pub fn run(args: Args) -> anyhow::Result<()> {
    let prepared = prepare(args).map_err(in_flags)?;
    print!("{}", prepared.text);
    let mut written = String::new();
    let result = finish(prepared, &mut written);
    print!("{written}");
    Ok(result?)
}

/// Runs a calibration and returns what `run` prints: report, fragment and what was written.
pub fn execute(args: Args) -> Result<String, CalError> {
    let prepared = prepare(args).map_err(in_flags)?;
    let mut text = prepared.text.clone();
    finish(prepared, &mut text)?;
    Ok(text)
}

/// A library error that names an input, in this command's words: the flag that gave it.
fn in_flags(e: CalError) -> CalError {
    match e {
        CalError::RoiTooSmall {
            w,
            h,
            frame_w,
            frame_h,
            min,
        } => CalError::arg(format!(
            "--roi leaves {w}x{h} px of the {frame_w}x{frame_h} frames; at least {min}x{min} are needed"
        )),
        CalError::Option(o) => CalError::arg(o.message(flag)),
        CalError::OverLimit { path, what, option } => CalError::arg(format!(
            "{}: {what}; raise the limit with {} if this input is right",
            path.display(),
            flag(option)
        )),
        CalError::NeedsDensity { path, unit } => CalError::Unclear {
            path,
            message: format!("flows are in {unit}: say --density G_PER_ML to turn them into volume"),
        },
        CalError::KindUnclear { path, header } => CalError::Unclear {
            path,
            message: format!(
                "cannot tell from the header {header:?} whether this is a rotational or an \
                 oscillatory test; say --kind rotational or --kind oscillatory"
            ),
        },
        CalError::RateUnitUnclear { path } => CalError::Unclear {
            path,
            message: "the flow column's unit is not in its header (mm3/s, ul/s, ml/min, \
                      mg/s, g/s, g/min); say --rate-unit"
                .into(),
        },
        other => other,
    }
}

/// The flag that gives `o`.
fn flag(o: CalOption) -> &'static str {
    match o {
        CalOption::Diameter => "--diameter",
        CalOption::Lead => "--lead",
        CalOption::StepsPerRev => "--steps-per-rev",
        CalOption::Microsteps => "--microsteps",
        CalOption::GearRatio => "--gear-ratio",
        CalOption::MgPerStep => "--mg-per-step",
        CalOption::Density => "--density",
        CalOption::Shape => "--shape",
        CalOption::Speed => "--speed",
        CalOption::Flow => "--flow",
        CalOption::StepRate => "--step-rate",
        CalOption::Fps => "--fps",
        CalOption::MmPerPx => "--mm-per-px",
        CalOption::TargetWidth => "--target-width",
        CalOption::NozzleDiameter => "--nozzle-diameter",
        CalOption::MaxFrames => "--max-frames",
        CalOption::MaxPixels => "--max-pixels",
        CalOption::MaxCsvMb => "--max-csv-mb",
        CalOption::MaxRows => "--max-rows",
    }
}

/// A finished calibration, before its files are written.
struct Prepared {
    text: String,
    fragment: Option<String>,
    why_not: &'static str,
    output: Output,
    plotter: Plotter,
}

/// A calibration's report, fragment, output and plot, for the calibrations whose plot
/// takes only the path and the staged files.
macro_rules! ran {
    ($cal:ident, $output:expr) => {{
        let (report, fragment) = ($cal.report(), $cal.fragment());
        let plotter: Plotter = Box::new(move |p, o| $cal.plot(p, o));
        (report, fragment, $output, plotter)
    }};
}

fn prepare(args: Args) -> Result<Prepared, CalError> {
    let why_not = match &args.what {
        What::Rheology(_) => "no fitted model is one the core accepts (see the verdicts)",
        What::Flow(a) if a.config.is_none() => {
            "the effective rheology and pressure need the channel: give --config MACHINE.toml"
        }
        What::Flow(_) => "a material's law is not one the core accepts (see the verdicts)",
        What::Lag(a) if a.inlet == InletKind::Syringe => {
            "the syringe lag is outside what the core accepts (see the verdicts)"
        }
        What::Lag(_) => "the valve timings are outside what the core accepts (see the verdicts)",
        What::Camera(_) => "give --target-width MM for the nozzle speed to write",
        What::Syringe(_) => "",
    };
    let (mut text, fragment, output, plotter): Ran = match args.what {
        What::Rheology(a) => {
            let cal = rheology::calibrate(
                &a.data,
                rheology::Options {
                    kind: a.kind,
                    limits: a.limits.get(),
                    ..Default::default()
                },
            )?;
            ran!(cal, a.output)
        }
        What::Flow(a) => {
            let config = a.config.as_deref().map(load_config).transpose()?;
            let cal = flow::calibrate(
                &a.data,
                &flow::Options {
                    unit: a.rate_unit,
                    density_g_ml: a.density,
                    config,
                    speed_mm_s: a.speed,
                    material: a.material,
                    limits: a.limits.get(),
                    ..Default::default()
                },
            )?;
            ran!(cal, a.output)
        }
        What::Lag(a) => {
            let cal = lag::calibrate(
                &a.data,
                lag::Options {
                    time_unit: a.time_unit,
                    inlet: a.inlet,
                    steps_per_mm3: a.steps_per_mm3,
                    limits: a.limits.get(),
                    ..Default::default()
                },
            )?;
            ran!(cal, a.output)
        }
        What::Camera(a) => camera_run(a)?,
        What::Syringe(a) => syringe_run(a)?,
    };
    match &fragment {
        Some(f) => {
            let _ = write!(text, "\nfragment:\n{f}");
        }
        None => {
            let _ = writeln!(text, "\n(no config fragment: {why_not})");
        }
    }
    Ok(Prepared {
        text,
        fragment,
        why_not,
        output,
        plotter,
    })
}

fn finish(p: Prepared, text: &mut String) -> Result<(), CalError> {
    let Prepared {
        fragment,
        why_not,
        output,
        plotter,
        ..
    } = p;
    // Fragment and plot are staged, then renamed together: a failure on one leaves neither.
    let mut staged = StagedFiles::new();
    if let Some(path) = &output.out {
        let f = fragment.ok_or_else(|| {
            CalError::arg(format!(
                "--out {}: nothing to write: {why_not}",
                path.display()
            ))
        })?;
        output::stage(&mut staged, path, f.as_bytes())?;
    }
    if let Some(path) = &output.plot {
        plotter(path, &mut staged)?;
    }
    output::commit(staged)?;
    for path in [&output.out, &output.plot].into_iter().flatten() {
        let _ = writeln!(text, "wrote {}", path.display());
    }
    Ok(())
}

type Plotter = Box<dyn FnOnce(&Path, &mut StagedFiles) -> Result<(), CalError>>;

/// What one calibration prints, the fragment it writes, where, and its plot.
type Ran = (String, Option<String>, Output, Plotter);

/// `dollop calibrate camera`.
fn camera_run(a: CameraArgs) -> Result<Ran, CalError> {
    let config = a.config.as_deref().map(load_config).transpose()?;
    let mut o = camera::Options::new(a.fps, a.mm_per_px);
    o.target_width_mm = a.target_width;
    o.nozzle_mm = a.nozzle_diameter;
    o.roi = a.roi;
    o.window = a.window;
    o.config = config;
    o.limits = frames::Limits {
        max_frames: a.max_frames,
        max_pixels: a.max_pixels,
    };
    let fps = a.fps;
    let cal = camera::calibrate(&a.frames, &o)?;
    let fragment = cal.fragment();
    Ok((
        cal.report(),
        fragment,
        a.output,
        Box::new(move |p, o| cal.plot(p, fps, o)),
    ))
}

/// `dollop calibrate syringe` (with the lag fit when `--lag` is given).
fn syringe_run(a: SyringeArgs) -> Result<Ran, CalError> {
    let config = a.config.as_deref().map(load_config).transpose()?;
    let lag_cal = match &a.lag {
        Some(path) => Some(lag::calibrate(
            path,
            lag::Options {
                time_unit: a.lag_time_unit,
                inlet: InletKind::Syringe,
                limits: a.limits.get(),
                ..Default::default()
            },
        )?),
        None => None,
    };
    let cal = syringe::calibrate(&syringe::Options {
        diameter_mm: a.diameter,
        lead_mm: a.lead,
        steps_per_rev: a.steps_per_rev,
        microsteps: a.microsteps,
        gear_ratio: a.gear_ratio,
        mg_per_step: a.mg_per_step,
        density_g_ml: a.density,
        flow_mm3_s: a.flow,
        step_rate_hz: a.step_rate,
        speed_mm_s: a.speed,
        shape_c: a.shape,
        lag: lag_cal.as_ref().map(|l| l.weibull),
        config,
    })?;
    let mut report = String::new();
    if let Some(l) = &lag_cal {
        report.push_str(&l.report());
    }
    report.push_str(&cal.report());
    let plotter: Plotter = match lag_cal {
        Some(l) => Box::new(move |p, o| l.plot(p, o)),
        None => Box::new(|_, _| {
            Err(CalError::arg(
                "--plot draws the lag fit: give --lag LAG.csv",
            ))
        }),
    };
    Ok((report, Some(cal.fragment()), a.output, plotter))
}
