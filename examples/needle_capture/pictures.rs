//! The error colour map of `needle_capture`'s preview renders (its scale is drawn as a colour
//! bar by `example_kit::plot::with_colour_bar`; the line plots are `example_kit::plot`
//! charts).

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
