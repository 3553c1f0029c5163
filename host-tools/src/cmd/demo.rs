//! `dollop demo`: the main job on built-in example data. Slices a bundled design for a
//! bundled machine (the seed paper's printhead with real valves), writes the job, G-code
//! and pictures, simulates the print through the firmware's executor and the reference
//! plant, and prints the report. Everything it needs is compiled into the binary.

use crate::simulate::{self, Heatmap};
use crate::slicer::{
    self, gcode_exec, image::ImageOptions, job_file, output, preview, SliceOptions,
};
use anyhow::Context;
use dollop::config::Config;
use dollop_sim::Job;
use std::path::{Path, PathBuf};

/// The bundled designs.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Design {
    /// A two-material logo picture, printed 40 mm wide.
    Logo,
    /// A two-material chessboard picture, one pixel per bead.
    Chessboard,
    /// A cube shell around a ball: two STL bodies, one per material.
    Cube,
}

/// Arguments of `dollop demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Which bundled design.
    #[arg(long, value_enum, default_value_t = Design::Logo)]
    pub design: Design,
    /// Directory for what it writes (config, design, job, G-code, pictures).
    #[arg(long, value_name = "DIR", default_value = "dollop-demo")]
    pub out_dir: PathBuf,
}

const MACHINE: &str = include_str!("../../../configs/seed-paper-valves.toml");
const LOGO: &[u8] = include_bytes!("../../designs/logo.png");
const CHESSBOARD: &[u8] = include_bytes!("../../designs/chessboard.png");
const CUBE_SHELL: &[u8] = include_bytes!("../../designs/cube-shell.stl");
const CUBE_BALL: &[u8] = include_bytes!("../../designs/cube-ball.stl");

/// Writes a bundled input where the slicer can read it (a private temporary folder: the
/// user's copies are staged with the other outputs) and returns its path.
fn input(tmp: &Path, name: &str, bytes: &[u8]) -> anyhow::Result<PathBuf> {
    let path = tmp.join(name);
    std::fs::write(&path, bytes).with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(path)
}

