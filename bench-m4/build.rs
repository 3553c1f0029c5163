//! Build script of the M4 benchmark: the board's memory map, and the configs and jobs
//! the benchmark runs, encoded (postcard, .dlp body) so the chip side parses no text.

use dollop::job;
use dollop_sim::designs::{boustrophedon, chessboard, Fill};
use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    // mps2-an386: 4 MiB of code memory at 0, 4 MiB of SRAM at 0x2000_0000.
    std::fs::write(
        out.join("memory.x"),
        "MEMORY {\n  FLASH : ORIGIN = 0x00000000, LENGTH = 4M\n  RAM : ORIGIN = 0x20000000, LENGTH = 4M\n}\n",
    )
    .unwrap();
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=build.rs");
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("..");
    for (name, file) in [
        ("valves", "seed-paper-valves.toml"),
        ("pastes", "food-pastes.toml"),
        ("syringes", "syringes.toml"),
        ("ramps", "seed-paper.toml"),
    ] {
        let path = root.join("configs").join(file);
        println!("cargo:rerun-if-changed={}", path.display());
        let cfg: dollop::Config = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        std::fs::write(
            out.join(format!("{name}.config")),
            postcard::to_allocvec(&cfg).unwrap(),
        )
        .unwrap();
    }
    // Issue 22's soft machine (real valves, X/Y at 500 mm/s^2): the channel holds 2.5 mm of
    // bead, so every switch of the 1 mm board meets several pastes in it and the flow's
    // follower (`dollop::flow_follow`) bends the head.
    let path = root.join("configs/soft-real-valves.toml");
    println!("cargo:rerun-if-changed={}", path.display());
    let mut cfg: dollop::Config = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    cfg.motion.max_accel_mm_s2[0] = 500.0;
    cfg.motion.max_accel_mm_s2[1] = 500.0;
    std::fs::write(
        out.join("soft.config"),
        postcard::to_allocvec(&cfg).unwrap(),
    )
    .unwrap();
    // Chessboard of 1 mm squares, 2 layers: a switch every millimetre, two corners a row.
    let fill = Fill {
        origin_mm: [20.0, 20.0],
        width_mm: 8.0,
        rows: 6,
        pitch_mm: 0.8,
        layers: 2,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 6.0,
    };
    let j = boustrophedon(&fill, chessboard(1.0));
    let mut body = Vec::new();
    for c in &j.commands {
        body.extend_from_slice(&postcard::to_allocvec(c).unwrap());
    }
    let mut header = Vec::new();
    for v in j.start_um {
        header.extend_from_slice(&v.to_le_bytes());
    }
    header.push(j.initial_material);
    let _ = job::FORMAT_VERSION;
    std::fs::write(out.join("job.head"), header).unwrap();
    std::fs::write(out.join("job.body"), body).unwrap();
}
