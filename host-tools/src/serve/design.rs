//! Design to job for the dashboard: the configs it offers (bundled, or `--config`), a
//! config's fields as the editor shows them and its check (`dollop config --check`'s
//! validation, each error tied to its field, the derived figures), and slicing uploaded
//! designs with the CLI's options into a job and its toolpath for the browser to draw.

use super::error::{ApiError, ApiResult};
use crate::slicer::{self, SliceError, SliceRequest, Sliced};
use dollop::command::MoveKind;
use dollop::config::Config;
use dollop::Command;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The configs compiled into the binary, by name.
pub const BUNDLED: [(&str, &str); 4] = [
    (
        "seed-paper-valves",
        include_str!("../../../configs/seed-paper-valves.toml"),
    ),
    (
        "seed-paper",
        include_str!("../../../configs/seed-paper.toml"),
    ),
    (
        "food-pastes",
        include_str!("../../../configs/food-pastes.toml"),
    ),
    ("syringes", include_str!("../../../configs/syringes.toml")),
];

/// The bundled designs, by file name.
pub const DESIGNS: [(&str, &[u8]); 4] = [
    ("logo.png", include_bytes!("../../designs/logo.png")),
    (
        "chessboard.png",
        include_bytes!("../../designs/chessboard.png"),
    ),
    (
        "cube-shell.stl",
        include_bytes!("../../designs/cube-shell.stl"),
    ),
    (
        "cube-ball.stl",
        include_bytes!("../../designs/cube-ball.stl"),
    ),
];

/// One editable value of a config: where it is and its TOML text.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Field {
    /// `channel.line_pitch_mm`, `inlet[0].pressure_kpa`, `motion.max_accel_mm_s2`.
    pub path: String,
    /// The value as TOML (`0.8`, `"auto"`, `[80.0, 80.0, 400.0]`, `{ newtonian = ... }`).
    pub raw: String,
}

/// What the core derives from a valid config (the figures `dollop config --check` prints).
#[derive(Debug, Clone, Serialize)]
pub struct Derived {
    /// Label and value, in order.
    pub figures: Vec<(String, String)>,
}

/// A config that parsed and validated.
pub struct Checked {
    /// The config.
    pub config: Config,
    /// Its TOML text (edits applied).
    pub text: String,
    /// Its fields, for the editor.
    pub fields: Vec<Field>,
    /// The derived figures.
    pub derived: Derived,
}

fn parse_table(text: &str) -> ApiResult<toml::Table> {
    text.parse::<toml::Table>().map_err(|e| {
        ApiError::bad(format!(
            "the config is not valid TOML: {}",
            one_line(e.message())
        ))
        .with_span(text, e.span())
    })
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

impl ApiError {
    /// Ties a TOML error to the field on the line where it was found.
    fn with_span(self, text: &str, span: Option<std::ops::Range<usize>>) -> Self {
        match span.and_then(|s| field_at(text, s.start)) {
            Some(f) => self.at(f),
            None => self,
        }
    }
}

/// The field (as `Field::path`) whose `key = value` line holds byte `at` of `text`.
fn field_at(text: &str, at: usize) -> Option<String> {
    let mut section = String::new();
    let mut counts: std::collections::HashMap<String, usize> = Default::default();
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        let t = line.trim();
        if let Some(name) = t.strip_prefix("[[").and_then(|r| r.split("]]").next()) {
            let n = counts.entry(name.trim().to_string()).or_insert(0);
            section = format!("{}[{}]", name.trim(), *n);
            *n += 1;
        } else if let Some(name) = t.strip_prefix('[').and_then(|r| r.split(']').next()) {
            // A sub-table of an array element (`[inlet.rheology]`) belongs to the element.
            let name = name.trim();
            let head = name.split('.').next().unwrap_or(name);
            section = match counts.get(head) {
                Some(n) if *n > 0 => format!(
                    "{head}[{}].{}",
                    n - 1,
                    name.split_once('.').map(|x| x.1).unwrap_or("")
                ),
                _ => name.to_string(),
            };
        }
        if at < offset + line.len() {
            let key = t.split('=').next()?.trim();
            if t.contains('=') && !key.is_empty() {
                let base = section.trim_end_matches('.');
                // Keys of a nested table belong to the field that holds the table.
                let base = match base.split_once("].") {
                    Some((arr, sub)) => {
                        return Some(format!("{arr}].{}", sub.split('.').next().unwrap_or(sub)))
                    }
                    None => base,
                };
                return Some(if base.is_empty() {
                    key.to_string()
                } else {
                    format!("{base}.{key}")
                });
            }
            return (!section.is_empty()).then(|| section.clone());
        }
        offset += line.len();
    }
    None
}

fn parse_doc(text: &str) -> ApiResult<toml_edit::DocumentMut> {
    // The same TOML as `parse_table` takes (checked there first, for its error's span).
    parse_table(text)?;
    text.parse::<toml_edit::DocumentMut>().map_err(|e| {
        ApiError::bad(format!(
            "the config is not valid TOML: {}",
            one_line(e.message())
        ))
        .with_span(text, e.span())
    })
}

