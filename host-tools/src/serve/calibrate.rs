//! Calibration for the dashboard: a rheology measurement (flow curve or oscillatory sweep
//! CSV) fitted by `calibrate::rheology` as `dollop calibrate rheology` fits it: the
//! report (fits, 95 % intervals, verdicts), the TOML fragment for an `[[inlet]]`, and the
//! plot of data against fits. The page applies the fragment to the config in its editor.
//! Other calibrations (flow, lag, camera, syringe) are the command's only, for now.

use super::error::{ApiError, ApiResult};
use crate::calibrate::output;
use crate::calibrate::rheology::{self, Kind};
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
    let dir = tempfile::tempdir()
        .map_err(|e| ApiError::internal(format!("cannot create a temporary folder: {e}")))?;
    let clean = super::design::safe_name(name, "data.csv");
    let path = dir.path().join(&clean);
    std::fs::write(&path, bytes)
        .map_err(|e| ApiError::internal(format!("cannot keep the upload: {e}")))?;
    let ours = format!("{}/", dir.path().display());
    let strip = |s: String| s.replace(&ours, "");
    let cal = rheology::calibrate(
        &path,
        rheology::Options {
            kind,
            ..Default::default()
        },
    )
    .map_err(|e| ApiError::bad(strip(e.to_string())))?;
    let plot = dir.path().join("plot.png");
    let mut out = output::Outputs::new();
    cal.plot(&plot, &mut out)
        .map_err(|e| ApiError::bad(strip(e.to_string())))?;
    output::commit(out).map_err(|e| ApiError::internal(strip(e.to_string())))?;
    let png = std::fs::read(&plot)
        .map_err(|e| ApiError::internal(format!("cannot read the plot: {e}")))?;
    Ok(Shown {
        report: strip(cal.report()),
        fragment: cal.fragment().map(strip),
        plot_png_base64: base64(&png),
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
        assert!(e.error.contains("x.csv"), "{}", e.error);
    }
}
