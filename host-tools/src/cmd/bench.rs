//! `dollop bench`: prints performance and size figures, one function per figure (add a
//! new one to `BENCHES`). Each prints its numbers with the machine's core count; none is
//! a pass/fail test. Run it from a release build for figures worth quoting.

use crate::fixtures::{bundled, chessboard_design, example_config, test_image};
use crate::slicer::gcode::{self, Style};
use crate::slicer::gcode_dialect::{Dialect, Kind};
use crate::slicer::gcode_exec::{self, RunExport};
use crate::slicer::gcode_judge::{self, Setup};
use crate::slicer::image::{self, ImageOptions};
use crate::slicer::mesh::{self, shapes};
use crate::slicer::{self, voxel};
use anyhow::Context as _;
use dollop::config::Config;
use std::path::Path;
use std::time::Instant;

/// Arguments of `dollop bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Run only the figures whose name contains this (e.g. `image`, `mesh`, `job-size`).
    #[arg(long, value_name = "NAME")]
    pub only: Option<String>,
    /// Smaller inputs, for a quick look (figures are then not comparable with the goals).
    #[arg(long)]
    pub quick: bool,
}

/// What every figure gets.
#[derive(Clone, Debug)]
pub struct Ctx {
    /// Cores this machine offers (`available_parallelism`).
    pub cores: usize,
    /// Smaller inputs.
    pub quick: bool,
}

/// One figure: prints its lines, or fails with a reason.
pub type Bench = fn(&Ctx) -> anyhow::Result<()>;

/// Every figure, in the order printed.
pub const BENCHES: &[(&str, Bench)] = &[
    ("image-slicing", image_slicing),
    ("mesh-slicing", mesh_slicing),
    ("job-size", job_size),
    ("gcode-quality", gcode_quality),
    ("simulation", simulation),
    ("link", link),
];

/// Runs `dollop bench`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let ctx = Ctx {
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        quick: a.quick,
    };
    if cfg!(debug_assertions) {
        println!("(debug build: figures are not representative; use --release)");
    }
    let mut ran = 0;
    for (name, f) in BENCHES {
        if a.only.as_deref().is_some_and(|o| !name.contains(o)) {
            continue;
        }
        println!("== {name} ({} core(s) available)", ctx.cores);
        f(&ctx).with_context(|| format!("bench {name}"))?;
        ran += 1;
    }
    if ran == 0 {
        anyhow::bail!("no bench matches --only {:?}", a.only.unwrap_or_default());
    }
    Ok(())
}

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// Slicing a 4000 x 4000 two-material image at 0.2 mm pitch (goal: under 1 s on one core;
/// the slicer is single-threaded).
pub fn image_slicing(ctx: &Ctx) -> anyhow::Result<()> {
    let px = if ctx.quick { 1000 } else { 4000 };
    let mut config = example_config()?;
    config.channel.line_pitch_mm = 0.2;
    config.channel.layer_height_mm = 0.2;
    config.channel.nozzle_diameter_mm = 0.25;
    config.channel.nozzle_height_mm = 0.25;
    config.channel.bead_area_mm2 = None;
    config.motion.travel_max_mm = [1000.0, 1000.0, 100.0];
    let machine = slicer::validate(Path::new("bench config"), &config)?;
    let img = test_image(px);
    let inlets = machine.inlet_count();
    for (label, width) in [
        ("1 px = 1 pitch", None),
        ("resampled to 200 mm", Some(200.0)),
    ] {
        let opts = ImageOptions {
            width_mm: width,
            ..Default::default()
        };
        let t = Instant::now();
        let design = image::slice_image(&img, "bench", &opts, 0.2, 1, inlets, 0.1)?;
        let t_design = secs(t);
        let sliced = slicer::slice_design(&design, &config, &machine, &Default::default())?;
        let total = secs(t);
        println!(
            "image {px}x{px} px, {label}: {:.0} x {:.0} mm, {} rows, {} runs -> {} print segments; classify+resample {:.3} s, total {:.3} s (goal < 1 s on one core)",
            design.size_mm[0],
            design.size_mm[1],
            design.layers[0].rows(),
            design.layers[0].runs().len(),
            sliced.header.print_segments,
            t_design,
            total,
        );
    }
    // Decoding is the image crate's; shown apart.
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("bench.png");
    img.save(&path)?;
    let t = Instant::now();
    let _ = image::load(&path)?;
    println!(
        "decoding that image from PNG ({} bytes): {:.3} s",
        std::fs::metadata(&path)?.len(),
        secs(t)
    );
    Ok(())
}

