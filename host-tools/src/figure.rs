//! Pictures framed for a person: a plate picture (or several, one per layer) set on mm axes
//! with a title, a key of materials or marks, and a labelled colour bar with units. The
//! pictures themselves are painted by their owners (`slicer::preview`, `simulate::heatmap`,
//! `inspect::picture`); this only frames them, and encodes a picture as PNG bytes for those
//! who send it rather than write it. Text uses the font embedded in the binary.

use image::RgbImage;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::sync::Once;

/// A picture as PNG bytes (in memory: the dashboard's replies).
pub fn png(img: &RgbImage) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| format!("cannot draw the picture: {e}"))?;
    Ok(out)
}

static FONT: Once = Once::new();
/// The font family plotters draws text in (registered from the embedded font).
pub const FAMILY: &str = "sans-serif";

/// Registers the embedded font once, so figures need no system fonts.
pub fn register_font() {
    FONT.call_once(|| {
        // The embedded font is a valid TrueType file; if it ever were not, plotters would
        // report a font error when drawing text, which the callers turn into their errors.
        let _ = plotters::style::register_font(
            FAMILY,
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        );
    });
}

/// One picture of the plate and the mm it spans.
#[derive(Clone, Debug)]
pub struct Plate {
    /// Its caption (empty for none), e.g. "layer 3, z = 1.80 mm".
    pub caption: String,
    /// The picture, top row at `y_mm.1`.
    pub img: RgbImage,
    /// X range, mm, left to right.
    pub x_mm: (f64, f64),
    /// Y range, mm, bottom to top.
    pub y_mm: (f64, f64),
}

/// One entry of the key beside the plates.
#[derive(Clone, Debug)]
pub enum Key {
    /// A filled square: a material.
    Swatch(String, [u8; 3]),
    /// A dot: a mark drawn on the plate.
    Dot(String, [u8; 3]),
    /// A line: travel moves, outlines.
    Line(String, [u8; 3]),
    /// A vertical colour bar from `lo` (bottom) to `hi` (top), with ticks.
    Bar {
        /// What it measures, with units, e.g. "boundary error (mm)".
        label: String,
        /// Bottom value.
        lo: f64,
        /// Top value.
        hi: f64,
        /// The colour of a value.
        colour: fn(f64) -> [u8; 3],
    },
    /// A line of text.
    Note(String),
}

/// Largest side of a framed figure, pixels.
pub const MAX_SIDE: u32 = 4000;
const KEY_WIDTH: u32 = 250;
const LEFT: u32 = 70;
const BOTTOM: u32 = 50;
const TOP: u32 = 44;
const PANEL_GAP: u32 = 16;

/// Frames `plates` (side by side in a grid of `columns`) on mm axes, with `title` above and
/// `key` on the right. Each plate is scaled to its panel keeping its aspect.
pub fn framed(
    title: &str,
    plates: &[Plate],
    columns: usize,
    key: &[Key],
) -> Result<RgbImage, String> {
    register_font();
    let columns = columns.clamp(1, plates.len().max(1));
    let rows = plates.len().div_ceil(columns).max(1);
    // Panels as large as the biggest plate, within MAX_SIDE for the whole figure.
    let (pw0, ph0) = plates.iter().fold((200u32, 150u32), |(w, h), p| {
        (w.max(p.img.width()), h.max(p.img.height()))
    });
    let room_w = (MAX_SIDE / columns as u32).saturating_sub(LEFT + PANEL_GAP);
    let room_h = ((MAX_SIDE - 36) / rows as u32).saturating_sub(TOP + BOTTOM);
    let fit = (room_w as f64 / pw0 as f64)
        .min(room_h as f64 / ph0 as f64)
        .min(1.0);
    let (pw, ph) = (
        ((pw0 as f64 * fit) as u32).max(120),
        ((ph0 as f64 * fit) as u32).max(90),
    );
    let panel_w = LEFT + pw + PANEL_GAP;
    let panel_h = TOP + ph + BOTTOM;
    let width = panel_w * columns as u32 + KEY_WIDTH;
    let height = (panel_h * rows as u32 + 36).max(key_height(key) + 60);
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    let mut areas = Vec::new();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        let e = |err: DrawingAreaErrorKind<_>| err.to_string();
        root.fill(&WHITE).map_err(e)?;
        root.draw(&Text::new(title.to_string(), (12, 8), (FAMILY, 22)))
            .map_err(e)?;
        let (grid, side) = root.split_horizontally(panel_w * columns as u32);
        let grid = grid.margin(36, 0, 0, 0);
        let cells = grid.split_evenly((rows, columns));
        for (area, plate) in cells.iter().zip(plates) {
            areas.push(panel(area, plate)?);
        }
        draw_key(&side.margin(44, 8, 8, 8), key)?;
        root.present().map_err(e)?;
    }
    let mut out =
        RgbImage::from_raw(width, height, buf).ok_or("figure buffer of the wrong size")?;
    for (plate, (xs, ys)) in plates.iter().zip(areas) {
        blit(&mut out, plate, xs, ys);
    }
    Ok(out)
}

