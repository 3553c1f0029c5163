//! 3MF designs: the bundled cube-and-ball pair written as one 3MF (with base materials,
//! without, with item transforms and another unit) slices to exactly the commands of the
//! two STL files; broken or inconsistent 3MF files are refused with a reason.

use dollop_host::fixtures::designs_dir;
use dollop_host::slicer::mesh::{read_stl, Mesh as Body};
use dollop_host::slicer::{self, SliceError, SliceOptions};
use std::path::{Path, PathBuf};
use threemf::model::{
    Base, BaseMaterials, Build, Item, Model, Object, Resources, Triangle, Triangles, Unit, Vertex,
    Vertices,
};

fn config() -> dollop::config::Config {
    slicer::load_config(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/seed-paper.toml"))
        .unwrap()
}

fn bodies() -> [Body; 2] {
    [
        read_stl(&designs_dir().join("cube-shell.stl")).unwrap(),
        read_stl(&designs_dir().join("cube-ball.stl")).unwrap(),
    ]
}

/// A 3MF object from a body, its vertices mapped by `f`.
fn object(
    id: usize,
    b: &Body,
    material: Option<usize>,
    f: impl Fn([f32; 3]) -> [f64; 3],
) -> Object {
    Object {
        id,
        name: Some(format!("body {id}")),
        pid: material.map(|_| 100),
        pindex: material,
        mesh: Some(threemf::Mesh {
            vertices: Vertices {
                vertex: b
                    .vertices
                    .iter()
                    .map(|&v| {
                        let p = f(v);
                        Vertex {
                            x: p[0],
                            y: p[1],
                            z: p[2],
                        }
                    })
                    .collect(),
            },
            triangles: Triangles {
                triangle: b
                    .triangles
                    .iter()
                    .map(|t| Triangle {
                        v1: t[0] as usize,
                        v2: t[1] as usize,
                        v3: t[2] as usize,
                    })
                    .collect(),
            },
        }),
        ..Default::default()
    }
}

fn model(objects: Vec<Object>, items: Vec<Item>, materials: usize, unit: Unit) -> Model {
    Model {
        resources: Resources {
            object: objects,
            basematerials: (materials > 0).then(|| {
                vec![BaseMaterials {
                    id: 100,
                    base: (0..materials)
                        .map(|i| Base {
                            name: format!("paste {i}"),
                            displaycolor: "#808080".into(),
                        })
                        .collect(),
                }]
            }),
        },
        build: Build { item: items },
        unit,
        ..Default::default()
    }
}

fn item(objectid: usize, transform: Option<[f64; 12]>) -> Item {
    Item {
        objectid,
        transform,
        partnumber: None,
    }
}

fn write(dir: &Path, name: &str, m: Model) -> PathBuf {
    let path = dir.join(name);
    let f = std::fs::File::create(&path).unwrap();
    threemf::write(f, m).unwrap();
    path
}

fn stl_commands() -> Vec<dollop::Command> {
    let files = vec![
        designs_dir().join("cube-shell.stl"),
        designs_dir().join("cube-ball.stl"),
    ];
    slicer::slice_files(&files, &config(), &SliceOptions::default())
        .unwrap()
        .commands
}

fn slice(path: &Path) -> Result<Vec<dollop::Command>, SliceError> {
    slicer::slice_files(&[path.to_path_buf()], &config(), &SliceOptions::default())
        .map(|s| s.commands)
}

fn id(v: [f32; 3]) -> [f64; 3] {
    [v[0] as f64, v[1] as f64, v[2] as f64]
}

#[test]
fn base_materials_choose_the_inlets_whatever_the_object_order() {
    let dir = tempfile::tempdir().unwrap();
    let [shell, ball] = bodies();
    // The ball first in the file and the build, but it is material 1.
    let m = model(
        vec![
            object(1, &ball, Some(1), id),
            object(2, &shell, Some(0), id),
        ],
        vec![item(1, None), item(2, None)],
        2,
        Unit::Millimeter,
    );
    let path = write(dir.path(), "cube.3mf", m);
    assert_eq!(slice(&path).unwrap(), stl_commands());
}

#[test]
fn without_materials_each_object_is_one_material_in_build_order() {
    let dir = tempfile::tempdir().unwrap();
    let [shell, ball] = bodies();
    let m = model(
        vec![object(7, &ball, None, id), object(3, &shell, None, id)],
        vec![item(3, None), item(7, None)],
        0,
        Unit::Millimeter,
    );
    let path = write(dir.path(), "cube.3mf", m);
    assert_eq!(slice(&path).unwrap(), stl_commands());
}

#[test]
fn transforms_and_units_are_applied() {
    let dir = tempfile::tempdir().unwrap();
    let [shell, ball] = bodies();
    // In microns, the ball stored 10 mm to the left and moved back by its build item.
    let um = |v: [f32; 3]| {
        [
            v[0] as f64 * 1000.0,
            v[1] as f64 * 1000.0,
            v[2] as f64 * 1000.0,
        ]
    };
    let left = |v: [f32; 3]| {
        [
            (v[0] as f64 - 10.0) * 1000.0,
            v[1] as f64 * 1000.0,
            v[2] as f64 * 1000.0,
        ]
    };
    let shift = [
        1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 10_000.0, 0.0, 0.0,
    ];
    let m = model(
        vec![
            object(1, &shell, Some(0), um),
            object(2, &ball, Some(1), left),
        ],
        vec![item(1, None), item(2, Some(shift))],
        2,
        Unit::Micron,
    );
    let path = write(dir.path(), "cube.3mf", m);
    assert_eq!(slice(&path).unwrap(), stl_commands());
}

fn refused(path: &Path, needle: &str) {
    let e = slice(path).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains(&path.display().to_string()) && msg.contains(needle),
        "{msg:?} should name the file and say {needle:?}"
    );
    assert!(!msg.contains('\n'), "one line: {msg:?}");
}

