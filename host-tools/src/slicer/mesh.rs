//! Triangle meshes for 3D designs: reading STL (ASCII or binary) with vertices welded,
//! refusing empty files and NaN/infinite vertices, and checking that a body is closed
//! (every edge shared by exactly two triangles). Slicing meshes is `voxel`'s job.

use super::error::{SliceError, SliceLimit};
use super::image::one_line;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// An indexed triangle mesh, one body of one material.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Where it came from, for messages.
    pub path: PathBuf,
    /// Welded vertices, mm.
    pub vertices: Vec<[f32; 3]>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Lowest and highest corner, mm.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices {
            for a in 0..3 {
                lo[a] = lo[a].min(v[a] as f64);
                hi[a] = hi[a].max(v[a] as f64);
            }
        }
        (lo, hi)
    }

    /// Builds a mesh from triangle soup, welding equal vertices (by value; -0 equals 0).
    pub fn from_triangles(path: &Path, tris: &[[[f32; 3]; 3]]) -> Result<Mesh, SliceError> {
        let mut mesh = Mesh {
            path: path.to_path_buf(),
            ..Default::default()
        };
        let mut index: HashMap<[u32; 3], u32> = HashMap::new();
        for (ti, t) in tris.iter().enumerate() {
            let mut tri = [0u32; 3];
            for (k, v) in t.iter().enumerate() {
                if !v.iter().all(|c| c.is_finite()) {
                    return Err(SliceError::NonFinite {
                        path: path.to_path_buf(),
                        triangle: ti,
                    });
                }
                // Adding 0.0 turns -0.0 into +0.0 so both weld to one vertex.
                let key = [
                    (v[0] + 0.0).to_bits(),
                    (v[1] + 0.0).to_bits(),
                    (v[2] + 0.0).to_bits(),
                ];
                let next = mesh.vertices.len() as u32;
                let i = *index.entry(key).or_insert(next);
                if i == next {
                    mesh.vertices.push([v[0] + 0.0, v[1] + 0.0, v[2] + 0.0]);
                }
                tri[k] = i;
            }
            mesh.triangles.push(tri);
        }
        if mesh.triangles.is_empty() {
            return Err(SliceError::NoTriangles {
                path: path.to_path_buf(),
            });
        }
        Ok(mesh)
    }

    /// Checks the body is closed: every edge belongs to exactly two triangles. (Without
    /// that, "inside" has no meaning and the ray parity would fill or hollow at random.)
    /// Then that it is consistently oriented: the two triangles of an edge run along it in
    /// opposite directions. A triangle flipped against its neighbours would make the
    /// winding rule fill or hollow part of the body, so it is refused by name rather than
    /// found later as a layer that does not close. A body flipped as a whole is consistent
    /// and prints as it would facing outward. Degenerate triangles (two equal corners) are
    /// skipped: they enclose nothing.
    pub fn check_closed(&self) -> Result<(), SliceError> {
        // Undirected edge in the high bits, direction (1: the lower vertex comes second)
        // in the lowest bit, so the two uses of an edge sort side by side.
        let mut edges: Vec<u64> = Vec::with_capacity(self.triangles.len() * 3);
        for t in &self.triangles {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let (lo, hi, dir) = if a < b { (a, b, 0) } else { (b, a, 1) };
                edges.push((((lo as u64) << 32 | hi as u64) << 1) | dir);
            }
        }
        edges.sort_unstable();
        let (mut open, mut flipped) = (0usize, 0usize);
        let (mut first_open, mut first_flipped): (Option<u64>, Option<u64>) = (None, None);
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j] >> 1 == edges[i] >> 1 {
                j += 1;
            }
            if j - i != 2 {
                open += 1;
                first_open.get_or_insert(edges[i] >> 1);
            } else if edges[i] & 1 == edges[i + 1] & 1 {
                flipped += 1;
                first_flipped.get_or_insert(edges[i] >> 1);
            }
            i = j;
        }
        let at = |e: u64| {
            let v = self.vertices[(e >> 32) as usize];
            [v[0] as f64, v[1] as f64, v[2] as f64]
        };
        if let Some(e) = first_open {
            return Err(SliceError::NonManifold {
                path: self.path.clone(),
                edges: open,
                at: at(e),
            });
        }
        if let Some(e) = first_flipped {
            return Err(SliceError::Misoriented {
                path: self.path.clone(),
                edges: flipped,
                at: at(e),
            });
        }
        Ok(())
    }
}

