//! The sliced design before placement: per layer, rows of material runs at the line pitch
//! (design millimetres, rows at `y = (r + 0.5) * pitch`). Images and meshes both turn into
//! this; turning it into commands is `toolpath`'s job.

/// One stretch of one material along a row, design mm, `x0 < x1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    /// Start, mm.
    pub x0: f64,
    /// End, mm.
    pub x1: f64,
    /// Inlet (material) index.
    pub material: u8,
}

impl Run {
    /// Length, mm.
    pub fn len(&self) -> f64 {
        self.x1 - self.x0
    }
    /// True when the run has no length.
    pub fn is_empty(&self) -> bool {
        self.x1 <= self.x0
    }
}

/// Gaps and overlaps smaller than this (mm) count as touching: below the job's 1 um grid.
pub const TOUCH_MM: f64 = 5e-4;

/// One layer: rows of sorted, disjoint runs, stored flat (rows are many and short).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Layer {
    row_start: Vec<u32>,
    runs: Vec<Run>,
}

impl Layer {
    /// An empty layer.
    pub fn new() -> Self {
        Layer {
            row_start: vec![0],
            runs: Vec::new(),
        }
    }
    /// Appends the next row. `runs` must be sorted by `x0`; they are normalised (see
    /// [`normalize_row`]) first.
    pub fn push_row(&mut self, runs: &mut Vec<Run>, min_run_mm: f64) {
        if self.row_start.is_empty() {
            self.row_start.push(0);
        }
        normalize_row(runs, min_run_mm);
        self.runs.extend_from_slice(runs);
        self.row_start.push(self.runs.len() as u32);
    }
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.row_start.len().saturating_sub(1)
    }
    /// The runs of row `r`.
    pub fn row(&self, r: usize) -> &[Run] {
        match (self.row_start.get(r), self.row_start.get(r + 1)) {
            (Some(&a), Some(&b)) => &self.runs[a as usize..b as usize],
            _ => &[],
        }
    }
    /// All runs of the layer.
    pub fn runs(&self) -> &[Run] {
        &self.runs
    }
    /// True when nothing in the layer is printed.
    pub fn is_empty(&self) -> bool {
        self.runs.is_empty()
    }
}

/// A whole design in its own frame: x from 0 to `size_mm[0]`, rows from y = 0 upward.
#[derive(Clone, Debug, PartialEq)]
pub struct Design {
    /// What it was made from, for messages ("logo.png", "a.stl + b.stl").
    pub name: String,
    /// Extent along X and Y, mm.
    pub size_mm: [f64; 2],
    /// Row spacing, mm.
    pub pitch_mm: f64,
    /// Layers bottom up; empty layers are kept so that Z stays true to the model.
    pub layers: Vec<Layer>,
}

impl Design {
    /// Bit i set when material i is printed somewhere.
    pub fn materials_used(&self) -> u32 {
        let mut m = 0u32;
        for l in &self.layers {
            for r in l.runs() {
                m |= 1 << (r.material as u32).min(31);
            }
        }
        m
    }
    /// True when no layer prints anything.
    pub fn is_empty(&self) -> bool {
        self.layers.iter().all(Layer::is_empty)
    }
}

/// Cleans one row in place: drops empty runs, merges touching runs of one material, and
/// folds runs shorter than `min_run_mm` into a touching neighbour (the longer one), or
/// drops them when they touch nothing. Such slivers come from anti-aliased edges or from
/// grazing a mesh; a bead cannot place them, and a valve switch for each would be waste.
pub fn normalize_row(runs: &mut Vec<Run>, min_run_mm: f64) {
    runs.retain(|r| r.x1 - r.x0 > TOUCH_MM);
    merge_touching(runs);
    if min_run_mm <= 0.0 || runs.is_empty() {
        return;
    }
    // Each pass removes at least one short run, so this ends; rows are short.
    while let Some(i) = runs.iter().position(|r| r.len() < min_run_mm) {
        let prev = (i > 0 && runs[i].x0 - runs[i - 1].x1 <= TOUCH_MM).then(|| runs[i - 1]);
        let next =
            (i + 1 < runs.len() && runs[i + 1].x0 - runs[i].x1 <= TOUCH_MM).then(|| runs[i + 1]);
        match (prev, next) {
            (None, None) => {
                runs.remove(i);
            }
            (Some(p), n) if n.is_none_or(|n| p.len() >= n.len()) => {
                runs[i - 1].x1 = runs[i].x1;
                runs.remove(i);
            }
            _ => {
                runs[i + 1].x0 = runs[i].x0;
                runs.remove(i);
            }
        }
        merge_touching(runs);
    }
}

fn merge_touching(runs: &mut Vec<Run>) {
    let mut out: usize = 0;
    for i in 0..runs.len() {
        let r = runs[i];
        if out > 0 {
            let last = &mut runs[out - 1];
            if last.material == r.material && r.x0 - last.x1 <= TOUCH_MM {
                last.x1 = last.x1.max(r.x1);
                continue;
            }
        }
        runs[out] = r;
        out += 1;
    }
    runs.truncate(out);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(x0: f64, x1: f64, material: u8) -> Run {
        Run { x0, x1, material }
    }

    #[test]
    fn touching_same_material_runs_merge_and_slivers_fold_into_neighbours() {
        let mut row = vec![
            run(0.0, 1.0, 0),
            run(1.0, 2.0, 0),
            run(2.0, 2.02, 1),
            run(2.02, 5.0, 0),
            run(6.0, 6.01, 1),
        ];
        normalize_row(&mut row, 0.1);
        assert_eq!(row, vec![run(0.0, 5.0, 0)]);
    }

    #[test]
    fn layer_rows_come_back_in_order() {
        let mut l = Layer::new();
        l.push_row(&mut vec![run(0.0, 1.0, 1)], 0.0);
        l.push_row(&mut vec![], 0.0);
        l.push_row(&mut vec![run(0.0, 1.0, 0), run(1.0, 3.0, 1)], 0.0);
        assert_eq!(l.rows(), 3);
        assert_eq!(l.row(1), &[]);
        assert_eq!(l.row(2).len(), 2);
        assert_eq!(l.row(7), &[]);
    }
}
