//! Regenerates the worked example of `dollop inspect` bundled in `host-tools/data/inspect/`:
//! a 12 mm two-material chessboard job for `configs/seed-paper-valves.toml` with the corner
//! markers `dollop slice --markers` adds, printed (in simulation) on a machine whose channel is 20 % longer than that config says, and a
//! photo of it synthesized from the reference plant's deposit (random perspective, uneven
//! light, blur, noise; seeded, so the files change only when this does).
//! Run: `cargo run -p dollop-host --example inspect_photo`.

use dollop_host::inspect::frame::DesignFrame;
use dollop_host::inspect::synth::{self, Camera, Truth};
use dollop_host::inspect::{self, design};
use dollop_host::slicer::{job_file, markers};
use dollop_sim::designs::{self, Fill};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cfg_path = root.join("../configs/seed-paper-valves.toml");
    let config: dollop::Config = toml::from_str(&std::fs::read_to_string(cfg_path)?)?;
    let fill = Fill {
        origin_mm: [20.0, 20.0],
        width_mm: 12.0,
        rows: 12,
        pitch_mm: 0.8,
        layers: 1,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 8.0,
    };
    let job = designs::boustrophedon(&fill, designs::chessboard(3.0));
    // With the corner markers, as `dollop slice --markers` prints them.
    let travel = (
        [
            config.motion.travel_min_mm[0] as f64,
            config.motion.travel_min_mm[1] as f64,
        ],
        [
            config.motion.travel_max_mm[0] as f64,
            config.motion.travel_max_mm[1] as f64,
        ],
    );
    let pitch = config.channel.line_pitch_mm as f64;
    let commands =
        markers::add(&job.commands, job.start_um, pitch, travel).map_err(|e| e.to_string())?;
    let job = dollop_sim::Job { commands, ..job };
    let dir = root.join("data/inspect");
    std::fs::create_dir_all(&dir)?;
    job_file::write(&dir.join("chessboard.dlp"), &job, &config)?;
    let truth = Truth {
        channel_scale: 1.2,
        ..Default::default()
    };
    let plant = synth::plant_config(&config, &truth.physics(&config), &truth.supply_scale)
        .map_err(|e| e.to_string())?;
    let (pitch, radius) = inspect::geometry(&config);
    let plan = design::plan(&job.commands, job.start_um, pitch, radius);
    // The photo takes in the markers.
    let (lo, hi) = plan.extent();
    let frame = DesignFrame {
        lo,
        hi,
        px_per_mm: 40.0,
        margin_mm: 2.0 * pitch,
    };
    let (deposit, _) = synth::deposit(&config, &plant, &job, frame)?;
    let cam = Camera {
        size: (1600, 1200),
        seed: 12,
        ..Default::default()
    };
    let (photo, _) = synth::photograph(&deposit, &synth::FOOD, synth::PLATE_COLOUR, &cam);
    let path = dir.join("chessboard-photo.jpg");
    photo.save(&path)?;
    println!(
        "wrote {} and {}",
        dir.join("chessboard.dlp").display(),
        path.display()
    );
    Ok(())
}