/// Reads an ASCII or binary STL file (default triangle limit).
pub fn read_stl(path: &Path) -> Result<Mesh, SliceError> {
    let max = super::Limits::default().max_triangles;
    read_stl_limited(path, max, max)
}

/// Reads an STL, streaming it from the file, and refuses it once it holds more than
/// `left` triangles (`limit` is the `--max-triangles` value, for the message).
pub fn read_stl_limited(path: &Path, left: u64, limit: u64) -> Result<Mesh, SliceError> {
    let file = std::fs::File::open(path).map_err(|e| SliceError::read(path, e))?;
    let mut reader = std::io::BufReader::new(file);
    let bad = |e: std::io::Error| SliceError::Stl {
        path: path.to_path_buf(),
        reason: one_line(&e.to_string()),
    };
    let stl = stl_io::create_stl_reader(&mut reader).map_err(bad)?;
    let mut tris = Vec::new();
    for t in stl {
        let t = t.map_err(bad)?;
        if tris.len() as u64 >= left {
            return Err(SliceError::OverLimit {
                what: format!(
                    "{}: more than {limit} triangles (all bodies together) exceeds the limit",
                    path.display()
                ),
                limit: SliceLimit::Triangles,
                or: None,
            });
        }
        tris.push([t.vertices[0].0, t.vertices[1].0, t.vertices[2].0]);
    }
    Mesh::from_triangles(path, &tris)
}

/// Writes a binary STL (for bundled and generated designs).
pub fn write_stl(path: &Path, mesh: &Mesh) -> Result<(), SliceError> {
    let tris: Vec<stl_io::Triangle> = mesh
        .triangles
        .iter()
        .map(|t| {
            let p = |i: u32| mesh.vertices[i as usize];
            let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let n = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
                .sqrt()
                .max(f32::MIN_POSITIVE);
            stl_io::Triangle {
                normal: stl_io::Normal::new([n[0] / l, n[1] / l, n[2] / l]),
                vertices: [
                    stl_io::Vertex::new(a),
                    stl_io::Vertex::new(b),
                    stl_io::Vertex::new(c),
                ],
            }
        })
        .collect();
    super::output::write_atomic(path, |w| stl_io::write_stl(&mut { w }, tris.iter()))
}

/// Procedural bodies for tests, bundled designs and benchmarks.
pub mod shapes {
    use super::Mesh;
    use std::f64::consts::PI;
    use std::path::Path;

    /// Axis-aligned box from `lo` to `hi`, outward facing.
    pub fn cuboid(path: &Path, lo: [f32; 3], hi: [f32; 3]) -> Mesh {
        let mut m = Mesh {
            path: path.to_path_buf(),
            ..Default::default()
        };
        add_cuboid(&mut m, lo, hi);
        m
    }

    /// Appends a box shell to `m`.
    pub fn add_cuboid(m: &mut Mesh, lo: [f32; 3], hi: [f32; 3]) {
        let base = m.vertices.len() as u32;
        for i in 0..8u32 {
            m.vertices.push([
                if i & 1 != 0 { hi[0] } else { lo[0] },
                if i & 2 != 0 { hi[1] } else { lo[1] },
                if i & 4 != 0 { hi[2] } else { lo[2] },
            ]);
        }
        // Faces as quads (outward, counter-clockwise), split into two triangles.
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        for q in quads {
            m.triangles.push([base + q[0], base + q[1], base + q[2]]);
            m.triangles.push([base + q[0], base + q[2], base + q[3]]);
        }
    }

