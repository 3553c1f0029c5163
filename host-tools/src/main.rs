//! The `dollop` command line: parses arguments and hands each subcommand to its module;
//! every error ends the process with a one-line reason and a non-zero exit code.

use clap::{Parser, Subcommand};
use dollop_host::cmd;
use std::process::ExitCode;

/// Host tools for the dollop multi-material food-printer controller.
#[derive(Parser)]
#[command(name = "dollop", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Slice images, multi-material 3D models or another slicer's G-code into a job (.dlp),
    /// G-code and previews.
    Slice(Box<cmd::slice::Args>),
    /// Run a job through the firmware's executor in virtual time; trace, heatmap, report.
    Simulate(cmd::simulate::Args),
    /// Print a complete, commented example machine config.
    Config(cmd::config::Args),
    /// Slice and simulate a bundled design with a bundled config; write previews.
    Demo(cmd::demo::Args),
    /// Upload a job to the board over USB, start it and follow it.
    Send(cmd::link::SendArgs),
    /// Show the board's state.
    Status(cmd::link::PortArgs),
    /// Pause the print mid-bead (valves shut, head stopped), until resumed; `--park`
    /// lifts and moves to the park position, `--refill` retracts syringe plungers.
    Pause(cmd::link::PauseArgs),
    /// Resume a paused print.
    Resume(cmd::link::PortArgs),
    /// Abort the print: valves closed, motion stopped.
    Abort(cmd::link::PortArgs),
    /// Move an axis by hand.
    Jog(cmd::link::JogArgs),
    /// Open or close one valve by hand (valve test).
    Valve(cmd::link::ValveArgs),
    /// Turn measurements into config values.
    Calibrate(cmd::calibrate::Args),
    /// Measure a printed job from a top-view photo: pattern error, boundary offsets, bead
    /// width; --suggest turns them into config corrections.
    Inspect(cmd::inspect::Args),
    /// Start the web dashboard (design, simulate, print, on this computer's browser).
    Serve(dollop_host::serve::Args),
    /// Print performance figures (slicing, voxelizing, simulation, link, job size).
    Bench(cmd::bench::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Slice(a) => cmd::slice::run(*a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Config(a) => cmd::config::run(a),
        Command::Demo(a) => cmd::demo::run(a),
        Command::Send(a) => cmd::link::send(a),
        Command::Status(a) => cmd::link::status(a),
        Command::Pause(a) => cmd::link::pause(a),
        Command::Resume(a) => cmd::link::resume(a),
        Command::Abort(a) => cmd::link::abort(a),
        Command::Jog(a) => cmd::link::jog(a),
        Command::Valve(a) => cmd::link::valve(a),
        Command::Calibrate(a) => cmd::calibrate::run(a),
        Command::Inspect(a) => cmd::inspect::run(a),
        Command::Bench(a) => cmd::bench::run(a),
        Command::Serve(a) => dollop_host::serve::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the context chain joined by ": ".
            eprintln!("dollop: {}", cmd::one_line(&e));
            ExitCode::from(1)
        }
    }
}
