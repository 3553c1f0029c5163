//! Meshes to designs: each layer is sampled at its mid-height and each row at its centre
//! line by casting a ray along X through every body (one body per material). Triangles are
//! bucketed by the layers they span, so a ray only meets the triangles that cut its layer,
//! and within a layer each triangle's section is crossed only with the rows it spans.
//! Inside is decided by the nonzero winding rule (as mature slicers do): each crossing
//! counts +1 where the ray enters through a face and -1 where it leaves, by the face's
//! orientation, so a body that intersects itself or holds several overlapping shells is
//! filled where any shell covers it, never holed where two overlap (parity would hole
//! it); an inward-facing shell inside another is a cavity. Half-open rules computed
//! identically for shared edges keep closed bodies consistent and bodies that share a
//! surface touching without overlapping. Overlaps between bodies are refused.

use super::design::{Design, Layer, Run, TOUCH_MM};
use super::error::{SliceError, SliceLimit, SliceOption};
use super::mesh::Mesh;
use super::output::progress;

/// How to slice meshes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshOptions {
    /// Row spacing, mm.
    pub pitch_mm: f64,
    /// Layer height, mm.
    pub layer_mm: f64,
    /// Print at most this many layers (from the bottom).
    pub max_layers: Option<usize>,
    /// Runs shorter than this are folded into neighbours, mm.
    pub min_run_mm: f64,
    /// Show a progress bar (on a terminal only).
    pub progress: bool,
    /// Most runs (about print segments) in the whole design; refused past it.
    pub max_segments: u64,
}

/// A triangle's vertices in f64 (exact from f32), for one layer's work.
type Tri = [[f64; 3]; 3];

struct Body<'a> {
    mesh: &'a Mesh,
    /// For layer k, the triangles that may cut it: `tris[start[k]..start[k + 1]]`.
    start: Vec<u32>,
    tris: Vec<u32>,
}

/// Slices `meshes` (mesh i is material i) into a design. Checks each body is closed.
pub fn slice_meshes(meshes: &[Mesh], opts: &MeshOptions) -> Result<Design, SliceError> {
    let name = meshes
        .iter()
        .map(|m| m.path.display().to_string())
        .collect::<Vec<_>>()
        .join(" + ");
    for m in meshes {
        if m.triangles.is_empty() {
            return Err(SliceError::NoTriangles {
                path: m.path.clone(),
            });
        }
        m.check_closed()?;
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for m in meshes {
        let (l, h) = m.bounds();
        for a in 0..3 {
            lo[a] = lo[a].min(l[a]);
            hi[a] = hi[a].max(h[a]);
        }
    }
    let (pitch, h) = (opts.pitch_mm, opts.layer_mm);
    if !(pitch > 0.0 && h > 0.0) {
        return Err(SliceError::NoSpacing);
    }
    let mut layers_n = (((hi[2] - lo[2]) / h).round() as usize).max(1);
    if let Some(n) = opts.max_layers {
        layers_n = layers_n.min(n.max(1));
    }
    let rows = (((hi[1] - lo[1]) / pitch).round() as usize).max(1);
    if rows.saturating_mul(layers_n) > 50_000_000 {
        return Err(SliceError::TooManyRows {
            what: name.to_string(),
            rows,
            layers: layers_n,
        });
    }
    let z_of = |k: usize| lo[2] + (k as f64 + 0.5) * h;
    let y_of = |r: usize| lo[1] + (r as f64 + 0.5) * pitch;
    let bodies: Vec<Body> = meshes
        .iter()
        .map(|m| bucket(m, lo[2], h, layers_n))
        .collect();

    let bar = if opts.progress {
        progress(layers_n as u64, "voxelizing")
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut crossings: Vec<Vec<(u32, f64, i8)>> = vec![Vec::new(); meshes.len()];
    let mut intervals: Vec<(f64, f64, u8)> = Vec::new();
    let mut row_runs: Vec<Run> = Vec::new();
    let mut out_layers = Vec::with_capacity(layers_n);
    let mut total_runs = 0u64;
    for k in 0..layers_n {
        let z = z_of(k);
        for (body, cx) in bodies.iter().zip(crossings.iter_mut()) {
            layer_crossings(body, k, z, (lo[1], pitch, rows), cx);
        }
        let mut layer = Layer::new();
        let mut next = vec![0usize; meshes.len()];
        for r in 0..rows {
            let at = [y_of(r), z];
            row_intervals(meshes, &crossings, &mut next, r, at, &mut intervals)?;
            row_runs_of(meshes, &mut intervals, lo[0], at, &mut row_runs)?;
            layer.push_row(&mut row_runs, opts.min_run_mm);
        }
        total_runs += layer.runs().len() as u64;
        if total_runs > opts.max_segments {
            return Err(super::over_limit(
                &name,
                &format!("runs in the first {} of {layers_n} layers:", k + 1),
                total_runs,
                opts.max_segments,
                SliceLimit::Segments,
                Some(SliceOption::Layers),
            ));
        }
        out_layers.push(layer);
        bar.inc(1);
    }
    bar.finish_and_clear();
    // Empty layers at the top carry nothing; inner empty ones keep Z true.
    while out_layers.last().is_some_and(Layer::is_empty) {
        out_layers.pop();
    }
    let design = Design {
        name: name.clone(),
        size_mm: [hi[0] - lo[0], rows as f64 * pitch],
        pitch_mm: pitch,
        layers: out_layers,
    };
    if design.is_empty() {
        return Err(SliceError::EmptyDesign {
            what: name,
            why: "no row of any layer passes through a body (is it thinner than a line pitch?)"
                .into(),
        });
    }
    Ok(design)
}

/// A body's crossings of layer `k` (mid-plane `z`) with the rows (`(y0, pitch, rows)`),
/// by row, then x, entries before exits at the same x (so touching shells join).
fn layer_crossings(
    body: &Body,
    k: usize,
    z: f64,
    (y0, pitch, rows): (f64, f64, usize),
    cx: &mut Vec<(u32, f64, i8)>,
) {
    cx.clear();
    let ts = &body.tris[body.start[k] as usize..body.start[k + 1] as usize];
    for &t in ts {
        let tri = tri_f64(body.mesh, t);
        let sign = winding_sign(&tri);
        if sign == 0 {
            continue;
        }
        if let Some((p, q)) = section(&tri, z) {
            cross_rows(p, q, y0, pitch, rows, sign, cx);
        }
    }
    cx.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)).then(b.2.cmp(&a.2)));
}