/// A value as the editor shows it: its TOML without the spacing and comments around it.
fn raw_of(item: &toml_edit::Item) -> Option<String> {
    let mut v = match item {
        toml_edit::Item::Value(v) => v.clone(),
        // A sub-table written as `[inlet.rheology]`: shown inline, as one field.
        toml_edit::Item::Table(t) => toml_edit::Value::InlineTable(t.clone().into_inline_table()),
        _ => return None,
    };
    v.decor_mut().clear();
    Some(v.to_string())
}

/// The fields of a config's TOML, in file order (sections, then `[[inlet]]` tables).
pub fn fields(text: &str) -> ApiResult<Vec<Field>> {
    let doc = parse_doc(text)?;
    let mut out = Vec::new();
    for (section, item) in doc.iter() {
        match item {
            toml_edit::Item::Table(t) => {
                for (k, v) in t.iter() {
                    if let Some(raw) = raw_of(v) {
                        out.push(Field {
                            path: format!("{section}.{k}"),
                            raw,
                        });
                    }
                }
            }
            toml_edit::Item::ArrayOfTables(a) => {
                for (i, t) in a.iter().enumerate() {
                    for (k, v) in t.iter() {
                        if let Some(raw) = raw_of(v) {
                            out.push(Field {
                                path: format!("{section}[{i}].{k}"),
                                raw,
                            });
                        }
                    }
                }
            }
            other => {
                if let Some(raw) = raw_of(other) {
                    out.push(Field {
                        path: section.to_string(),
                        raw,
                    });
                }
            }
        }
    }
    Ok(out)
}

/// Sets `path` (a `Field::path`) in `doc` to `value`, keeping the old value's spacing and
/// comment on its line.
fn set(doc: &mut toml_edit::DocumentMut, path: &str, mut value: toml_edit::Value) -> ApiResult<()> {
    let unknown = || ApiError::bad(format!("{path}: no such field in this config")).at(path);
    let (head, key) = match path.split_once('.') {
        Some((h, k)) => (h, Some(k)),
        None => (path, None),
    };
    let table: &mut toml_edit::Table = match (key, head.split_once('[')) {
        (None, _) => doc.as_table_mut(),
        (Some(_), Some((name, idx))) => {
            let i: usize = idx.trim_end_matches(']').parse().map_err(|_| unknown())?;
            doc.get_mut(name)
                .and_then(|v| v.as_array_of_tables_mut())
                .and_then(|a| a.get_mut(i))
                .ok_or_else(unknown)?
        }
        (Some(_), None) => doc
            .get_mut(head)
            .and_then(|v| v.as_table_mut())
            .ok_or_else(unknown)?,
    };
    let key = key.unwrap_or(head);
    match table.get_mut(key) {
        Some(toml_edit::Item::Value(old)) => {
            *value.decor_mut() = old.decor().clone();
            *old = value;
        }
        Some(item) => *item = toml_edit::Item::Value(value),
        None => {
            table.insert(key, toml_edit::Item::Value(value));
        }
    }
    Ok(())
}

/// Applies the editor's edits to `text`; each value is TOML (`0.8`, `"auto"`). The rest
/// of the file stays as written: its order, comments and spacing.
pub fn apply(text: &str, edits: &[Field]) -> ApiResult<String> {
    if edits.is_empty() {
        return Ok(text.to_string());
    }
    let mut doc = parse_doc(text)?;
    for e in edits {
        let value = e.raw.trim().parse::<toml_edit::Value>().map_err(|_| {
            ApiError::bad(format!(
                "{}: {:?} is not a value (a number, \"text\" in quotes, [a, b] or {{ k = v }})",
                e.path, e.raw
            ))
            .at(&e.path)
        })?;
        set(&mut doc, &e.path, value)?;
    }
    Ok(doc.to_string())
}

/// The field of a core validation error, as the editor names it.
fn field_of(problem: &dollop::ConfigError) -> String {
    let f = problem.field.to_string();
    // `motion.max_accel_mm_s2[1]` is one input holding the whole list.
    match (f.starts_with("inlet["), f.rfind('[')) {
        (false, Some(i)) => f[..i].to_string(),
        _ => f,
    }
}