/// Voxelizing and slicing a 1 000 000-triangle two-material mesh at 0.8 mm pitch and
/// 0.6 mm layers (goal: under 3 s), generated procedurally: a 100 mm cube with a
/// spherical cavity and the ball that fills it.
pub fn mesh_slicing(ctx: &Ctx) -> anyhow::Result<()> {
    let tris = if ctx.quick { 100_000 } else { 1_000_000 };
    let config = example_config()?;
    let machine = slicer::validate(Path::new("example config"), &config)?;
    let dir = tempfile::tempdir()?;
    let paths = [dir.path().join("shell.stl"), dir.path().join("ball.stl")];
    let meshes = shapes::box_with_sphere(
        [&paths[0], &paths[1]],
        [50.0, 50.0, 0.0],
        [150.0, 150.0, 80.0],
        38.0,
        tris,
    );
    let n: usize = meshes.iter().map(|m| m.triangles.len()).sum();
    let t = Instant::now();
    let design = voxel::slice_meshes(
        &meshes,
        &voxel::MeshOptions {
            pitch_mm: 0.8,
            layer_mm: 0.6,
            max_layers: None,
            min_run_mm: 0.1,
            progress: false,
            max_segments: u64::MAX,
        },
    )?;
    let t_vox = secs(t);
    let sliced = slicer::slice_design(&design, &config, &machine, &Default::default())?;
    let total = secs(t);
    println!(
        "mesh of {n} triangles (2 bodies), {} layers x {} rows: checked+voxelized {:.3} s, with toolpath and encoding {:.3} s (goal < 3 s); {} print segments, single-threaded",
        design.layers.len(),
        design.layers.first().map_or(0, |l| l.rows()),
        t_vox,
        total,
        sliced.header.print_segments
    );
    for (m, p) in meshes.iter().zip(&paths) {
        mesh::write_stl(p, m)?;
    }
    let t = Instant::now();
    for p in &paths {
        let _ = mesh::read_stl(p)?;
    }
    println!(
        "reading the two binary STL files ({} MB, stl_io and vertex welding): {:.3} s",
        (std::fs::metadata(&paths[0])?.len() + std::fs::metadata(&paths[1])?.len()) / 1_000_000,
        secs(t)
    );
    Ok(())
}

/// Job bytes per print segment against the exported G-code's, on the bundled designs
/// (goal: at most 8 bytes per segment in the job).
pub fn job_size(_ctx: &Ctx) -> anyhow::Result<()> {
    let config = example_config()?;
    let machine = slicer::validate(Path::new("example config"), &config)?;
    let names = crate::slicer::material_names(&config);
    for (label, files, opts) in bundled() {
        let s = slicer::slice_files(&files, &config, &opts)?;
        let segs = s.header.print_segments.max(1) as f64;
        let g = |style| {
            gcode::export(
                &s.commands,
                s.header.start_um,
                s.header.initial_material,
                &machine,
                &names,
                style,
            )
            .map(|x| x.1)
        };
        let fine = g(Style::default())?;
        let coarse = g(Style::Coarse { segments: 4 })?;
        let (_, run) = gcode_exec::export(
            &config,
            &s.commands,
            s.header.start_um,
            s.header.initial_material,
            &names,
            &RunExport::default(),
        )?;
        println!(
            "{label}: {} print segments; job {} bytes = {:.2} B/segment (body {:.2}); G-code from the executor's run {:.1} B/segment ({:.0}x the job), older fine {:.1}, coarse {:.1} B/segment",
            s.header.print_segments,
            s.to_bytes().len(),
            s.file_bytes_per_segment(),
            s.body_bytes_per_segment(),
            run.bytes as f64 / segs,
            run.bytes as f64 / s.to_bytes().len() as f64,
            fine.bytes as f64 / segs,
            coarse.bytes as f64 / segs,
        );
    }
    Ok(())
}

