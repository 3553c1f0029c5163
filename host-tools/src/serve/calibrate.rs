//! Calibration for the dashboard, calling the library code behind `dollop calibrate`:
//! rheology (flow curve or oscillatory sweep), flow (flow against supply pressure, per
//! material, with the Design page's config for the channel), lag (a valve's or a
//! syringe's start-up mass curve) and camera (side-view frames of the filament leaving the
//! nozzle: extrusion speed, width, die swell and the head speed for a target line width).
//! Each gives the report as the command prints it (fits, 95 % intervals, verdicts), the
//! TOML fragment, and the plot of data against fits; the page applies the fragment to the
//! config in its editor. The syringe model is the command's only, for now.

use super::design::Upload;
use super::error::{ApiError, ApiResult};
use crate::calibrate::camera::{self, frames};
use crate::calibrate::error::{CalError, CalOption};
use crate::calibrate::lag::{self, InletKind};
use crate::calibrate::rheology::{self, Kind};
use crate::calibrate::{flow, output};
use dollop::config::Config;
use serde::Serialize;

/// What the page shows of a calibration.
#[derive(Debug, Clone, Serialize)]
pub struct Shown {
    /// The report as the command prints it.
    pub report: String,
    /// The fragment (`rheology = { .. }`), or None when no model fits the core.
    pub fragment: Option<String>,
    /// The plot, PNG, base64 (shown inline).
    pub plot_png_base64: String,
}

