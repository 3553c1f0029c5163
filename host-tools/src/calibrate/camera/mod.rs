//! `calibrate camera`: from side-view frames of the filament leaving the nozzle, the
//! extrusion speed (pyramidal Lucas-Kanade optical flow on the filament's texture), the
//! filament width (Canny edges), both smoothed over the sequence with a Savitzky-Golay
//! filter; then die swell and the feed-forward nozzle speed `V_n = V_ex (D_ex / D_t)^2`
//! that lays a line of width `D_t`. Loading, tracking, edges and test frames are submodules.

pub mod edges;
pub mod frames;
pub mod synth;
pub mod track;

use super::error::{positive, CalOption};
use super::format::{short, sig, toml_float};
use super::output::StagedFiles;
use super::plot::{self, Mark, Panel, Series};
use super::savgol;
use super::CalError;
use dollop::config::Config;
use edges::{median, Roi};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The least region of interest, px a side, the edge finder and the tracker work in.
pub const MIN_ROI_PX: u32 = 8;
use track::{LkOptions, Pyramid};

/// Options of `calibrate camera`.
#[derive(Clone, Debug)]
pub struct Options {
    /// Frames per second.
    pub fps: f64,
    /// Scale, mm per pixel.
    pub mm_per_px: f64,
    /// Target line width D_t, mm.
    pub target_width_mm: Option<f64>,
    /// Nozzle bore for die swell, mm (default: the config's).
    pub nozzle_mm: Option<f64>,
    /// Region to measure in (default: whole frame).
    pub roi: Option<Roi>,
    /// Savitzky-Golay window, frames.
    pub window: usize,
    /// Savitzky-Golay polynomial order.
    pub order: usize,
    /// Machine config (nozzle bore, print-speed cap).
    pub config: Option<Config>,
    /// How many frames and pixels are read.
    pub limits: frames::Limits,
}

impl Options {
    /// Options with the defaults for everything but the two scales.
    pub fn new(fps: f64, mm_per_px: f64) -> Options {
        Options {
            fps,
            mm_per_px,
            target_width_mm: None,
            nozzle_mm: None,
            roi: None,
            window: 7,
            order: 2,
            config: None,
            limits: frames::Limits::default(),
        }
    }
}

/// The result of `calibrate camera`.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// The folder.
    pub path: PathBuf,
    /// Frames read.
    pub frames: usize,
    /// Frame size, px.
    pub size: (u32, u32),
    /// Speed of each frame pair (pair i: frames i, i+1), mm/s; NaN where untracked.
    pub speed_raw: Vec<f64>,
    /// Smoothed speeds of the tracked pairs, with their pair index.
    pub speed_smooth: Vec<(usize, f64)>,
    /// Points tracked per pair.
    pub tracked: Vec<usize>,
    /// Sideways drift per pair, mm/s.
    pub drift: Vec<f64>,
    /// Width of each frame, mm; NaN where no sides were found.
    pub width_raw: Vec<f64>,
    /// Smoothed widths with their frame index.
    pub width_smooth: Vec<(usize, f64)>,
    /// Extrusion speed V_ex, mm/s.
    pub v_ex: f64,
    /// Filament width D_ex, mm.
    pub d_ex: f64,
    /// Nozzle bore and die swell D_ex / D_nozzle.
    pub die_swell: Option<(f64, f64)>,
    /// Target width and the nozzle speed that lays it.
    pub feed_forward: Option<(f64, f64)>,
    /// Verdicts.
    pub verdicts: Vec<String>,
}

/// `X,Y,W,H` in whole pixels, as the command line and the dashboard take a region of interest.
pub fn parse_roi(s: &str) -> Result<Roi, String> {
    let v: Vec<u32> = s
        .split(',')
        .map(|p| p.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{s:?}: expected X,Y,W,H in whole pixels"))?;
    match v[..] {
        [x, y, w, h] => Ok(Roi { x, y, w, h }),
        _ => Err(format!("{s:?}: expected four numbers X,Y,W,H")),
    }
}

/// The smoothing window: an odd number of frames from 3 (a window of 1 or 0 would not
/// smooth, an even one has no centre) to 101 (wider smooths the lag's rise away). Both front ends
/// check theirs with this.
pub fn parse_window(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(w) if (3..=101).contains(&w) && !w.is_multiple_of(2) => Ok(w),
        _ => Err(format!(
            "{s:?}: the window is an odd number of frames from 3 to 101"
        )),
    }
}

