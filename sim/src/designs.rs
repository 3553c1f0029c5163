//! Programmatic test designs as jobs: boustrophedon fills of a material function (stripes,
//! chessboards, short features) with a priming bead first. Image and STL slicing is the
//! host tools' job; these exist so whole-job tests need no files.

use dollop::Command;

/// A job ready for the executor.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// Where the head stands when the job begins, micrometres.
    pub start_um: [i32; 3],
    /// Material the channel is primed with.
    pub initial_material: u8,
    /// The commands, ending with `End`.
    pub commands: Vec<Command>,
}

impl Job {
    /// Number of print segments.
    pub fn print_segments(&self) -> usize {
        self.commands
            .iter()
            .filter(|c| matches!(c, Command::Print { .. }))
            .count()
    }
}

/// A rectangular boustrophedon fill.
#[derive(Clone, Copy, Debug)]
pub struct Fill {
    /// Lower-left corner of the fill, mm.
    pub origin_mm: [f64; 2],
    /// Size along X, mm.
    pub width_mm: f64,
    /// Number of rows (bead lines) per layer.
    pub rows: usize,
    /// Row spacing, mm.
    pub pitch_mm: f64,
    /// Layers.
    pub layers: usize,
    /// Layer height, mm (the first layer prints at this Z).
    pub layer_mm: f64,
    /// Material sampling step along a row, mm (boundaries snap to it).
    pub cell_mm: f64,
    /// Length of the priming bead printed first (below the fill), mm.
    pub prime_mm: f64,
}

/// Millimetres to the jobs' integer micrometres, rounded to the nearest (saturating at
/// the `i32` range): the one conversion the designs, the slicer and the G-code import use.
pub fn um(mm: f64) -> i32 {
    (mm * 1000.0).round() as i32
}

/// Builds the job for `fill`, with `material(x, y, layer)` giving the design's material at
/// a point (x, y in mm).
pub fn boustrophedon(fill: &Fill, material: impl Fn(f64, f64, usize) -> u8) -> Job {
    let [x0, y0] = fill.origin_mm;
    let z = fill.layer_mm;
    let first = material(x0 + fill.cell_mm / 2.0, y0, 0);
    let mut cmds = Vec::new();
    // Priming bead along y0 - 3 pitches, ending under the fill's start.
    let prime_y = y0 - 3.0 * fill.pitch_mm;
    let start = [um(x0 - fill.prime_mm - 2.0), um(prime_y), um(z)];
    cmds.push(Command::Travel {
        x: start[0],
        y: start[1],
        z: start[2],
    });
    cmds.push(Command::Print {
        dx: um(fill.prime_mm),
        dy: 0,
        material: first,
    });
    let cells = (fill.width_mm / fill.cell_mm).round() as usize;
    for layer in 0..fill.layers {
        let zl = um(z * (layer + 1) as f64);
        cmds.push(Command::Travel {
            x: um(x0),
            y: um(y0),
            z: zl,
        });
        let mut cur = [um(x0), um(y0)];
        for row in 0..fill.rows {
            let y = y0 + row as f64 * fill.pitch_mm;
            let forward = row % 2 == 0;
            // Runs of equal material along the row, in travel order.
            let cell_x = |c: usize| {
                if forward {
                    x0 + (c as f64 + 0.5) * fill.cell_mm
                } else {
                    x0 + fill.width_mm - (c as f64 + 0.5) * fill.cell_mm
                }
            };
            let mut m = material(cell_x(0), y, layer);
            for c in 1..=cells {
                let mc = if c < cells {
                    material(cell_x(c), y, layer)
                } else {
                    255
                };
                if mc != m {
                    let to_x = if forward {
                        um(x0 + c as f64 * fill.cell_mm)
                    } else {
                        um(x0 + fill.width_mm - c as f64 * fill.cell_mm)
                    };
                    cmds.push(Command::Print {
                        dx: to_x - cur[0],
                        dy: 0,
                        material: m,
                    });
                    cur[0] = to_x;
                    m = mc;
                }
            }
            if row + 1 < fill.rows {
                // Connector up to the next row, in the material at the row's end.
                let end_x = if forward {
                    x0 + fill.width_mm - fill.cell_mm / 2.0
                } else {
                    x0 + fill.cell_mm / 2.0
                };
                let mat = material(end_x, y + fill.pitch_mm / 2.0, layer);
                let ny = um(y + fill.pitch_mm);
                cmds.push(Command::Print {
                    dx: 0,
                    dy: ny - cur[1],
                    material: mat,
                });
                cur[1] = ny;
            }
        }
    }
    cmds.push(Command::End);
    Job {
        start_um: start,
        initial_material: first,
        commands: cmds,
    }
}

/// Vertical stripes of `width_mm`, alternating materials 0 and 1.
pub fn stripes(width_mm: f64) -> impl Fn(f64, f64, usize) -> u8 {
    move |x, _, _| ((x / width_mm).floor() as i64).rem_euclid(2) as u8
}

/// Features shorter than the channel: four 9 mm rows of 0.6 mm stripes at 0.8 mm pitch
/// from (20, 20) mm, one layer, after an 8 mm priming line. On issue 22's soft machine
/// at 500 mm/s^2 the report warns on their section (the simulate CLI's and the
/// dashboard's tests of the `section floor` line).
pub fn short_stripes() -> Job {
    let fill = Fill {
        origin_mm: [20.0, 20.0],
        width_mm: 9.0,
        rows: 4,
        pitch_mm: 0.8,
        layers: 1,
        layer_mm: 0.6,
        cell_mm: 0.1,
        prime_mm: 8.0,
    };
    boustrophedon(&fill, stripes(0.6))
}

/// A chessboard of `square_mm` squares, shifted by one square per layer.
pub fn chessboard(square_mm: f64) -> impl Fn(f64, f64, usize) -> u8 {
    move |x, y, layer| {
        ((x / square_mm).floor() as i64 + (y / square_mm).floor() as i64 + layer as i64)
            .rem_euclid(2) as u8
    }
}