    /// Appends a UV sphere of `rings` x `sectors` (about 2 rings sectors triangles); with
    /// `inward` the faces point inside (a cavity in an enclosing body).
    pub fn add_sphere(m: &mut Mesh, c: [f64; 3], r: f64, rings: u32, sectors: u32, inward: bool) {
        let rings = rings.max(2);
        let sectors = sectors.max(3);
        let base = m.vertices.len() as u32;
        m.vertices
            .push([c[0] as f32, c[1] as f32, (c[2] - r) as f32]);
        for i in 1..rings {
            let th = PI * i as f64 / rings as f64;
            let z = c[2] - r * th.cos();
            let rr = r * th.sin();
            for j in 0..sectors {
                let ph = 2.0 * PI * j as f64 / sectors as f64;
                m.vertices.push([
                    (c[0] + rr * ph.cos()) as f32,
                    (c[1] + rr * ph.sin()) as f32,
                    z as f32,
                ]);
            }
        }
        let top = m.vertices.len() as u32;
        m.vertices
            .push([c[0] as f32, c[1] as f32, (c[2] + r) as f32]);
        let ring = |i: u32, j: u32| base + 1 + (i - 1) * sectors + (j % sectors);
        let mut push = |t: [u32; 3]| {
            if inward {
                m.triangles.push([t[0], t[2], t[1]]);
            } else {
                m.triangles.push(t);
            }
        };
        for j in 0..sectors {
            push([base, ring(1, j + 1), ring(1, j)]);
            push([top, ring(rings - 1, j), ring(rings - 1, j + 1)]);
        }
        for i in 1..rings - 1 {
            for j in 0..sectors {
                push([ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)]);
                push([ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)]);
            }
        }
    }

    /// Two bodies that fill a box together: the box with a spherical cavity, and the
    /// sphere that fills it, sharing its surface exactly. About `triangles` in all.
    pub fn box_with_sphere(
        paths: [&Path; 2],
        lo: [f32; 3],
        hi: [f32; 3],
        r: f64,
        triangles: usize,
    ) -> [Mesh; 2] {
        let c = [
            (lo[0] as f64 + hi[0] as f64) / 2.0,
            (lo[1] as f64 + hi[1] as f64) / 2.0,
            (lo[2] as f64 + hi[2] as f64) / 2.0,
        ];
        // 2 rings sectors triangles per sphere, two spheres: rings = sectors / 2.
        let sectors = ((triangles as f64 / 2.0).sqrt().round() as u32).max(6);
        let rings = (sectors / 2).max(3);
        let mut shell = cuboid(paths[0], lo, hi);
        add_sphere(&mut shell, c, r, rings, sectors, true);
        let mut ball = Mesh {
            path: paths[1].to_path_buf(),
            ..Default::default()
        };
        add_sphere(&mut ball, c, r, rings, sectors, false);
        [shell, ball]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_bodies_are_closed_and_an_open_one_is_refused() {
        let p = Path::new("x.stl");
        let [a, b] = shapes::box_with_sphere([p, p], [0.0; 3], [10.0; 3], 3.0, 2000);
        a.check_closed().unwrap();
        b.check_closed().unwrap();
        let mut open = b.clone();
        open.triangles.pop();
        let e = open.check_closed().unwrap_err().to_string();
        assert!(e.starts_with("x.stl: not a closed manifold body"), "{e}");
    }

    #[test]
    fn a_triangle_flipped_against_its_neighbours_is_refused_and_a_flipped_body_is_not() {
        let p = Path::new("x.stl");
        let mut body = shapes::cuboid(p, [0.0; 3], [10.0; 3]);
        let mut inside_out = body.clone();
        for t in &mut inside_out.triangles {
            t.swap(1, 2);
        }
        inside_out.check_closed().unwrap();
        body.triangles[4].swap(1, 2);
        let e = body.check_closed().unwrap_err().to_string();
        // One triangle flipped: its three edges each meet a neighbour running the same way.
        assert!(
            e.starts_with("x.stl: faces not consistently oriented: 3 edge(s)"),
            "{e}"
        );
        assert!(e.contains("repair the mesh"), "{e}");
    }

    #[test]
    fn nan_and_empty_are_refused_and_negative_zero_welds() {
        let p = Path::new("n.stl");
        let e = Mesh::from_triangles(p, &[[[0.0, f32::NAN, 0.0], [1.0; 3], [2.0; 3]]]).unwrap_err();
        assert!(
            matches!(e, SliceError::NonFinite { triangle: 0, .. }),
            "{e}"
        );
        assert!(matches!(
            Mesh::from_triangles(p, &[]),
            Err(SliceError::NoTriangles { .. })
        ));
        let m = Mesh::from_triangles(p, &[[[-0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]])
            .unwrap();
        assert_eq!(m.vertices.len(), 2);
    }
}
