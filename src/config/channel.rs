//! `[channel]`: the nozzle, the shared channel and the bead, checked and turned into the
//! volumes the flow model runs on. It stops at geometry; the flow through it is the
//! inlets' and `flow.rs`'s business.

use super::check::Check;
use super::{ChannelConfig, ConfigError};

/// The channel's geometry in mm and mm^3 (f64: validation time only).
pub(super) struct Geometry {
    /// Nozzle and channel diameter, mm.
    pub(super) d: f64,
    /// Bead section, mm^2.
    pub(super) s: f64,
    /// Volume of the shared channel, mm^3.
    pub(super) v_channel: f64,
    /// Volume of the filament hanging below the nozzle, mm^3.
    pub(super) v_hang: f64,
}

/// Checks `[channel]`.
pub(super) fn check(c: &ChannelConfig) -> Result<Geometry, ConfigError> {
    let ch = Check::section("channel");
    // Lower bounds below are where printing stops making sense (a 50 um bead, a 10 um
    // layer, 0.1 mm/s): past them the slicer's sampling and the step timing degenerate
    // (a pitch under the 20 um sample grid panicked the image slicer).
    let d = ch.range("nozzle_diameter_mm", c.nozzle_diameter_mm, 0.05, 20.0)? as f64;
    let ls = ch.positive_max("channel_length_mm", c.channel_length_mm, 500.0)? as f64;
    let h_noz = ch.range("nozzle_height_mm", c.nozzle_height_mm, 0.0, 50.0)? as f64;
    let h_layer = ch.range("layer_height_mm", c.layer_height_mm, 0.01, 20.0)? as f64;
    let pitch = ch.range("line_pitch_mm", c.line_pitch_mm, 0.05, 50.0)? as f64;
    let s = match c.bead_area_mm2 {
        Some(a) => ch.range("bead_area_mm2", a, 1e-4, 1000.0)? as f64,
        None => pitch * h_layer,
    };
    let area = core::f64::consts::PI * d * d / 4.0;
    Ok(Geometry {
        d,
        s,
        v_channel: area * ls,
        v_hang: area * (h_noz - h_layer).max(0.0),
    })
}
