//! Pictures that explain themselves: line and scatter charts with a title, axis labels with
//! units and a legend, false-colour images with a colour bar, and titled or labelled
//! compositions of pictures. Drawn with `plotters` into `image` 0.25 buffers (the bitmap
//! backend without its encoder, which would pull a second `image`), with the bundled DejaVu
//! Sans font (`fonts/`, Bitstream Vera licence) registered through `ab_glyph`: no system
//! font lookup.

use std::path::Path;
use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, ScaleFont};
use image::{Rgb, RgbImage};
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::Pos;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{BackendColor, BackendCoord, BackendTextStyle, DrawingErrorKind};

use crate::{Error, Result};

/// DejaVu Sans 2.37 (see `fonts/SOURCE.md`).
static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");
/// The family name the charts ask for.
const FAMILY: &str = "sans-serif";

/// Registers the bundled font once; every drawing function calls it.
fn font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(Error::Plot("the bundled font does not parse".into()))
    }
}

fn plot_err(e: impl std::fmt::Display) -> Error {
    Error::Plot(e.to_string())
}

/// The bundled font for [`Backend`]'s own text drawing.
fn font_ref() -> Result<&'static FontRef<'static>> {
    static FONT_REF: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT_REF
        .get_or_init(|| FontRef::try_from_slice(FONT).ok())
        .as_ref()
        .ok_or(Error::Plot("the bundled font does not parse".into()))
}

/// The bitmap backend with its text drawn here: plotters 0.3.7's `ab_glyph` text puts the
/// baseline at half the font size (full stops float mid-line) and ignores glyph bearings
/// (spaces vanish). Everything else is the bitmap backend's.
pub struct Backend<'a> {
    inner: BitMapBackend<'a>,
    font: &'static FontRef<'static>,
}

impl Backend<'_> {
    /// Width of `text` at `size` px, and the line height.
    fn layout(&self, text: &str, size: f64) -> (i32, i32) {
        let f = self.font.as_scaled(size as f32);
        let mut w = 0.0f32;
        let mut prev = None;
        for c in text.chars() {
            let g = f.glyph_id(c);
            if let Some(p) = prev {
                w += f.kern(p, g);
            }
            w += f.h_advance(g);
            prev = Some(g);
        }
        (w.ceil() as i32, (f.ascent() - f.descent()).ceil() as i32)
    }
}

type BErr = <BitMapBackend<'static> as DrawingBackend>::ErrorType;