fn base64(bytes: &[u8]) -> String {
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// An upload kept in a temporary folder under its cleaned name, for the library's
/// path-based readers; messages have the folder taken out.
struct Kept {
    dir: tempfile::TempDir,
    /// The file, or for frames the folder `frames` holding them.
    path: std::path::PathBuf,
}

fn temp_dir() -> ApiResult<tempfile::TempDir> {
    tempfile::tempdir()
        .map_err(|e| ApiError::internal(format!("cannot create a temporary folder: {e}")))
}

fn keep(path: &std::path::Path, bytes: &[u8]) -> ApiResult<()> {
    std::fs::write(path, bytes)
        .map_err(|e| ApiError::internal(format!("cannot keep the upload: {e}")))
}

impl Kept {
    fn new(name: &str, bytes: &[u8]) -> ApiResult<Self> {
        let dir = temp_dir()?;
        let path = dir.path().join(super::design::safe_name(name, "data.csv"));
        keep(&path, bytes)?;
        Ok(Kept { dir, path })
    }

    /// Frames in a folder of their own, under names already cleaned and checked distinct
    /// (the reader takes every image in the folder, in name order).
    fn folder(files: &[(String, &[u8])]) -> ApiResult<Self> {
        let dir = temp_dir()?;
        let path = dir.path().join("frames");
        std::fs::create_dir(&path)
            .map_err(|e| ApiError::internal(format!("cannot create a temporary folder: {e}")))?;
        for (name, bytes) in files {
            keep(&path.join(name), bytes)?;
        }
        Ok(Kept { dir, path })
    }

    /// The message without our temporary folder: a frame is named by its file name, the
    /// frames' folder as `frames`, a CSV by its name.
    fn strip(&self, s: String) -> String {
        s.replace(&format!("{}/", self.path.display()), "")
            .replace(&format!("{}/", self.dir.path().display()), "")
    }

    /// The report, the fragment and the plot `plot` draws.
    fn show(
        &self,
        report: String,
        fragment: Option<String>,
        plot: impl FnOnce(&std::path::Path, &mut output::StagedFiles) -> Result<(), CalError>,
    ) -> ApiResult<Shown> {
        let at = self.dir.path().join("plot.png");
        let mut out = output::StagedFiles::new();
        plot(&at, &mut out)
            .map_err(|e| ApiError::from(e).map_message(|m| self.strip(m.to_string())))?;
        output::commit(out).map_err(|e| ApiError::internal(self.strip(e.to_string())))?;
        let png = std::fs::read(&at)
            .map_err(|e| ApiError::internal(format!("cannot read the plot: {e}")))?;
        Ok(Shown {
            report: self.strip(report),
            fragment: fragment.map(|f| self.strip(f)),
            plot_png_base64: base64(&png),
        })
    }
}

/// Fits an uploaded rheology CSV (`kind`: "rotational", "oscillatory" or "" for the
/// header's word). Blocking.
pub fn rheology(name: &str, bytes: &[u8], kind: &str) -> ApiResult<Shown> {
    use clap::ValueEnum;
    let kind =
        match kind.trim() {
            "" | "auto" => None,
            k => Some(Kind::from_str(k, true).map_err(|_| {
                ApiError::bad(format!("kind {k:?}: choose rotational or oscillatory"))
            })?),
        };
    let kept = Kept::new(name, bytes)?;
    let cal = rheology::calibrate(
        &kept.path,
        rheology::Options {
            kind,
            ..Default::default()
        },
    )
    .map_err(|e| ApiError::from(e).map_message(|m| kept.strip(m.to_string())))?;
    kept.show(cal.report(), cal.fragment(), |p, o| cal.plot(p, o))
}

/// Fits an uploaded flow-against-pressure CSV as `dollop calibrate flow` does, with
/// `config` (the Design page's) for the channel, bead and speed: without one there is no
/// fragment. `density_g_ml` is needed for mass flows. Blocking.
pub fn flow(
    name: &str,
    bytes: &[u8],
    config: Option<Config>,
    density_g_ml: Option<f64>,
) -> ApiResult<Shown> {
    if let Some(d) = density_g_ml {
        if !(d.is_finite() && d > 0.0 && d < 30.0) {
            return Err(ApiError::bad(format!(
                "density {d} g/ml: give the paste's density, e.g. 1.05"
            )));
        }
    }
    let kept = Kept::new(name, bytes)?;
    let cal = flow::calibrate(
        &kept.path,
        &flow::Options {
            density_g_ml,
            config,
            ..Default::default()
        },
    )
    .map_err(|e| ApiError::from(e).map_message(|m| kept.strip(m.to_string())))?;
    kept.show(cal.report(), cal.fragment(), |p, o| cal.plot(p, o))
}

/// Fits an uploaded start-up mass curve as `dollop calibrate lag` does (`inlet`: "valve"
/// for the valve timings, "syringe" for the Weibull lag). Blocking.
pub fn lag(name: &str, bytes: &[u8], inlet: &str) -> ApiResult<Shown> {
    let inlet = match inlet.trim() {
        "" | "valve" => InletKind::Valve,
        "syringe" => InletKind::Syringe,
        k => {
            return Err(ApiError::bad(format!(
                "inlet {k:?}: choose valve or syringe"
            )))
        }
    };
    let kept = Kept::new(name, bytes)?;
    let cal = lag::calibrate(
        &kept.path,
        lag::Options {
            inlet,
            ..Default::default()
        },
    )
    .map_err(|e| ApiError::from(e).map_message(|m| kept.strip(m.to_string())))?;
    kept.show(cal.report(), cal.fragment(), |p, o| cal.plot(p, o))
}

/// The camera fields of the Calibrate page as typed; `camera` checks them, a refusal
/// naming the field. Empty means the command's default (or, for fps and scale, missing).
#[derive(Debug, Clone, Default)]
pub struct CameraForm {
    /// Frames per second (required).
    pub fps: String,
    /// Scale, mm per pixel (required).
    pub mm_per_px: String,
    /// Target line width D_t, mm (no fragment without it).
    pub target_width: String,
    /// Nozzle bore for the die swell, mm (default: the config's).
    pub nozzle: String,
    /// Region of interest `X,Y,W,H`, px (default: the whole frame).
    pub roi: String,
    /// Savitzky-Golay window, frames (default 7).
    pub window: String,
}

/// How many frames one dashboard upload may hold and how many pixels over all of them:
/// the command's defaults (`--max-frames`, `--max-pixels`), which keep the decoded
/// frames near 0.35 GB at the peak. The bytes are bounded by `MAX_UPLOAD`.
pub const CAMERA_LIMITS: frames::Limits = frames::Limits {
    max_frames: frames::MAX_FRAMES,
    max_pixels: frames::MAX_PIXELS,
};

/// The refusal of more frames than `max` (the route says it before reading the rest).
pub fn too_many_frames(max: usize) -> ApiError {
    ApiError::bad(format!(
        "more than {max} frames: the dashboard fits at most {max} at a time; send fewer (every other frame halves them: give half the fps then), or run dollop calibrate camera on the folder with --max-frames"
    ))
}

/// The refusal of frames over `MAX_UPLOAD` bytes together.
pub fn frames_too_large() -> ApiError {
    ApiError::TooLarge(format!(
        "the frames are larger than the {} MiB this dashboard accepts in one upload; send fewer frames, or crop them to the filament, or run dollop calibrate camera on the folder",
        super::MAX_UPLOAD >> 20
    ))
}

/// A number above zero from a field, `None` when empty.
fn positive(field: &str, text: &str, example: &str) -> ApiResult<Option<f64>> {
    let t = text.trim();
    if t.is_empty() {
        return Ok(None);
    }
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(Some(v)),
        _ => Err(ApiError::bad(format!(
            "{field} {t:?}: give a number above zero, e.g. {example}"
        ))),
    }
}

