//! What a front end asks the slicer for: `SliceRequest`, the options as a person gives
//! them (text where they type text: a palette, a colour, an origin), which both
//! `dollop slice` (from its flags) and the dashboard (from its form) build, and its check
//! into `SliceOptions`; the G-code export's style and dialect as enums. A refused value is
//! an `OptionError` naming the option as a `SliceOption`: each front end words that name
//! its own way (a flag, a field on the page). Slicing itself is the rest of `slicer`'s.

use super::error::{OptionError, SliceOption};
use super::gcode::Style;
use super::gcode_dialect::{Dialect, Kind};
use super::image::{parse_colour, Classify, ImageOptions, Mirror, Rotation};
use super::{Limits, PathOptions, SliceError, SliceOptions};

/// How the G-code follows the flow.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GcodeStyle {
    /// Sampled from the executor's run of the job (`gcode_exec`).
    #[default]
    Run,
    /// The advance-distance feed-rate profile (`gcode::Style::Fine`).
    Fine,
    /// The seed paper's feed-rate profile (`gcode::Style::Coarse`).
    Coarse,
}

impl GcodeStyle {
    /// Every style, in the order the command line lists them.
    pub const ALL: [GcodeStyle; 3] = [GcodeStyle::Run, GcodeStyle::Fine, GcodeStyle::Coarse];

    /// The style's word (`run`, `fine`, `coarse`).
    pub fn name(self) -> &'static str {
        match self {
            GcodeStyle::Run => "run",
            GcodeStyle::Fine => "fine",
            GcodeStyle::Coarse => "coarse",
        }
    }

    /// The style of a word, if it is one.
    pub fn from_name(word: &str) -> Option<GcodeStyle> {
        GcodeStyle::ALL.into_iter().find(|s| s.name() == word)
    }

    /// The feed-rate profile of `Fine` and `Coarse` (`None` for `Run`, which is no profile).
    pub fn profile(self) -> Option<Style> {
        match self {
            GcodeStyle::Run => None,
            GcodeStyle::Fine => Some(Style::default()),
            GcodeStyle::Coarse => Some(Style::Coarse { segments: 4 }),
        }
    }
}

/// What the G-code export is asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct GcodeRequest {
    /// How the speeds follow the flow.
    pub style: GcodeStyle,
    /// How valve changes are written (`GcodeStyle::Run` only).
    pub dialect: Kind,
    /// Each inlet's valve port, inlet 0 first, as typed (`0,1`) [default: 0, 1, ..].
    pub ports: Option<String>,
    /// Largest G-code written, bytes (`GcodeStyle::Run`).
    pub max_bytes: u64,
}

impl Default for GcodeRequest {
    fn default() -> Self {
        GcodeRequest {
            style: GcodeStyle::Run,
            dialect: Kind::default(),
            ports: None,
            max_bytes: 1024 << 20,
        }
    }
}

impl GcodeRequest {
    /// The dialect with its ports checked for `inlets` inlets: at most one per inlet, each
    /// in the dialect's range, none twice (ports left to their defaults included).
    pub fn dialect(&self, inlets: usize) -> Result<Dialect, SliceError> {
        let kind = self.dialect;
        let max = Dialect::max_port(kind);
        let mut ports = Vec::new();
        if let Some(list) = &self.ports {
            let bad = || {
                SliceError::BadOption(OptionError::new(
                    SliceOption::GcodePorts,
                    Some(format!("{list:?}")),
                    format!(
                        "must be up to {inlets} different port numbers (0 to {max}{}) separated by commas, inlet 0 first",
                        if kind == Kind::Marlin { ": Marlin's fans P0 to P7" } else { "" }
                    ),
                ))
            };
            for t in list.split(',') {
                let p: u32 = t.trim().parse().map_err(|_| bad())?;
                if p > max || ports.contains(&p) {
                    return Err(bad());
                }
                ports.push(p);
            }
            if ports.len() > inlets {
                return Err(bad());
            }
            // Ports left to their defaults must not collide with the ones given.
            for i in ports.len()..inlets {
                if ports.contains(&(i as u32)) {
                    return Err(bad());
                }
            }
        }
        Ok(Dialect { kind, ports })
    }
}

/// A slice as a person asks for it; `Default` is what `dollop slice` does unasked.
#[derive(Clone, Debug, PartialEq)]
pub struct SliceRequest {
    /// Images: printed width, mm.
    pub width_mm: Option<f64>,
    /// Images: printed height, mm.
    pub height_mm: Option<f64>,
    /// Images: layers to stack. Meshes: print at most this many.
    pub layers: Option<usize>,
    /// Images: rotation.
    pub rotate: Rotation,
    /// Images: mirror (after rotating).
    pub mirror: Mirror,
    /// Images: swap the materials.
    pub invert: bool,
    /// Images: grey level dividing material 0 from 1 (without a palette).
    pub threshold: u8,
    /// Images: `auto` or `#rrggbb,#rrggbb,...`, as typed.
    pub palette: Option<String>,
    /// Images: the colour not printed, as typed.
    pub background: Option<String>,
    /// Images: RGB distance within which a pixel is background.
    pub background_tolerance: f64,
    /// Lower-left corner on the plate, `X,Y` in mm as typed [default: centred].
    pub origin: Option<String>,
    /// Priming bead length, mm.
    pub prime_mm: Option<f64>,
    /// Runs shorter than this are merged into their neighbours, mm.
    pub min_run_mm: f64,
    /// Rows whose ends lie this close are joined, mm.
    pub connect_mm: Option<f64>,
    /// Corner markers for `dollop inspect`.
    pub markers: bool,
    /// The calibration pattern instead of a design (with markers).
    pub calibration_pattern: bool,
    /// Resource limits.
    pub limits: Limits,
    /// Show progress bars on a terminal.
    pub progress: bool,
    /// The G-code export, when one is written.
    pub gcode: GcodeRequest,
}