/// Parses and validates a config as `dollop config --check` does.
pub fn check(text: &str) -> ApiResult<Checked> {
    let config: Config = toml::from_str(text).map_err(|e| {
        ApiError::bad(format!(
            "the config does not parse: {}",
            one_line(e.message())
        ))
        .with_span(text, e.span())
    })?;
    let m = match slicer::validate(Path::new("config"), &config) {
        Ok(m) => m,
        Err(SliceError::ConfigInvalid { problem, .. }) => {
            return Err(ApiError::bad(problem.to_string()).at(field_of(&problem)))
        }
        Err(e) => return Err(ApiError::bad(e.to_string())),
    };
    let transit = slicer::toolpath::transit_mm(&m);
    let mut figures = vec![
        ("bead section S".into(), format!("{:.4} mm²", m.bead_area)),
        (
            "channel volume".into(),
            format!("{:.4} mm³", m.v_channel.mm3::<f64>()),
        ),
        (
            "hanging filament".into(),
            format!("{:.4} mm³", m.v_hang.mm3::<f64>()),
        ),
        (
            "advance distance".into(),
            format!(
                "{transit:.3} mm (priming bead at least {:.1} mm)",
                2.0 * transit
            ),
        ),
        (
            "fastest flow-driven speed".into(),
            format!(
                "{:.2} mm/s (cap {} mm/s)",
                m.v_flow_max, config.motion.print_speed_max_mm_s
            ),
        ),
        ("corner radius".into(), format!("{:.3} mm", m.corner_radius)),
    ];
    // `dollop config --check`'s line, and its note when the U-turns take too much.
    let turns = slicer::row_turns::RowTurns::of(&config, &m);
    figures.push((
        "row-end U-turns".into(),
        format!(
            "{}{}",
            turns.figure("mm/s²"),
            turns
                .advice()
                .map_or(String::new(), |a| format!(". Note: {a}"))
        ),
    ));
    for (i, (inlet, c)) in m.inlets.iter().zip(config.inlets.iter()).enumerate() {
        figures.push((
            format!("inlet {i} ({}) supply", c.material),
            format!("{:.2} kPa", inlet.supply_pa / 1e3),
        ));
    }
    Ok(Checked {
        fields: fields(text)?,
        text: text.to_string(),
        config,
        derived: Derived { figures },
    })
}

/// The slicing options of the page, by the names its form sends (`opt-width_mm`, ...;
/// strings as typed, empty = unset). The comments give the matching `dollop slice` flag.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(default)]
pub struct SliceForm {
    /// --width-mm
    pub width_mm: Option<f64>,
    /// --height-mm
    pub height_mm: Option<f64>,
    /// --layers
    pub layers: Option<usize>,
    /// --rotate (0, 90, 180, 270)
    pub rotate: Option<String>,
    /// --mirror (none, x, y)
    pub mirror: Option<String>,
    /// --invert
    pub invert: bool,
    /// --threshold
    pub threshold: Option<u8>,
    /// --palette (auto or colours)
    pub palette: Option<String>,
    /// --background
    pub background: Option<String>,
    /// --background-tolerance
    pub background_tolerance: Option<f64>,
    /// --origin X,Y
    pub origin: Option<String>,
    /// --prime-mm
    pub prime_mm: Option<f64>,
    /// --min-run-mm
    pub min_run_mm: Option<f64>,
    /// --connect-mm
    pub connect_mm: Option<f64>,
    /// --markers: fiducial markers around the part for `dollop inspect`.
    pub markers: bool,
    /// --calibration-pattern: the pattern for `dollop inspect --suggest` instead of a
    /// design (with markers).
    pub calibration_pattern: bool,
}

fn nonempty(s: &Option<String>) -> Option<String> {
    s.as_ref()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
}

impl SliceForm {
    /// The slice these options ask for (the command line's defaults where a field is
    /// empty; no G-code is written from the page).
    pub fn request(&self) -> ApiResult<SliceRequest> {
        use crate::slicer::image::{Mirror, Rotation};
        let rotate = match nonempty(&self.rotate).as_deref() {
            None | Some("0") => Rotation::default(),
            Some("90") => Rotation::R90,
            Some("180") => Rotation::R180,
            Some("270") => Rotation::R270,
            Some(r) => {
                return Err(ApiError::bad(format!(
                    "rotate {r:?}: choose 0, 90, 180 or 270"
                )))
            }
        };
        let mirror = match nonempty(&self.mirror)
            .map(|m| m.to_ascii_lowercase())
            .as_deref()
        {
            None | Some("none") => Mirror::None,
            Some("x") => Mirror::X,
            Some("y") => Mirror::Y,
            Some(_) => {
                let m = nonempty(&self.mirror).unwrap_or_default();
                return Err(ApiError::bad(format!("mirror {m:?}: choose none, x or y")));
            }
        };
        let d = SliceRequest::default();
        Ok(SliceRequest {
            width_mm: self.width_mm,
            height_mm: self.height_mm,
            layers: self.layers,
            rotate,
            mirror,
            invert: self.invert,
            threshold: self.threshold.unwrap_or(d.threshold),
            palette: nonempty(&self.palette),
            background: nonempty(&self.background),
            background_tolerance: self.background_tolerance.unwrap_or(d.background_tolerance),
            origin: nonempty(&self.origin),
            prime_mm: self.prime_mm,
            min_run_mm: self.min_run_mm.unwrap_or(d.min_run_mm),
            connect_mm: self.connect_mm,
            markers: self.markers,
            calibration_pattern: self.calibration_pattern,
            progress: false,
            ..d
        })
    }
}

/// A slicer error as the page says it: a refused option by its field's label (see
/// `ApiError`'s `From<SliceError>`).
pub fn slice_error(e: SliceError) -> ApiError {
    ApiError::from(e)
}