/// Runs `dollop demo`. Every file it writes (the inputs' copies included) is staged and
/// renamed into the folder together at the end, so a failed or interrupted demo leaves
/// none of them.
pub fn run(a: Args) -> anyhow::Result<()> {
    let dir = &a.out_dir;
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let tmp = tempfile::tempdir().context("cannot create a temporary folder")?;
    let tmp = tmp.path();
    let machine_path = dir.join("machine.toml");
    let config = slicer::load_config(&input(tmp, "machine.toml", MACHINE.as_bytes())?)?;
    let (name, inputs, opts) = bundled(a.design);
    let files = inputs
        .iter()
        .map(|(n, b)| input(tmp, n, b))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let opts = SliceOptions {
        progress: true,
        ..opts
    };
    let sliced = slicer::slice_files(&files, &config, &opts)?;
    let job_path = dir.join(format!("{name}.dlp"));
    slicer::validate(&machine_path, &config)?;
    let names = crate::slicer::material_names(&config);
    let gcode_text = gcode_of(&config, &sliced, &names)?;
    let gcode_path = dir.join(format!("{name}.gcode"));
    let preview_path = dir.join(format!("{name}-toolpath.png"));
    let preview_img = preview::figure(
        &sliced.commands,
        sliced.header.start_um,
        &preview::PreviewOptions {
            bead_mm: config.channel.line_pitch_mm as f64,
            ..Default::default()
        },
        &names,
    )?;
    println!(
        "sliced {} for {}: {} print segments, {:.1} x {:.1} mm, job {} bytes ({:.1} B/segment; G-code {:.0} B/segment)",
        files
            .iter()
            .filter_map(|p| p.file_name())
            .map(|n| n.to_string_lossy())
            .collect::<Vec<_>>()
            .join(" + "),
        machine_path.display(),
        sliced.header.print_segments,
        sliced.size_mm[0],
        sliced.size_mm[1],
        sliced.to_bytes().len(),
        sliced.file_bytes_per_segment(),
        gcode_text.len() as f64 / sliced.header.print_segments.max(1) as f64,
    );
    let job = Job {
        start_um: sliced.header.start_um,
        initial_material: sliced.header.initial_material,
        commands: sliced.commands.clone(),
    };
    let mut heat = Heatmap::for_job(&job, &config);
    let t = std::time::Instant::now();
    let result = simulate::simulate_job(
        &config,
        &job,
        true,
        simulate::Recording {
            trace: None,
            heatmap: Some(&mut heat),
            progress: true,
            max_seconds: f64::INFINITY,
            pauses: None,
        },
    )?;
    let wall = t.elapsed();
    heat.mark_boundaries(&result.metrics.boundaries);
    let plate_path = dir.join(format!("{name}-plate.png"));
    let mut staged = output::StagedFiles::new();
    output::stage(&mut staged, &machine_path, |w| {
        w.write_all(MACHINE.as_bytes())
    })?;
    for (n, b) in inputs {
        output::stage(&mut staged, &dir.join(n), |w| w.write_all(b))?;
    }
    output::stage(&mut staged, &job_path, |w| {
        w.write_all(&job_file::job_bytes(&sliced.header, &sliced.body))
    })?;
    output::stage(&mut staged, &gcode_path, |w| {
        w.write_all(gcode_text.as_bytes())
    })?;
    preview::stage_png(&mut staged, &preview_path, &preview_img)?;
    heat.stage(&mut staged, &plate_path)?;
    output::commit(staged)?;
    print!("{}", simulate::report_text(&result, &config, true, wall));
    let bound = simulate::Bounds::of(&config).section;
    let plan = dollop_sim::PausePlan::default();
    if let Some(f) = simulate::section_floor(&config, &job, &plan, true, &result, bound) {
        print!("{f}");
    }
    println!(
        "wrote {}, {}, {}, {}",
        job_path.display(),
        gcode_path.display(),
        preview_path.display(),
        plate_path.display()
    );
    if let Some(f) = result.fault {
        anyhow::bail!("the demo job ended in a fault: {f}");
    }
    if let Some(first) = result.metrics.mismatches.first() {
        anyhow::bail!(
            "the demo's material sequence on the plate differs from the design ({} difference(s); first: {first})",
            result.metrics.mismatches.len()
        );
    }
    Ok(())
}

/// A bundled design: its name, its files (name, bytes) and how it is sliced.
fn bundled(
    design: Design,
) -> (
    &'static str,
    &'static [(&'static str, &'static [u8])],
    SliceOptions,
) {
    match design {
        Design::Logo => (
            "logo",
            &[("logo.png", LOGO)],
            SliceOptions {
                image: ImageOptions {
                    width_mm: Some(40.0),
                    ..Default::default()
                },
                ..Default::default()
            },
        ),
        Design::Chessboard => (
            "chessboard",
            &[("chessboard.png", CHESSBOARD)],
            SliceOptions::default(),
        ),
        Design::Cube => (
            "cube",
            &[("cube-shell.stl", CUBE_SHELL), ("cube-ball.stl", CUBE_BALL)],
            SliceOptions::default(),
        ),
    }
}

/// The G-code `dollop slice --gcode` writes by default for `sliced`: from the executor's
/// own run.
fn gcode_of(config: &Config, sliced: &slicer::Sliced, names: &[String]) -> anyhow::Result<String> {
    let (text, _) = gcode_exec::export(
        config,
        &sliced.commands,
        sliced.header.start_um,
        sliced.header.initial_material,
        names,
        &gcode_exec::RunExport {
            host: crate::slicer::gcode_dialect::HostText {
                progress: true,
                ..Default::default()
            },
            ..gcode_exec::RunExport::default()
        },
    )?;
    Ok(text)
}