/// Row `r`'s inside intervals `(x0, x1, body)` of every body into `intervals`, from each
/// body's crossings starting at `next[body]` (moved past row `r`'s); `at` = the row's
/// (y, z) for the error. A body whose winding does not return to zero is not closed.
fn row_intervals(
    meshes: &[Mesh],
    crossings: &[Vec<(u32, f64, i8)>],
    next: &mut [usize],
    r: usize,
    [y, z]: [f64; 2],
    intervals: &mut Vec<(f64, f64, u8)>,
) -> Result<(), SliceError> {
    intervals.clear();
    for (b, cx) in crossings.iter().enumerate() {
        let i0 = next[b];
        let mut i1 = i0;
        while i1 < cx.len() && cx[i1].0 == r as u32 {
            i1 += 1;
        }
        next[b] = i1;
        let xs = &cx[i0..i1];
        // Inside wherever the winding number is not zero.
        let mut w = 0i32;
        let mut start = 0.0;
        for &(_, x, sign) in xs {
            let before = w;
            w += sign as i32;
            if before == 0 && w != 0 {
                start = x;
            } else if before != 0 && w == 0 && x - start > TOUCH_MM {
                intervals.push((start, x, b as u8));
            }
        }
        if w != 0 {
            // A closed, consistently oriented body always winds back to zero.
            return Err(SliceError::NonManifold {
                path: meshes[b].path.clone(),
                edges: 1,
                at: [xs[0].1, y, z],
            });
        }
    }
    Ok(())
}

/// A row's runs from its intervals (sorted here), x from `x0`; two bodies' intervals that
/// overlap by more than a touch are refused (`at` = the row's (y, z)).
fn row_runs_of(
    meshes: &[Mesh],
    intervals: &mut [(f64, f64, u8)],
    x0: f64,
    [y, z]: [f64; 2],
    row_runs: &mut Vec<Run>,
) -> Result<(), SliceError> {
    intervals.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    row_runs.clear();
    let mut reach: Option<(f64, u8)> = None;
    for &(a, b, m) in intervals.iter() {
        if let Some((end, om)) = reach {
            if a < end - TOUCH_MM && om != m {
                return Err(SliceError::Overlap {
                    a: meshes[om as usize].path.clone(),
                    b: meshes[m as usize].path.clone(),
                    at: [(a + end.min(b)) / 2.0, y, z],
                });
            }
        }
        if reach.is_none_or(|(end, _)| b > end) {
            reach = Some((b, m));
        }
        row_runs.push(Run {
            x0: a - x0,
            x1: b - x0,
            material: m,
        });
    }
    Ok(())
}