/// An uploaded design file: the name the user gave it and its bytes.
pub struct Upload {
    /// The file name as uploaded.
    pub name: String,
    /// Its content.
    pub bytes: Vec<u8>,
}

/// A file name safe to write in our temporary folder (letters, digits, `._-`; no folders,
/// no leading dots), keeping the extension the reader goes by; `fallback` if nothing is
/// left.
pub(super) fn safe_name(name: &str, fallback: &str) -> String {
    let clean = super::store::plain_name(name);
    if clean.is_empty() {
        fallback.to_string()
    } else {
        clean
    }
}

/// Slices uploaded designs for `config` with `form`'s options. Blocking: run it off the
/// async threads.
pub fn slice(uploads: &[Upload], config: &Config, form: &SliceForm) -> ApiResult<Sliced> {
    if form.calibration_pattern {
        return calibration_pattern(config, form);
    }
    if uploads.is_empty() {
        return Err(ApiError::bad(
            "choose a design: an image, one STL per material, a 3MF, or a slicer's G-code",
        ));
    }
    if uploads
        .iter()
        .any(|u| crate::gcode_in::is_gcode(Path::new(&u.name)))
    {
        return import_gcode(uploads, config, form);
    }
    let req = form.request()?;
    let opts = req.options().map_err(slice_error)?;
    let dir = tempfile::tempdir()
        .map_err(|e| ApiError::internal(format!("cannot create a temporary folder: {e}")))?;
    let mut paths = Vec::new();
    for (i, u) in uploads.iter().enumerate() {
        let mut name = safe_name(&u.name, &format!("design-{i}"));
        if paths
            .iter()
            .any(|p: &PathBuf| p.file_name().is_some_and(|n| n == name.as_str()))
        {
            name = format!("{i}-{name}");
        }
        let path = dir.path().join(&name);
        std::fs::write(&path, &u.bytes)
            .map_err(|e| ApiError::internal(format!("cannot keep the upload {name}: {e}")))?;
        paths.push(path);
    }
    // The slicer names the files in its messages: the user's names, not our folder's.
    let ours = format!("{}/", dir.path().display());
    let strip = |e: slicer::SliceError| ApiError::from(e).map_message(|m| m.replace(&ours, ""));
    let mut sliced = slicer::slice_files(&paths, config, &opts).map_err(strip)?;
    if req.markers {
        let machine = slicer::validate(Path::new("config"), config).map_err(strip)?;
        sliced = slicer::with_markers(sliced, config, &machine).map_err(strip)?;
    }
    sliced.name = sliced.name.replace(&ours, "");
    Ok(sliced)
}

/// Another slicer's G-code, imported as `dollop slice FILE.gcode` does (tools in inlet
/// order, the form's priming bead); the import summary goes to the job's name line.
fn import_gcode(uploads: &[Upload], config: &Config, form: &SliceForm) -> ApiResult<Sliced> {
    use crate::gcode_in::{self, ImportOptions};
    let [u] = uploads else {
        return Err(ApiError::bad(format!(
            "a G-code file is imported alone ({} files chosen)",
            uploads.len()
        )));
    };
    let opts = ImportOptions {
        prime_mm: form.request()?.prime_mm,
        ..ImportOptions::default()
    };
    gcode_in::check_size(u.bytes.len() as u64, opts.max_bytes)
        .map_err(|e| ApiError::bad(format!("{}: {e}", u.name)))?;
    let text = std::str::from_utf8(&u.bytes)
        .map_err(|_| ApiError::bad(format!("{}: not a text file, so not G-code", u.name)))?;
    let machine = slicer::validate(Path::new("config"), config).map_err(slice_error)?;
    let mut imported = gcode_in::import_text(text, &u.name, &opts, config, &machine)
        .map_err(|e| ApiError::bad(format!("{}: {e}", u.name)))?;
    if form.request()?.markers {
        imported.sliced =
            slicer::with_markers(imported.sliced, config, &machine).map_err(slice_error)?;
    }
    Ok(imported.sliced)
}

/// The calibration pattern of `dollop slice --calibration-pattern` for this config (every
/// pair of its materials, switches at several distances), with markers.
fn calibration_pattern(config: &Config, form: &SliceForm) -> ApiResult<Sliced> {
    let opts = form.request()?.options().map_err(slice_error)?;
    let bad = slice_error;
    let machine = slicer::validate(Path::new("config"), config).map_err(bad)?;
    let design = slicer::calibration::pattern(
        machine.inlet_count(),
        config.channel.line_pitch_mm as f64,
        slicer::toolpath::transit_mm(&machine),
    );
    let path = slicer::calibration::path_options(opts.path);
    let sliced = slicer::slice_design(&design, config, &machine, &path).map_err(bad)?;
    let mut sliced = slicer::with_markers(sliced, config, &machine).map_err(bad)?;
    sliced.name = "calibration pattern".into();
    Ok(sliced)
}

