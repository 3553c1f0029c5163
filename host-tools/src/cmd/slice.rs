//! `dollop slice`: reads designs and a machine config, slices them with the `slicer`
//! library and writes the job (.dlp), and on request G-code and a preview PNG; prints a
//! short summary. All the work is the library's; this file maps options and prints.

use crate::gcode_in::{self, emit::CountLimits, ImportOptions};
use crate::slicer::gcode;
use crate::slicer::gcode_dialect::{self, Kind};
use crate::slicer::gcode_exec::{self, RunExport};
use crate::slicer::image::{Mirror, Rotation};
use crate::slicer::preview::{self, PreviewOptions};
use crate::slicer::{
    self, output, GcodeRequest, GcodeStyle, Limits, Names, SliceError, SliceLimit, SliceOption,
    SliceRequest,
};
use clap::builder::{PossibleValuesParser, TypedValueParser};
use std::path::{Path, PathBuf};

/// Arguments of `dollop slice`.
#[derive(clap::Args, Debug)]
#[command(after_help = "Examples:\n  \
dollop slice logo.png --config machine.toml --width-mm 40 --preview logo-preview.png\n  \
dollop slice base.stl inlay.stl --config machine.toml --out coaster.dlp --gcode coaster.gcode\n  \
dollop slice coaster.3mf --config machine.toml --preview coaster.png")]
pub struct Args {
    /// Design: one image (PNG, JPEG, BMP; colours are materials), one STL per material
    /// in inlet order (ASCII or binary), one 3MF whose objects carry the materials
    /// (base material i prints from inlet i; without materials, object i in build order),
    /// or one slicer's G-code (.gcode; tools to inlets by --tools), imported as written.
    #[arg(
        required_unless_present = "calibration_pattern",
        conflicts_with = "calibration_pattern",
        value_name = "DESIGN"
    )]
    pub designs: Vec<PathBuf>,
    /// Machine config (TOML; `dollop config --example` prints one).
    #[arg(long, value_name = "MACHINE.toml")]
    pub config: PathBuf,
    /// Job file to write [default: the first design's name with .dlp, in the current directory].
    #[arg(long, value_name = "JOB.dlp")]
    pub out: Option<PathBuf>,
    /// Also write G-code for controllers without volume keying.
    #[arg(long, value_name = "OUT.gcode")]
    pub gcode: Option<PathBuf>,
    /// G-code: `run` (sampled from the executor's run of the job: moves of at most 0.25 mm
    /// at its speeds, valves where it switched them, so dead time, pressure rise/decay and
    /// the speed law carry over), or the older feed-rate profiles `fine` (advance distance
    /// plus dead time) and `coarse` (the seed paper's), for comparison.
    #[arg(long, value_name = "STYLE", default_value = "run", value_parser = style_parser())]
    pub gcode_style: GcodeStyle,
    /// How `--gcode-style run` writes valve changes: `plain` (`M42 P<port> S0|1` between
    /// moves; the firmware must run M42 in its place in the move sequence), `reprap`
    /// (RepRapFirmware 3: `G1 ... P<bitmap>` mapped by `M670`, `M400` + `M42` while
    /// standing), `klipper` (`SET_PIN PIN=dollop_valve<port> VALUE=0|1`, which Klipper
    /// schedules with the moves; needs `[output_pin dollop_valve<port>]` sections),
    /// `marlin` (`M106 P<fan> S255` / `M107 P<fan>`: valves on fan outputs, Marlin built
    /// with LASER_SYNCHRONOUS_M106_M107 so fan changes are queued with the moves) or
    /// `marlin-m42` (`M400` then `M42 P<pin> S0|255`, for stock Marlin: the head stops at
    /// each valve change).
    #[arg(long, value_name = "DIALECT", default_value = "plain", value_parser = dialect_parser())]
    pub gcode_dialect: Kind,
    /// Port (plain, reprap), output_pin number (klipper), fan index 0-7 (marlin) or board
    /// pin (marlin-m42) of each inlet's valve, inlet 0 first [default: 0,1,..].
    #[arg(long, value_name = "P0,P1,..")]
    pub gcode_ports: Option<String>,
    /// Refuse to write G-code larger than this, MiB (`--gcode-style run`): it is built in
    /// memory, and a day-long print's runs to gigabytes. Checked from the job before the
    /// executor's run, then on the text.
    #[arg(long, value_name = "MIB", default_value_t = 1024, value_parser = clap::value_parser!(u64).range(1..=1_048_576))]
    pub gcode_max_mb: u64,
    /// G-code written before the job's first move (`--gcode-style run`): homing, a
    /// purge line, whatever the machine needs; at most 64 KiB of text.
    #[arg(long, value_name = "FILE")]
    pub gcode_start: Option<PathBuf>,
    /// G-code written after the job's last move, before `; end of job` (`--gcode-style
    /// run`): park, motors off; at most 64 KiB of text.
    #[arg(long, value_name = "FILE")]
    pub gcode_end: Option<PathBuf>,
    /// Also write a PNG of the toolpath coloured by material, travel moves dashed.
    #[arg(long, value_name = "OUT.png")]
    pub preview: Option<PathBuf>,
    /// Draw only this layer in the preview (0 = the first) [default: one layer only: it;
    /// several: a grid of up to 9 layers].
    #[arg(long, value_name = "N", requires = "preview")]
    pub preview_layer: Option<usize>,
    /// Images: layers to stack [default: 1]. Meshes: print at most this many layers.
    #[arg(long, value_name = "N")]
    pub layers: Option<usize>,
    /// Images: printed width in mm (bilinear resampling to the line pitch).
    #[arg(long, value_name = "MM")]
    pub width_mm: Option<f64>,
    /// Images: printed height in mm (with only one of width/height the aspect is kept;
    /// with neither, one pixel is one line pitch).
    #[arg(long, value_name = "MM")]
    pub height_mm: Option<f64>,
    /// Images: rotate counter-clockwise by this many degrees.
    #[arg(long, value_enum, default_value = "0")]
    pub rotate: Rotation,
    /// Images: mirror across an axis (after rotating).
    #[arg(long, value_enum, default_value = "none")]
    pub mirror: Mirror,
    /// Images: swap the materials (dark/light, or the palette's order).
    #[arg(long)]
    pub invert: bool,
    /// Images: grey level (0-255) dividing material 0 (darker) from material 1.
    #[arg(
        long,
        value_name = "LEVEL",
        default_value_t = 150,
        conflicts_with = "palette"
    )]
    pub threshold: u8,
    /// Images: materials by nearest colour instead of threshold: `auto` (the image's main
    /// colours, darkest first) or `#rrggbb,#rrggbb,...` (inlet 0 first).
    #[arg(long, value_name = "auto|COLOURS")]
    pub palette: Option<String>,
    /// Images: colour not printed (besides transparent pixels), e.g. `#ffffff`.
    #[arg(long, value_name = "#rrggbb")]
    pub background: Option<String>,
    /// Images: RGB distance within which a pixel counts as background.
    #[arg(long, value_name = "D", default_value_t = 40.0)]
    pub background_tolerance: f64,
    /// Lower-left corner of the design on the plate, mm [default: centred].
    #[arg(long, value_name = "X,Y")]
    pub origin: Option<String>,
    /// Priming bead length, mm [default: 2.5 times the bead length between valves and plate, at least 5]
    /// (G-code in: 0 for none, where the file primes itself).
    #[arg(long, value_name = "MM")]
    pub prime_mm: Option<f64>,
    /// Material runs shorter than this are merged into their neighbours, mm.
    #[arg(long, value_name = "MM", default_value_t = 0.1)]
    pub min_run_mm: f64,
    /// Rows whose ends lie at most this far apart are joined by a printed connector, mm
    /// [default: two line pitches].
    #[arg(long, value_name = "MM")]
    pub connect_mm: Option<f64>,
    /// Print an L-shaped marker outside each corner of a single-layer job (one with longer
    /// legs), after the design and in its last material, so that `dollop inspect` can
    /// register a photo of the print by them.
    #[arg(long)]
    pub markers: bool,
    /// Instead of a design: the calibration pattern for `dollop inspect --suggest` (for
    /// every pair of the config's materials, switches in both directions at several
    /// distances from each row's start, so at different flows), with markers; written to
    /// --out [default: calibration.dlp].
    #[arg(long)]
    pub calibration_pattern: bool,
    /// G-code in: inlet of tool 0, tool 1, ... (also the valve numbers of `M42 P`,
    /// `M106 P`, `SET_PIN PIN=..<n>` and RRF's `G1 .. P<bitmap>`) [default: tool i on inlet i].
    #[arg(long, value_name = "I0,I1,..")]
    pub tools: Option<String>,
    /// G-code in: drop wipe towers and prime towers (refused otherwise), saying how much
    /// paste that saves.
    #[arg(long)]
    pub strip_purge: bool,
    /// G-code in: largest distance between an arc (G2/G3) and the segments it becomes, mm.
    #[arg(long, value_name = "MM", default_value_t = 0.01)]
    pub chord_mm: f64,
    /// G-code in: filament diameter E is measured in, mm, for the beads' sections
    /// (E x filament area / length) [default: the slicer's `filament_diameter` in the
    /// file, else 1.75].
    #[arg(long, value_name = "MM")]
    pub filament_mm: Option<f64>,
    /// G-code in: E is volume, mm^3, from the start (as after `M200 D<d>`).
    #[arg(long)]
    pub volumetric: bool,
    /// G-code in: refuse files larger than this, MiB (checked from the size, before reading).
    #[arg(long, value_name = "MIB", default_value_t = gcode_in::DEFAULT_MAX_BYTES >> 20)]
    pub max_gcode_in_mb: u64,
    /// Refuse images of more pixels than this (width x height; each takes 4 bytes as RGBA).
    #[arg(long, value_name = "N", default_value_t = Limits::default().max_pixels)]
    pub max_pixels: u64,
    /// Refuse designs of more print runs than this (layers x rows x material runs: about
    /// the job's print segments; 2 million make a job of about 12 MB, and G-code of several
    /// hundred bytes a segment).
    #[arg(long, value_name = "N", default_value_t = Limits::default().max_segments)]
    pub max_segments: u64,
    /// Refuse meshes of more triangles than this (all bodies together, 3MF components
    /// expanded).
    #[arg(long, value_name = "N", default_value_t = Limits::default().max_triangles)]
    pub max_triangles: u64,
    /// Refuse 3MF files whose model XML is larger than this, MiB (uncompressed).
    #[arg(long, value_name = "MIB", default_value_t = Limits::default().max_3mf_bytes >> 20)]
    pub max_3mf_mb: u64,
}

