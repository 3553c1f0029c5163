//! Reading a 3MF design (the `threemf` crate parses the package): every build item's
//! mesh, with its components and transforms applied and the model's unit turned into mm,
//! grouped into one body per material. A material is the item's base material
//! (`pid`/`pindex`: base material i prints from inlet i) or, for a file without
//! materials, the item itself in build order. Checking and voxelizing the
//! bodies is `mesh`'s and `voxel`'s job.

use super::error::{SliceError, SliceLimit};
use super::image::one_line;
use super::mesh::Mesh;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use threemf::model::{Model, Object, Unit};

/// Nesting of components within components that we follow; deeper is refused (and a
/// cycle, which the format forbids, is caught by it rather than recursing forever).
const MAX_DEPTH: usize = 16;

/// A row-vector affine transform as 3MF writes it: `p' = [x y z 1] * M`, with `M` the
/// 4x3 matrix `m00 m01 m02 m10 m11 m12 m20 m21 m22 m30 m31 m32`.
type Transform = [f64; 12];

/// A triangle's corners, mm.
type Tri = [[f32; 3]; 3];

const IDENTITY: Transform = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];

fn apply(m: &Transform, p: [f64; 3]) -> [f64; 3] {
    [
        p[0] * m[0] + p[1] * m[3] + p[2] * m[6] + m[9],
        p[0] * m[1] + p[1] * m[4] + p[2] * m[7] + m[10],
        p[0] * m[2] + p[1] * m[5] + p[2] * m[8] + m[11],
    ]
}

/// `inner` then `outer`.
fn compose(inner: &Transform, outer: &Transform) -> Transform {
    let mut r = [0.0; 12];
    for row in 0..4 {
        for col in 0..3 {
            let mut s = if row == 3 { outer[9 + col] } else { 0.0 };
            for k in 0..3 {
                s += inner[row * 3 + k] * outer[k * 3 + col];
            }
            r[row * 3 + col] = s;
        }
    }
    r
}

fn unit_mm(u: &Unit) -> f64 {
    match u {
        Unit::Micron => 0.001,
        Unit::Millimeter => 1.0,
        Unit::Centimeter => 10.0,
        Unit::Inch => 25.4,
        Unit::Foot => 304.8,
        Unit::Meter => 1000.0,
    }
}

fn bad(path: &Path, reason: impl Into<String>) -> SliceError {
    SliceError::ThreeMf {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Which material an object is: its base material's index, if it names one. Materials are
/// numbered across the file's base-material groups in file order; where the groups cannot
/// be read (the `threemf` crate reads only `m:`-prefixed ones) `pindex` alone is the
/// material, which is right for the usual single group.
fn material_of(model: &Model, o: &Object) -> Option<usize> {
    let (pid, pindex) = (o.pid?, o.pindex.unwrap_or(0));
    let Some(groups) = model.resources.basematerials.as_ref() else {
        return Some(pindex);
    };
    let mut first = 0usize;
    for g in groups {
        if g.id == pid {
            return Some(first + pindex);
        }
        first += g.base.len();
    }
    Some(pindex)
}

/// Appends `object`'s triangles (and its components'), transformed by `m`, to `out`.
fn collect(
    path: &Path,
    model: &Model,
    object: &Object,
    m: &Transform,
    depth: usize,
    out: &mut Vec<Tri>,
) -> Result<(), SliceError> {
    if depth > MAX_DEPTH {
        return Err(bad(
            path,
            format!("components nest deeper than {MAX_DEPTH} levels (or refer to themselves)"),
        ));
    }
    if let Some(mesh) = &object.mesh {
        let v = &mesh.vertices.vertex;
        for (ti, t) in mesh.triangles.triangle.iter().enumerate() {
            let mut tri = [[0f32; 3]; 3];
            for (k, &i) in [t.v1, t.v2, t.v3].iter().enumerate() {
                let Some(p) = v.get(i) else {
                    return Err(bad(
                        path,
                        format!(
                            "object {}: triangle {ti} refers to vertex {i}, but the mesh has {}",
                            object.id,
                            v.len()
                        ),
                    ));
                };
                let q = apply(m, [p.x, p.y, p.z]);
                tri[k] = [q[0] as f32, q[1] as f32, q[2] as f32];
            }
            out.push(tri);
        }
    }
    if let Some(c) = &object.components {
        for comp in &c.component {
            let Some(child) = model
                .resources
                .object
                .iter()
                .find(|o| o.id == comp.objectid)
            else {
                return Err(bad(
                    path,
                    format!(
                        "object {} has a component of object {}, which the file does not define",
                        object.id, comp.objectid
                    ),
                ));
            };
            let cm = compose(&comp.transform.unwrap_or(IDENTITY), m);
            collect(path, model, child, &cm, depth + 1, out)?;
        }
    }
    Ok(())
}

/// Reads a 3MF file with the default limits.
pub fn read_3mf(path: &Path) -> Result<Vec<Mesh>, SliceError> {
    read_3mf_limited(path, &super::Limits::default())
}

/// Decompresses each model part of the package (counting, not keeping, the bytes) and
/// refuses the file when they pass `max`: the parser holds about three times its XML in
/// memory, and a 2 MB file can hold 2 GB of whitespace. Counting the real output, not
/// the sizes the package declares, is what a hostile file cannot lie about.
fn check_xml_size(path: &Path, max: u64) -> Result<(), SliceError> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| SliceError::read(path, e))?;
    let mut zip = zip::ZipArchive::new(std::io::BufReader::new(file))
        .map_err(|e| bad(path, one_line(&e.to_string())))?;
    let mut total = 0u64;
    for i in 0..zip.len() {
        let entry = zip
            .by_index(i)
            .map_err(|e| bad(path, one_line(&e.to_string())))?;
        let is_model = entry.name().is_ok_and(|n| n.ends_with(".model"));
        if !is_model {
            continue;
        }
        let left = max.saturating_sub(total);
        let n = std::io::copy(&mut entry.take(left + 1), &mut std::io::sink())
            .map_err(|e| bad(path, one_line(&e.to_string())))?;
        total += n;
        if total > max {
            return Err(SliceError::OverLimit {
                what: format!(
                    "{}: its model XML is more than the limit of {} MiB",
                    path.display(),
                    max >> 20
                ),
                limit: SliceLimit::ThreeMfSize,
                or: None,
            });
        }
    }
    Ok(())
}

