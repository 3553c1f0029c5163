//! Calibration for the dashboard, calling the library code behind `dollop calibrate`:
//! rheology (flow curve or oscillatory sweep), flow (flow against supply pressure, per
//! material, with the Design page's config for the channel) and lag (a valve's or a
//! syringe's start-up mass curve). Each gives the report as the command prints it (fits,
//! 95 % intervals, verdicts), the TOML fragment, and the plot of data against fits; the
//! page applies the fragment to the config in its editor. Camera frames and the syringe
//! model are the command's only, for now.

use super::error::{ApiError, ApiResult};
use crate::calibrate::error::CalError;
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
    path: std::path::PathBuf,
}

impl Kept {
    fn new(name: &str, bytes: &[u8]) -> ApiResult<Self> {
        let dir = tempfile::tempdir()
            .map_err(|e| ApiError::internal(format!("cannot create a temporary folder: {e}")))?;
        let path = dir.path().join(super::design::safe_name(name, "data.csv"));
        std::fs::write(&path, bytes)
            .map_err(|e| ApiError::internal(format!("cannot keep the upload: {e}")))?;
        Ok(Kept { dir, path })
    }

    fn strip(&self, s: String) -> String {
        s.replace(&format!("{}/", self.dir.path().display()), "")
    }

    /// The report, the fragment and the plot `plot` draws.
    fn show(
        &self,
        report: String,
        fragment: Option<String>,
        plot: impl FnOnce(&std::path::Path, &mut output::Outputs) -> Result<(), CalError>,
    ) -> ApiResult<Shown> {
        let at = self.dir.path().join("plot.png");
        let mut out = output::Outputs::new();
        plot(&at, &mut out).map_err(|e| ApiError::bad(self.strip(e.to_string())))?;
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
    .map_err(|e| ApiError::bad(kept.strip(e.to_string())))?;
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
    .map_err(|e| ApiError::bad(kept.strip(e.to_string())))?;
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
    .map_err(|e| ApiError::bad(kept.strip(e.to_string())))?;
    kept.show(cal.report(), cal.fragment(), |p, o| cal.plot(p, o))
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
        assert!(e.error.contains("x.csv"), "{}", e.error);
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
        assert!(e.error.contains("density"), "{}", e.error);
        let e = super::flow("f.csv", csv, None, Some(-1.0)).expect_err("refused");
        assert!(e.error.contains("density -1"), "{}", e.error);

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
}