/// `--gcode-style`: the words `GcodeStyle` knows, listed in the help.
fn style_parser() -> impl TypedValueParser<Value = GcodeStyle> {
    // The possible values have been checked before the map: the default is never taken.
    PossibleValuesParser::new(GcodeStyle::ALL.map(GcodeStyle::name))
        .map(|w| GcodeStyle::from_name(&w).unwrap_or_default())
}

/// `--gcode-dialect`: the words `Kind` knows, listed in the help.
fn dialect_parser() -> impl TypedValueParser<Value = Kind> {
    PossibleValuesParser::new(Kind::ALL.map(Kind::name))
        .map(|w| Kind::from_name(&w).unwrap_or_default())
}

impl Args {
    /// The slice these arguments ask for.
    pub fn request(&self) -> SliceRequest {
        SliceRequest {
            width_mm: self.width_mm,
            height_mm: self.height_mm,
            layers: self.layers,
            rotate: self.rotate,
            mirror: self.mirror,
            invert: self.invert,
            threshold: self.threshold,
            palette: self.palette.clone(),
            background: self.background.clone(),
            background_tolerance: self.background_tolerance,
            origin: self.origin.clone(),
            prime_mm: self.prime_mm,
            min_run_mm: self.min_run_mm,
            connect_mm: self.connect_mm,
            markers: self.markers,
            calibration_pattern: self.calibration_pattern,
            limits: Limits {
                max_pixels: self.max_pixels,
                max_segments: self.max_segments,
                max_triangles: self.max_triangles,
                max_3mf_bytes: self.max_3mf_mb.saturating_mul(1 << 20),
            },
            progress: true,
            gcode: GcodeRequest {
                style: self.gcode_style,
                dialect: self.gcode_dialect,
                ports: self.gcode_ports.clone(),
                max_bytes: self.gcode_max_mb << 20,
            },
        }
    }
}