impl CameraForm {
    /// The library's options, as the command builds them from its arguments.
    fn options(
        &self,
        config: Option<Config>,
        limits: frames::Limits,
    ) -> ApiResult<camera::Options> {
        let fps = positive("frame rate", &self.fps, "30")?.ok_or_else(|| {
            ApiError::bad(
                "give the frame rate the frames were filmed at, in frames per second (e.g. 30)",
            )
        })?;
        let mm_per_px = positive("scale", &self.mm_per_px, "0.02")?.ok_or_else(|| {
            ApiError::bad("give the scale in mm per pixel (photograph a ruler, or the nozzle, where the filament is; e.g. 0.02)")
        })?;
        let mut o = camera::Options::new(fps, mm_per_px);
        o.target_width_mm = positive("target width", &self.target_width, "0.8 (mm)")?;
        o.nozzle_mm = positive("nozzle diameter", &self.nozzle, "0.8 (mm)")?;
        if !self.roi.trim().is_empty() {
            o.roi = Some(camera::parse_roi(&self.roi).map_err(|e| {
                ApiError::bad(format!(
                    "region of interest {e}, or leave it empty for the whole frame"
                ))
            })?);
        }
        if !self.window.trim().is_empty() {
            o.window = camera::parse_window(&self.window)
                .map_err(|e| ApiError::bad(format!("smoothing window {e}")))?;
        }
        o.config = config;
        o.limits = limits;
        Ok(o)
    }
}

/// Measures uploaded side-view frames as `dollop calibrate camera` does, with `config`
/// (the Design page's) for the nozzle bore and the print-speed cap. The frames are taken
/// in file-name order; `limits` bound their number and pixels (`CAMERA_LIMITS` on the
/// server). Blocking.
pub fn camera(
    uploads: &[Upload],
    form: &CameraForm,
    config: Option<Config>,
    limits: frames::Limits,
) -> ApiResult<Shown> {
    if uploads.is_empty() {
        return Err(ApiError::bad(
            "choose the frames: two or more side views of the filament leaving the nozzle (.png, .jpg, .jpeg or .bmp), in filming order by file name",
        ));
    }
    let o = form.options(config, limits)?;
    if uploads.len() > limits.max_frames {
        return Err(too_many_frames(limits.max_frames));
    }
    // Names as they will be on disk: the reader goes by the extension and sorts by name,
    // so each must be an image and no two may be the same.
    let mut files: Vec<(String, &[u8])> = Vec::with_capacity(uploads.len());
    let mut seen = std::collections::HashSet::new();
    for u in uploads {
        let name = super::design::safe_name(&u.name, "frame");
        let ext = name.rsplit_once('.').map(|(_, e)| e.to_ascii_lowercase());
        if !ext.is_some_and(|e| frames::EXTENSIONS.contains(&e.as_str())) {
            return Err(ApiError::bad(format!(
                "{}: not a frame the calibration reads (.png, .jpg, .jpeg or .bmp); convert it or leave it out",
                u.name
            )));
        }
        if !seen.insert(name.clone()) {
            return Err(ApiError::bad(format!(
                "two frames are named {name}: the frames are taken in file-name order, so each needs its own name; rename one or leave it out"
            )));
        }
        files.push((name, &u.bytes));
    }
    if files.len() < 2 {
        return Err(ApiError::bad(format!(
            "{}: one frame; the speed is measured between frames, so choose two or more (a few seconds of film is best)",
            files[0].0
        )));
    }
    let kept = Kept::folder(&files)?;
    let fps = o.fps;
    let cal = camera::calibrate(&kept.path, &o).map_err(|e| camera_refusal(&kept, e))?;
    kept.show(cal.report(), cal.fragment(), |p, out| cal.plot(p, fps, out))
}

