//! The slicer: turns designs (an image, or one STL per material) into the core's compact
//! job, plus G-code for other controllers and preview pictures. Entry points for the
//! `dollop slice` command and for `demo`/`simulate`: [`load_config`], [`slice_files`],
//! [`job_file::write`]/[`job_file::read_job`], [`gcode_exec::export`] (and the older
//! [`gcode::export`]) and
//! [`preview::render`]. Running jobs is the `dollop-sim` crate's business.

pub mod calibration;
pub mod design;
pub mod error;
pub mod gcode;
pub mod gcode_dialect;
pub mod gcode_exec;
pub mod gcode_feed_judge;
pub mod gcode_judge;
pub mod gcode_ramps;
pub mod gcode_step;
pub mod image;
pub mod job_file;
pub mod markers;
pub mod mesh;
pub mod output;
pub mod preview;
pub mod request;
pub mod row_turns;
pub mod threemf;
pub mod toolpath;
pub mod voxel;

pub use error::{
    MarkerError, MaterialsHint, Names, OptionError, SliceError, SliceLimit, SliceOption, Words,
};
pub use request::{GcodeRequest, GcodeStyle, SliceRequest};
pub use toolpath::{PathOptions, PathStats};

use dollop::config::Config;
use dollop::job::JobHeader;
use dollop::{Command, Machine};
use std::path::{Path, PathBuf};

/// Inlets the firmware build supports; configs with more are refused.
pub const INLETS: usize = dollop::DEFAULT_INLETS;

/// Everything `slice_files` needs besides the designs and the config.
#[derive(Clone, Debug, PartialEq)]
pub struct SliceOptions {
    /// How images become materials and how large they print.
    pub image: image::ImageOptions,
    /// Images: layers to stack (default 1). Meshes: print at most this many.
    pub layers: Option<usize>,
    /// Placement, priming bead and row joining.
    pub path: PathOptions,
    /// Material runs shorter than this are folded into their neighbours, mm.
    pub min_run_mm: f64,
    /// Show progress bars (only ever drawn on a terminal).
    pub progress: bool,
    /// Resource limits, checked before anything that size is allocated.
    pub limits: Limits,
}

/// What one slice may use, checked before allocating; each is a `dollop slice --max-...`
/// option. The defaults keep peak memory near 1 GiB at most.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Image pixels (width x height, before and after rotation; 4 bytes each as RGBA).
    pub max_pixels: u64,
    /// Print runs in the whole design (layers x rows x runs): about the job's segments.
    pub max_segments: u64,
    /// Mesh triangles, all bodies together, after 3MF components are expanded.
    pub max_triangles: u64,
    /// Uncompressed size of a 3MF's parts (its XML), bytes.
    pub max_3mf_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_pixels: 50_000_000,
            max_segments: 2_000_000,
            max_triangles: 5_000_000,
            max_3mf_bytes: 128 << 20,
        }
    }
}

/// The refusal for `what` = `got` over `limit`, the value of `which` (or within it by
/// `or`).
pub fn over_limit(
    name: &str,
    what: &str,
    got: u64,
    limit: u64,
    which: SliceLimit,
    or: Option<SliceOption>,
) -> SliceError {
    SliceError::OverLimit {
        what: format!(
            "{name}: {what} {got} exceeds the limit of {limit} by {}",
            got.saturating_sub(limit)
        ),
        limit: which,
        or,
    }
}

/// Each inlet's material name, inlet 0 first (what reports, pictures and G-code call them).
pub fn material_names(config: &Config) -> Vec<String> {
    config
        .inlets
        .iter()
        .map(|i| i.material.to_string())
        .collect()
}

impl Default for SliceOptions {
    fn default() -> Self {
        SliceOptions {
            image: image::ImageOptions::default(),
            layers: None,
            path: PathOptions::default(),
            min_run_mm: 0.1,
            progress: false,
            limits: Limits::default(),
        }
    }
}

/// A sliced job: the header and commands of the `.dlp`, its encoded body, and counts.
#[derive(Clone, Debug, PartialEq)]
pub struct Sliced {
    /// The job header, filled in completely.
    pub header: JobHeader,
    /// The commands, ending with `End`.
    pub commands: Vec<Command>,
    /// The encoded body (what `header.body_len`/`body_crc` describe).
    pub body: Vec<u8>,
    /// What the design was ("logo.png", "a.stl + b.stl").
    pub name: String,
    /// Design size on the plate (X, Y) and layers.
    pub size_mm: [f64; 2],
    /// Toolpath counts.
    pub stats: PathStats,
}