fn std_dev(v: &[f64], around: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter()
        .zip(around)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        / v.len() as f64)
        .sqrt()
}

/// Reads the frames in `dir` and measures them.
pub fn calibrate(dir: &Path, o: &Options) -> Result<Calibration, CalError> {
    let fps = positive(CalOption::Fps, o.fps)?;
    let scale = positive(CalOption::MmPerPx, o.mm_per_px)?;
    if let Some(t) = o.target_width_mm {
        positive(CalOption::TargetWidth, t)?;
    }
    let files = frames::list(dir, o.limits.max_frames)?;
    if files.len() < 2 {
        return Err(CalError::TooFewFrames {
            path: dir.to_path_buf(),
            frames: files.len(),
            need: 2,
        });
    }
    let (w, h) = frames::check_sizes(&files, dir, o.limits.max_pixels)?;
    // Decoding, edges and tracking take seconds per 10^6 pixels: show the progress.
    let bar = crate::slicer::output::progress(2 * files.len() as u64 - 1, "frames");
    let imgs = files
        .iter()
        .map(|f| {
            bar.inc(1);
            frames::load_one(f, (w, h))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let roi = o.roi.unwrap_or(Roi::full(w, h)).clip(w, h);
    if roi.w < MIN_ROI_PX || roi.h < MIN_ROI_PX {
        return Err(CalError::RoiTooSmall {
            w: roi.w,
            h: roi.h,
            frame_w: w,
            frame_h: h,
            min: MIN_ROI_PX,
        });
    }
    let sides: Vec<Vec<edges::Sides>> = imgs.iter().map(|f| edges::sides(f, roi)).collect();
    let width_px: Vec<Option<f64>> = sides
        .iter()
        .map(|s| median(&s.iter().map(|s| s.width()).collect::<Vec<_>>()))
        .collect();
    let (speed_raw, drift, tracked) = track_pairs(&imgs, &sides, (scale, fps), &bar);
    bar.finish_and_clear();
    let width_raw: Vec<f64> = width_px
        .iter()
        .map(|w| w.map_or(f64::NAN, |w| w * scale))
        .collect();
    let smooth = |raw: &[f64]| -> Vec<(usize, f64)> {
        let idx: Vec<usize> = (0..raw.len()).filter(|&i| raw[i].is_finite()).collect();
        let vals: Vec<f64> = idx.iter().map(|&i| raw[i]).collect();
        idx.into_iter()
            .zip(savgol::smooth(&vals, o.window, o.order))
            .collect()
    };
    let speed_smooth = smooth(&speed_raw);
    let width_smooth = smooth(&width_raw);
    let not = |message: &str| CalError::NotMeasurable {
        path: dir.to_path_buf(),
        message: message.into(),
    };
    let v_signed = median(&speed_smooth.iter().map(|p| p.1).collect::<Vec<_>>())
        .ok_or_else(|| not("no frame pair had enough texture inside the filament to track"))?;
    let d_ex = median(&width_smooth.iter().map(|p| p.1).collect::<Vec<_>>())
        .ok_or_else(|| not("no filament sides (Canny edges) found in any frame"))?;
    let v_ex = v_signed.abs();
    let nozzle = o.nozzle_mm.or(o
        .config
        .as_ref()
        .map(|c| c.channel.nozzle_diameter_mm as f64));
    let die_swell = match nozzle {
        Some(n) => Some((n, d_ex / positive(CalOption::NozzleDiameter, n)?)),
        None => None,
    };
    let feed_forward = o.target_width_mm.map(|t| (t, v_ex * (d_ex / t).powi(2)));
    let mut cal = Calibration {
        path: dir.to_path_buf(),
        frames: imgs.len(),
        size: (w, h),
        speed_raw,
        speed_smooth,
        tracked,
        drift,
        width_raw,
        width_smooth,
        v_ex,
        d_ex,
        die_swell,
        feed_forward,
        verdicts: Vec::new(),
    };
    cal.verdicts = verdicts(&cal, v_signed, o);
    Ok(cal)
}

/// Each frame pair's filament speed and sideways drift (mm/s; NaN where fewer than five
/// points were tracked) and the points tracked, from the texture inside the filament
/// between `sides`, with `scale` mm per px at `fps` frames per second. Ticks `bar` once
/// a pair.
fn track_pairs(
    imgs: &[image::GrayImage],
    sides: &[Vec<edges::Sides>],
    (scale, fps): (f64, f64),
    bar: &indicatif::ProgressBar,
) -> (Vec<f64>, Vec<f64>, Vec<usize>) {
    let lk = LkOptions::default();
    let mut speed_raw = Vec::with_capacity(imgs.len() - 1);
    let mut drift = Vec::with_capacity(imgs.len() - 1);
    let mut tracked = Vec::with_capacity(imgs.len() - 1);
    let mut prev = Pyramid::new(&imgs[0], lk.levels);
    for i in 0..imgs.len() - 1 {
        let next = Pyramid::new(&imgs[i + 1], lk.levels);
        let (dxs, dys) = track_inside(&prev, &next, &sides[i], lk);
        tracked.push(dys.len());
        let ok = dys.len() >= 5;
        speed_raw.push(match median(&dys) {
            Some(v) if ok => v * scale * fps,
            _ => f64::NAN,
        });
        drift.push(match median(&dxs) {
            Some(v) if ok => v * scale * fps,
            _ => f64::NAN,
        });
        prev = next;
        bar.inc(1);
    }
    (speed_raw, drift, tracked)
}

/// The moves (x, y in px) from `prev` to `next` of the texture inside the filament: on
/// every fifth row's sides, every 4 px between them, away from the edges.
fn track_inside(
    prev: &Pyramid,
    next: &Pyramid,
    sides: &[edges::Sides],
    lk: LkOptions,
) -> (Vec<f64>, Vec<f64>) {
    let mut dxs = Vec::new();
    let mut dys = Vec::new();
    for s in sides.iter().step_by(5) {
        let margin = (0.2 * s.width()).max(6.0);
        let mut x = s.left + margin;
        while x <= s.right - margin {
            if let Some((dx, dy)) = track::track(prev, next, x, s.y as f64, lk) {
                dxs.push(dx);
                dys.push(dy);
            }
            x += 4.0;
        }
    }
    (dxs, dys)
}

fn verdicts(cal: &Calibration, v_signed: f64, o: &Options) -> Vec<String> {
    let mut out = Vec::new();
    if v_signed < 0.0 {
        out.push("the texture moves up the frame: is the camera upside down?".into());
    }
    let drift = median(
        &cal.drift
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .collect::<Vec<_>>(),
    )
    .unwrap_or(0.0);
    if drift.abs() > 0.1 * cal.v_ex {
        out.push(format!(
            "the filament also drifts sideways at {} mm/s: is the camera square to it?",
            sig(drift, 3)
        ));
    }
    let untracked = cal.speed_raw.iter().filter(|v| !v.is_finite()).count();
    if untracked > 0 {
        out.push(format!(
            "{untracked} of {} frame pairs had too little texture to track and were left out",
            cal.speed_raw.len()
        ));
    }
    if let Some((n, swell)) = cal.die_swell {
        out.push(if swell > 1.02 {
            format!(
                "die swell {}: the filament leaves {} % wider than the {} mm nozzle",
                sig(swell, 3),
                sig(100.0 * (swell - 1.0), 2),
                short(n)
            )
        } else if swell < 0.98 {
            format!(
                "the filament is {} % narrower than the {} mm nozzle (stretched by gravity or the head?)",
                sig(100.0 * (1.0 - swell), 2),
                short(n)
            )
        } else {
            format!(
                "no die swell: the filament is as wide as the {} mm nozzle",
                short(n)
            )
        });
    }
    if let (Some((t, vn)), Some(cfg)) = (cal.feed_forward, &o.config) {
        let cap = cfg.motion.print_speed_max_mm_s as f64;
        if vn > cap {
            out.push(format!(
                "a {t} mm line needs {} mm/s, above print_speed_max_mm_s = {}: lower the pressure",
                sig(vn, 3),
                short(cap)
            ));
        }
    }
    out
}

impl Calibration {
    /// Volumetric flow `V_ex pi D_ex^2 / 4`, mm^3/s.
    pub fn flow(&self) -> f64 {
        self.v_ex * PI * self.d_ex * self.d_ex / 4.0
    }

    /// The human-readable report.
    pub fn report(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "camera: {} frames of {}x{} px from {}",
            self.frames,
            self.size.0,
            self.size.1,
            self.path.display()
        );
        let sp: Vec<f64> = self
            .speed_raw
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .collect();
        let sps: Vec<f64> = self.speed_smooth.iter().map(|p| p.1).collect();
        let wr: Vec<f64> = self
            .width_raw
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .collect();
        let wrs: Vec<f64> = self.width_smooth.iter().map(|p| p.1).collect();
        let _ = writeln!(
            s,
            "  extrusion speed V_ex = {} mm/s (pyramidal Lucas-Kanade, median of {} points per pair; \
             Savitzky-Golay smoothed; raw pairs scatter {} mm/s)",
            sig(self.v_ex, 4),
            median(&self.tracked.iter().map(|&n| n as f64).collect::<Vec<_>>()).unwrap_or(0.0),
            sig(std_dev(&sp, &sps), 2)
        );
        let _ = writeln!(
            s,
            "  filament width D_ex = {} mm (Canny sides, sub-pixel; raw frames scatter {} mm)",
            sig(self.d_ex, 4),
            sig(std_dev(&wr, &wrs), 2)
        );
        let _ = writeln!(
            s,
            "  flow Q = V_ex pi D_ex^2 / 4 = {} mm^3/s (a point for `calibrate flow` at this pressure)",
            sig(self.flow(), 4)
        );
        if let Some((n, swell)) = self.die_swell {
            let _ = writeln!(
                s,
                "  die swell D_ex / D_nozzle = {} (nozzle {} mm)",
                sig(swell, 4),
                short(n)
            );
        }
        if let Some((t, vn)) = self.feed_forward {
            let _ = writeln!(
                s,
                "  feed-forward nozzle speed V_n = V_ex (D_ex / D_t)^2 = {} mm/s for D_t = {t} mm",
                sig(vn, 4)
            );
        }
        for v in &self.verdicts {
            let _ = writeln!(s, "verdict: {v}");
        }
        s
    }

    /// `[motion] print_speed_mm_s` for the target width; `None` without one.
    pub fn fragment(&self) -> Option<String> {
        let (t, vn) = self.feed_forward?;
        Some(format!(
            "# dollop calibrate camera {}: V_ex = {} mm/s, D_ex = {} mm\n\
             # Head speed that lays a {t} mm line at the pressure filmed: give that inlet\n\
             # the pressure as pressure_kpa (not \"auto\", which would rescale it).\n\
             [motion]\nprint_speed_mm_s = {}\n",
            self.path.display(),
            sig(self.v_ex, 4),
            sig(self.d_ex, 4),
            toml_float(vn, 4)
        ))
    }

    /// Speed and width through the sequence, raw and smoothed.
    pub fn plot(&self, path: &Path, fps: f64, out: &mut StagedFiles) -> Result<(), CalError> {
        let t = |i: usize| i as f64 / fps;
        let speed = Panel {
            title: format!("extrusion speed: {} mm/s", sig(self.v_ex, 4)),
            x_label: "time (s)".into(),
            y_label: "speed (mm/s)".into(),
            series: vec![
                Series {
                    label: "optical flow, per frame pair".into(),
                    points: self
                        .speed_raw
                        .iter()
                        .enumerate()
                        .map(|(i, &v)| (t(i) + 0.5 / fps, v.abs()))
                        .collect(),
                    mark: Mark::Points,
                    color: 0,
                },
                Series {
                    label: "Savitzky-Golay".into(),
                    points: self
                        .speed_smooth
                        .iter()
                        .map(|&(i, v)| (t(i) + 0.5 / fps, v.abs()))
                        .collect(),
                    mark: Mark::Line,
                    color: 1,
                },
            ],
            y_min_span: 0.1 * self.v_ex,
            ..Panel::default()
        };
        let width = Panel {
            title: format!("filament width: {} mm", sig(self.d_ex, 4)),
            x_label: "time (s)".into(),
            y_label: "width (mm)".into(),
            series: vec![
                Series {
                    label: "Canny sides, per frame".into(),
                    points: self
                        .width_raw
                        .iter()
                        .enumerate()
                        .map(|(i, &v)| (t(i), v))
                        .collect(),
                    mark: Mark::Points,
                    color: 0,
                },
                Series {
                    label: "Savitzky-Golay".into(),
                    points: self.width_smooth.iter().map(|&(i, v)| (t(i), v)).collect(),
                    mark: Mark::Line,
                    color: 2,
                },
            ],
            y_min_span: 0.1 * self.d_ex,
            ..Panel::default()
        };
        plot::render(path, &[speed, width], 900, 360, out)
    }
}