/// A camera failure in the page's words: the frame named, and what to do.
fn camera_refusal(kept: &Kept, e: CalError) -> ApiError {
    let name = |p: &std::path::Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    ApiError::bad(match e {
        CalError::Image { path, message } => format!(
            "{}: this frame does not decode ({message}); export it again, or leave it out",
            name(&path)
        ),
        CalError::FrameSize {
            path,
            got_w,
            got_h,
            want_w,
            want_h,
        } => format!(
            "{}: this frame is {got_w}x{got_h} px but the first (by name) is {want_w}x{want_h}; all frames must be one size: leave it out, or crop them alike",
            name(&path)
        ),
        CalError::OverLimit { what, option, .. } => format!(
            "{what} (the dashboard's limit); send fewer frames or crop them to the filament, or run dollop calibrate camera on the folder with {}",
            // The command's flags for the two limits frames are read under.
            if option == CalOption::MaxFrames {
                "--max-frames"
            } else {
                "--max-pixels"
            }
        ),
        CalError::NotMeasurable { message, .. } => format!(
            "{message}: the frames should show the filament leaving the nozzle, moving down, in focus and lit; set the region of interest around it"
        ),
        // The one input the library checks against the frames themselves, named as the
        // page's field is.
        e @ CalError::RoiTooSmall { .. } => e.to_string(),
        other => kept.strip(other.to_string()),
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn base64_pads() {
        assert_eq!(super::base64(b"Man"), "TWFu");
        assert_eq!(super::base64(b"Ma"), "TWE=");
        assert_eq!(super::base64(b"M"), "TQ==");
        assert_eq!(super::base64(b""), "");
    }

    #[test]
    fn the_bundled_puree_fits_a_power_law() {
        let csv = include_bytes!("../../data/calibration/rheology-puree.csv");
        let s = super::rheology("rheology-puree.csv", csv, "").expect("fits");
        assert!(s.report.contains("power law"), "{}", s.report);
        let f = s.fragment.expect("a fragment");
        assert!(f.contains("rheology = ") && !f.contains("/tmp"), "{f}");
        assert!(s.plot_png_base64.starts_with("iVBORw0KGgo"));
        let e = super::rheology("x.csv", b"a,b\n1,2\n", "").expect_err("refused");
        assert!(e.message().contains("x.csv"), "{e}");
    }

    #[test]
    fn flow_and_lag_fit_the_bundled_measurements() {
        let csv = include_bytes!("../../data/calibration/flow-two-pastes.csv");
        let cfg = crate::serve::design::check(crate::serve::design::BUNDLED[0].1)
            .expect("config")
            .config;
        let s =
            super::flow("flow-two-pastes.csv", csv, Some(cfg.clone()), Some(1.05)).expect("fits");
        assert!(
            s.report.contains("puree") && s.report.contains("custard"),
            "{}",
            s.report
        );
        let f = s.fragment.expect("a fragment with the config");
        assert_eq!(f.matches("[[inlet]]").count(), 2, "{f}");
        assert!(f.contains("pressure_kpa = ") && !f.contains("/tmp"), "{f}");
        assert!(s.plot_png_base64.starts_with("iVBORw0KGgo"));
        // Mass flows without a density: refused, naming what to give.
        let e = super::flow("flow-two-pastes.csv", csv, Some(cfg), None).expect_err("refused");
        assert!(e.message().contains("density"), "{e}");
        // In the page's words, at its field (the library names the command line's flag).
        assert!(!e.message().contains("--"), "{e}");
        assert_eq!(e.field(), Some("cal-density"), "{e}");
        let e = super::flow("f.csv", csv, None, Some(-1.0)).expect_err("refused");
        assert!(e.message().contains("density -1"), "{e}");

        let csv = include_bytes!("../../data/calibration/lag-valve.csv");
        let s = super::lag("lag-valve.csv", csv, "valve").expect("fits");
        let f = s.fragment.expect("valve timings");
        assert!(
            f.contains("valve_open_delay_ms = ") && f.contains("pressure_rise_ms = "),
            "{f}"
        );
        let csv = include_bytes!("../../data/calibration/lag-syringe.csv");
        let s = super::lag("lag-syringe.csv", csv, "syringe").expect("fits");
        assert!(
            s.fragment.expect("lag").contains("lag_k = "),
            "{}",
            s.report
        );
        assert!(super::lag("x.csv", csv, "pump").is_err());
    }

    /// The bundled frames as the page uploads them.
    fn bundled_frames() -> Vec<crate::serve::design::Upload> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/calibration/camera");
        let mut names: Vec<_> = std::fs::read_dir(&dir)
            .expect("the bundled frames")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
            .into_iter()
            .map(|name| crate::serve::design::Upload {
                bytes: std::fs::read(dir.join(&name)).expect("a frame"),
                name,
            })
            .collect()
    }

    fn form(fps: &str, mm_per_px: &str) -> super::CameraForm {
        super::CameraForm {
            fps: fps.into(),
            mm_per_px: mm_per_px.into(),
            target_width: "1.2".into(),
            ..Default::default()
        }
    }

    #[test]
    fn the_bundled_frames_give_the_commands_figures() {
        use crate::calibrate::camera;
        let cfg = crate::serve::design::check(crate::serve::design::BUNDLED[0].1)
            .expect("config")
            .config;
        let frames = bundled_frames();
        let s = super::camera(
            &frames,
            &form("30", "0.02"),
            Some(cfg.clone()),
            super::CAMERA_LIMITS,
        )
        .expect("fits");
        // Rendered at 4.5 px/frame and 48 px wide, 30 fps at 0.02 mm/px: 2.7 mm/s, 0.96 mm
        // (what tests/calibrate_cli.rs expects of the command on these frames).
        assert!(s.report.contains("V_ex = 2.70"), "{}", s.report);
        assert!(s.report.contains("D_ex = 0.96"), "{}", s.report);
        assert!(
            s.report
                .starts_with("camera: 12 frames of 160x120 px from frames\n"),
            "{}",
            s.report
        );
        // The library on the bundled folder with the options the command builds: the same
        // report but for the folder's name.
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/calibration/camera");
        let mut o = camera::Options::new(30.0, 0.02);
        o.target_width_mm = Some(1.2);
        o.config = Some(cfg);
        let cli = camera::calibrate(&dir, &o).expect("the command's fit");
        let body = |r: &str| r.lines().skip(1).collect::<Vec<_>>().join("\n");
        assert_eq!(body(&s.report), body(&cli.report()));
        let f = s.fragment.expect("a fragment with the target width");
        assert!(
            f.contains("[motion]\nprint_speed_mm_s = ") && !f.contains("/tmp"),
            "{f}"
        );
        assert_eq!(
            f.lines().skip(1).collect::<Vec<_>>(),
            cli.fragment()
                .expect("fragment")
                .lines()
                .skip(1)
                .collect::<Vec<_>>()
        );
        assert!(s.plot_png_base64.starts_with("iVBORw0KGgo"));
        eprintln!("{}{f}", s.report);
        // Without a target width: the figures, no fragment.
        let mut no_target = form("30", "0.02");
        no_target.target_width.clear();
        let s = super::camera(&frames, &no_target, None, super::CAMERA_LIMITS).expect("fits");
        assert!(
            s.fragment.is_none() && s.report.contains("V_ex = 2.70"),
            "{}",
            s.report
        );
    }

    /// The camera page's refusal of `uploads` with `f` under `limits`.
    fn refused(
        uploads: &[crate::serve::design::Upload],
        f: &super::CameraForm,
        limits: crate::calibrate::camera::frames::Limits,
    ) -> String {
        super::camera(uploads, f, None, limits)
            .expect_err("refused")
            .message()
            .to_string()
    }

    #[test]
    fn bad_fields_are_refused_naming_them() {
        let frames = bundled_frames();
        let limits = super::CAMERA_LIMITS;
        let ok = form("30", "0.02");
        let e = refused(&[], &ok, limits);
        assert!(e.contains("choose the frames"), "{e}");
        let e = refused(&frames[..1], &ok, limits);
        assert!(
            e.contains("frame_000.png: one frame") && e.contains("two or more"),
            "{e}"
        );
        let e = refused(&frames, &form("", "0.02"), limits);
        assert!(
            e.contains("frame rate") && e.contains("frames per second"),
            "{e}"
        );
        let e = refused(&frames, &form("30", " "), limits);
        assert!(e.contains("mm per pixel"), "{e}");
        let e = refused(&frames, &form("-3", "0.02"), limits);
        assert!(
            e.contains("frame rate \"-3\": give a number above zero"),
            "{e}"
        );
        let e = refused(&frames, &form("30", "NaN"), limits);
        assert!(e.contains("scale \"NaN\""), "{e}");
        let mut f = ok.clone();
        f.window = "4".into();
        let e = refused(&frames, &f, limits);
        assert!(
            e.contains("smoothing window") && e.contains("odd number"),
            "{e}"
        );
        let mut f = ok.clone();
        f.roi = "1,2,3".into();
        let e = refused(&frames, &f, limits);
        assert!(
            e.contains("region of interest") && e.contains("X,Y,W,H"),
            "{e}"
        );
        let mut f = ok.clone();
        f.roi = "155,0,100,100".into();
        let e = refused(&frames, &f, limits);
        assert!(
            e.starts_with("the region of interest leaves 5x100 px") && !e.contains("--"),
            "{e}"
        );
    }

    #[test]
    fn bad_frames_are_refused_naming_them() {
        let limits = super::CAMERA_LIMITS;
        let ok = form("30", "0.02");
        // A corrupt frame, a frame of another size, another kind of file, a name twice.
        let mut bad = bundled_frames();
        bad[3].bytes = b"\x89PNG\r\n\x1a\nnot a picture".to_vec();
        let e = refused(&bad, &ok, limits);
        assert!(
            e.starts_with("frame_003.png: ") && e.contains("leave it out"),
            "{e}"
        );
        let mut bad = bundled_frames();
        let mut png = Vec::new();
        image::GrayImage::new(100, 80)
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("a PNG");
        bad[5].bytes = png;
        let e = refused(&bad, &ok, limits);
        assert!(
            e.starts_with(
                "frame_005.png: this frame is 100x80 px but the first (by name) is 160x120"
            ),
            "{e}"
        );
        let mut bad = bundled_frames();
        bad[2].name = "notes.txt".into();
        let e = refused(&bad, &ok, limits);
        assert!(e.starts_with("notes.txt: not a frame"), "{e}");
        let mut bad = bundled_frames();
        bad[2].name = "frame_001.png".into();
        let e = refused(&bad, &ok, limits);
        assert!(e.contains("two frames are named frame_001.png"), "{e}");
    }

    #[test]
    fn frames_over_the_limits_or_blank_are_refused_saying_so() {
        use crate::serve::design::Upload;
        let frames = bundled_frames();
        let limits = super::CAMERA_LIMITS;
        let ok = form("30", "0.02");
        // Over the frame and pixel limits (small ones here; the server's are the command's).
        let small = crate::calibrate::camera::frames::Limits {
            max_frames: 5,
            max_pixels: 100_000,
        };
        let e = refused(&frames, &ok, small);
        assert!(
            e.contains("more than 5 frames") && e.contains("send fewer"),
            "{e}"
        );
        let few = crate::calibrate::camera::frames::Limits {
            max_frames: 5,
            max_pixels: 50_000,
        };
        let e = refused(&frames[..5], &ok, few);
        assert!(
            e.contains("96000 pixels, over the limit of 50000") && e.contains("dashboard's limit"),
            "{e}"
        );

        // Blank frames: nothing to measure, said so.
        let blank: Vec<Upload> = (0..3)
            .map(|i| {
                let mut png = Vec::new();
                image::GrayImage::from_pixel(64, 48, image::Luma([90]))
                    .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                    .expect("a PNG");
                Upload {
                    name: format!("f{i}.png"),
                    bytes: png,
                }
            })
            .collect();
        let e = refused(&blank, &ok, limits);
        assert!(e.contains("region of interest"), "{e}");
    }
}
