//! §3.2.2 data-driven normals, calibration: a grey diffuse sphere of known geometry seen under
//! the patterns gives, per camera, pairs (key `k/‖k‖`, camera-frame normal) stored in a
//! kd-tree ([`LookupTable`]); §3.2.3: spheres at several heights, interpolated linearly
//! between the two nearest ([`HeightCalibration`]).

use std::num::NonZero;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use skin_core::camera::Camera;
use skin_core::math::{DVec2, DVec3};

use crate::patterns::{key, Exposure, PatternImages};
use crate::{Error, Result};

/// A calibration sphere: centre (world frame, m) and radius (m).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationSphere {
    /// Centre, world frame, m.
    pub centre: DVec3,
    /// Radius, m.
    pub radius_m: f64,
}

/// Options of the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CalibrationParams {
    /// Exposure of the calibration images.
    pub exposure: Exposure,
    /// Pixels are used when their ray meets the sphere shrunk to this fraction of its radius
    /// (drops the rim, where a pixel mixes sphere and background). Default: 0.97 (not in the
    /// thesis).
    pub rim_fraction: f64,
    /// Fewest usable sphere pixels per camera. Default: 50 (not in the thesis).
    pub min_samples: usize,
}

impl Default for CalibrationParams {
    fn default() -> Self {
        Self {
            exposure: Exposure::default(),
            rim_fraction: 0.97,
            min_samples: 50,
        }
    }
}

/// The lookup of one camera and one sphere: normalised keys and camera-frame normals in a
/// kd-tree, plus the sphere's height (world `up` component of its centre, m).
pub struct LookupTable {
    keys: Vec<[f64; 3]>,
    normals: Vec<DVec3>,
    tree: ImmutableKdTree<f64, 3>,
    height_m: f64,
}

impl std::fmt::Debug for LookupTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "LookupTable({} samples at height {} m)",
            self.keys.len(),
            self.height_m
        )
    }
}

impl LookupTable {
    /// Builds the table of `camera` from its images of `sphere` under the patterns; `up`
    /// (world) defines the sphere's height.
    ///
    /// # Errors
    /// [`Error::OutOfView`] if part of the sphere's outline is outside the image (or behind
    /// the camera); [`Error::SizeMismatch`] if the images do not have the camera's size;
    /// [`Error::Empty`] with fewer than `min_samples` usable pixels; invalid params.
    pub fn from_sphere(
        camera: &Camera,
        sphere: &CalibrationSphere,
        images: &PatternImages,
        up: DVec3,
        params: &CalibrationParams,
    ) -> Result<Self> {
        params.exposure.validate()?;
        skin_core::check::positive("sphere radius_m", sphere.radius_m)?;
        skin_core::check::in_range("rim_fraction", params.rim_fraction, 0.0..=1.0)?;
        let k = &camera.intrinsics;
        if (images.width(), images.height()) != (k.width, k.height) {
            return Err(Error::SizeMismatch {
                what: "calibration images vs camera pixels",
                expected: (k.width * k.height) as usize,
                got: (images.width() * images.height()) as usize,
            });
        }
        check_in_view(camera, sphere)?;
        let cam_from_world = camera.camera_from_world();
        let r_in = sphere.radius_m * params.rim_fraction;
        let w = images.width() as usize;
        let samples: Vec<([f64; 3], DVec3)> = (0..w * images.height() as usize)
            .into_par_iter()
            .filter_map(|i| {
                let px = DVec2::new((i % w) as f64, (i / w) as f64);
                let ray = camera.ray(px).ok()?;
                // Ray–sphere: |o + t d − c|² = r², d unit.
                let oc = ray.origin - sphere.centre;
                let b = oc.dot(ray.direction);
                let c_in = oc.length_squared() - r_in * r_in;
                if b * b - c_in <= 0.0 {
                    return None;
                }
                let c = oc.length_squared() - sphere.radius_m * sphere.radius_m;
                let t = -b - (b * b - c).max(0.0).sqrt();
                let n_world = (ray.origin + ray.direction * t - sphere.centre).normalize();
                let inten = images.pixel(i);
                let brightest = inten.iter().copied().fold(f32::MIN, f32::max);
                if !params.exposure.trusted(inten[3], brightest) {
                    return None;
                }
                let kv = key(&inten);
                let kn = kv.try_normalize()?;
                Some((kn.to_array(), cam_from_world.transform_vector3(n_world)))
            })
            .collect();
        if samples.len() < params.min_samples.max(1) {
            return Err(Error::Empty {
                what: "usable calibration-sphere pixels (fewer than min_samples)",
            });
        }
        let (keys, normals) = samples.into_iter().unzip();
        Self::from_samples(keys, normals, sphere.centre.dot(up))
    }