impl DrawingBackend for Backend<'_> {
    type ErrorType = BErr;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }
    fn ensure_prepared(&mut self) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.ensure_prepared()
    }
    fn present(&mut self) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.present()
    }
    fn draw_pixel(
        &mut self,
        p: BackendCoord,
        c: BackendColor,
    ) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.draw_pixel(p, c)
    }
    fn draw_line<S: plotters_backend::BackendStyle>(
        &mut self,
        a: BackendCoord,
        b: BackendCoord,
        s: &S,
    ) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.draw_line(a, b, s)
    }
    fn draw_rect<S: plotters_backend::BackendStyle>(
        &mut self,
        a: BackendCoord,
        b: BackendCoord,
        s: &S,
        fill: bool,
    ) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.draw_rect(a, b, s, fill)
    }
    fn draw_path<S: plotters_backend::BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        s: &S,
    ) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.draw_path(path, s)
    }
    fn draw_circle<S: plotters_backend::BackendStyle>(
        &mut self,
        c: BackendCoord,
        r: u32,
        s: &S,
        fill: bool,
    ) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.draw_circle(c, r, s, fill)
    }
    fn fill_polygon<S: plotters_backend::BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        v: I,
        s: &S,
    ) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.fill_polygon(v, s)
    }
    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        size: (u32, u32),
        src: &[u8],
    ) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        self.inner.blit_bitmap(pos, size, src)
    }
    fn estimate_text_size<T: BackendTextStyle>(
        &self,
        text: &str,
        style: &T,
    ) -> std::result::Result<(u32, u32), DrawingErrorKind<BErr>> {
        let (w, h) = self.layout(text, style.size());
        Ok((w.max(0) as u32, h.max(0) as u32))
    }
    fn draw_text<T: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &T,
        pos: BackendCoord,
    ) -> std::result::Result<(), DrawingErrorKind<BErr>> {
        let colour = style.color();
        if colour.alpha == 0.0 {
            return Ok(());
        }
        let (width, height) = self.layout(text, style.size());
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Right => -width,
            HPos::Center => -width / 2,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -height / 2,
            VPos::Bottom => -height,
        };
        let trans = style.transform();
        let (w, h) = self.get_size();
        let f = self.font.as_scaled(style.size() as f32);
        let mut pen = 0.0f32;
        let mut prev = None;
        let mut pixels = Vec::new();
        for c in text.chars() {
            let id = f.glyph_id(c);
            if let Some(p) = prev {
                pen += f.kern(p, id);
            }
            prev = Some(id);
            let glyph = id.with_scale_and_position(f.scale(), ab_glyph::point(pen, f.ascent()));
            if let Some(q) = f.outline_glyph(glyph) {
                let b = q.px_bounds();
                q.draw(|x, y, cov| {
                    pixels.push((b.min.x as i32 + x as i32, b.min.y as i32 + y as i32, cov))
                });
            }
            pen += f.h_advance(id);
        }
        for (x, y, cov) in pixels {
            let (x, y) = trans.transform(x + dx, y + dy);
            let (x, y) = (pos.0 + x, pos.1 + y);
            if x >= 0 && y >= 0 && x < w as i32 && y < h as i32 && cov > 0.0 {
                let c = BackendColor {
                    alpha: colour.alpha * f64::from(cov.min(1.0)),
                    rgb: colour.rgb,
                };
                self.inner.draw_pixel((x, y), c)?;
            }
        }
        Ok(())
    }
}

type Area<'a> = DrawingArea<Backend<'a>, Shift>;

/// Runs `f` on a drawing area over `img` (RGB, drawn in place).
fn draw_on(img: &mut RgbImage, f: impl FnOnce(&Area) -> Result<()>) -> Result<()> {
    font()?;
    let font = font_ref()?;
    let (w, h) = img.dimensions();
    let root = Backend {
        inner: BitMapBackend::with_buffer(img.as_mut(), (w, h)),
        font,
    }
    .into_drawing_area();
    f(&root)?;
    root.present().map_err(plot_err)?;
    Ok(())
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// A number for a tick label: up to 4 significant digits, no trailing zeros.
pub fn tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        return format!("{v:.2e}");
    }
    let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}

/// How a [`Series`] is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// A polyline.
    Line,
    /// A polyline with a marker at every point.
    LineMarkers,
    /// A dashed polyline (a baseline or reference).
    Dashed,
    /// Markers only (a scatter).
    Markers,
    /// Separate segments: points 0–1, 2–3, … (e.g. residual vectors).
    Segments,
}

/// One labelled set of points of a [`Chart`].
#[derive(Debug, Clone)]
pub struct Series {
    /// The legend entry.
    pub label: String,
    /// `[r, g, b]`.
    pub colour: [u8; 3],
    /// How it is drawn.
    pub style: Style,
    /// Points in data units.
    pub points: Vec<(f64, f64)>,
}

impl Series {
    /// A series of `style`.
    pub fn new(
        label: impl Into<String>,
        colour: [u8; 3],
        style: Style,
        points: Vec<(f64, f64)>,
    ) -> Self {
        Series {
            label: label.into(),
            colour,
            style,
            points,
        }
    }
}

/// Where the legend goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LegendPosition {
    /// Upper left corner of the plotting area.
    UpperLeft,
    /// Upper right corner.
    UpperRight,
    /// Lower left corner.
    LowerLeft,
    /// Lower right corner.
    LowerRight,
}

