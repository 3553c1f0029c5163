//! `dollop config --check` states the flow's worst speed step and the acceleration that
//! keeps the bead section through it, so a user sees when the machine is the limit.

use std::path::Path;
use std::process::Command;

fn check(config: &str) -> String {
    check_path(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../configs")
            .join(config),
    )
}

fn check_path(path: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_dollop"))
        .args(["config", "--check"])
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).to_string()
}

#[test]
fn instantaneous_valves_state_the_acceleration_their_worst_step_needs() {
    let out = check("seed-paper.toml");
    // Paste B's supply through a channel full of paste A: 10 mm/s * 3.17 / 1.41 at once
    // when its valve opens; 22.48^2 / (8 * 0.02 * 0.2) mm/s^2 of ramp keeps 2 % over
    // 0.2 mm, and the ramp gets RAMP_SHARE (0.95) of the X/Y limit.
    assert!(
        out.contains("worst flow step         22.48 mm/s at once"),
        "{out}"
    );
    assert!(
        out.contains("needs 15795 mm/s^2 of ramp, an X/Y limit of 16627 mm/s^2"),
        "{out}"
    );
    assert!(
        out.contains("(the machine's acceleration is the limit)"),
        "{out}"
    );
}

#[test]
fn real_valves_need_no_ramp() {
    let out = check("seed-paper-valves.toml");
    assert!(out.contains("worst flow step         none"), "{out}");
}

/// Issue 22's soft machine: paste B's line decaying into a channel full of paste A slows
/// the head faster than its 1 000 mm/s^2, but not at once: the window is what that
/// 20 ms decay needs (7.1 ms), and the section bound stays 1 %.
#[test]
fn real_valves_on_a_soft_machine_state_the_change_and_its_window() {
    let out = check("soft-real-valves.toml");
    assert!(
        out.contains("worst flow change       22.48 mm/s, faster than the X/Y limit of 1000 mm/s^2 follows (pressure rise/decay): speed ramps 7.1 ms, section bound 1.0 % over 0.2 mm"),
        "{out}"
    );
}

/// The other machines of issue 22 (`docs/soft-machines.md`): instantaneous valves at
/// 5 000 mm/s^2 ramp each step within the limit and say what that costs; the food pastes
/// behind real valves at 500 mm/s^2 change their flow faster than the limit follows.
#[test]
fn the_bundled_soft_machines_state_their_flow_changes() {
    let out = check("soft-instant-valves.toml");
    assert!(
        out.contains("speed ramps             4.9 ms at the X/Y limit of 5000 mm/s^2"),
        "{out}"
    );
    let out = check("soft-food-pastes.toml");
    assert!(
        out.contains(
            "worst flow change       10.63 mm/s, faster than the X/Y limit of 500 mm/s^2 follows"
        ),
        "{out}"
    );
    assert!(
        out.contains("(mashed potato)") && out.contains("(chocolate)"),
        "{out}"
    );
}