/// G-code quality as a conventional firmware would print it (`gcode_judge`: trapezoids at
/// the configured acceleration, full stops at junctions it would not take at speed, `M42`
/// in sequence, on the reference plant), with ideal valves and with the example machine's
/// real ones (10 ms dead time, 30/20 ms rise/decay): the export from the executor's run in
/// each dialect, and the older feed-rate profiles for comparison, on 1 mm and 5 mm
/// chessboards and the bundled designs. Goal for the run export: boundaries within 0.1 mm
/// at the 95th percentile, section within 5 % over every 0.2 mm.
pub fn gcode_quality(ctx: &Ctx) -> anyhow::Result<()> {
    let real = example_config()?;
    let mut ideal = real.clone();
    for i in ideal.inlets.iter_mut() {
        i.valve_open_delay_ms = 0.0;
        i.valve_close_delay_ms = 0.0;
        i.pressure_rise_ms = 0.0;
        i.pressure_decay_ms = 0.0;
    }
    let width = if ctx.quick { 10.0 } else { 20.0 };
    for (label, config) in [
        ("ideal valves", ideal),
        ("real valves (10 ms dead time, 30/20 ms rise/decay)", real),
    ] {
        let machine = slicer::validate(Path::new("example config"), &config)?;
        let pitch = config.channel.line_pitch_mm as f64;
        let mut jobs: Vec<(String, slicer::Sliced)> = Vec::new();
        for square in [1.0, 5.0] {
            let design = chessboard_design(width, square, pitch);
            let s = slicer::slice_design(&design, &config, &machine, &Default::default())?;
            jobs.push((format!("{width} mm chessboard, {square} mm squares"), s));
        }
        if !ctx.quick {
            for (name, files, opts) in bundled() {
                jobs.push((
                    name.to_string(),
                    slicer::slice_files(&files, &config, &opts)?,
                ));
            }
        }
        for (job, s) in &jobs {
            let start = s.header.start_um.map(|v| v as f64 * 1e-3);
            let init = s.header.initial_material;
            let design = gcode_judge::design_boundaries(&s.commands, s.header.start_um, init);
            // (name, text, Klipper's corner rule instead of Marlin's junction deviation)
            let mut outputs: Vec<(&str, String, bool)> = Vec::new();
            for (name, kind) in [
                ("run, plain", Kind::Plain),
                ("run, reprap", Kind::RepRap),
                ("run, klipper", Kind::Klipper),
                ("run, marlin", Kind::Marlin),
                ("run, marlin-m42", Kind::MarlinM42),
            ] {
                let opt = RunExport {
                    dialect: Dialect::new(kind),
                    ..RunExport::default()
                };
                let (text, _) =
                    gcode_exec::export(&config, &s.commands, s.header.start_um, init, &[], &opt)?;
                outputs.push((name, text, kind == Kind::Klipper));
            }
            for (name, style) in [
                ("older fine", Style::default()),
                ("older coarse", Style::Coarse { segments: 4 }),
            ] {
                let (text, _) =
                    gcode::export(&s.commands, s.header.start_um, init, &machine, &[], style)?;
                outputs.push((name, text, false));
            }
            for (name, text, klipper) in &outputs {
                let mut setup = Setup::new(&config, init, start);
                if *klipper {
                    // Klipper's default square_corner_velocity.
                    setup.firmware = setup.firmware.with_square_corner_velocity(5.0);
                }
                let v = gcode_judge::judge(text, &setup, &design)?;
                println!(
                    "{label}, {job}, {name:>12}: boundaries p95 {:.3} mm, worst {:.3} mm (mean {:.3}, {} designed, {} landed, {} off the beads); section {:.3}..{:.3} of S over {} windows of 0.2 mm; {} full stops on beads; {:.0} s",
                    v.p95_mm, v.worst_mm, v.mean_mm, v.boundaries, v.landed, v.changes_off_path, v.section_range.0, v.section_range.1, v.windows, v.full_stops, v.time_s
                );
            }
        }
    }
    Ok(())
}

/// Simulation speed: the executor the firmware runs, in virtual time on this machine,
/// alone (what `dollop simulate` does) and with the reference plant (what tests do).
pub fn simulation(_ctx: &Ctx) -> anyhow::Result<()> {
    let config = example_config()?;
    let text = dollop_sim::bench::report(&config).map_err(|e| anyhow::anyhow!("{e}"))?;
    print!("seed paper printhead, real valves: {text}");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/syringes.toml");
    let syringes: Config = toml::from_str(
        &std::fs::read_to_string(&path).with_context(|| format!("{}", path.display()))?,
    )?;
    let text = dollop_sim::bench::report(&syringes).map_err(|e| anyhow::anyhow!("{e}"))?;
    print!("two stepper syringes: {text}");
    Ok(())
}

/// Link code throughput on the host: frame codec, and a whole 100 000-segment upload
/// through the protocol client and the simulated board.
pub fn link(_ctx: &Ctx) -> anyhow::Result<()> {
    let text = crate::link::bench_link();
    print!("{text}");
    if text.contains("failed") || text.contains("does not parse") {
        anyhow::bail!("the link benchmark did not complete");
    }
    Ok(())
}