impl LegendPosition {
    fn plotters(self) -> SeriesLabelPosition {
        match self {
            LegendPosition::UpperLeft => SeriesLabelPosition::UpperLeft,
            LegendPosition::UpperRight => SeriesLabelPosition::UpperRight,
            LegendPosition::LowerLeft => SeriesLabelPosition::LowerLeft,
            LegendPosition::LowerRight => SeriesLabelPosition::LowerRight,
        }
    }
}

/// A 2-D chart: title, axis labels (with units, e.g. `"error (mm)"`), legend.
#[derive(Debug, Clone)]
pub struct Chart {
    /// Title above the chart.
    pub title: String,
    /// x axis label with its unit.
    pub x_label: String,
    /// y axis label with its unit.
    pub y_label: String,
    /// Size in pixels.
    pub size: (u32, u32),
    /// Logarithmic x axis.
    pub log_x: bool,
    /// The y axis starts at 0 (unless data go below).
    pub y_from_zero: bool,
    /// y grows downwards (image coordinates).
    pub y_down: bool,
    /// Fixed x range (data span otherwise).
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range (data span otherwise).
    pub y_range: Option<(f64, f64)>,
    /// Legend position.
    pub legend: LegendPosition,
    /// Marker radius, px.
    pub marker_px: u32,
    /// The data.
    pub series: Vec<Series>,
}

