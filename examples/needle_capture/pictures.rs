//! The PNGs of `needle_capture`: line plots (error against N, silhouette error against each
//! reconstruction parameter as in Sand 2003 Figure 11) drawn on a white canvas, and an error
//! colour map for the preview renders.

use image::{Rgb, RgbImage};

type Res<T> = Result<T, Box<dyn std::error::Error>>;

/// One polyline of a [`Plot`] (x in data units, possibly log-scaled by the plot).
pub struct Series {
    pub points: Vec<(f64, f64)>,
    pub colour: [u8; 3],
    /// Dashed and without markers (a baseline).
    pub dashed: bool,
}

/// A small line plot: axes, polylines with square markers, no text (the colours are
/// explained in the example's docs).
pub struct Plot {
    pub width: u32,
    pub height: u32,
    pub log_x: bool,
    pub series: Vec<Series>,
}

impl Plot {
    /// Draws the plot; the y axis starts at 0, x spans the data.
    pub fn draw(&self) -> RgbImage {
        let mut img = RgbImage::from_pixel(self.width, self.height, Rgb([255, 255, 255]));
        let tx = |x: f64| if self.log_x { x.max(1e-12).log10() } else { x };
        let finite = || {
            self.series
                .iter()
                .flat_map(|s| s.points.iter().copied())
                .filter(|p| p.0.is_finite() && p.1.is_finite())
        };
        let (mut x0, mut x1) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut ymax = 0.0f64;
        for (x, y) in finite() {
            x0 = x0.min(tx(x));
            x1 = x1.max(tx(x));
            ymax = ymax.max(y);
        }
        if x0 >= x1 || !x0.is_finite() || !x1.is_finite() {
            // One point or none: a unit-wide range around it.
            let c = if x0.is_finite() { x0 } else { 0.0 };
            (x0, x1) = (c - 0.5, c + 0.5);
        }
        let ymax = if ymax > 0.0 { ymax * 1.1 } else { 1.0 };
        let (l, r, b, t) = (
            30.0,
            self.width as f64 - 12.0,
            self.height as f64 - 20.0,
            12.0,
        );
        let px = |x: f64| l + (r - l) * (tx(x) - x0) / (x1 - x0);
        let py = |y: f64| b + (t - b) * y / ymax;
        let black = [0, 0, 0];
        line(&mut img, (l, b), (r, b), black, false);
        line(&mut img, (l, b), (l, t), black, false);
        for s in &self.series {
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .map(|&(x, y)| (px(x), py(y)))
                .collect();
            if s.dashed {
                // A baseline: a horizontal dash across the plot at its (first) value.
                if let Some(&(_, y)) = pts.first() {
                    line(&mut img, (l, y), (r, y), s.colour, true);
                }
                continue;
            }
            for w in pts.windows(2) {
                line(&mut img, w[0], w[1], s.colour, false);
            }
            for &(x, y) in &pts {
                for dx in -2..=2 {
                    for dy in -2..=2 {
                        put(&mut img, x + dx as f64, y + dy as f64, s.colour);
                    }
                }
            }
        }
        img
    }
}

/// Panels side by side (same height), e.g. one plot per parameter.
pub fn side_by_side(panels: &[RgbImage]) -> Res<RgbImage> {
    let h = panels.iter().map(|p| p.height()).max().ok_or("no panels")?;
    let w = panels.iter().map(|p| p.width()).sum();
    let mut out = RgbImage::from_pixel(w, h, Rgb([255, 255, 255]));
    let mut x0 = 0;
    for p in panels {
        image::imageops::overlay(&mut out, p, x0 as i64, 0);
        x0 += p.width();
    }
    Ok(out)
}

/// Error colour map: blue (0) → green → yellow → red (≥ `max`); grey for no value.
pub fn error_colour(e: Option<f64>, max: f64) -> [u8; 3] {
    let Some(e) = e.filter(|e| e.is_finite()) else {
        return [170, 170, 170];
    };
    let t = (e / max).clamp(0.0, 1.0);
    let stops = [
        (0.0, [40.0, 80.0, 230.0]),
        (0.33, [40.0, 200.0, 80.0]),
        (0.66, [240.0, 220.0, 40.0]),
        (1.0, [230.0, 30.0, 30.0]),
    ];
    let k = stops.windows(2).position(|w| t <= w[1].0).unwrap_or(2);
    let ((t0, c0), (t1, c1)) = (stops[k], stops[k + 1]);
    let u = (t - t0) / (t1 - t0);
    [0, 1, 2].map(|i| (c0[i] + (c1[i] - c0[i]) * u) as u8)
}

fn put(img: &mut RgbImage, x: f64, y: f64, c: [u8; 3]) {
    if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, Rgb(c));
    }
}

fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), c: [u8; 3], dashed: bool) {
    let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()) as usize).max(1);
    for i in 0..=steps {
        if dashed && (i / 6) % 2 == 1 {
            continue;
        }
        let t = i as f64 / steps as f64;
        put(img, a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t, c);
    }
}