/// The flag that sets a request's option.
pub fn flag(o: SliceOption) -> &'static str {
    match o {
        SliceOption::Palette => "--palette",
        SliceOption::Background => "--background",
        SliceOption::BackgroundTolerance => "--background-tolerance",
        SliceOption::MinRun => "--min-run-mm",
        SliceOption::Origin => "--origin",
        SliceOption::Layers => "--layers",
        SliceOption::Connect => "--connect-mm",
        SliceOption::Prime => "--prime-mm",
        SliceOption::GcodePorts => "--gcode-ports",
        SliceOption::Width => "--width-mm",
        SliceOption::Height => "--height-mm",
        SliceOption::Size => "--width-mm/--height-mm",
        SliceOption::Threshold => "--threshold",
        SliceOption::Markers => "--markers",
    }
}

/// The flag that sets a slice's limit.
pub fn limit_flag(l: SliceLimit) -> &'static str {
    match l {
        SliceLimit::Pixels => "--max-pixels",
        SliceLimit::Segments => "--max-segments",
        SliceLimit::Triangles => "--max-triangles",
        SliceLimit::ThreeMfSize => "--max-3mf-mb",
        SliceLimit::GcodeSize => "--gcode-max-mb",
    }
}

/// The slicer's options and limits by the flags that set them.
pub struct Flags;