#[test]
fn broken_and_inconsistent_files_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let [shell, ball] = bodies();

    let not_zip = dir.path().join("text.3mf");
    std::fs::write(&not_zip, "solid not a 3mf").unwrap();
    refused(&not_zip, "unusable 3MF");

    let empty = write(
        dir.path(),
        "empty.3mf",
        model(vec![], vec![], 0, Unit::Millimeter),
    );
    refused(&empty, "no object");

    let mut o = object(1, &shell, None, id);
    if let Some(m) = o.mesh.as_mut() {
        m.triangles.triangle[5].v2 = 1_000_000;
    }
    let bad_index = write(
        dir.path(),
        "index.3mf",
        model(vec![o], vec![item(1, None)], 0, Unit::Millimeter),
    );
    refused(&bad_index, "refers to vertex 1000000");

    let dangling = write(
        dir.path(),
        "dangling.3mf",
        model(
            vec![object(1, &shell, None, id)],
            vec![item(9, None)],
            0,
            Unit::Millimeter,
        ),
    );
    refused(&dangling, "object 9");

    let gap = write(
        dir.path(),
        "gap.3mf",
        model(
            vec![object(1, &ball, Some(1), id)],
            vec![item(1, None)],
            2,
            Unit::Millimeter,
        ),
    );
    refused(&gap, "no object uses material 0");

    let mixed = write(
        dir.path(),
        "mixed.3mf",
        model(
            vec![object(1, &shell, Some(0), id), object(2, &ball, None, id)],
            vec![item(1, None), item(2, None)],
            1,
            Unit::Millimeter,
        ),
    );
    refused(&mixed, "has no material while others do");

    // Three materials for a two-inlet machine.
    let three = write(
        dir.path(),
        "three.3mf",
        model(
            vec![
                object(1, &shell, None, id),
                object(2, &ball, None, id),
                object(3, &ball, None, |v| {
                    [v[0] as f64 + 40.0, v[1] as f64, v[2] as f64]
                }),
            ],
            vec![item(1, None), item(2, None), item(3, None)],
            0,
            Unit::Millimeter,
        ),
    );
    refused(&three, "3");

    let with_stl = slicer::slice_files(
        &[designs_dir().join("cube-shell.stl"), three.clone()],
        &config(),
        &SliceOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        with_stl.contains("three.3mf: cannot mix with STL bodies"),
        "{with_stl}"
    );

    let mut open = object(1, &shell, None, id);
    if let Some(m) = open.mesh.as_mut() {
        m.triangles.triangle.pop();
    }
    let open = write(
        dir.path(),
        "open.3mf",
        model(vec![open], vec![item(1, None)], 0, Unit::Millimeter),
    );
    let msg = slice(&open).unwrap_err().to_string();
    assert!(msg.contains("open.3mf (body 1)"), "{msg}");
}
