//! `dollop inspect PHOTO --job JOB.dlp --config MACHINE.toml`: measures a printed
//! single-layer job from a top-view photo, prints the report, writes the rectified picture
//! (`--picture`) and, with `--suggest`, config corrections (`--out`). The measuring is
//! `crate::inspect`'s.

use crate::inspect::{self, suggest, InspectError};
use crate::slicer::{self, job_file, output};
use anyhow::Context;
use std::path::PathBuf;

/// Arguments of `dollop inspect`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Top-view photo of the printed job (PNG, JPEG, BMP), the whole print in the frame on
    /// a plain plate.
    pub photo: PathBuf,
    /// The job that was printed.
    #[arg(long, value_name = "JOB.dlp")]
    pub job: PathBuf,
    /// The machine config it was printed with.
    #[arg(long, value_name = "MACHINE.toml")]
    pub config: PathBuf,
    /// Write the rectified photo with the design's boundaries, coloured by offset.
    #[arg(long, value_name = "OUT.png")]
    pub picture: Option<PathBuf>,
    /// Turn the measurements into config corrections.
    #[arg(long)]
    pub suggest: bool,
    /// With --suggest: write the corrections as a TOML fragment here.
    #[arg(long, value_name = "FRAGMENT.toml", requires = "suggest")]
    pub out: Option<PathBuf>,
    /// Resolution of the rectified picture and the measurements, px per mm.
    #[arg(long, value_name = "N", default_value_t = 25.0)]
    pub px_per_mm: f64,
    /// Largest photo, pixels (width x height), checked from its header.
    #[arg(long, value_name = "N", default_value_t = inspect::photo::MAX_PIXELS)]
    pub max_pixels: u64,
}

/// A library error that names an input, in this command's words: the flag that gave it.
fn in_flags(e: InspectError) -> anyhow::Error {
    match e {
        InspectError::Resolution { px_per_mm, min, max } => {
            anyhow::anyhow!("--px-per-mm {px_per_mm} must be from {min} to {max}")
        }
        InspectError::FrameTooLarge { w, h } => {
            anyhow::anyhow!("the design frame would be {w} x {h} px; lower --px-per-mm")
        }
        InspectError::TooLarge {
            path,
            w,
            h,
            px,
            limit,
            over,
        } => anyhow::anyhow!(
            "{}: {w} x {h} = {px} pixels, over the limit of {limit} by {over} (--max-pixels); scale the photo down or raise the limit",
            path.display()
        ),
        e => e.into(),
    }
}

/// Runs `dollop inspect`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let config = slicer::load_config(&a.config)?;
    let (header, commands) = job_file::read_job(&a.job)?;
    slicer::validate(&a.config, &config)?;
    let opts = inspect::Options {
        px_per_mm: a.px_per_mm,
        max_pixels: a.max_pixels,
        ..Default::default()
    };
    let ins = inspect::inspect(&a.photo, &commands, header.start_um, &config, &opts).map_err(
        |e| match e {
            InspectError::Job { message, .. } => anyhow::anyhow!("{}: {message}", a.job.display()),
            e => in_flags(e),
        },
    )?;
    if ins.plan.layers > 1 {
        eprintln!(
            "dollop: note: {} has {} layers; the photo is compared with the top one",
            a.job.display(),
            ins.plan.layers
        );
    }
    print!("{}", ins.report(&slicer::material_names(&config)));
    let mut staged = output::StagedFiles::new();
    let mut written_out = a.out.is_some();
    if a.suggest {
        let s = suggest::for_job(
            &ins,
            &config,
            header.start_um,
            header.initial_material,
            &commands,
        );
        println!("suggestions:");
        for l in &s.lines {
            println!("  {l}");
        }
        match (&a.out, &s.fragment) {
            (Some(path), Some(f)) => {
                println!("\nfragment:\n{f}");
                output::stage(&mut staged, path, |w| w.write_all(f.as_bytes()))?;
            }
            // A print that needs no correction is the good outcome: say so, exit 0.
            (Some(path), None) if s.none_needed() => {
                println!(
                    "no correction needed: the config already puts the boundaries where the photo shows them; {} not written",
                    path.display()
                );
                written_out = false;
            }
            (Some(path), None) => anyhow::bail!(
                "--out {}: nothing to write: no single parameter explains the offsets (see the suggestions above)",
                path.display()
            ),
            (None, Some(f)) => println!("\nfragment:\n{f}"),
            (None, None) => {}
        }
    }
    if let Some(path) = &a.picture {
        let img = inspect::picture::figure(&ins)
            .map_err(|e| anyhow::anyhow!("{}: cannot draw the picture: {e}", path.display()))?;
        slicer::preview::stage_png(&mut staged, path, &img)?;
    }
    output::commit(staged).context("writing the outputs")?;
    let out = a.out.as_ref().filter(|_| written_out);
    for p in [a.picture.as_ref(), out].into_iter().flatten() {
        println!("wrote {}", p.display());
    }
    Ok(())
}
