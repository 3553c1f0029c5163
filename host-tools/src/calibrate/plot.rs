//! PNG plots of data against fits: panels stacked vertically, each with points, lines
//! and a legend, log axes drawn as decades of the data. Text uses a font embedded in the
//! binary (Ubuntu Light from `epaint_default_fonts`), so plots need no system fonts.
//! Which series to draw is each calibration's business.

use super::output::{self, StagedFiles};
use super::CalError;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::Path;
use std::sync::Once;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    /// Filled circles (measurements).
    Points,
    /// Solid line (fits).
    Line,
    /// Dashed line (derived or secondary curves).
    Dashed,
}

/// One series of a panel.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points in data units.
    pub points: Vec<(f64, f64)>,
    /// How to draw it.
    pub mark: Mark,
    /// Palette index (0 is black, for data).
    pub color: usize,
}

/// One chart.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    /// Caption.
    pub title: String,
    /// X axis description.
    pub x_label: String,
    /// Y axis description.
    pub y_label: String,
    /// Logarithmic X axis.
    pub log_x: bool,
    /// Logarithmic Y axis.
    pub log_y: bool,
    /// Series, drawn in order.
    pub series: Vec<Series>,
    /// Smallest Y span shown (data units, linear axes): keeps a steady measurement from
    /// filling the panel with its noise.
    pub y_min_span: f64,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(20, 20, 20),
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
];

fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

static FONT: Once = Once::new();
const FAMILY: &str = "sans-serif";

fn register_font() {
    FONT.call_once(|| {
        // The embedded font is a valid TrueType file; if it ever were not, plotters would
        // report a font error when drawing text, which `render` turns into CalError::Plot.
        let _ = plotters::style::register_font(
            FAMILY,
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        );
    });
}

fn axis_value(v: f64, log: bool) -> Option<f64> {
    if !v.is_finite() {
        None
    } else if log {
        (v > 0.0).then(|| v.log10())
    } else {
        Some(v)
    }
}

/// Axis label: log axes show the decade value to 3 significant digits; linear axes show
/// as many decimals as a tenth of the span needs, so close ticks stay distinct.
fn tick_label(v: f64, log: bool, span: f64) -> String {
    let s = if log {
        super::format::sig(10f64.powf(v), 3)
    } else {
        let decimals = (-(span / 10.0).log10()).ceil().clamp(0.0, 9.0) as usize;
        let v = if v.abs() < span * 1e-9 { 0.0 } else { v };
        format!("{v:.decimals$}")
    };
    // Trim "2.00" to "2" on log axes; linear axes keep equal decimals.
    if log && s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() || !hi.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo { (hi - lo) * 0.05 } else { 0.5 };
    (lo - pad, hi + pad)
}

/// Draws `panels` stacked vertically into a PNG of `width` x `height_per_panel * n` pixels,
/// staged for `path` in `out`.
pub fn render(
    path: &Path,
    panels: &[Panel],
    width: u32,
    height_per_panel: u32,
    out: &mut StagedFiles,
) -> Result<(), CalError> {
    register_font();
    let height = height_per_panel * panels.len().max(1) as u32;
    let mut buf = vec![255u8; width as usize * height as usize * 3];
    let plot_err = |message: String| CalError::Plot {
        path: path.to_path_buf(),
        message,
    };
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(e.to_string()))?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        for (area, panel) in areas.iter().zip(panels) {
            draw_panel(area, panel).map_err(plot_err)?;
        }
        root.present().map_err(|e| plot_err(e.to_string()))?;
    }
    let image = image::RgbImage::from_raw(width, height, buf)
        .ok_or_else(|| plot_err("image buffer has the wrong size".into()))?;
    let mut png = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| plot_err(e.to_string()))?;
    output::stage(out, path, &png)
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
) -> Result<(), String> {
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| err.to_string();
    let pts: Vec<Vec<(f64, f64)>> = panel
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter_map(|&(x, y)| {
                    Some((axis_value(x, panel.log_x)?, axis_value(y, panel.log_y)?))
                })
                .collect()
        })
        .collect();
    let (x0, x1) = range(pts.iter().flatten().map(|p| p.0));
    let (mut y0, mut y1) = range(pts.iter().flatten().map(|p| p.1));
    if !panel.log_y && y1 - y0 < panel.y_min_span {
        let mid = 0.5 * (y0 + y1);
        (y0, y1) = (mid - 0.5 * panel.y_min_span, mid + 0.5 * panel.y_min_span);
    }
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FAMILY, 20))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    let (lx, ly) = (panel.log_x, panel.log_y);
    let (sx, sy) = (x1 - x0, y1 - y0);
    let fx = move |v: &f64| tick_label(*v, lx, sx);
    let fy = move |v: &f64| tick_label(*v, ly, sy);
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style((FAMILY, 14))
        .axis_desc_style((FAMILY, 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(e)?;
    for (series, points) in panel.series.iter().zip(pts) {
        let c = color(series.color);
        match series.mark {
            Mark::Points => chart
                .draw_series(points.into_iter().map(|p| Circle::new(p, 3, c.filled())))
                .map_err(e)?
                .label(series.label.as_str())
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, c.filled())),
            Mark::Line => chart
                .draw_series(LineSeries::new(points, c.stroke_width(2)))
                .map_err(e)?
                .label(series.label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
                }),
            Mark::Dashed => chart
                .draw_series(DashedLineSeries::new(points, 6, 4, c.stroke_width(2)))
                .map_err(e)?
                .label(series.label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(1))
                }),
        };
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(180, 180, 180))
        .label_font((FAMILY, 14))
        .draw()
        .map_err(e)?;
    Ok(())
}

/// `n` points spaced evenly (or evenly in log when `log`) from `lo` to `hi`.
pub fn grid(lo: f64, hi: f64, n: usize, log: bool) -> Vec<f64> {
    let n = n.max(2);
    (0..n)
        .map(|i| {
            let f = i as f64 / (n - 1) as f64;
            if log && lo > 0.0 && hi > 0.0 {
                (lo.ln() + f * (hi.ln() - lo.ln())).exp()
            } else {
                lo + f * (hi - lo)
            }
        })
        .collect()
}
