//! Epipolar planes: each view's set-up for a pair (rays, surface points, the other surface
//! rendered in) and the samples of a plane's line in an image.

use skin_core::math::DVec3;

use crate::{mesh_proxy_depth, DepthMap, Error, Result};

use super::mesh::{mesh_of_points, points_of};
use super::views::MatchView;

/// A sampled epipolar line: pixel indices and their world rays, ordered by angle to the
/// baseline.
pub(super) struct Line {
    pub(super) pixels: Vec<usize>,
    pub(super) rays: Vec<DVec3>,
}

/// Per-view data computed once per pair.
pub(super) struct Prepared<'a> {
    pub(super) view: MatchView<'a>,
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) centre: DVec3,
    /// World ray direction per pixel.
    pub(super) rays: &'a [DVec3],
    /// Surface point per pixel (NaN-free only where the surface exists).
    pub(super) points: Vec<Option<DVec3>>,
    /// The other view's surface rendered into this camera, as points.
    pub(super) other_points: Vec<Option<DVec3>>,
    pub(super) guide: &'a DepthMap,
    /// Coarse-to-fine: per pixel, the depth interval along its ray around the coarse path
    /// (`NaN` where the coarse path gave none).
    pub(super) narrow: Option<Vec<(f64, f64)>>,
}

/// The input checks of one view: maps of the camera's size, an undistorted camera.
pub(super) fn check_view(view: &MatchView<'_>) -> Result<()> {
    let cam = view.camera;
    view.surface.check_camera(cam)?;
    if let Some(g) = view.guide {
        g.check_camera(cam)?;
    }
    if cam.distortion.k1 != 0.0 {
        return Err(Error::InvalidParam {
            name: "camera",
            reason: "matching needs undistorted cameras (undistort the images first)".into(),
        });
    }
    Ok(())
}

impl<'a> Prepared<'a> {
    /// The view's set-up: `rays` are its world rays, `other_points` the other view's surface
    /// points (both computed once per pair and shared by the two sides).
    pub(super) fn new(
        view: MatchView<'a>,
        rays: &'a [DVec3],
        points: Vec<Option<DVec3>>,
        (other, other_points): (&MatchView<'_>, &[Option<DVec3>]),
        jump_m: f64,
    ) -> Result<Self> {
        let cam = view.camera;
        let other_mesh = mesh_of_points(other.surface, other_points, jump_m)?;
        let other_depth = mesh_proxy_depth(cam, &other_mesh)?;
        let other_points = points_of(cam, &other_depth, rays);
        Ok(Self {
            view,
            width: cam.intrinsics.width,
            height: cam.intrinsics.height,
            centre: cam.centre(),
            rays,
            points,
            other_points,
            guide: view.guide.unwrap_or(view.surface),
            narrow: None,
        })
    }

    /// The samples of the plane with world normal `m`: integer pixels on the image line that
    /// have a surface, ordered by the angle of their ray to `baseline`.
    pub(super) fn line(&self, m: DVec3, baseline: DVec3) -> Line {
        let cam = self.view.camera;
        let k = &cam.intrinsics;
        let mc = cam.camera_from_world().transform_vector3(m);
        let l = DVec3::new(
            mc.x / k.fx,
            mc.y / k.fy,
            mc.z - k.cx * mc.x / k.fx - k.cy * mc.y / k.fy,
        );
        let (w, h) = (self.width as i64, self.height as i64);
        let mut pixels = Vec::new();
        let mut push = |x: i64, y: i64| {
            if x >= 0 && y >= 0 && x < w && y < h {
                let i = (y * w + x) as usize;
                if self.points[i].is_some() && pixels.last() != Some(&i) {
                    pixels.push(i);
                }
            }
        };
        if l.y.abs() >= l.x.abs() {
            for x in 0..w {
                let y = -(l.x * x as f64 + l.z) / l.y;
                push(x, y.round() as i64);
            }
        } else {
            for y in 0..h {
                let x = -(l.y * y as f64 + l.z) / l.x;
                push(x.round() as i64, y);
            }
        }
        let b = baseline.normalize();
        let mut keyed: Vec<(f64, usize)> = pixels
            .into_iter()
            .map(|i| (self.rays[i].dot(b), i))
            .collect();
        // Decreasing cosine = increasing angle to the baseline.
        keyed.sort_by(|p, q| q.0.total_cmp(&p.0));
        keyed.dedup_by_key(|k| k.1);
        Line {
            rays: keyed.iter().map(|k| self.rays[k.1]).collect(),
            pixels: keyed.into_iter().map(|k| k.1).collect(),
        }
    }

    /// The coarse path's depth interval at a pixel, if any.
    pub(super) fn narrow(&self, pixel: usize) -> Option<(f64, f64)> {
        let (lo, hi) = self.narrow.as_ref()?[pixel];
        (!lo.is_nan()).then_some((lo, hi))
    }

    pub(super) fn pixel_footprint(&self, depth: f64) -> f64 {
        depth / self.view.camera.intrinsics.fx
    }

    /// Nearest pixel of a world point's projection.
    pub(super) fn pixel_of(&self, p: DVec3) -> Option<usize> {
        let px = self.view.camera.project(p).ok()?;
        let (x, y) = (px.x.round(), px.y.round());
        (x >= 0.0 && y >= 0.0 && x < f64::from(self.width) && y < f64::from(self.height))
            .then(|| y as usize * self.width as usize + x as usize)
    }

    pub(super) fn window(
        &self,
        centre: usize,
        half: i64,
    ) -> impl Iterator<Item = Option<usize>> + '_ {
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let (cx, cy) = ((centre % w as usize) as i64, (centre / w as usize) as i64);
        (-half..=half).flat_map(move |dy| {
            (-half..=half).map(move |dx| {
                let (x, y) = (cx + dx, cy + dy);
                (x >= 0 && y >= 0 && x < w && y < h).then_some((y * w + x) as usize)
            })
        })
    }

    pub(super) fn stack_at(&self, pixel: usize, out: &mut Vec<f64>, from: usize) -> bool {
        let Some(images) = self.view.images else {
            return false;
        };
        let (x, y) = (pixel as u32 % self.width, pixel as u32 / self.width);
        for im in &images[from.min(images.len())..] {
            out.push(f64::from(im.get_pixel(x, y).0[0]));
        }
        true
    }
}
