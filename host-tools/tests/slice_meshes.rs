//! STL designs: ASCII and binary files slice alike, the bundled pair keeps the ball inside
//! the shell, and layers stack with the Z step of the config.

use dollop::Command;
use dollop_host::fixtures::designs_dir;
use dollop_host::slicer::mesh::read_stl;
use dollop_host::slicer::{self, SliceOptions};
use std::io::Write;
use std::path::Path;

fn config() -> dollop::config::Config {
    slicer::load_config(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/seed-paper.toml"))
        .unwrap()
}

#[test]
fn ascii_and_binary_stl_give_the_same_job() {
    let dir = tempfile::tempdir().unwrap();
    let mut ascii = Vec::new();
    for name in ["cube-shell", "cube-ball"] {
        let m = read_stl(&designs_dir().join(format!("{name}.stl"))).unwrap();
        let path = dir.path().join(format!("{name}.stl"));
        let mut f = std::fs::File::create(&path).unwrap();
        writeln!(f, "solid {name}").unwrap();
        for t in &m.triangles {
            writeln!(f, "facet normal 0 0 0\nouter loop").unwrap();
            for &i in t {
                let v = m.vertices[i as usize];
                // Shortest round-trip formatting keeps the f32 values exact.
                writeln!(f, "vertex {:?} {:?} {:?}", v[0], v[1], v[2]).unwrap();
            }
            writeln!(f, "endloop\nendfacet").unwrap();
        }
        writeln!(f, "endsolid {name}").unwrap();
        ascii.push(path);
    }
    let binary = vec![
        designs_dir().join("cube-shell.stl"),
        designs_dir().join("cube-ball.stl"),
    ];
    let c = config();
    let a = slicer::slice_files(&ascii, &c, &SliceOptions::default()).unwrap();
    let b = slicer::slice_files(&binary, &c, &SliceOptions::default()).unwrap();
    assert_eq!(a.commands, b.commands);
}

#[test]
fn the_ball_prints_inside_the_shell_layer_by_layer() {
    let c = config();
    let files = vec![
        designs_dir().join("cube-shell.stl"),
        designs_dir().join("cube-ball.stl"),
    ];
    let s = slicer::slice_files(&files, &c, &SliceOptions::default()).unwrap();
    // 20 mm at 0.6 mm layers: 33 layers, Z rising by 0.6 mm each.
    assert_eq!(s.stats.layers, 33);
    let zs: Vec<i32> = s
        .commands
        .iter()
        .filter_map(|c| match c {
            Command::Layer { z } => Some(*z),
            _ => None,
        })
        .collect();
    for w in zs.windows(2).take(31) {
        assert_eq!(w[1] - w[0], 600);
    }
    // Material 1 (the ball, radius 7 mm around the centre) only within the ball's span.
    let mut at = [s.header.start_um[0] as i64, s.header.start_um[1] as i64];
    let (lo, hi) = (s.header.bounds_min_um, s.header.bounds_max_um);
    let _ = (lo, hi);
    let mut xs = Vec::new();
    for c in &s.commands {
        match *c {
            Command::Travel { x, y, .. } => at = [x as i64, y as i64],
            Command::Print { dx, dy, material } => {
                if material == 1 {
                    xs.push(at[0]);
                    xs.push(at[0] + dx as i64);
                }
                at[0] += dx as i64;
                at[1] += dy as i64;
            }
            _ => {}
        }
    }
    let span = xs.iter().max().unwrap() - xs.iter().min().unwrap();
    assert!((13_000..=14_100).contains(&span), "ball spans {span} um");
}