fn key_height(key: &[Key]) -> u32 {
    key.iter()
        .map(|k| match k {
            Key::Bar { .. } => 260,
            _ => 24,
        })
        .sum()
}

/// Draws one panel's axes and returns the pixel ranges of its plotting area.
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    plate: &Plate,
) -> Result<(std::ops::Range<i32>, std::ops::Range<i32>), String> {
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| err.to_string();
    let (aw, ah) = area.dim_in_pixel();
    // Keep the plate's aspect: shrink the plotting area on one side.
    let (avail_w, avail_h) = (
        aw.saturating_sub(LEFT + PANEL_GAP) as f64,
        ah.saturating_sub(TOP + BOTTOM) as f64,
    );
    let (sx, sy) = (plate.x_mm.1 - plate.x_mm.0, plate.y_mm.1 - plate.y_mm.0);
    let scale = (avail_w / sx.max(1e-9)).min(avail_h / sy.max(1e-9));
    let (w, h) = ((sx * scale) as u32, (sy * scale) as u32);
    let right = aw.saturating_sub(LEFT + w).max(1);
    let below = ah.saturating_sub(TOP + h + BOTTOM);
    let mut chart = ChartBuilder::on(area)
        .caption(plate.caption.as_str(), (FAMILY, 16))
        .margin_right(right)
        .margin_bottom(below)
        .x_label_area_size(BOTTOM)
        .y_label_area_size(LEFT)
        .build_cartesian_2d(plate.x_mm.0..plate.x_mm.1, plate.y_mm.0..plate.y_mm.1)
        .map_err(e)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (mm)")
        .y_desc("y (mm)")
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&|v| tick(*v, sx))
        .y_label_formatter(&|v| tick(*v, sy))
        .label_style((FAMILY, 13))
        .axis_desc_style((FAMILY, 14))
        .draw()
        .map_err(e)?;
    Ok(chart.plotting_area().get_pixel_range())
}

/// A tick label with as many decimals as a tenth of the span needs.
fn tick(v: f64, span: f64) -> String {
    let decimals = (-(span / 10.0).log10()).ceil().clamp(0.0, 3.0) as usize;
    let v = if v.abs() < span * 1e-9 { 0.0 } else { v };
    format!("{v:.decimals$}")
}