/// Buckets a body's triangles by the layers whose mid-plane they may cut.
fn bucket<'a>(mesh: &'a Mesh, z0: f64, h: f64, layers: usize) -> Body<'a> {
    let range = |t: &[u32; 3]| {
        let zs = t.map(|i| mesh.vertices[i as usize][2] as f64);
        let zmin = zs[0].min(zs[1]).min(zs[2]);
        let zmax = zs[0].max(zs[1]).max(zs[2]);
        // Layer k's plane z_k = z0 + (k + 0.5) h is cut when zmin < z_k <= zmax; widen
        // by one layer each side, `section` decides exactly.
        let k0 = ((zmin - z0) / h - 0.5).floor().max(0.0) as usize;
        let k1 = (((zmax - z0) / h - 0.5).floor() + 1.0).max(0.0) as usize;
        (k0, k1.min(layers.saturating_sub(1)))
    };
    let mut count = vec![0u32; layers + 1];
    for t in &mesh.triangles {
        let (k0, k1) = range(t);
        for c in count.iter_mut().take(k1 + 1).skip(k0) {
            *c += 1;
        }
    }
    let mut start = vec![0u32; layers + 1];
    for k in 0..layers {
        start[k + 1] = start[k] + count[k];
    }
    let mut fill = start.clone();
    let mut tris = vec![0u32; start[layers] as usize];
    for (i, t) in mesh.triangles.iter().enumerate() {
        let (k0, k1) = range(t);
        for f in fill.iter_mut().take(k1 + 1).skip(k0) {
            tris[*f as usize] = i as u32;
            *f += 1;
        }
    }
    Body { mesh, start, tris }
}

#[inline]
fn tri_f64(m: &Mesh, t: u32) -> Tri {
    let tri = m.triangles[t as usize];
    tri.map(|i| {
        let v = m.vertices[i as usize];
        [v[0] as f64, v[1] as f64, v[2] as f64]
    })
}

/// Orders two points the same way whichever triangle they come from.
#[inline]
fn canonical(a: [f64; 3], b: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let key = |p: &[f64; 3]| (p[2], p[1], p[0]);
    if key(&a).partial_cmp(&key(&b)) == Some(std::cmp::Ordering::Greater) {
        (b, a)
    } else {
        (a, b)
    }
}

/// The section of a triangle by the plane z: the points where its edges cross it, with
/// vertices on the plane counted as above (half-open), so each shared edge is crossed by
/// both its triangles or neither, at bitwise the same point.
#[inline]
fn section(t: &Tri, z: f64) -> Option<([f64; 2], [f64; 2])> {
    let mut pts = [[0.0f64; 2]; 2];
    let mut n = 0;
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        if (a[2] < z) != (b[2] < z) {
            let (p, q) = canonical(a, b);
            let f = (z - p[2]) / (q[2] - p[2]);
            if n < 2 {
                pts[n] = [p[0] + (q[0] - p[0]) * f, p[1] + (q[1] - p[1]) * f];
            }
            n += 1;
        }
    }
    (n == 2).then_some((pts[0], pts[1]))
}

/// +1 when a ray along +X enters the body through this triangle (its outward normal
/// points toward -X), -1 when it leaves, 0 for a face parallel to X (never crossed).
#[inline]
fn winding_sign(t: &Tri) -> i8 {
    let u = [t[1][1] - t[0][1], t[1][2] - t[0][2]];
    let v = [t[2][1] - t[0][1], t[2][2] - t[0][2]];
    let nx = u[0] * v[1] - u[1] * v[0];
    if nx < 0.0 {
        1
    } else if nx > 0.0 {
        -1
    } else {
        0
    }
}