impl Names for Flags {
    fn option(&self, o: SliceOption) -> &'static str {
        flag(o)
    }
    fn limit(&self, l: SliceLimit) -> &'static str {
        limit_flag(l)
    }
}

/// A slicer error as the command line says it: options and limits by their flags.
pub fn in_flags(e: &SliceError) -> String {
    e.message(&Flags)
}

/// Largest start or end G-code file, bytes: a few hundred lines is already a long one.
pub const MAX_HOST_GCODE_BYTES: u64 = 64 << 10;

/// Reads a start/end G-code file named by `flag`: text, within its size limit.
fn host_gcode(flag: &str, path: Option<&Path>) -> anyhow::Result<Option<String>> {
    let Some(path) = path else {
        return Ok(None);
    };
    let len = std::fs::metadata(path)
        .map_err(|e| anyhow::anyhow!("{flag} {}: {e}", path.display()))?
        .len();
    if len > MAX_HOST_GCODE_BYTES {
        anyhow::bail!(
            "{flag} {}: {len} bytes; start and end G-code are at most {MAX_HOST_GCODE_BYTES} bytes",
            path.display()
        );
    }
    let bytes =
        std::fs::read(path).map_err(|e| anyhow::anyhow!("{flag} {}: {e}", path.display()))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| anyhow::anyhow!("{flag} {}: not text (UTF-8)", path.display()))?;
    Ok(Some(text))
}

/// The default job path: the first design's stem with `.dlp`, in the current directory.
fn default_out(design: &Path) -> PathBuf {
    let stem = design
        .file_stem()
        .map(|s| s.to_os_string())
        .unwrap_or_else(|| "job".into());
    let mut p = PathBuf::from(stem);
    p.set_extension("dlp");
    p
}

/// Runs `dollop slice`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let req = a.request();
    let opts = req.options()?;
    let config = slicer::load_config(&a.config)?;
    let machine = slicer::validate(&a.config, &config)?;
    if a.designs.iter().any(|d| gcode_in::is_gcode(d)) {
        return run_gcode(a, &req, config, machine);
    }
    let (design, path) = if a.calibration_pattern {
        let d = slicer::calibration::pattern(
            machine.inlet_count(),
            config.channel.line_pitch_mm as f64,
            slicer::toolpath::transit_mm(&machine),
        );
        (d, slicer::calibration::path_options(opts.path))
    } else {
        (
            slicer::load_design(&a.designs, &config, &machine, &opts)?,
            opts.path,
        )
    };
    let sliced = slicer::slice_design(&design, &config, &machine, &path)?;
    // The design was filled in rows one pitch apart (another slicer's G-code has its
    // own turns, and is not told this).
    if let Some(advice) = slicer::row_turns::RowTurns::of(&config, &machine).advice() {
        eprintln!("dollop: note: {advice}");
    }
    finish(a, &req, config, machine, sliced)
}

