//! Telling the materials apart by colour: k-means (k = the job's materials, seeded
//! k-means++) over the print's evened colours, with the plate as one more fixed colour;
//! each cluster is then named by the material it overlaps most in the design (the best of
//! every assignment, at most 4! of them). Checks that the photo holds as many distinct
//! colours as the job has materials.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// Label of a pixel that shows the plate.
pub const PLATE: u8 = 255;

/// Colours learned from the photo.
#[derive(Clone, Debug)]
pub struct Palette {
    /// Cluster centres in evened RGB (the plate is (1, 1, 1)).
    pub centres: Vec<[f32; 3]>,
    /// Sum of squared distances of the samples to their centres, per sample.
    pub spread: f64,
}

fn d2(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// k-means of `samples` into `k` colours (the plate held fixed as one more), seeded.
pub fn kmeans(samples: &[[f32; 3]], k: usize, seed: u64) -> Palette {
    let plate = [1.0f32; 3];
    let mut rng = StdRng::seed_from_u64(seed);
    let mut centres: Vec<[f32; 3]> = Vec::with_capacity(k);
    // k-means++: each next centre drawn with probability by distance to the nearest so far
    // (the plate counts as chosen, so no cluster starts on it).
    while centres.len() < k && !samples.is_empty() {
        let w: Vec<f64> = samples
            .iter()
            .map(|&s| {
                centres
                    .iter()
                    .chain(std::iter::once(&plate))
                    .map(|&c| d2(s, c))
                    .fold(f32::INFINITY, f32::min) as f64
            })
            .collect();
        let total: f64 = w.iter().sum();
        let pick = if total > 0.0 {
            let mut r = rng.random::<f64>() * total;
            w.iter()
                .position(|&x| {
                    r -= x;
                    r <= 0.0
                })
                .unwrap_or(samples.len() - 1)
        } else {
            rng.random_range(0..samples.len())
        };
        centres.push(samples[pick]);
    }
    let mut spread = 0.0;
    for _ in 0..40 {
        let mut sum = vec![[0.0f64; 3]; k];
        let mut n = vec![0usize; k];
        spread = 0.0;
        for &s in samples {
            let (j, d) = nearest(&centres, s);
            spread += d as f64;
            if let Some(j) = j {
                n[j] += 1;
                for c in 0..3 {
                    sum[j][c] += s[c] as f64;
                }
            }
        }
        let mut moved = 0.0f32;
        for j in 0..k {
            if n[j] > 0 {
                let c: [f32; 3] = std::array::from_fn(|i| (sum[j][i] / n[j] as f64) as f32);
                moved = moved.max(d2(c, centres[j]));
                centres[j] = c;
            }
        }
        if moved < 1e-8 {
            break;
        }
    }
    Palette {
        centres,
        spread: spread / samples.len().max(1) as f64,
    }
}

/// The best of `restarts` k-means runs (seeds `seed`, `seed + 1`, ...): the one whose
/// samples lie closest to their centres. One run can settle with two colours in one
/// cluster and one split in two, which then looks like a photo of more colours than the
/// job has.
pub fn kmeans_best(samples: &[[f32; 3]], k: usize, seed: u64, restarts: u64) -> Palette {
    (0..restarts.max(1))
        .map(|r| kmeans(samples, k, seed + r))
        .min_by(|a, b| a.spread.total_cmp(&b.spread))
        .unwrap_or_else(|| kmeans(samples, k, seed))
}

/// Index of the centre nearest to `s` (`None`: the plate) and the squared distance.
pub fn nearest(centres: &[[f32; 3]], s: [f32; 3]) -> (Option<usize>, f32) {
    let mut best = (None, d2(s, [1.0; 3]));
    for (j, &c) in centres.iter().enumerate() {
        let d = d2(s, c);
        if d < best.1 {
            best = (Some(j), d);
        }
    }
    best
}

/// The colour a pixel shows: blur and the bead's soft edge mix two colours (a paste and
/// the plate, or two pastes), and a mix of dark paste and a light plate can lie nearer a
/// third, mid-toned paste than either of its own. So the pixel is placed on the nearest
/// line between two known colours (the plate among them) and given the end it is nearer
/// to. `None`: the plate.
pub fn label(centres: &[[f32; 3]], s: [f32; 3]) -> Option<usize> {
    let plate = [1.0f32; 3];
    let colour = |j: usize| if j < centres.len() { centres[j] } else { plate };
    let n = centres.len() + 1;
    let mut best = (f32::INFINITY, None);
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (colour(i), colour(j));
            let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
            let t = if len2 > 0.0 {
                (((s[0] - a[0]) * ab[0] + (s[1] - a[1]) * ab[1] + (s[2] - a[2]) * ab[2]) / len2)
                    .clamp(0.0, 1.0)
            } else {
                0.0
            };
            let q = [a[0] + ab[0] * t, a[1] + ab[1] * t, a[2] + ab[2] * t];
            let d = d2(s, q);
            if d < best.0 {
                let end = if t < 0.5 { i } else { j };
                best = (d, (end < centres.len()).then_some(end));
            }
        }
    }
    best.1
}

/// The assignment of clusters to `materials` that agrees best with `design` (per pixel:
/// material or `PLATE`), given each pixel's cluster (`PLATE` for the plate). Returns the
/// material of each cluster and the fraction of the design's printed pixels that agree.
pub fn name_clusters(clusters: &[u8], design: &[u8], materials: &[u8]) -> (Vec<u8>, f64) {
    let k = materials.len();
    // Overlap counts: cluster j against design material index i.
    let mut overlap = vec![vec![0u64; k]; k];
    let mut printed = 0u64;
    for (&c, &d) in clusters.iter().zip(design) {
        if d == PLATE {
            continue;
        }
        printed += 1;
        if let (Some(i), true) = (materials.iter().position(|&m| m == d), (c as usize) < k) {
            overlap[c as usize][i] += 1;
        }
    }
    let mut best = (Vec::new(), 0u64);
    permute(&mut (0..k).collect::<Vec<_>>(), 0, &mut |perm| {
        let agree: u64 = (0..k).map(|j| overlap[j][perm[j]]).sum();
        if best.0.is_empty() || agree > best.1 {
            best = (perm.to_vec(), agree);
        }
    });
    let names = best.0.iter().map(|&i| materials[i]).collect();
    (names, best.1 as f64 / printed.max(1) as f64)
}

fn permute(v: &mut Vec<usize>, i: usize, f: &mut impl FnMut(&[usize])) {
    if i == v.len() {
        f(v);
        return;
    }
    for j in i..v.len() {
        v.swap(i, j);
        permute(v, i + 1, f);
        v.swap(i, j);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_colours_are_found_and_named_by_the_design() {
        let mut s = Vec::new();
        for i in 0..400 {
            let e = (i % 7) as f32 * 0.004;
            s.push([0.4 + e, 0.25, 0.1]);
            s.push([0.9, 0.8 - e, 0.3]);
        }
        let p = kmeans(&s, 2, 1);
        let mut c = p.centres.clone();
        c.sort_by(|a, b| a[0].total_cmp(&b[0]));
        assert!(
            (c[0][0] - 0.412).abs() < 0.01 && (c[1][1] - 0.788).abs() < 0.01,
            "{c:?}"
        );
        // Cluster 0 lies where the design has material 3.
        let clusters = [0u8, 0, 1, 1, PLATE];
        let design = [3u8, 3, 1, 1, PLATE];
        let (names, agree) = name_clusters(&clusters, &design, &[1, 3]);
        assert_eq!(names, vec![3, 1]);
        assert!((agree - 1.0).abs() < 1e-12);
    }
}