impl Chart {
    /// A 640×420 chart with linear axes, y from zero, legend at the upper right.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Chart {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            size: (640, 420),
            log_x: false,
            y_from_zero: true,
            y_down: false,
            x_range: None,
            y_range: None,
            legend: LegendPosition::UpperRight,
            marker_px: 4,
            series: Vec::new(),
        }
    }

    /// Adds a series.
    pub fn with(mut self, s: Series) -> Self {
        self.series.push(s);
        self
    }

    fn span(&self, pick: impl Fn(&(f64, f64)) -> f64, log: bool) -> Option<(f64, f64)> {
        let vals = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .map(pick)
            .filter(|v| v.is_finite() && (!log || *v > 0.0));
        let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        lo.is_finite().then_some((lo, hi))
    }

    /// Tick label of `v` on an axis spanning `span`: enough decimals to tell ticks apart.
    fn tick_in(v: f64, span: f64) -> String {
        if !(span.is_finite() && span > 0.0) || v == 0.0 {
            return tick(v);
        }
        let a = v.abs();
        if !(1e-3..1e6).contains(&a) {
            return tick(v);
        }
        let decimals = (1.0 - (span / 5.0).log10().floor()).clamp(0.0, 8.0) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            s
        }
    }

    /// Tick label of a log axis: only at 1, 2 and 5 × a power of ten (the others stay unlabelled).
    fn log_tick(v: f64) -> String {
        if v <= 0.0 || !v.is_finite() {
            return String::new();
        }
        let m = v / 10f64.powf(v.log10().floor());
        if [1.0, 2.0, 5.0, 10.0].iter().any(|k| (m - k).abs() < 1e-6) {
            tick(v)
        } else {
            String::new()
        }
    }

    /// Draws the chart.
    ///
    /// # Errors
    /// [`Error::Plot`] when plotters fails (e.g. a size of zero).
    pub fn draw(&self) -> Result<RgbImage> {
        let mut img =
            RgbImage::from_pixel(self.size.0.max(1), self.size.1.max(1), Rgb([255, 255, 255]));
        let (mut x0, mut x1) = self
            .x_range
            .or_else(|| self.span(|p| p.0, self.log_x))
            .unwrap_or((0.0, 1.0));
        if x1 <= x0 {
            (x0, x1) = if self.log_x {
                (x0 / 2.0, x0 * 2.0)
            } else {
                (x0 - 0.5, x1 + 0.5)
            };
        }
        let sign = if self.y_down { -1.0 } else { 1.0 };
        let (mut y0, mut y1) = match self.y_range {
            Some(r) => r,
            None => {
                let (lo, hi) = self.span(|p| p.1, false).unwrap_or((0.0, 1.0));
                let (lo, hi) = if self.y_from_zero {
                    (lo.min(0.0), hi.max(0.0))
                } else {
                    (lo, hi)
                };
                // A flat series gets a visible range around its value.
                let flat = hi - lo <= 1e-9 * hi.abs().max(lo.abs()).max(1e-12);
                let pad = if flat {
                    0.05 * hi.abs().max(1e-3)
                } else {
                    0.08 * (hi - lo)
                };
                (
                    if self.y_from_zero && lo >= 0.0 {
                        lo
                    } else {
                        lo - pad
                    },
                    hi + pad,
                )
            }
        };
        if y1 <= y0 {
            (y0, y1) = (y0 - 0.5, y1 + 0.5);
        }
        let y: RangedCoordf64 = if self.y_down {
            (-y1..-y0).into()
        } else {
            (y0..y1).into()
        };
        draw_on(&mut img, |root| {
            root.fill(&WHITE).map_err(plot_err)?;
            if self.log_x {
                self.draw_axes(root, (x0..x1).log_scale(), y, sign)
            } else {
                self.draw_axes(root, x0..x1, y, sign)
            }
        })?;
        Ok(img)
    }

    fn draw_axes<'b, X>(&self, root: &Area<'b>, x: X, y: RangedCoordf64, sign: f64) -> Result<()>
    where
        X: AsRangedCoord<Value = f64>,
        X::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        let y_span = {
            let r = y.range();
            r.end - r.start
        };
        let mut chart = ChartBuilder::on(root)
            .caption(&self.title, (FAMILY, 20))
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(78)
            .build_cartesian_2d(x, y)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .axis_desc_style((FAMILY, 15))
            .label_style((FAMILY, 13))
            .x_label_formatter(&|v| {
                if self.log_x {
                    Self::log_tick(*v)
                } else {
                    tick(*v)
                }
            })
            .y_label_formatter(&|v| Self::tick_in(sign * *v, y_span))
            .light_line_style(WHITE)
            .bold_line_style(RGBColor(215, 215, 215))
            .draw()
            .map_err(plot_err)?;
        for s in &self.series {
            let c = rgb(s.colour);
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .filter(|p| p.0.is_finite() && p.1.is_finite())
                .map(|&(a, b)| (a, sign * b))
                .collect();
            let stroke = c.stroke_width(2);
            let anno = match s.style {
                Style::Line | Style::LineMarkers => {
                    if s.style == Style::LineMarkers {
                        chart
                            .draw_series(
                                pts.iter()
                                    .map(|&p| Circle::new(p, self.marker_px, c.filled())),
                            )
                            .map_err(plot_err)?;
                    }
                    chart
                        .draw_series(LineSeries::new(pts.clone(), stroke))
                        .map_err(plot_err)?
                }
                Style::Dashed => chart
                    .draw_series(DashedLineSeries::new(pts.clone(), 8, 5, stroke))
                    .map_err(plot_err)?,
                Style::Markers => chart
                    .draw_series(
                        pts.iter()
                            .map(|&p| Circle::new(p, self.marker_px, c.filled())),
                    )
                    .map_err(plot_err)?,
                Style::Segments => chart
                    .draw_series(
                        pts.chunks_exact(2)
                            .map(|w| PathElement::new(vec![w[0], w[1]], c.stroke_width(1))),
                    )
                    .map_err(plot_err)?,
            };
            if s.label.is_empty() {
                continue;
            }
            let style = s.style;
            anno.label(&s.label).legend(
                move |(x, y)| -> DynElement<'static, Backend<'b>, (i32, i32)> {
                    match style {
                        Style::Markers => Circle::new((x + 10, y), 4, c.filled()).into_dyn(),
                        Style::Dashed => DashedPathElement::new(
                            vec![(x, y), (x + 22, y)],
                            5,
                            3,
                            c.stroke_width(2),
                        )
                        .into_dyn(),
                        _ => PathElement::new(vec![(x, y), (x + 22, y)], c.stroke_width(2))
                            .into_dyn(),
                    }
                },
            );
        }
        if self.series.iter().any(|s| !s.label.is_empty()) {
            chart
                .configure_series_labels()
                .position(self.legend.plotters())
                .label_font((FAMILY, 13))
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(150, 150, 150))
                .draw()
                .map_err(plot_err)?;
        }
        Ok(())
    }
}

