//! The design's frame: the image the photo is resampled into and the design painted in,
//! `px_per_mm` pixels a millimetre around the design's footprint, and the mapping from
//! design millimetres to its pixels. Geometry only: registering a photo into it is
//! `register`'s, measuring in it `measure`'s.

/// The design's frame as an image: `px_per_mm` pixels a millimetre, `margin_mm` around
/// the footprint from `lo` to `hi`, image y running down (design y up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DesignFrame {
    /// Lower-left of the footprint, mm.
    pub lo: [f64; 2],
    /// Upper-right of the footprint, mm.
    pub hi: [f64; 2],
    /// Scale.
    pub px_per_mm: f64,
    /// Margin around the footprint, mm.
    pub margin_mm: f64,
}

impl DesignFrame {
    /// Image size, px.
    pub fn size(&self) -> (u32, u32) {
        let w = (self.hi[0] - self.lo[0] + 2.0 * self.margin_mm) * self.px_per_mm;
        let h = (self.hi[1] - self.lo[1] + 2.0 * self.margin_mm) * self.px_per_mm;
        (w.ceil() as u32, h.ceil() as u32)
    }
    /// Design point (mm) to frame pixel (continuous; pixel centres at +0.5).
    pub fn to_px(&self, p: [f64; 2]) -> [f64; 2] {
        [
            (p[0] - self.lo[0] + self.margin_mm) * self.px_per_mm,
            (self.hi[1] - p[1] + self.margin_mm) * self.px_per_mm,
        ]
    }
    /// The footprint's corners in frame pixels: top-left, top-right, bottom-right,
    /// bottom-left.
    pub fn corners(&self) -> [[f64; 2]; 4] {
        [
            self.to_px([self.lo[0], self.hi[1]]),
            self.to_px([self.hi[0], self.hi[1]]),
            self.to_px([self.hi[0], self.lo[1]]),
            self.to_px([self.lo[0], self.lo[1]]),
        ]
    }
}