fn draw_key<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    key: &[Key],
) -> Result<(), String> {
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| err.to_string();
    let mut y = 0i32;
    let font = (FAMILY, 14);
    for k in key {
        match k {
            Key::Swatch(label, c) => {
                let c = RGBColor(c[0], c[1], c[2]);
                area.draw(&Rectangle::new([(0, y), (16, y + 16)], c.filled()))
                    .map_err(e)?;
                area.draw(&Rectangle::new(
                    [(0, y), (16, y + 16)],
                    BLACK.stroke_width(1),
                ))
                .map_err(e)?;
                area.draw(&Text::new(label.clone(), (24, y), font))
                    .map_err(e)?;
                y += 24;
            }
            Key::Dot(label, c) => {
                let c = RGBColor(c[0], c[1], c[2]);
                area.draw(&Circle::new((8, y + 8), 6, BLACK.filled()))
                    .map_err(e)?;
                area.draw(&Circle::new((8, y + 8), 5, c.filled()))
                    .map_err(e)?;
                area.draw(&Text::new(label.clone(), (24, y), font))
                    .map_err(e)?;
                y += 24;
            }
            Key::Line(label, c) => {
                if c.iter().map(|&v| v as u32).sum::<u32>() > 600 {
                    // A light line (drawn over a photo) shows on a dark patch, as on the plate.
                    area.draw(&Rectangle::new(
                        [(0, y), (16, y + 16)],
                        RGBColor(90, 100, 115).filled(),
                    ))
                    .map_err(e)?;
                }
                let c = RGBColor(c[0], c[1], c[2]);
                area.draw(&PathElement::new(
                    vec![(0, y + 8), (16, y + 8)],
                    c.stroke_width(2),
                ))
                .map_err(e)?;
                area.draw(&Text::new(label.clone(), (24, y), font))
                    .map_err(e)?;
                y += 24;
            }
            Key::Note(text) => {
                area.draw(&Text::new(text.clone(), (0, y), font))
                    .map_err(e)?;
                y += 24;
            }
            Key::Bar {
                label,
                lo,
                hi,
                colour,
            } => {
                area.draw(&Text::new(label.clone(), (0, y), font))
                    .map_err(e)?;
                let (top, len) = (y + 26, 200i32);
                for i in 0..len {
                    let v = hi - (hi - lo) * i as f64 / (len - 1) as f64;
                    let c = colour(v);
                    area.draw(&Rectangle::new(
                        [(0, top + i), (22, top + i + 1)],
                        RGBColor(c[0], c[1], c[2]).filled(),
                    ))
                    .map_err(e)?;
                }
                area.draw(&Rectangle::new(
                    [(0, top), (22, top + len)],
                    BLACK.stroke_width(1),
                ))
                .map_err(e)?;
                for t in 0..=4 {
                    let f = t as f64 / 4.0;
                    let yy = top + ((len - 1) as f64 * (1.0 - f)) as i32;
                    area.draw(&PathElement::new(
                        vec![(22, yy), (28, yy)],
                        BLACK.stroke_width(1),
                    ))
                    .map_err(e)?;
                    area.draw(&Text::new(
                        tick(lo + (hi - lo) * f, (hi - lo) / 10.0),
                        (32, yy - 7),
                        (FAMILY, 13),
                    ))
                    .map_err(e)?;
                }
                y = top + len + 24;
            }
        }
    }
    Ok(())
}

/// Copies `plate` into the pixel rectangle `xs` x `ys`, scaled.
fn blit(out: &mut RgbImage, plate: &Plate, xs: std::ops::Range<i32>, ys: std::ops::Range<i32>) {
    let (w, h) = (
        (xs.end - xs.start).max(1) as u32,
        (ys.end - ys.start).max(1) as u32,
    );
    let scaled = image::imageops::resize(&plate.img, w, h, image::imageops::FilterType::Triangle);
    image::imageops::replace(out, &scaled, xs.start as i64, ys.start as i64);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plate(w: u32, h: u32) -> Plate {
        Plate {
            caption: "layer 0".into(),
            img: RgbImage::from_pixel(w, h, image::Rgb([10, 200, 10])),
            x_mm: (0.0, w as f64 / 10.0),
            y_mm: (0.0, h as f64 / 10.0),
        }
    }

    #[test]
    fn the_plate_lands_inside_its_axes_with_the_key_beside() {
        let key = [
            Key::Swatch("paste A".into(), [122, 72, 36]),
            Key::Bar {
                label: "error (mm)".into(),
                lo: 0.0,
                hi: 0.05,
                colour: |v| [(v * 5000.0) as u8, 0, 0],
            },
        ];
        let img = framed("title", &[plate(400, 300)], 1, &key).unwrap();
        assert!(img.width() > 400 + KEY_WIDTH && img.height() > 300);
        let green = img.pixels().filter(|p| p.0 == [10, 200, 10]).count();
        // The plate keeps (most of) its pixels and nothing else is that green.
        assert!(green > 400 * 300 / 2, "{green}");
        let swatch = img.pixels().filter(|p| p.0 == [122, 72, 36]).count();
        assert!(swatch > 100, "{swatch}");
    }

    #[test]
    fn many_plates_stay_within_the_largest_side() {
        let plates: Vec<Plate> = (0..9).map(|_| plate(3000, 3000)).collect();
        let img = framed("grid", &plates, 3, &[]).unwrap();
        assert!(img.width() <= MAX_SIDE + KEY_WIDTH && img.height() <= MAX_SIDE + 100);
    }
}
