//! The bundled measurement samples the Calibrate page offers (the CSVs under
//! `host-tools/data/calibration/`, compiled in): a new user can run each fit before
//! measuring anything. Data only; the fits are `calibrate`'s.

/// A bundled sample: file name, the calibration it is for, what the page fills in with
/// it (density g/ml for mass flows, the lag's inlet kind), and its bytes.
pub struct Sample {
    /// File name.
    pub name: &'static str,
    /// `rheology`, `flow` or `lag`.
    pub what: &'static str,
    /// The flow fit's density (g/ml) or the lag fit's inlet (`valve`, `syringe`); "" none.
    pub with: &'static str,
    /// The CSV.
    pub bytes: &'static [u8],
}

/// The samples, in the order the page lists them.
pub const SAMPLES: [Sample; 6] = [
    Sample {
        name: "rheology-puree.csv",
        what: "rheology",
        with: "",
        bytes: include_bytes!("../../data/calibration/rheology-puree.csv"),
    },
    Sample {
        name: "rheology-hummus.csv",
        what: "rheology",
        with: "",
        bytes: include_bytes!("../../data/calibration/rheology-hummus.csv"),
    },
    Sample {
        name: "rheology-gel-oscillatory.csv",
        what: "rheology",
        with: "",
        bytes: include_bytes!("../../data/calibration/rheology-gel-oscillatory.csv"),
    },
    Sample {
        name: "flow-two-pastes.csv",
        what: "flow",
        with: "1.05",
        bytes: include_bytes!("../../data/calibration/flow-two-pastes.csv"),
    },
    Sample {
        name: "lag-valve.csv",
        what: "lag",
        with: "valve",
        bytes: include_bytes!("../../data/calibration/lag-valve.csv"),
    },
    Sample {
        name: "lag-syringe.csv",
        what: "lag",
        with: "syringe",
        bytes: include_bytes!("../../data/calibration/lag-syringe.csv"),
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    /// Every sample fits with what the page fills in (a sample that no longer fits would
    /// greet a new user with an error).
    #[test]
    fn every_sample_fits() {
        let cfg = super::super::design::check(super::super::design::BUNDLED[0].1)
            .expect("config")
            .config;
        for s in &SAMPLES {
            let r = match s.what {
                "rheology" => super::super::calibrate::rheology(s.name, s.bytes, ""),
                "lag" => super::super::calibrate::lag(s.name, s.bytes, s.with),
                "flow" => super::super::calibrate::flow(
                    s.name,
                    s.bytes,
                    Some(cfg.clone()),
                    s.with.parse().ok(),
                ),
                other => panic!("{other}"),
            };
            let shown = r.unwrap_or_else(|e| panic!("{}: {e}", s.name));
            assert!(!shown.report.is_empty(), "{}", s.name);
        }
    }
}