/// `dollop slice FILE.gcode`: imports the G-code, prints the import summary, then writes
/// the outputs as for a design.
fn run_gcode(
    a: Args,
    req: &SliceRequest,
    config: dollop::config::Config,
    machine: dollop::Machine<f64, 4>,
) -> anyhow::Result<()> {
    if a.designs.len() != 1 {
        anyhow::bail!(
            "give one G-code file alone ({} files given)",
            a.designs.len()
        );
    }
    let opts = ImportOptions {
        tools: a.tools.clone(),
        chord_mm: a.chord_mm,
        strip_purge: a.strip_purge,
        prime_mm: a.prime_mm,
        max_bytes: a.max_gcode_in_mb.saturating_mul(1 << 20),
        limits: CountLimits {
            max_segments: a.max_segments,
            max_commands: a.max_segments.saturating_mul(4),
        },
        filament_mm: a.filament_mm,
        volumetric: a.volumetric,
    };
    let imported = gcode_in::import_file(&a.designs[0], &opts, &config, &machine)?;
    print!("{}", imported.summary);
    finish(a, req, config, machine, imported.sliced)
}

/// Everything after the job is made: markers, G-code out, preview, the summary.
fn finish(
    a: Args,
    req: &SliceRequest,
    config: dollop::config::Config,
    machine: dollop::Machine<f64, 4>,
    mut sliced: slicer::Sliced,
) -> anyhow::Result<()> {
    let host = gcode_dialect::HostText {
        progress: true,
        start: host_gcode("--gcode-start", a.gcode_start.as_deref())?,
        end: host_gcode("--gcode-end", a.gcode_end.as_deref())?,
    };
    if a.markers || a.calibration_pattern {
        sliced = slicer::with_markers(sliced, &config, &machine)?;
    }
    // Checked before the (possibly long) G-code export, so nothing waits on a typo.
    let layers = preview::layer_count(&sliced.commands, sliced.header.start_um);
    if let Some(layer) = a.preview_layer.filter(|&l| l >= layers) {
        anyhow::bail!(
            "--preview-layer {layer}: the job has {layers} layer(s), numbered 0 to {}",
            layers - 1
        );
    }
    // Everything is computed before anything is written; each file is written whole.
    let gcode = a
        .gcode
        .as_ref()
        .map(|_| gcode_text(req, &host, &config, &machine, &sliced))
        .transpose()?;
    let out = a.out.clone().unwrap_or_else(|| match a.designs.first() {
        Some(d) => default_out(d),
        None => PathBuf::from("calibration.dlp"),
    });
    // Every output is staged (written whole to a temporary file beside it) before any is
    // renamed into place: a failure on one (a missing folder, a FIFO at the path) leaves
    // none of them.
    let mut staged = output::StagedFiles::new();
    let job_bytes = sliced.to_bytes();
    output::stage(&mut staged, &out, |w| w.write_all(&job_bytes))?;
    if let (Some(path), Some((text, _))) = (&a.gcode, &gcode) {
        output::stage(&mut staged, path, |w| w.write_all(text.as_bytes()))?;
    }
    if let Some(path) = &a.preview {
        stage_preview(&mut staged, path, a.preview_layer, &config, &sliced)?;
    }
    let existed: Vec<PathBuf> = [Some(&out), a.gcode.as_ref(), a.preview.as_ref()]
        .into_iter()
        .flatten()
        .filter(|p| p.exists())
        .cloned()
        .collect();
    output::commit(staged)?;
    let gcode_stats = gcode.as_ref().map(|(_, gs)| gs);
    print_summary(
        &a,
        &sliced,
        &config,
        &out,
        job_bytes.len(),
        gcode_stats,
        &existed,
    );
    Ok(())
}

/// Stages the preview picture (of `layer`, or of the whole job) at `path`.
fn stage_preview(
    staged: &mut output::StagedFiles,
    path: &Path,
    layer: Option<usize>,
    config: &dollop::config::Config,
    sliced: &slicer::Sliced,
) -> anyhow::Result<()> {
    let names = crate::slicer::material_names(config);
    let img = preview::figure(
        &sliced.commands,
        sliced.header.start_um,
        &PreviewOptions {
            bead_mm: config.channel.line_pitch_mm as f64,
            layer,
            ..Default::default()
        },
        &names,
    )?;
    preview::stage_png(staged, path, &img)?;
    Ok(())
}

