//! `cargo bench -p dollop-sim`: prints the simulation speed figures (no timing asserts).

fn main() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../configs/seed-paper-valves.toml"
    );
    let text = std::fs::read_to_string(path).expect("bundled config");
    let cfg: dollop::Config = toml::from_str(&text).expect("bundled config parses");
    match dollop_sim::bench::report(&cfg) {
        Ok(text) => print!("{text}"),
        Err(e) => {
            eprintln!("benchmark failed: {e}");
            std::process::exit(1);
        }
    }
}