/// The toolpath as the browser draws it: polylines per layer and material (travel
/// moves with material -1), coordinates in mm.
#[derive(Debug, Clone, Serialize)]
pub struct Toolpath {
    /// [x0, y0, x1, y1] of everything drawn, mm.
    pub bounds: [f64; 4],
    /// Layers (the priming bead's is layer 0).
    pub layers: usize,
    /// The polylines.
    pub paths: Vec<Polyline>,
    /// Command at which each polyline starts.
    pub starts: Vec<u32>,
    /// Command after each polyline's last (for drawing a print's progress).
    pub ends: Vec<u32>,
    /// Bead width, mm.
    pub bead_mm: f64,
    /// Points were thinned to keep the page responsive.
    pub simplified: bool,
}

/// One run of moves of the same kind.
#[derive(Debug, Clone, Serialize)]
pub struct Polyline {
    /// Layer.
    pub l: usize,
    /// Material (inlet), or -1 for travel.
    pub m: i32,
    /// x0, y0, x1, y1, ... in mm (rounded to 1 µm).
    pub p: Vec<f64>,
}

/// Most points sent to the browser for one toolpath.
const MAX_POINTS: usize = 400_000;

/// The toolpath of a job's commands (`dollop::command::walk`'s moves and layers).
pub fn toolpath(commands: &[Command], start_um: [i32; 3], bead_mm: f64) -> Toolpath {
    let prints = commands
        .iter()
        .filter(|c| matches!(c, Command::Print { .. } | Command::Travel { .. }))
        .count();
    let stride = prints.div_ceil(MAX_POINTS).max(1);
    let mm = |v: i32| (v as f64 * 1e-3 * 1000.0).round() / 1000.0;
    let mut paths: Vec<Polyline> = Vec::new();
    let mut ends = Vec::new();
    let mut starts = Vec::new();
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut n = 0usize;
    let mut tail: Option<[f64; 2]> = None;
    let mut moves = dollop::command::walk(commands, start_um);
    for mv in moves.by_ref() {
        let m = match mv.kind {
            MoveKind::Print { material } => material as i32,
            MoveKind::Travel => -1,
            // A layer change is drawn as nothing; its layer shows on what follows.
            MoveKind::Layer => continue,
        };
        let (ci, layer) = (mv.index, mv.layer as usize);
        let (at, to) = ([mv.from[0], mv.from[1]], [mv.to[0], mv.to[1]]);
        n += 1;
        let same = paths.last().is_some_and(|p| p.l == layer && p.m == m);
        if !same {
            // The previous run ends where it ended, thinned or not.
            if let (Some(p), Some(t)) = (paths.last_mut(), tail.take()) {
                p.p.extend_from_slice(&t);
            }
            paths.push(Polyline {
                l: layer,
                m,
                p: vec![mm(at[0]), mm(at[1])],
            });
            starts.push(ci as u32);
            ends.push(ci as u32);
        }
        if let (Some(p), Some(e)) = (paths.last_mut(), ends.last_mut()) {
            if n.is_multiple_of(stride) || m < 0 {
                p.p.push(mm(to[0]));
                p.p.push(mm(to[1]));
                tail = None;
            } else {
                tail = Some([mm(to[0]), mm(to[1])]);
            }
            *e = ci as u32 + 1;
        }
        for a in 0..2 {
            let v = mm(to[a]);
            lo[a] = lo[a].min(v);
            hi[a] = hi[a].max(v);
        }
    }
    let layer = moves.layer() as usize;
    if let (Some(p), Some(t)) = (paths.last_mut(), tail) {
        p.p.extend_from_slice(&t);
    }
    if !lo[0].is_finite() {
        lo = [0.0; 2];
        hi = [1.0; 2];
    }
    Toolpath {
        bounds: [lo[0], lo[1], hi[0], hi[1]],
        layers: layer + 1,
        paths,
        starts,
        ends,
        bead_mm,
        simplified: stride > 1,
    }
}

/// The job's figures, shown under the preview.
#[derive(Debug, Clone, Serialize)]
pub struct Figures {
    /// Design name.
    pub name: String,
    /// Print segments.
    pub segments: u32,
    /// Material switches.
    pub switches: usize,
    /// Layers.
    pub layers: usize,
    /// Beads.
    pub beads: usize,
    /// Size on the plate, mm.
    pub size_mm: [f64; 2],
    /// Printed length (priming included), mm.
    pub print_mm: f64,
    /// Travel length, mm.
    pub travel_mm: f64,
    /// Job file size, bytes.
    pub job_bytes: usize,
    /// Estimated print time, s: how long the executor takes over the job in virtual time
    /// (ramps, corners, valve waits and switches included; no plant), or lengths over
    /// speeds if that run could not be made.
    pub est_time_s: f64,
    /// How `est_time_s` was found, in words for the page.
    pub est_time_from: String,
    /// Lengths over speeds (no acceleration, no waits), s: for comparison.
    pub length_time_s: f64,
    /// Commands in the job.
    pub commands: usize,
    /// The executor's virtual time at which each command began, s (empty when that run
    /// could not be made): the print's ETA reads it against the board's command count.
    #[serde(skip)]
    pub command_t_s: Vec<f64>,
}