impl Sliced {
    /// The whole `.dlp` file.
    pub fn to_bytes(&self) -> Vec<u8> {
        job_file::job_bytes(&self.header, &self.body)
    }
    /// Body bytes per print segment.
    pub fn body_bytes_per_segment(&self) -> f64 {
        self.body.len() as f64 / self.header.print_segments.max(1) as f64
    }
    /// File bytes (header included) per print segment.
    pub fn file_bytes_per_segment(&self) -> f64 {
        self.to_bytes().len() as f64 / self.header.print_segments.max(1) as f64
    }
}

/// `sliced` with corner markers for `dollop inspect` printed after the design (see
/// [`markers`]), within `machine`'s travel.
pub fn with_markers(
    sliced: Sliced,
    config: &Config,
    machine: &Machine<f64, INLETS>,
) -> Result<Sliced, SliceError> {
    let h = &sliced.header;
    let travel = (
        [machine.motion.min_mm[0], machine.motion.min_mm[1]],
        [machine.motion.max_mm[0], machine.motion.max_mm[1]],
    );
    let commands = markers::add(
        &sliced.commands,
        h.start_um,
        config.channel.line_pitch_mm as f64,
        travel,
    )
    .map_err(SliceError::Markers)?;
    let mut stats = sliced.stats;
    for c in &commands[sliced.commands.len() - 1..] {
        match *c {
            Command::Print { dx, dy, .. } => {
                stats.print_segments += 1;
                stats.print_mm += (dx as f64).hypot(dy as f64) * 1e-3;
            }
            Command::Travel { .. } => {
                stats.travels += 1;
                stats.beads += 1;
            }
            _ => {}
        }
    }
    let (header, body) = job_file::encode(&commands, h.start_um, h.initial_material, config);
    Ok(Sliced {
        header,
        commands,
        body,
        stats,
        ..sliced
    })
}

/// Reads and validates a machine config (TOML, the core's `Config`).
pub fn load_config(path: &Path) -> Result<Config, SliceError> {
    let text = std::fs::read_to_string(path).map_err(|e| SliceError::read(path, e))?;
    let config: Config = toml::from_str(&text).map_err(|e| SliceError::ConfigParse {
        path: path.to_path_buf(),
        reason: e
            .to_string()
            .replace('\n', " ")
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" "),
    })?;
    validate(path, &config)?;
    Ok(config)
}

/// Validates `config` (read from `path`) for this build.
pub fn validate(path: &Path, config: &Config) -> Result<Machine<f64, INLETS>, SliceError> {
    config
        .validate::<f64, INLETS>()
        .map_err(|problem| SliceError::ConfigInvalid {
            path: path.to_path_buf(),
            problem,
        })
}

/// What kind of design a file is, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DesignKind {
    /// PNG, JPEG or BMP.
    Image,
    /// STL, one body per file.
    Stl,
    /// 3MF: every body in one file, materials per object.
    ThreeMf,
}

/// The kind of `path` by its extension.
pub fn design_kind(path: &Path) -> Result<DesignKind, SliceError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    if image::IMAGE_EXTENSIONS.contains(&ext.as_str()) {
        Ok(DesignKind::Image)
    } else if ext == "stl" {
        Ok(DesignKind::Stl)
    } else if ext == "3mf" {
        Ok(DesignKind::ThreeMf)
    } else {
        Err(SliceError::UnknownFormat {
            path: path.to_path_buf(),
        })
    }
}

/// Slices design files for `config`: one image (materials by colour), or one STL per
/// material in inlet order. Nothing is written; see [`job_file::write`].
pub fn slice_files(
    paths: &[PathBuf],
    config: &Config,
    opts: &SliceOptions,
) -> Result<Sliced, SliceError> {
    let machine = validate(Path::new("config"), config)?;
    let design = load_design(paths, config, &machine, opts)?;
    slice_design(&design, config, &machine, &opts.path)
}

