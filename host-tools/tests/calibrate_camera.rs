//! `calibrate camera` on synthetic frame sequences rendered with known speed and width
//! (textured filament moving down): speed within 2 %, width within 3 %, the die swell
//! and feed-forward speed follow, and bad folders are typed errors naming the file.

mod calibrate_common;

use calibrate_common::*;
use dollop_host::calibrate::camera::synth::Synth;
use dollop_host::calibrate::camera::{calibrate, Options};
use dollop_host::calibrate::CalError;

#[test]
fn speed_and_width_of_synthetic_sequences() {
    // (px per frame, width px, centre px, seed): slow and fast, narrow and wide.
    let cases = [
        (1.3, 30.0, 70.0, 1),
        (3.0, 41.5, 81.2, 2),
        (6.2, 64.0, 90.0, 3),
        (9.5, 52.3, 77.7, 4),
    ];
    for (speed, width, center, seed) in cases {
        let dir = tempfile::tempdir().unwrap();
        let synth = Synth {
            width: 180,
            height: 140,
            filament_px: width,
            center_px: center,
            speed_px_per_frame: speed,
            seed,
            ..Synth::default()
        };
        synth.write(dir.path(), 10).unwrap();
        let (fps, mm_per_px) = (25.0, 0.01);
        let mut o = Options::new(fps, mm_per_px);
        o.nozzle_mm = Some(0.4);
        o.target_width_mm = Some(0.5);
        let cal = calibrate(dir.path(), &o).unwrap();
        let v = speed * fps * mm_per_px;
        let d = width * mm_per_px;
        assert!(
            rel(cal.v_ex, v) < 0.02,
            "speed {} vs {v} ({speed} px/frame)",
            cal.v_ex
        );
        assert!(
            rel(cal.d_ex, d) < 0.03,
            "width {} vs {d} ({width} px)",
            cal.d_ex
        );
        let (_, swell) = cal.die_swell.unwrap();
        assert!((swell - cal.d_ex / 0.4).abs() < 1e-12);
        let (_, vn) = cal.feed_forward.unwrap();
        assert!((vn - cal.v_ex * (cal.d_ex / 0.5).powi(2)).abs() < 1e-12);
    }
}

#[test]
fn the_fragment_sets_the_print_speed_and_validates() {
    let dir = tempfile::tempdir().unwrap();
    Synth::default().write(dir.path(), 8).unwrap();
    let mut o = Options::new(30.0, 0.02);
    o.target_width_mm = Some(1.2);
    let cal = calibrate(dir.path(), &o).unwrap();
    let (config, _) = merge_into_seed(&cal.fragment().unwrap()).unwrap();
    let (_, vn) = cal.feed_forward.unwrap();
    assert!(rel(config.motion.print_speed_mm_s as f64, vn) < 1e-3);
    // No target width, no fragment.
    o.target_width_mm = None;
    assert!(calibrate(dir.path(), &o).unwrap().fragment().is_none());
}

#[test]
fn a_folder_without_images_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "notes.txt", "no frames here");
    let e = calibrate(dir.path(), &Options::new(30.0, 0.01)).unwrap_err();
    assert!(matches!(e, CalError::NoImages { .. }), "{e}");
    assert!(e.to_string().contains(&dir.path().display().to_string()));
}

#[test]
fn a_single_frame_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    Synth::default().write(dir.path(), 1).unwrap();
    let e = calibrate(dir.path(), &Options::new(30.0, 0.01)).unwrap_err();
    assert!(matches!(e, CalError::TooFewFrames { frames: 1, .. }), "{e}");
}

#[test]
fn frames_of_different_sizes_name_the_odd_one() {
    let dir = tempfile::tempdir().unwrap();
    Synth::default().write(dir.path(), 3).unwrap();
    let odd = Synth {
        width: 100,
        ..Synth::default()
    };
    odd.frame(3).save(dir.path().join("frame_003.png")).unwrap();
    let e = calibrate(dir.path(), &Options::new(30.0, 0.01)).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, CalError::FrameSize { .. }), "{text}");
    assert!(
        text.contains("frame_003.png") && text.contains("100x120"),
        "{text}"
    );
}

#[test]
fn an_image_that_does_not_decode_is_named() {
    let dir = tempfile::tempdir().unwrap();
    Synth::default().write(dir.path(), 2).unwrap();
    write(dir.path(), "frame_002.png", "not a png");
    let e = calibrate(dir.path(), &Options::new(30.0, 0.01)).unwrap_err();
    assert!(e.to_string().contains("frame_002.png"), "{e}");
}

#[test]
fn blank_frames_are_not_measurable() {
    let dir = tempfile::tempdir().unwrap();
    for i in 0..3 {
        image::GrayImage::from_pixel(64, 48, image::Luma([90]))
            .save(dir.path().join(format!("f{i}.png")))
            .unwrap();
    }
    let e = calibrate(dir.path(), &Options::new(30.0, 0.01)).unwrap_err();
    assert!(matches!(e, CalError::NotMeasurable { .. }), "{e}");
}

#[test]
fn bad_scales_are_argument_errors() {
    let dir = tempfile::tempdir().unwrap();
    Synth::default().write(dir.path(), 2).unwrap();
    for (fps, s) in [(0.0, 0.01), (30.0, -1.0), (f64::NAN, 0.01)] {
        let e = calibrate(dir.path(), &Options::new(fps, s)).unwrap_err();
        assert!(matches!(e, CalError::Option(_)), "{e}");
    }
}
