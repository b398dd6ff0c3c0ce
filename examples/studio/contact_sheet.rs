//! The contact sheet of one captured frame and the picture helpers it shares.

use std::path::Path;

use dynamic_shapes::core::image::{
    normals_rgb8, write_depth_png16, write_mask_png, DepthEncoding, GrayF32Image, Mask,
};
use dynamic_shapes::core::raster::NO_TRIANGLE;
use dynamic_shapes_studio::shading::srgb8;
use dynamic_shapes_studio::{CaptureFrame, Performer, ViewTruth};
use example_kit::plot::{self as kplot, ColourBar};
use image::imageops::{resize, FilterType};
use image::{Rgb, Rgb32FImage, RgbImage};

use crate::AnyResult;

/// Tile size of the contact sheet, px.
const TILE: (u32, u32) = (240, 180);

/// A false-colour ramp (dark blue → cyan → yellow → red) of `t ∈ [0, 1]`.
pub(crate) fn ramp(t: f64) -> [f64; 3] {
    let stops = [
        [0.05, 0.05, 0.5],
        [0.0, 0.7, 0.9],
        [0.95, 0.9, 0.1],
        [0.9, 0.1, 0.05],
    ];
    let x = t.clamp(0.0, 1.0) * (stops.len() - 1) as f64;
    let i = (x.floor() as usize).min(stops.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|c| stops[i][c] * (1.0 - f) + stops[i + 1][c] * f)
}

/// Depth as grey (near bright), scaled over the covered pixels of the view.
pub(crate) fn depth_picture(depth_m: &GrayF32Image) -> RgbImage {
    let covered = depth_m.as_raw().iter().filter(|d| d.is_finite());
    let (lo, hi) = covered.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &d| {
        (a.min(d), b.max(d))
    });
    let mut img = RgbImage::new(depth_m.width(), depth_m.height());
    for (p, &d) in img.pixels_mut().zip(depth_m.as_raw()) {
        if d.is_finite() {
            let g = (255.0 * (1.0 - 0.8 * (d - lo) / (hi - lo).max(1e-6))) as u8;
            *p = Rgb([g, g, g]);
        }
    }
    img
}

/// Per-pixel |truth − LBS| (mm) interpolated from the vertices with the barycentrics, coloured
/// on a false-colour scale from 0 to `max_mm` and shaded by the normal for shape.
pub(crate) fn difference_picture(
    v: &ViewTruth,
    faces: &[[u32; 3]],
    dist_mm: &[f64],
    max_mm: f64,
) -> AnyResult<RgbImage> {
    let ids = v
        .triangle_ids
        .as_ref()
        .ok_or("the spec renders triangle ids")?;
    let bary = v
        .barycentric
        .as_ref()
        .ok_or("the spec renders barycentrics")?;
    let normals = v
        .normals_camera
        .as_ref()
        .ok_or("the spec renders normals")?;
    let mut img = RgbImage::new(ids.width(), ids.height());
    for (x, y, p) in img.enumerate_pixels_mut() {
        let t = ids.get_pixel(x, y)[0];
        if t == NO_TRIANGLE {
            continue;
        }
        let f = faces[t as usize];
        let [b1, b2] = bary.get_pixel(x, y).0.map(f64::from);
        let d = dist_mm[f[0] as usize] * (1.0 - b1 - b2)
            + dist_mm[f[1] as usize] * b1
            + dist_mm[f[2] as usize] * b2;
        let light = 0.45 + 0.55 * f64::from(-normals.get_pixel(x, y)[2]).clamp(0.0, 1.0);
        *p = Rgb(ramp(d / max_mm).map(|c| (255.0 * c * light) as u8));
    }
    Ok(img)
}

/// Exposure mapping the 99th percentile of the covered radiance to 0.9.
pub(crate) fn exposure(views: &[&Rgb32FImage], masks: &[&Mask]) -> f32 {
    let mut lum: Vec<f32> = views
        .iter()
        .zip(masks)
        .flat_map(|(s, m)| {
            s.pixels()
                .zip(m.iter())
                .filter(|(_, m)| *m)
                .map(|(r, _)| r[0].max(r[1]).max(r[2]))
        })
        .collect();
    if lum.is_empty() {
        return 1.0;
    }
    lum.sort_by(f32::total_cmp);
    let p99 = lum[lum.len() * 99 / 100];
    if p99 > 0.0 {
        0.9 / p99
    } else {
        1.0
    }
}