/// Reads and slices the design files into a [`design::Design`] (before placement).
pub fn load_design(
    paths: &[PathBuf],
    config: &Config,
    machine: &Machine<f64, INLETS>,
    opts: &SliceOptions,
) -> Result<design::Design, SliceError> {
    let Some(first) = paths.first() else {
        return Err(SliceError::NoDesign);
    };
    let inlets = machine.inlet_count();
    let pitch = config.channel.line_pitch_mm as f64;
    let kinds = paths
        .iter()
        .map(|p| design_kind(p))
        .collect::<Result<Vec<_>, _>>()?;
    for p in paths {
        if !p.exists() {
            return Err(SliceError::NotFound { path: p.clone() });
        }
    }
    match kinds[0] {
        DesignKind::Image => {
            if paths.len() > 1 {
                return Err(SliceError::ImageNotAlone {
                    path: first.clone(),
                    count: paths.len(),
                });
            }
            let img = image::load_limited(first, opts.limits.max_pixels)?;
            let name = first.display().to_string();
            let d =
                image::slice_image(&img, &name, &opts.image, pitch, 1, inlets, opts.min_run_mm)?;
            // The layers are copies of one: check their total before making them.
            stack_layers(d, opts.layers.unwrap_or(1), &opts.limits, &name)
        }
        DesignKind::ThreeMf => {
            if paths.len() > 1 {
                return Err(SliceError::ThreeMfNotAlone {
                    path: first.clone(),
                    count: paths.len(),
                });
            }
            let meshes = threemf::read_3mf_limited(first, &opts.limits)?;
            if meshes.len() > inlets {
                return Err(SliceError::TooManyMaterials {
                    what: first.display().to_string(),
                    found: meshes.len(),
                    inlets,
                    hint: MaterialsHint::ThreeMfObjects,
                });
            }
            slice_meshes(&meshes, config, opts, pitch)
        }
        DesignKind::Stl => {
            if let Some(p) = paths
                .iter()
                .zip(&kinds)
                .find(|(_, k)| **k != DesignKind::Stl)
            {
                return Err(SliceError::MixedWithStl { path: p.0.clone() });
            }
            if paths.len() > inlets {
                return Err(SliceError::TooManyMaterials {
                    what: first.display().to_string(),
                    found: paths.len(),
                    inlets,
                    hint: MaterialsHint::StlPerMaterial,
                });
            }
            let mut left = opts.limits.max_triangles;
            let mut meshes = Vec::with_capacity(paths.len());
            for p in paths {
                let m = mesh::read_stl_limited(p, left, opts.limits.max_triangles)?;
                left -= m.triangles.len() as u64;
                meshes.push(m);
            }
            slice_meshes(&meshes, config, opts, pitch)
        }
    }
}

/// `layers` copies of the design's one layer, refused before allocating when the runs
/// in all of them would pass `--max-segments`.
fn stack_layers(
    mut d: design::Design,
    layers: usize,
    limits: &Limits,
    name: &str,
) -> Result<design::Design, SliceError> {
    let per = d.layers.first().map_or(0, |l| l.runs().len() as u64).max(1);
    let total = per.saturating_mul(layers as u64);
    if total > limits.max_segments {
        return Err(over_limit(
            name,
            &format!("{layers} layers x {per} runs ="),
            total,
            limits.max_segments,
            SliceLimit::Segments,
            None,
        ));
    }
    if let Some(l) = d.layers.first().cloned() {
        d.layers = vec![l; layers.max(1)];
    }
    Ok(d)
}

fn slice_meshes(
    meshes: &[mesh::Mesh],
    config: &Config,
    opts: &SliceOptions,
    pitch: f64,
) -> Result<design::Design, SliceError> {
    voxel::slice_meshes(
        meshes,
        &voxel::MeshOptions {
            pitch_mm: pitch,
            layer_mm: config.channel.layer_height_mm as f64,
            max_layers: opts.layers,
            min_run_mm: opts.min_run_mm,
            progress: opts.progress,
            max_segments: opts.limits.max_segments,
        },
    )
}

/// Places a design, plans its toolpath and encodes the job.
pub fn slice_design(
    design: &design::Design,
    config: &Config,
    machine: &Machine<f64, INLETS>,
    opts: &PathOptions,
) -> Result<Sliced, SliceError> {
    let tp = toolpath::plan(design, config, machine, opts)?;
    let (header, body) = job_file::encode(&tp.commands, tp.start_um, tp.initial_material, config);
    Ok(Sliced {
        header,
        commands: tp.commands,
        body,
        name: design.name.clone(),
        size_mm: design.size_mm,
        stats: tp.stats,
    })
}