impl Default for SliceRequest {
    fn default() -> Self {
        SliceRequest {
            width_mm: None,
            height_mm: None,
            layers: None,
            rotate: Rotation::default(),
            mirror: Mirror::None,
            invert: false,
            threshold: 150,
            palette: None,
            background: None,
            background_tolerance: 40.0,
            origin: None,
            prime_mm: None,
            min_run_mm: 0.1,
            connect_mm: None,
            markers: false,
            calibration_pattern: false,
            limits: Limits::default(),
            progress: true,
            gcode: GcodeRequest::default(),
        }
    }
}

impl SliceRequest {
    /// The slicer options this request asks for, checked.
    pub fn options(&self) -> Result<SliceOptions, SliceError> {
        let bad = |option, value: Option<String>, problem: String| {
            SliceError::BadOption(OptionError::new(option, value, problem))
        };
        let classify = match self.palette.as_deref() {
            None => Classify::Threshold(self.threshold),
            Some("auto") => Classify::AutoPalette,
            Some(list) => Classify::Palette(
                list.split(',')
                    .map(parse_colour)
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|e| bad(SliceOption::Palette, None, e.to_string()))?,
            ),
        };
        let background = self
            .background
            .as_deref()
            .map(parse_colour)
            .transpose()
            .map_err(|e| bad(SliceOption::Background, None, e.to_string()))?;
        if !(self.min_run_mm.is_finite() && self.min_run_mm >= 0.0) {
            return Err(bad(
                SliceOption::MinRun,
                Some(self.min_run_mm.to_string()),
                "must be 0 or more".into(),
            ));
        }
        let origin = match self.origin.as_deref() {
            None => None,
            Some(o) => {
                let v: Vec<f64> = o.split(',').filter_map(|t| t.trim().parse().ok()).collect();
                match v[..] {
                    [x, y] if x.is_finite() && y.is_finite() => Some([x, y]),
                    _ => {
                        return Err(bad(
                            SliceOption::Origin,
                            Some(format!("{o:?}")),
                            "must be two numbers X,Y in mm".into(),
                        ))
                    }
                }
            }
        };
        if self.layers == Some(0) {
            return Err(bad(
                SliceOption::Layers,
                Some("0".into()),
                "must be at least 1".into(),
            ));
        }
        if let Some(c) = self.connect_mm {
            if !(c.is_finite() && c >= 0.0) {
                return Err(bad(
                    SliceOption::Connect,
                    Some(c.to_string()),
                    "must be a distance of 0 or more".into(),
                ));
            }
        }
        if !(self.background_tolerance.is_finite() && self.background_tolerance >= 0.0) {
            return Err(bad(
                SliceOption::BackgroundTolerance,
                Some(self.background_tolerance.to_string()),
                "must be a distance of 0 or more".into(),
            ));
        }
        if let Some(p) = self.prime_mm {
            if !p.is_finite() {
                return Err(bad(
                    SliceOption::Prime,
                    Some(p.to_string()),
                    "must be a number of mm".into(),
                ));
            }
        }
        Ok(SliceOptions {
            image: ImageOptions {
                width_mm: self.width_mm,
                height_mm: self.height_mm,
                rotate: self.rotate,
                mirror: self.mirror,
                invert: self.invert,
                classify,
                background,
                background_tolerance: self.background_tolerance,
                ..ImageOptions::default()
            },
            layers: self.layers,
            path: PathOptions {
                origin_mm: origin,
                prime_mm: self.prime_mm,
                connect_mm: self.connect_mm,
            },
            min_run_mm: self.min_run_mm,
            progress: self.progress,
            limits: self.limits,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_request_checks() {
        let o = SliceRequest::default()
            .options()
            .expect("the defaults work");
        assert_eq!(o.min_run_mm, 0.1);
        assert_eq!(o.image.classify, Classify::Threshold(150));
    }

    #[test]
    fn a_refused_value_names_its_option_and_reads_after_any_name() {
        let r = SliceRequest {
            min_run_mm: -1.0,
            ..Default::default()
        };
        match r.options() {
            Err(SliceError::BadOption(e)) => {
                assert_eq!(e.option, SliceOption::MinRun);
                assert_eq!(
                    e.message("--min-run-mm"),
                    "--min-run-mm -1 must be 0 or more"
                );
            }
            other => panic!("{other:?}"),
        }
        let r = SliceRequest {
            palette: Some("#12".into()),
            ..Default::default()
        };
        match r.options() {
            Err(SliceError::BadOption(e)) => {
                assert_eq!(e.option, SliceOption::Palette);
                assert!(e.message("Palette").starts_with("Palette: "), "{e}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn ports_are_checked_against_the_dialect() {
        let g = GcodeRequest {
            ports: Some("3,3".into()),
            ..Default::default()
        };
        assert!(matches!(
            g.dialect(2),
            Err(SliceError::BadOption(OptionError {
                option: SliceOption::GcodePorts,
                ..
            }))
        ));
        let g = GcodeRequest {
            ports: Some("5,6".into()),
            ..Default::default()
        };
        assert_eq!(g.dialect(2).expect("fine").ports, [5, 6]);
    }

    #[test]
    fn styles_round_trip_their_words() {
        for s in GcodeStyle::ALL {
            assert_eq!(GcodeStyle::from_name(s.name()), Some(s));
        }
        assert_eq!(GcodeStyle::from_name("smooth"), None);
    }
}