/// Writes `text` centred in the box `(x, y, w, h)` of `img`.
fn text(root: &Area, s: &str, size: u32, (x, y, w, h): (i32, i32, i32, i32)) -> Result<()> {
    let style =
        TextStyle::from((FAMILY, size).into_font()).pos(Pos::new(HPos::Center, VPos::Center));
    root.draw_text(s, &style, (x + w / 2, y + h / 2))
        .map_err(plot_err)
}

/// Text scale of a picture `width` px wide: 1 up to 1100 px, then in proportion.
fn text_scale(width: u32) -> f64 {
    (f64::from(width) / 1100.0).max(1.0)
}

/// `img` with a title strip above it (and a subtitle line), text larger on wide pictures.
///
/// # Errors
/// [`Error::Plot`] when plotters fails.
pub fn titled(img: &RgbImage, title: &str, subtitle: Option<&str>) -> Result<RgbImage> {
    // Text grows with wide pictures so it stays readable when the picture is shown scaled down.
    let k = text_scale(img.width());
    let (t, st) = ((18.0 * k) as u32, (14.0 * k) as u32);
    let strip = if subtitle.is_some() {
        t + st + 24
    } else {
        t + 14
    };
    let w = img.width().max(8 * title.chars().count() as u32 + 20);
    let mut out = RgbImage::from_pixel(w, img.height() + strip, Rgb([255, 255, 255]));
    image::imageops::overlay(
        &mut out,
        img,
        i64::from((w - img.width()) / 2),
        i64::from(strip),
    );
    draw_on(&mut out, |root| {
        text(root, title, t, (0, 2, w as i32, t as i32 + 10))?;
        if let Some(s) = subtitle {
            text(root, s, st, (0, t as i32 + 12, w as i32, st as i32 + 8))?;
        }
        Ok(())
    })?;
    Ok(out)
}

/// `img` (rows of equal height `img.height() / labels.len()`) with a label column on the left.
///
/// # Errors
/// [`Error::Plot`] when plotters fails.
pub fn label_rows(img: &RgbImage, labels: &[&str], column_px: u32) -> Result<RgbImage> {
    let k = text_scale(img.width());
    let column_px = (column_px as f64 * k) as u32;
    let mut out = RgbImage::from_pixel(img.width() + column_px, img.height(), Rgb([255, 255, 255]));
    image::imageops::overlay(&mut out, img, i64::from(column_px), 0);
    let rh = img.height() as i32 / labels.len().max(1) as i32;
    draw_on(&mut out, |root| {
        for (i, l) in labels.iter().enumerate() {
            text(
                root,
                l,
                (14.0 * k) as u32,
                (0, i as i32 * rh, column_px as i32, rh),
            )?;
        }
        Ok(())
    })?;
    Ok(out)
}

/// Pictures side by side, top-aligned, on white.
///
/// # Errors
/// [`Error::Plot`] for no pictures.
pub fn side_by_side(panels: &[RgbImage]) -> Result<RgbImage> {
    let h = panels
        .iter()
        .map(RgbImage::height)
        .max()
        .ok_or(Error::Plot("no panels".into()))?;
    let w = panels.iter().map(RgbImage::width).sum();
    let mut out = RgbImage::from_pixel(w, h, Rgb([255, 255, 255]));
    let mut x0 = 0i64;
    for p in panels {
        image::imageops::overlay(&mut out, p, x0, 0);
        x0 += i64::from(p.width());
    }
    Ok(out)
}

