//! Purge blocks a multi-extruder slicer adds for a single nozzle: PrusaSlicer's wipe tower
//! (ramming and wiping included), Cura's prime tower, Orca/Bambu's prime tower. dollop
//! switches by volume and needs none; the import refuses them, naming the slicer setting,
//! or (`--strip-purge`) drops them and counts what that saves.

/// What a `;TYPE:` comment or block marker says about the lines after it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Region {
    /// A purge block: what it is and the setting that makes it.
    Purge {
        /// Human name.
        what: &'static str,
        /// The slicer setting to turn off.
        setting: &'static str,
    },
    /// Any other feature: printed.
    Part,
}

/// The region a comment starts, if it starts one. Feature-type comments (`;TYPE:...`)
/// and PrusaSlicer/Orca's wipe-tower markers are recognised, case-insensitively.
pub fn region(comment: &str) -> Option<(Region, &str)> {
    let c = comment.trim();
    let lower = c.to_ascii_lowercase();
    if let Some(kind) = c.strip_prefix("TYPE:").or_else(|| c.strip_prefix("type:")) {
        let k = kind.trim().to_ascii_lowercase();
        let r = if k.contains("wipe tower") || k.contains("wipe_tower") {
            Region::Purge {
                what: "a wipe tower",
                setting: "the wipe tower (PrusaSlicer: Print Settings > Multiple Extruders > Wipe tower, `wipe_tower = 0`)",
            }
        } else if k.contains("prime-tower")
            || k.contains("prime tower")
            || k.contains("prime_tower")
        {
            Region::Purge {
                what: "a prime tower",
                setting: "the prime tower (Cura: Dual Extrusion > Enable Prime Tower, `prime_tower_enable = false`; Orca: `enable_prime_tower = 0`)",
            }
        } else {
            Region::Part
        };
        return Some((r, kind.trim()));
    }
    if lower.starts_with("wipe_tower_start") || lower.starts_with("cp toolchange start") {
        return Some((
            Region::Purge {
                what: "a wipe-tower tool change",
                setting: "the wipe tower (`wipe_tower = 0` / `enable_prime_tower = 0`)",
            },
            "Wipe tower",
        ));
    }
    if lower.starts_with("wipe_tower_end") || lower.starts_with("cp toolchange end") {
        return Some((Region::Part, ""));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slicers_purge_comments() {
        assert!(matches!(
            region("TYPE:Wipe tower"),
            Some((Region::Purge { .. }, "Wipe tower"))
        ));
        assert!(matches!(
            region("TYPE:PRIME-TOWER"),
            Some((Region::Purge { .. }, _))
        ));
        assert!(matches!(
            region("TYPE:Perimeter"),
            Some((Region::Part, "Perimeter"))
        ));
        assert!(matches!(
            region(" CP TOOLCHANGE START"),
            Some((Region::Purge { .. }, _))
        ));
        assert_eq!(region("LAYER:3"), None);
    }
}