    fn from_samples(keys: Vec<[f64; 3]>, normals: Vec<DVec3>, height_m: f64) -> Result<Self> {
        let tree = ImmutableKdTree::new_from_slice(&keys).map_err(|e| Error::InvalidParam {
            name: "lookup keys",
            reason: format!("kd-tree construction failed: {e:?}"),
        })?;
        Ok(Self {
            keys,
            normals,
            tree,
            height_m,
        })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// True without samples (never, for a built table).
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Height of the sphere's centre along `up`, m.
    pub fn height_m(&self) -> f64 {
        self.height_m
    }

    /// Eq. 3.2: the `n_best` nearest keys to the unit key `key`, their normals weighted by
    /// `max_j ‖k − k_j‖ − ‖k − k_i‖`, summed and renormalised (camera frame). When every
    /// distance is equal (e.g. `n_best` = 1) the weights are equal.
    pub fn lookup(&self, key: DVec3, n_best: NonZero<usize>) -> Option<DVec3> {
        // Eq. 3.2 needs the N matches, not their order: unsorted saves the sort.
        let found = self
            .tree
            .query(&key.to_array())
            .nearest_n::<SquaredEuclidean<f64>>(n_best)
            .unsorted()
            .execute();
        let dmax = found
            .iter()
            .map(|f| f.distance.max(0.0).sqrt())
            .fold(0.0, f64::max);
        let mut n = DVec3::ZERO;
        for f in &found {
            n += self.normals[f.item as usize] * (dmax - f.distance.max(0.0).sqrt());
        }
        if n.length_squared() < 1e-24 {
            n = found
                .iter()
                .map(|f| self.normals[f.item as usize])
                .sum::<DVec3>();
        }
        n.try_normalize()
    }
}

/// Checks that the sphere's whole outline projects inside the image.
fn check_in_view(camera: &Camera, s: &CalibrationSphere) -> Result<()> {
    let c = camera.centre();
    let to = s.centre - c;
    let dist = to.length();
    if dist <= s.radius_m {
        return Err(Error::OutOfView {
            reason: "the camera is inside the sphere".into(),
        });
    }
    let axis = to / dist;
    let e1 = axis.any_orthonormal_vector();
    let e2 = axis.cross(e1);
    // The outline: tangent points of the cone from the camera centre.
    let sin_a = s.radius_m / dist;
    let cos_a = (1.0 - sin_a * sin_a).sqrt();
    let k = &camera.intrinsics;
    for j in 0..64 {
        let phi = std::f64::consts::TAU * j as f64 / 64.0;
        let dir = axis * cos_a + (e1 * phi.cos() + e2 * phi.sin()) * sin_a;
        let p = c + dir * dist * cos_a;
        let inside = camera.project(p).is_ok_and(|px| {
            px.x >= 0.0
                && px.y >= 0.0
                && px.x <= (k.width - 1) as f64
                && px.y <= (k.height - 1) as f64
        });
        if !inside {
            return Err(Error::OutOfView {
                reason: format!(
                    "outline point {p} of the sphere at {} (radius {} m) is outside the {}x{} image",
                    s.centre, s.radius_m, k.width, k.height
                ),
            });
        }
    }
    Ok(())
}

/// The tables of one camera for spheres at several heights (§3.2.3: 7 heights), sorted by
/// height.
#[derive(Debug)]
pub struct HeightCalibration {
    tables: Vec<LookupTable>,
}

impl HeightCalibration {
    /// Sorts the tables by height.
    ///
    /// # Errors
    /// [`Error::Empty`] for no tables; [`Error::InvalidParam`] for two at the same height.
    pub fn new(mut tables: Vec<LookupTable>) -> Result<Self> {
        if tables.is_empty() {
            return Err(Error::Empty {
                what: "calibration tables",
            });
        }
        tables.sort_by(|a, b| a.height_m.total_cmp(&b.height_m));
        if tables.windows(2).any(|w| w[0].height_m == w[1].height_m) {
            return Err(Error::InvalidParam {
                name: "calibration tables",
                reason: "two spheres at the same height".into(),
            });
        }
        Ok(Self { tables })
    }

    /// The tables, by increasing height.
    pub fn tables(&self) -> &[LookupTable] {
        &self.tables
    }

    /// §3.2.3: the normal of unit key `key` at height `height_m`: looked up in the two tables
    /// nearest in height and interpolated linearly (clamped to the lowest/highest table
    /// outside their range), renormalised.
    pub fn lookup(&self, key: DVec3, height_m: f64, n_best: NonZero<usize>) -> Option<DVec3> {
        let t = &self.tables;
        let hi = t.partition_point(|x| x.height_m < height_m);
        if hi == 0 {
            return t[0].lookup(key, n_best);
        }
        if hi == t.len() {
            return t[t.len() - 1].lookup(key, n_best);
        }
        let (a, b) = (&t[hi - 1], &t[hi]);
        let s = (height_m - a.height_m) / (b.height_m - a.height_m);
        let na = a.lookup(key, n_best)?;
        let nb = b.lookup(key, n_best)?;
        (na * (1.0 - s) + nb * s).try_normalize()
    }
}