/// The summary of what was sliced and written (`existed`: the outputs that replaced a
/// file).
fn print_summary(
    a: &Args,
    sliced: &slicer::Sliced,
    config: &dollop::config::Config,
    out: &Path,
    job_len: usize,
    gcode: Option<&gcode::GcodeStats>,
    existed: &[PathBuf],
) {
    let replaced = |p: &Path| {
        if existed.iter().any(|e| e == p) {
            " (replaced the file that was there)"
        } else {
            ""
        }
    };
    let segs = sliced.header.print_segments.max(1) as f64;
    let st = &sliced.stats;
    println!(
        "{}: {:.1} x {:.1} mm, {} layer(s), {} bead(s), {} print segments, {} material switches, {:.0} mm printed ({:.0} mm priming), {:.0} mm travel",
        sliced.name,
        sliced.size_mm[0],
        sliced.size_mm[1],
        st.layers,
        st.beads,
        sliced.header.print_segments,
        st.switches,
        st.print_mm,
        st.prime_mm,
        st.travel_mm,
    );
    if unsized_image(a) {
        eprintln!(
            "dollop: note: no --width-mm or --height-mm, so one pixel is one line pitch ({} mm) and this prints {:.1} x {:.1} mm; give --width-mm to choose the size",
            config.channel.line_pitch_mm, sliced.size_mm[0], sliced.size_mm[1]
        );
    }
    println!(
        "wrote {} ({} bytes, {:.2} bytes per print segment, {:.2} in the body){}",
        out.display(),
        job_len,
        job_len as f64 / segs,
        sliced.body_bytes_per_segment(),
        replaced(out)
    );
    if let (Some(path), Some(gs)) = (&a.gcode, gcode) {
        println!(
            "wrote {} ({} bytes, {:.1} bytes per print segment, {} moves, {} valve switches){}",
            path.display(),
            gs.bytes,
            gs.bytes as f64 / segs,
            gs.print_moves,
            gs.switches,
            replaced(path)
        );
    }
    if let Some(path) = &a.preview {
        println!("wrote {}{}", path.display(), replaced(path));
    }
}

/// The G-code `--gcode` asks for: from the executor's run (`--gcode-style run`) or the
/// older feed-rate profiles.
fn gcode_text(
    req: &SliceRequest,
    host: &gcode_dialect::HostText,
    config: &dollop::config::Config,
    machine: &dollop::Machine<f64, 4>,
    sliced: &slicer::Sliced,
) -> anyhow::Result<(String, gcode::GcodeStats)> {
    let names = crate::slicer::material_names(config);
    let style = match req.gcode.style.profile() {
        Some(style) => style,
        None => {
            let opt = RunExport {
                dialect: req.gcode.dialect(config.inlets.len())?,
                max_bytes: req.gcode.max_bytes,
                host: host.clone(),
                ..RunExport::default()
            };
            // The executor runs the whole job: minutes for a day-long print.
            let bar = output::progress(sliced.commands.len() as u64, "writing G-code");
            let r = gcode_exec::export_with_progress(
                config,
                &sliced.commands,
                sliced.header.start_um,
                sliced.header.initial_material,
                &names,
                &opt,
                &mut |done| bar.set_position(done),
            );
            bar.finish_and_clear();
            return Ok(r?);
        }
    };
    if req.gcode.dialect != Kind::Plain
        || req.gcode.ports.is_some()
        || host.start.is_some()
        || host.end.is_some()
    {
        anyhow::bail!(
            "--gcode-dialect, --gcode-ports, --gcode-start and --gcode-end apply to --gcode-style run, not {}",
            req.gcode.style.name()
        );
    }
    // These profiles model one section for the whole job: say so rather than drop the
    // beads' own widths (an imported slicer's G-code) unannounced.
    let sections = sliced
        .commands
        .iter()
        .filter(|c| matches!(c, dollop::Command::Section { .. }))
        .count();
    if sections > 0 {
        eprintln!(
            "note: --gcode-style {} lays the config's section on every bead: this job's {sections} Section command(s) (its beads' own widths) are not in the G-code; --gcode-style run keeps them",
            req.gcode.style.name()
        );
    }
    Ok(gcode::export(
        &sliced.commands,
        sliced.header.start_um,
        sliced.header.initial_material,
        machine,
        &names,
        style,
    )?)
}

/// An image sliced without a size: one pixel per line pitch, often not what was meant.
fn unsized_image(a: &Args) -> bool {
    !a.calibration_pattern
        && a.width_mm.is_none()
        && a.height_mm.is_none()
        && a.designs.len() == 1
        && slicer::design_kind(&a.designs[0]).is_ok_and(|k| k == slicer::DesignKind::Image)
}
