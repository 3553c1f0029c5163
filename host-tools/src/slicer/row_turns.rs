//! How hard the row-end U-turns of a filled design load the X/Y acceleration limit at
//! the speed the beads run: rows one pitch apart leave each U-turn a fillet of half the
//! pitch, and a head that must slow in it (the flow does not) swells the bead there. This
//! states the load and, past `ROW_TURN_SHARE`, what would bring it back; it does not
//! change the path (another slicer's G-code has its own turns).

use dollop::config::{Config, Pressure};
use dollop::Machine;

use super::INLETS;

/// Share of the X/Y limit the row-end U-turns may take at the beads' speed before the
/// section is at risk there: the rest is what the head's speed changes for the flow's
/// changes of paste need inside them. On the random pattern (`docs/soft-machines.md`,
/// food pastes, `auto` pressure) at 1 000 mm/s^2, 56 % (15 mm/s) held every straight
/// 0.2 mm within 1 %, 64 % (16 mm/s) left it by 1.33 %, 81 % by 2.63 % and 100 % (20 mm/s)
/// by 17.1 %; at 2 000 mm/s^2, 72 % held and 98 % left it by 15.6 %. With real valves
/// (Newtonian pastes at fixed pressures, whose flow overshoots its steady speed after a
/// change of paste) at 1 000 mm/s^2, 56 % left it by 2.18 %; 64 % took Y to 1 030 mm/s^2,
/// 81 % to 1 228 (the head, lagging the flow out of a U-turn, speeds back up before its
/// turn has ended) and 100 % X to 1 381 (it meets a U-turn at the overshoot's speed).
pub const ROW_TURN_SHARE: f64 = 0.6;

/// The row-end U-turns' load at the beads' speed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowTurns {
    /// The U-turn's fillet radius, half the line pitch, mm.
    pub radius_mm: f64,
    /// The fastest speed a bead runs once the channel has flushed, mm/s.
    pub speed_mm_s: f64,
    /// The machine's X/Y limit (the lower of the two), mm/s^2.
    pub limit: f64,
    /// Whether every inlet's pressure follows the print speed (`auto`): then
    /// `print_speed_mm_s` is what sets the beads' speed.
    pub auto_pressure: bool,
}

impl RowTurns {
    /// The load for `config` and its validated machine.
    pub fn of(config: &Config, m: &Machine<f64, INLETS>) -> RowTurns {
        let radius_mm = 0.5 * config.channel.line_pitch_mm as f64;
        // A syringe's bead runs at the print speed (its flushed speed is 0).
        let flushed = m.inlets.iter().map(|i| i.flushed_mm_s).fold(0.0, f64::max);
        let speed_mm_s = if flushed > 0.0 {
            flushed
        } else {
            config.motion.print_speed_mm_s as f64
        };
        let limit = config.motion.max_accel_mm_s2[0].min(config.motion.max_accel_mm_s2[1]) as f64;
        RowTurns {
            radius_mm,
            speed_mm_s,
            limit,
            auto_pressure: config
                .inlets
                .iter()
                .all(|i| i.syringe.is_some() || i.pressure_kpa == Pressure::Auto),
        }
    }

    /// What the beads' speed takes round the fillet, `v^2 / r`, mm/s^2.
    pub fn accel(&self) -> f64 {
        self.speed_mm_s * self.speed_mm_s / self.radius_mm
    }

    /// The share of the limit the U-turns take.
    pub fn share(&self) -> f64 {
        self.accel() / self.limit
    }

    /// The fastest bead speed that keeps the U-turns within `ROW_TURN_SHARE`, mm/s.
    pub fn speed_within(&self) -> f64 {
        (ROW_TURN_SHARE * self.limit * self.radius_mm).sqrt()
    }

    /// The X/Y limit at which the beads' speed keeps the U-turns within
    /// `ROW_TURN_SHARE`, mm/s^2.
    pub fn limit_within(&self) -> f64 {
        self.accel() / ROW_TURN_SHARE
    }

    /// The load, as `config --check` and the dashboard state it (`per_s2`: how the
    /// page writes mm/s^2).
    pub fn figure(&self, per_s2: &str) -> String {
        format!(
            "{:.2} mm radius (half the pitch) at {:.2} mm/s: {:.0} {per_s2}, {:.0} % of the X/Y limit of {:.0} {per_s2}",
            self.radius_mm,
            self.speed_mm_s,
            self.accel(),
            self.share() * 100.0,
            self.limit
        )
    }

    /// What to do, when the U-turns take more than `ROW_TURN_SHARE` of the limit.
    pub fn advice(&self) -> Option<String> {
        let share = self.share();
        if share.is_nan() || share <= ROW_TURN_SHARE {
            return None;
        }
        let lever = if self.auto_pressure {
            format!("print_speed_mm_s at most {:.1}", self.speed_within())
        } else {
            format!(
                "lower pressure_kpa until the beads run at most {:.1} mm/s",
                self.speed_within()
            )
        };
        Some(format!(
            "the row-end U-turns ({:.2} mm radius, half the {:.2} mm pitch) take {:.0} % of the X/Y limit at {:.1} mm/s; past {:.0} % the head may have to slow in them while the flow does not: the bead swells at the row ends, and the axes may leave their limit there; {lever}, or an X/Y limit of at least {:.0} mm/s^2, keeps them within {:.0} %",
            self.radius_mm,
            2.0 * self.radius_mm,
            share * 100.0,
            self.speed_mm_s,
            ROW_TURN_SHARE * 100.0,
            self.limit_within(),
            ROW_TURN_SHARE * 100.0
        ))
    }
}
