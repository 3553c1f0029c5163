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

/// The row-end U-turns' load: stated for every machine, and a note with what would bring
/// it back where the beads' speed takes more than 60 % of the X/Y limit round half the
/// pitch (the food pastes at 20 mm/s on 1 000 mm/s^2 left the section by 17 % there,
/// `docs/soft-machines.md`). Every bundled machine is within it.
#[test]
fn row_end_u_turns_past_the_limit_s_share_say_what_would_do() {
    for name in [
        "seed-paper.toml",
        "seed-paper-valves.toml",
        "food-pastes.toml",
        "syringes.toml",
        "soft-real-valves.toml",
        "soft-instant-valves.toml",
        "soft-food-pastes.toml",
    ] {
        let out = check(name);
        assert!(
            out.contains("  row-end U-turns         0.40 mm radius"),
            "{name}: {out}"
        );
        assert!(!out.contains("note:"), "{name}: {out}");
    }
    let out = check("soft-food-pastes.toml");
    assert!(
        out.contains("at 10.00 mm/s: 250 mm/s^2, 50 % of the X/Y limit of 500 mm/s^2"),
        "{out}"
    );
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/soft-food-pastes.toml"),
    )
    .unwrap();
    let fast = text
        .replace(
            "max_accel_mm_s2 = [500.0, 500.0, 200.0]",
            "max_accel_mm_s2 = [1000.0, 1000.0, 200.0]",
        )
        .replace("print_speed_mm_s = 10.0", "print_speed_mm_s = 20.0");
    assert_ne!(fast, text);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fast.toml");
    std::fs::write(&path, fast).unwrap();
    let out = check_path(&path);
    assert!(
        out.contains("at 20.00 mm/s: 1000 mm/s^2, 100 % of the X/Y limit of 1000 mm/s^2"),
        "{out}"
    );
    // sqrt(0.6 * 1000 * 0.4) = 15.49 mm/s; 20^2 / 0.4 / 0.6 = 1667 mm/s^2.
    assert!(
        out.contains("note: the row-end U-turns (0.40 mm radius, half the 0.80 mm pitch) take 100 % of the X/Y limit at 20.0 mm/s"),
        "{out}"
    );
    assert!(
        out.contains("print_speed_mm_s at most 15.5, or an X/Y limit of at least 1667 mm/s^2"),
        "{out}"
    );
}