/// The silhouette's bounding box, padded by 10 % and widened to the tile's aspect ratio,
/// clipped to the image: `(x, y, width, height)` (the whole image for an empty mask).
pub(crate) fn crop_box(mask: &Mask) -> (u32, u32, u32, u32) {
    let (w, h) = mask.dimensions();
    let Some(b) = mask.bounding_box() else {
        return (0, 0, w, h);
    };
    let (lo, hi) = ((b.x_min, b.y_min), (b.x_max, b.y_max));
    let aspect = f64::from(TILE.0) / f64::from(TILE.1);
    let (cx, cy) = (f64::from(lo.0 + hi.0) / 2.0, f64::from(lo.1 + hi.1) / 2.0);
    let mut bh = f64::from(hi.1 - lo.1 + 1) * 1.2;
    let bw = (f64::from(hi.0 - lo.0 + 1) * 1.2).max(bh * aspect);
    bh = bw / aspect;
    let (bw, bh) = (bw.min(f64::from(w)), bh.min(f64::from(h)));
    let x0 = (cx - bw / 2.0).clamp(0.0, f64::from(w) - bw);
    let y0 = (cy - bh / 2.0).clamp(0.0, f64::from(h) - bh);
    (x0 as u32, y0 as u32, (bw as u32).max(1), (bh as u32).max(1))
}

/// Writes the contact sheet and camera 0's full-size pictures; returns the frame's largest
/// |truth − LBS|, mm.
pub(crate) fn write_pictures(
    performer: &Performer,
    frame: &CaptureFrame,
    out: &Path,
) -> AnyResult<f64> {
    let dist_mm: Vec<f64> = frame
        .truth
        .nonskinning_m()
        .iter()
        .map(|d| d * 1e3)
        .collect();
    let max_mm = dist_mm.iter().copied().fold(0.0, f64::max).max(1e-3);
    let faces = &performer.template.faces;
    let shaded: Vec<&Rgb32FImage> = frame
        .observations
        .iter()
        .map(|o| o.shaded.as_ref().ok_or("the spec has lighting"))
        .collect::<Result<_, _>>()?;
    let masks: Vec<&Mask> = frame.observations.iter().map(|o| &o.mask).collect();
    let exp = exposure(&shaded, &masks);
    let n = frame.observations.len() as u32;
    let mut sheet = RgbImage::new(TILE.0 * n, TILE.1 * 5);
    for (c, (o, v)) in frame
        .observations
        .iter()
        .zip(&frame.truth.views)
        .enumerate()
    {
        let mask_rgb = image::DynamicImage::ImageLuma8(o.mask.to_gray()).to_rgb8();
        let depth = v.depth_m.as_ref().ok_or("the spec renders depth")?;
        let normals = v
            .normals_camera
            .as_ref()
            .ok_or("the spec renders normals")?;
        let pictures = [
            mask_rgb,
            depth_picture(depth),
            normals_rgb8(normals),
            srgb8(shaded[c], exp),
            difference_picture(v, faces, &dist_mm, max_mm)?,
        ];
        let (x0, y0, cw, ch) = crop_box(&o.mask);
        for (row, pic) in pictures.iter().enumerate() {
            let cropped = image::imageops::crop_imm(pic, x0, y0, cw, ch).to_image();
            let tile = resize(&cropped, TILE.0, TILE.1, FilterType::Triangle);
            image::imageops::replace(
                &mut sheet,
                &tile,
                (c as u32 * TILE.0).into(),
                (row as u32 * TILE.1).into(),
            );
        }
        if c == 0 {
            write_mask_png(&o.mask, out.join("cam0_silhouette.png"))?;
            let mm = DepthEncoding {
                scale_m: 1e-3,
                offset_m: 0.0,
            };
            write_depth_png16(depth, out.join("cam0_depth_mm.png"), &mm)?;
            pictures[1].save(out.join("cam0_depth_grey.png"))?;
            pictures[2].save(out.join("cam0_normals.png"))?;
            pictures[3].save(out.join("cam0_shaded.png"))?;
            pictures[4].save(out.join("cam0_lbs_vs_truth.png"))?;
        }
    }
    let sheet = kplot::label_rows(
        &sheet,
        &["silhouette", "depth", "normals", "shaded", "|truth − LBS|"],
        110,
    )?;
    let ramp_u8 = |t: f64| ramp(t).map(|c| (255.0 * c) as u8);
    let sheet = kplot::with_colour_bar(
        &sheet,
        &ColourBar {
            label: "|truth − LBS| (mm), last row",
            min: 0.0,
            max: max_mm,
            ramp: &ramp_u8,
            note: None,
        },
    )?;
    let sheet = kplot::titled(
        &sheet,
        "Studio capture of the frame of largest non-skinning deformation",
        Some(&format!(
            "columns: the {n} ring cameras, each cropped to its silhouette; depth near = bright; normals in camera space"
        )),
    )?;
    kplot::save(&sheet, out.join("contact_sheet.png"))?;
    Ok(max_mm)
}