/// The figures of a sliced job on `config`.
pub fn figures(s: &Sliced, config: &Config) -> Figures {
    let st = &s.stats;
    let print = st.print_mm + st.prime_mm;
    let length_time_s = print / (config.motion.print_speed_mm_s as f64).max(1e-3)
        + st.travel_mm / (config.motion.travel_speed_mm_s as f64).max(1e-3);
    let (est_time_s, est_time_from, command_t_s) = match executor_timeline(s, config) {
        Ok((t, starts)) => (
            t,
            "a run of the executor in virtual time (ramps and valve waits included; no plant)"
                .to_string(),
            starts,
        ),
        Err(e) => (
            length_time_s,
            format!("lengths over speeds ({e})"),
            Vec::new(),
        ),
    };
    Figures {
        name: s.name.clone(),
        segments: s.header.print_segments,
        switches: st.switches,
        layers: st.layers,
        beads: st.beads,
        size_mm: s.size_mm,
        print_mm: print,
        travel_mm: st.travel_mm,
        job_bytes: s.to_bytes().len(),
        est_time_s,
        est_time_from,
        length_time_s,
        commands: s.commands.len(),
        command_t_s,
    }
}

/// Virtual time the executor (in the board's f32) takes over the job: no plant, no
/// outputs kept, so it costs the executor's ticks only.
pub fn executor_time(s: &Sliced, config: &Config) -> Result<f64, String> {
    executor_timeline(s, config).map(|(t, _)| t)
}