/// Pictures one above the other, centred, on white.
///
/// # Errors
/// [`Error::Plot`] for no pictures.
pub fn stacked(rows: &[RgbImage]) -> Result<RgbImage> {
    let w = rows
        .iter()
        .map(RgbImage::width)
        .max()
        .ok_or(Error::Plot("no rows".into()))?;
    let h = rows.iter().map(RgbImage::height).sum();
    let mut out = RgbImage::from_pixel(w, h, Rgb([255, 255, 255]));
    let mut y0 = 0i64;
    for r in rows {
        image::imageops::overlay(&mut out, r, i64::from((w - r.width()) / 2), y0);
        y0 += i64::from(r.height());
    }
    Ok(out)
}

/// Error colour map: blue (0) → green → yellow → red (≥ `max`); grey for no value (pair it
/// with a [`ColourBar`] whose ramp is `|t| error_colour(Some(t * max), max)`).
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

/// The scale of a false-colour picture.
pub struct ColourBar<'a> {
    /// What the colours measure, with the unit, e.g. `"needle error (mm)"`.
    pub label: &'a str,
    /// Value of the bottom colour.
    pub min: f64,
    /// Value of the top colour (values above are drawn in it: say so in `note`).
    pub max: f64,
    /// Colour of `t ∈ [0, 1]` (`min` → `max`).
    pub ramp: &'a dyn Fn(f64) -> [u8; 3],
    /// A line under the bar, e.g. `"grey: not scored"`.
    pub note: Option<&'a str>,
}

/// `img` with a colour bar (ticks in the bar's unit) on its right.
///
/// # Errors
/// [`Error::Plot`] when plotters fails.
pub fn with_colour_bar(img: &RgbImage, bar: &ColourBar) -> Result<RgbImage> {
    let k = text_scale(img.width().max(img.height() * 3 / 2));
    let px = |v: f64| (v * k) as u32;
    let bw = px(150.0);
    let h = img.height().max(240);
    let mut out = RgbImage::from_pixel(img.width() + bw, h, Rgb([255, 255, 255]));
    image::imageops::overlay(&mut out, img, 0, i64::from((h - img.height()) / 2));
    let (lo, hi) = if bar.max > bar.min {
        (bar.min, bar.max)
    } else {
        (bar.min, bar.min + 1.0)
    };
    draw_on(&mut out, |root| {
        let (_, right) = root.split_horizontally(img.width());
        let note_h = bar
            .note
            .map_or(0, |n| px(16.0) * n.split("; ").count() as u32 + 12);
        let (area, note) = right.split_vertically(h - note_h);
        let mut chart = ChartBuilder::on(&area)
            .margin_top(px(20.0))
            .margin_bottom(px(14.0))
            .margin_right(px(42.0))
            .y_label_area_size(px(62.0))
            .build_cartesian_2d(0.0..1.0, lo..hi)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .disable_y_mesh()
            .disable_x_axis()
            .y_desc(bar.label)
            .axis_desc_style((FAMILY, px(14.0)))
            .label_style((FAMILY, px(12.0)))
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(plot_err)?;
        let steps = 100;
        chart
            .draw_series((0..steps).map(|i| {
                let t0 = i as f64 / steps as f64;
                let t1 = (i + 1) as f64 / steps as f64;
                let c = (bar.ramp)((t0 + t1) / 2.0);
                Rectangle::new(
                    [(0.0, lo + (hi - lo) * t0), (1.0, lo + (hi - lo) * t1)],
                    rgb(c).filled(),
                )
            }))
            .map_err(plot_err)?;
        if let Some(n) = bar.note {
            let (w, _) = note.dim_in_pixel();
            for (i, line) in n.split("; ").enumerate() {
                let lh = px(16.0) as i32;
                text(&note, line, px(12.0), (0, lh * i as i32, w as i32, lh))?;
            }
        }
        Ok(())
    })?;
    Ok(out)
}

/// Saves `img` as PNG (with `image` 0.25).
///
/// # Errors
/// [`Error::Image`] when writing fails.
pub fn save(img: &RgbImage, path: impl AsRef<Path>) -> Result<()> {
    img.save(path.as_ref())
        .map_err(|e| Error::Image(format!("{}: {e}", path.as_ref().display())))
}