/// Triangles `object` expands to, components included (memoised per object: components
/// ten wide and nine deep are 10^9 triangles from a file of a few hundred bytes, which
/// must be counted, not built). Saturates instead of overflowing.
fn expanded(
    path: &Path,
    model: &Model,
    object: &Object,
    depth: usize,
    memo: &mut BTreeMap<usize, u64>,
) -> Result<u64, SliceError> {
    if let Some(&n) = memo.get(&object.id) {
        return Ok(n);
    }
    if depth > MAX_DEPTH {
        return Err(bad(
            path,
            format!("components nest deeper than {MAX_DEPTH} levels (or refer to themselves)"),
        ));
    }
    let mut n = object
        .mesh
        .as_ref()
        .map_or(0, |m| m.triangles.triangle.len() as u64);
    if let Some(c) = &object.components {
        for comp in &c.component {
            if let Some(child) = model
                .resources
                .object
                .iter()
                .find(|o| o.id == comp.objectid)
            {
                n = n.saturating_add(expanded(path, model, child, depth + 1, memo)?);
            }
        }
    }
    memo.insert(object.id, n);
    Ok(n)
}

/// Reads a 3MF file into one body per material, in material order (inlet order),
/// refusing it before parsing when its XML passes `limits.max_3mf_bytes`, and before
/// expanding components when its triangles would pass `limits.max_triangles`.
pub fn read_3mf_limited(path: &Path, limits: &super::Limits) -> Result<Vec<Mesh>, SliceError> {
    check_xml_size(path, limits.max_3mf_bytes)?;
    let file = std::fs::File::open(path).map_err(|e| SliceError::read(path, e))?;
    let models = threemf::read(std::io::BufReader::new(file)).map_err(|e| {
        // The crate's own words are generic ("Deserialization error ..."); the cause says
        // which element or entry.
        let cause = std::error::Error::source(&e).map_or(String::new(), |c| format!(": {c}"));
        bad(path, one_line(&format!("{e}{cause}")))
    })?;
    let mut total = 0u64;
    for model in &models {
        let mut memo = BTreeMap::new();
        for item in &model.build.item {
            if let Some(object) = model
                .resources
                .object
                .iter()
                .find(|o| o.id == item.objectid)
            {
                total = total.saturating_add(expanded(path, model, object, 0, &mut memo)?);
            }
        }
    }
    if total > limits.max_triangles {
        return Err(super::over_limit(
            &path.display().to_string(),
            "triangles after expanding components:",
            total,
            limits.max_triangles,
            SliceLimit::Triangles,
            None,
        ));
    }
    // Key: (material index, or build order for files without materials) -> triangles.
    let mut bodies: BTreeMap<usize, (String, Vec<Tri>)> = BTreeMap::new();
    let mut item_no = 0usize;
    let mut with_materials = None::<bool>;
    for model in &models {
        let scale = unit_mm(&model.unit);
        let unit = [
            scale, 0.0, 0.0, 0.0, scale, 0.0, 0.0, 0.0, scale, 0.0, 0.0, 0.0,
        ];
        for item in &model.build.item {
            let Some(object) = model
                .resources
                .object
                .iter()
                .find(|o| o.id == item.objectid)
            else {
                return Err(bad(
                    path,
                    format!(
                        "the build refers to object {}, which the file does not define",
                        item.objectid
                    ),
                ));
            };
            let material = material_of(model, object);
            match (with_materials, material.is_some()) {
                (None, m) => with_materials = Some(m),
                (Some(a), b) if a != b => {
                    return Err(bad(
                        path,
                        format!(
                            "object {} has {} material while others {}; give every object one, \
                             or none (then each object is one material, in build order)",
                            object.id,
                            if b { "a" } else { "no" },
                            if a { "do" } else { "do not" }
                        ),
                    ))
                }
                _ => {}
            }
            let key = material.unwrap_or(item_no);
            item_no += 1;
            let m = compose(&item.transform.unwrap_or(IDENTITY), &unit);
            let name = object
                .name
                .clone()
                .unwrap_or_else(|| format!("object {}", object.id));
            let entry = bodies.entry(key).or_insert_with(|| (name, Vec::new()));
            collect(path, model, object, &m, 0, &mut entry.1)?;
        }
    }
    if bodies.is_empty() {
        return Err(bad(path, "the build holds no object"));
    }
    // Materials must be 0..n without gaps: inlet i prints material i.
    let mut meshes = Vec::with_capacity(bodies.len());
    for (expect, (key, (name, tris))) in bodies.into_iter().enumerate() {
        if key != expect {
            return Err(bad(
                path,
                format!(
                    "no object uses material {expect} although material {key} is used; \
                     inlet i prints material i, so the materials in use must be 0..n"
                ),
            ));
        }
        let body = PathBuf::from(format!("{} ({name})", path.display()));
        if tris.is_empty() {
            return Err(bad(path, format!("{name}: no triangles")));
        }
        meshes.push(Mesh::from_triangles(&body, &tris)?);
    }
    Ok(meshes)
}