/// [`executor_time`], with the virtual time at which each command began (index by the
/// executor's command count; commands it never reached read the end time).
pub fn executor_timeline(s: &Sliced, config: &Config) -> Result<(f64, Vec<f64>), String> {
    let job = dollop_sim::Job {
        start_um: s.header.start_um,
        initial_material: s.header.initial_material,
        commands: s.commands.clone(),
    };
    let opts = dollop_sim::RunOptions {
        plant: false,
        // A day of printing is past any job the dashboard slices.
        max_time_s: 86_400.0,
        ..Default::default()
    };
    let n = s.commands.len();
    let mut starts: Vec<f64> = Vec::with_capacity(n + 1);
    let r = dollop_sim::run::<f32>(config, &job, &opts, |c| {
        let at = (c.report.command_index as usize).min(n);
        while starts.len() <= at {
            starts.push(c.t_s);
        }
    })
    .map_err(|e| e.to_string())?;
    match r.fault {
        Some(f) => Err(format!("the executor stopped the job: {f}")),
        None => {
            starts.resize(n + 1, r.time_s);
            Ok((r.time_s, starts))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seed() -> &'static str {
        BUNDLED[0].1
    }

    #[test]
    fn a_slicers_gcode_is_imported_from_the_design_page() {
        let config: Config = toml::from_str(seed()).unwrap();
        let gcode = include_str!("../../tests/data/gcode-in/square-abs-e.gcode");
        let up = |name: &str, bytes: &[u8]| Upload {
            name: name.into(),
            bytes: bytes.to_vec(),
        };
        let form = SliceForm::default();
        let s = slice(&[up("square.gcode", gcode.as_bytes())], &config, &form).unwrap();
        let materials: std::collections::BTreeSet<u8> = s
            .commands
            .iter()
            .filter_map(|c| match c {
                Command::Print { material, .. } => Some(*material),
                _ => None,
            })
            .collect();
        assert_eq!(materials.len(), 2, "{:?}", s.commands);
        // Bad uploads: typed, worded for the page, nothing sliced.
        let e = slice(&[up("bin.gcode", &[0xff, 0xfe, 0x00])], &config, &form).unwrap_err();
        assert!(e.message().contains("not a text file"), "{}", e.message());
        let two = [
            up("a.gcode", gcode.as_bytes()),
            up("b.gcode", gcode.as_bytes()),
        ];
        let e = slice(&two, &config, &form).unwrap_err();
        assert!(e.message().contains("imported alone"), "{}", e.message());
        let e = slice(
            &[up("t.gcode", b"G1 X10 Y10 Z0.6\nT5\nG1 X20 E1\n")],
            &config,
            &form,
        )
        .unwrap_err();
        assert!(e.message().contains("t.gcode"), "{}", e.message());
    }

    fn edit(path: &str, raw: &str) -> Vec<Field> {
        vec![Field {
            path: path.into(),
            raw: raw.into(),
        }]
    }

    #[test]
    fn bundled_configs_check_with_derived_figures() {
        for (name, text) in BUNDLED {
            let c = check(text).unwrap_or_else(|e| panic!("{name}: {}", e.message()));
            assert!(c.fields.len() > 10, "{name}: {} fields", c.fields.len());
        }
        let c = check(seed()).expect("seed config");
        let s = c.derived.figures.iter().find(|f| f.0 == "bead section S");
        assert_eq!(s.map(|f| f.1.as_str()), Some("0.4800 mm²"));
        let turns = |c: &Checked| {
            c.derived
                .figures
                .iter()
                .find(|f| f.0 == "row-end U-turns")
                .map(|f| f.1.clone())
                .unwrap_or_default()
        };
        assert_eq!(
            turns(&c),
            "0.40 mm radius (half the pitch) at 10.00 mm/s: 250 mm/s², 12 % of the X/Y limit of 2000 mm/s²"
        );
        // Too fast for the U-turns between rows: the note says what would do.
        let pastes = BUNDLED[2].1;
        let fast = apply(pastes, &edit("motion.print_speed_mm_s", "16")).expect("applies");
        let fast =
            apply(&fast, &edit("motion.max_accel_mm_s2", "[1000, 1000, 200]")).expect("applies");
        let t = turns(&check(&fast).unwrap_or_else(|e| panic!("{}", e.message())));
        assert!(
            t.contains("640 mm/s², 64 % of the X/Y limit of 1000 mm/s². Note: ")
                && t.contains("print_speed_mm_s at most 15.5"),
            "{t}"
        );
        assert!(c
            .fields
            .iter()
            .any(|f| f.path == "inlet[1].pressure_kpa" && f.raw == "\"auto\""));
    }

    #[test]
    fn a_validation_error_names_its_field() {
        let text = apply(seed(), &edit("channel.line_pitch_mm", "-1")).expect("applies");
        let e = check(&text).err().expect("refused");
        assert_eq!(e.field(), Some("channel.line_pitch_mm"), "{}", e.message());
        assert!(
            e.message().contains("must not be negative"),
            "{}",
            e.message()
        );
        // One element of a list: the field is the list.
        let text = apply(
            seed(),
            &edit("motion.max_accel_mm_s2", "[2000.0, -5.0, 200.0]"),
        )
        .expect("applies");
        let e = check(&text).err().expect("refused");
        assert_eq!(e.field(), Some("motion.max_accel_mm_s2"), "{}", e.message());
    }

    #[test]
    fn a_wrong_type_or_no_value_names_its_field() {
        let text = apply(seed(), &edit("channel.layer_height_mm", "\"thick\"")).expect("applies");
        let e = check(&text).err().expect("refused");
        assert_eq!(
            e.field(),
            Some("channel.layer_height_mm"),
            "{}",
            e.message()
        );
        let e = apply(seed(), &edit("channel.layer_height_mm", "0.6 mm")).expect_err("refused");
        assert_eq!(
            e.field(),
            Some("channel.layer_height_mm"),
            "{}",
            e.message()
        );
        let e = apply(seed(), &edit("inlet[1].material", "\"x")).expect_err("refused");
        assert_eq!(e.field(), Some("inlet[1].material"), "{}", e.message());
        let e = apply(seed(), &edit("inlet[7].material", "\"x\"")).expect_err("refused");
        assert!(e.message().contains("no such field"), "{}", e.message());
        let text =
            apply(seed(), &edit("inlet[1].valve_open_delay_ms", "\"soon\"")).expect("applies");
        let e = check(&text).err().expect("refused");
        assert_eq!(
            e.field(),
            Some("inlet[1].valve_open_delay_ms"),
            "{}",
            e.message()
        );
    }

    #[test]
    fn an_edit_keeps_the_files_order_and_comments() {
        let before = seed();
        let after = apply(before, &edit("inlet[1].valve_open_delay_ms", "12.5")).expect("applies");
        // Only that value changed: every other line is as written, comments included.
        let changed: Vec<(&str, &str)> = before
            .lines()
            .zip(after.lines())
            .filter(|(a, b)| a != b)
            .collect();
        assert_eq!(before.lines().count(), after.lines().count(), "{after}");
        assert_eq!(changed.len(), 1, "{changed:?}");
        assert_eq!(changed[0].1, "valve_open_delay_ms = 12.5");
        assert!(after.starts_with("# "), "{after}");
        // The editor lists the fields in file order: [channel] before [motion].
        let f = fields(&after).expect("fields");
        let pos = |p: &str| f.iter().position(|x| x.path == p).unwrap_or(usize::MAX);
        assert!(pos("channel.nozzle_diameter_mm") < pos("motion.print_speed_mm_s"));
        assert!(pos("inlet[0].material") < pos("inlet[0].rheology"));
        // A value that is not TOML names its field.
        let e = apply(before, &edit("motion.print_speed_mm_s", "fast")).expect_err("refused");
        assert_eq!(e.field(), Some("motion.print_speed_mm_s"));
    }

    #[test]
    fn edits_round_trip() {
        let text = apply(seed(), &edit("motion.print_speed_mm_s", "12.5")).expect("applies");
        let c = check(&text).expect("valid");
        assert_eq!(c.config.motion.print_speed_mm_s, 12.5);
        let f = c
            .fields
            .iter()
            .find(|f| f.path == "motion.print_speed_mm_s");
        assert_eq!(f.map(|f| f.raw.as_str()), Some("12.5"));
    }

    #[test]
    fn one_stl_per_material_slices() {
        let c = check(seed()).expect("config");
        let uploads: Vec<Upload> = DESIGNS[2..]
            .iter()
            .map(|(n, b)| Upload {
                name: n.to_string(),
                bytes: b.to_vec(),
            })
            .collect();
        let form = SliceForm::default();
        let s = slice(&uploads, &c.config, &form).expect("slices");
        assert_eq!(s.name, "cube-shell.stl + cube-ball.stl");
        let f = figures(&s, &c.config);
        assert!(f.segments > 10 && f.switches > 0, "{f:?}");
        // The executor's time: the same job in the simulator's own run, and longer than
        // lengths over speeds (ramps, valve waits).
        assert!(
            f.est_time_from.starts_with("a run of the executor"),
            "{}",
            f.est_time_from
        );
        let job = dollop_sim::Job {
            start_um: s.header.start_um,
            initial_material: s.header.initial_material,
            commands: s.commands.clone(),
        };
        let opts = dollop_sim::RunOptions {
            plant: false,
            ..Default::default()
        };
        let r = dollop_sim::run::<f32>(&c.config, &job, &opts, |_| {}).expect("runs");
        assert_eq!(f.est_time_s, r.time_s);
        eprintln!(
            "cube shell + ball: executor {:.1} s, lengths over speeds {:.1} s",
            f.est_time_s, f.length_time_s
        );
        assert!(f.est_time_s > f.length_time_s, "{f:?}");
        let e = slice(&[], &c.config, &form)
            .err()
            .map(|e| e.message().to_string());
        assert!(e.is_some_and(|e| e.contains("choose a design")));
    }

    #[test]
    fn markers_and_the_calibration_pattern_slice() {
        let c = check(seed()).expect("config");
        let uploads = [Upload {
            name: "chessboard.png".into(),
            bytes: DESIGNS[1].1.to_vec(),
        }];
        let mut form = SliceForm {
            width_mm: Some(8.0),
            ..Default::default()
        };
        let plain = slice(&uploads, &c.config, &form).expect("slices");
        form.markers = true;
        let marked = slice(&uploads, &c.config, &form).expect("slices with markers");
        assert!(
            marked.header.print_segments > plain.header.print_segments,
            "{} vs {}",
            marked.header.print_segments,
            plain.header.print_segments
        );
        let form = SliceForm {
            calibration_pattern: true,
            ..Default::default()
        };
        let p = slice(&[], &c.config, &form).expect("the pattern slices without a design");
        assert_eq!(p.name, "calibration pattern");
        assert!(figures(&p, &c.config).switches >= 2);
    }

    #[test]
    fn a_refused_option_names_the_pages_field_not_a_flag() {
        let c = check(seed()).expect("config");
        let uploads = [Upload {
            name: "chessboard.png".into(),
            bytes: DESIGNS[1].1.to_vec(),
        }];
        let cases = [
            (
                SliceForm {
                    min_run_mm: Some(-1.0),
                    ..Default::default()
                },
                "Shortest run, mm: -1 must be 0 or more",
            ),
            (
                SliceForm {
                    origin: Some("1;2".into()),
                    ..Default::default()
                },
                "Origin X,Y mm: \"1;2\" must be two numbers X,Y in mm",
            ),
            (
                SliceForm {
                    palette: Some("#zz".into()),
                    ..Default::default()
                },
                "Palette: ",
            ),
        ];
        for (form, want) in cases {
            let e = slice(&uploads, &c.config, &form).expect_err("refused");
            assert!(e.message().starts_with(want), "{}", e.message());
            assert!(!e.message().contains("--"), "{}", e.message());
        }
    }

    #[test]
    fn toolpath_groups_runs_by_layer_and_material() {
        let cmds = [
            Command::Travel {
                x: 1000,
                y: 1000,
                z: 800,
            },
            Command::Print {
                dx: 2000,
                dy: 0,
                material: 0,
            },
            Command::Print {
                dx: 2000,
                dy: 0,
                material: 0,
            },
            Command::Print {
                dx: 0,
                dy: 1000,
                material: 1,
            },
            Command::Travel {
                x: 0,
                y: 0,
                z: 1400,
            },
            Command::Print {
                dx: 500,
                dy: 0,
                material: 1,
            },
            Command::End,
        ];
        let t = toolpath(&cmds, [0, 0, 800], 0.8);
        let kinds: Vec<(usize, i32)> = t.paths.iter().map(|p| (p.l, p.m)).collect();
        assert_eq!(kinds, [(0, -1), (0, 0), (0, 1), (1, -1), (1, 1)]);
        assert_eq!(t.paths[1].p, [1.0, 1.0, 3.0, 1.0, 5.0, 1.0]);
        assert_eq!(t.starts, [0, 1, 3, 4, 5]);
        assert_eq!(t.ends, [1, 3, 4, 5, 6]);
        assert_eq!(t.bounds, [0.0, 0.0, 5.0, 2.0]);
        assert_eq!(t.layers, 2);
        assert!(!t.simplified);
    }
}