/// Adds the X where segment pq crosses each row's centre line (half-open in y as above),
/// with the crossing's winding `sign`.
#[inline]
fn cross_rows(
    p: [f64; 2],
    q: [f64; 2],
    y0: f64,
    pitch: f64,
    rows: usize,
    sign: i8,
    out: &mut Vec<(u32, f64, i8)>,
) {
    let (p, q) = if (p[1], p[0]) <= (q[1], q[0]) {
        (p, q)
    } else {
        (q, p)
    };
    if p[1] == q[1] {
        return;
    }
    // Rows with p.y < y_r <= q.y, y_r = y0 + (r + 0.5) pitch.
    let r0 = ((p[1] - y0) / pitch - 0.5).floor().max(0.0) as usize;
    let r1 = (((q[1] - y0) / pitch - 0.5).floor() + 1.0).max(0.0) as usize;
    for r in r0..=r1.min(rows.saturating_sub(1)) {
        let y = y0 + (r as f64 + 0.5) * pitch;
        if p[1] < y && y <= q[1] {
            let x = p[0] + (q[0] - p[0]) * (y - p[1]) / (q[1] - p[1]);
            out.push((r as u32, x, sign));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::mesh::shapes;
    use super::*;
    use std::path::Path;

    fn opts() -> MeshOptions {
        MeshOptions {
            pitch_mm: 0.8,
            layer_mm: 0.6,
            max_layers: None,
            min_run_mm: 0.0,
            progress: false,
            max_segments: u64::MAX,
        }
    }

    #[test]
    fn a_box_slices_into_full_rows_of_its_width() {
        let m = shapes::cuboid(Path::new("b.stl"), [1.0, 2.0, 0.0], [11.0, 10.0, 6.0]);
        let d = slice_meshes(&[m], &opts()).unwrap();
        assert_eq!(d.layers.len(), 10);
        assert_eq!(d.layers[0].rows(), 10);
        for l in &d.layers {
            for r in 0..l.rows() {
                let row = l.row(r);
                assert_eq!(row.len(), 1);
                assert!(
                    (row[0].x0).abs() < 1e-9 && (row[0].x1 - 10.0).abs() < 1e-9,
                    "{row:?}"
                );
            }
        }
    }

    #[test]
    fn a_sphere_in_its_cavity_touches_without_overlap_and_its_area_is_right() {
        let p = [Path::new("shell.stl"), Path::new("ball.stl")];
        let meshes = shapes::box_with_sphere(p, [0.0; 3], [20.0; 3], 6.0, 40_000);
        let o = MeshOptions {
            pitch_mm: 0.2,
            layer_mm: 0.2,
            ..opts()
        };
        let d = slice_meshes(&meshes, &o).unwrap();
        // The middle layer: the ball's section is a disc of radius ~6 mm.
        let l = &d.layers[d.layers.len() / 2];
        let ball: f64 = l
            .runs()
            .iter()
            .filter(|r| r.material == 1)
            .map(|r| r.len())
            .sum();
        let area = ball * 0.2;
        let disc = std::f64::consts::PI * 36.0;
        assert!((area / disc - 1.0).abs() < 0.02, "{area} vs {disc}");
        // Every row through the ball is shell | ball | shell with no gap.
        for r in 0..l.rows() {
            let row = l.row(r);
            let total: f64 = row.iter().map(|x| x.len()).sum();
            assert!((total - 20.0).abs() < 1e-6, "row {r}: {row:?}");
        }
    }

    #[test]
    fn overlapping_bodies_are_refused_naming_both_files() {
        let a = shapes::cuboid(Path::new("a.stl"), [0.0; 3], [10.0; 3]);
        let b = shapes::cuboid(Path::new("b.stl"), [5.0, 0.0, 0.0], [15.0, 10.0, 10.0]);
        let e = slice_meshes(&[a, b], &opts()).unwrap_err().to_string();
        assert!(e.starts_with("a.stl and b.stl overlap"), "{e}");
    }

    #[test]
    fn touching_boxes_are_accepted() {
        let a = shapes::cuboid(Path::new("a.stl"), [0.0; 3], [5.0, 10.0, 10.0]);
        let b = shapes::cuboid(Path::new("b.stl"), [5.0, 0.0, 0.0], [15.0, 10.0, 10.0]);
        let d = slice_meshes(&[a, b], &opts()).unwrap();
        assert_eq!(d.layers[0].row(0).len(), 2);
    }

    #[test]
    fn self_intersecting_shells_are_filled_by_the_nonzero_rule_not_holed() {
        // One body of two overlapping boxes (each closed and outward): parity would
        // leave the 4 mm overlap hollow; the winding rule fills the union, 0 to 14 mm.
        let mut m = shapes::cuboid(Path::new("two.stl"), [0.0; 3], [10.0, 10.0, 6.0]);
        shapes::add_cuboid(&mut m, [6.0, 0.0, 0.0], [14.0, 10.0, 6.0]);
        let d = slice_meshes(&[m], &opts()).unwrap();
        for l in &d.layers {
            for r in 0..l.rows() {
                let row = l.row(r);
                assert_eq!(row.len(), 1, "row {r} is holed: {row:?}");
                assert!(
                    row[0].x0.abs() < 1e-9 && (row[0].x1 - 14.0).abs() < 1e-9,
                    "{row:?}"
                );
            }
        }
    }

    #[test]
    fn an_inward_shell_inside_a_body_is_a_cavity() {
        let p = [Path::new("shell.stl"), Path::new("ball.stl")];
        let [shell, _] = shapes::box_with_sphere(p, [0.0; 3], [20.0; 3], 6.0, 4_000);
        let d = slice_meshes(&[shell], &opts()).unwrap();
        let l = &d.layers[d.layers.len() / 2];
        let mid = l.row(l.rows() / 2);
        assert_eq!(mid.len(), 2, "the cavity is missing: {mid:?}");
    }
}
