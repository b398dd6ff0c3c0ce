//! Compact storage of needle-length observations (Sand 2003 §4.3).
//!
//! The method is documented on [`ObservationStore`]; the module is private and
//! everything public is re-exported at the crate root.

use serde::{Deserialize, Serialize};

use crate::error::{Context, Error, Result, ResultExt};

/// Bits of the needle index in a [`PackedObservation`] (enough for
/// [`MAX_NEEDLES_PER_PRIMITIVE`]); the other 12 of its 24 bits hold the quantised length.
const NEEDLE_BITS: u32 = 12;

/// Most needles a primitive can have (radial × axial): the store packs a needle index in
/// 12 bits of its 3-byte observations, a fact of the storage format;
/// Table 3.1's largest primitive has 900.
pub const MAX_NEEDLES_PER_PRIMITIVE: usize = 1 << NEEDLE_BITS;

/// Number of quantisation steps of a needle length (12 bits): a step of 0.07 mm on a 30 cm
/// needle, some fifty times finer than a pixel of the cameras the method uses.
const LENGTH_STEPS: f32 = ((1u32 << (24 - NEEDLE_BITS)) - 1) as f32;

/// One packed observation: needle index within the primitive (12 bits) and quantised length
/// (12 bits) in 3 bytes.
///
/// The sample it belongs to is implicit in its position in the store. Three bytes rather
/// than two `u16` (ours): with the configuration rows a store of four-byte observations
/// comes to 4.15 bytes per observation on the studio's exercise, over the 4-byte budget; 12
/// bits index Table 3.1's 900-needle primitives and keep a length step of 1/4095 of the
/// primitive's maximum length.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[repr(transparent)]
pub(crate) struct PackedObservation([u8; 3]);

impl PackedObservation {
    /// Packs a needle index below [`MAX_NEEDLES_PER_PRIMITIVE`] and a length step count of
    /// at most 4095 (higher bits are dropped: callers check the ranges).
    fn pack(needle: u16, length_q: u16) -> Self {
        let v = u32::from(needle) & 0xfff | (u32::from(length_q) & 0xfff) << NEEDLE_BITS;
        let [a, b, c, _] = v.to_le_bytes();
        Self([a, b, c])
    }

    fn unpacked(self) -> u32 {
        let [a, b, c] = self.0;
        u32::from_le_bytes([a, b, c, 0])
    }

    /// Needle index within the primitive (ring-major order, see `primitive` module).
    pub(crate) fn needle(self) -> u16 {
        (self.unpacked() & 0xfff) as u16
    }

    /// Length in units of the primitive's [`ObservationStore::length_step_m`].
    pub(crate) fn length_q(self) -> u16 {
        (self.unpacked() >> NEEDLE_BITS) as u16
    }
}

/// One decoded observation, as yielded by [`ObservationStore::observations`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Index of the sample (row of [`ObservationStore::samples`]) the observation belongs to.
    pub sample: u32,
    /// Needle index within the primitive.
    pub needle: u16,
    /// Observed needle length, metres from the bone axis (dequantised).
    pub length_m: f32,
}

/// Shape of one primitive's observation table: what the store needs to know up front.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PrimitiveShape {
    /// Dimension `d` of the primitive's configuration space (§3.3, Table 3.1 "Dim.").
    pub config_dim: usize,
    /// Number of needles of the primitive (radial × axial, Table 3.1); at most
    /// [`MAX_NEEDLES_PER_PRIMITIVE`].
    pub needle_count: usize,
    /// Maximum needle length, metres (Table 3.1); sets the quantisation step.
    pub max_length_m: f64,
}

/// Observations of one primitive.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct PrimitiveTable {
    config_dim: usize,
    needle_count: usize,
    length_step_m: f32,
    /// Row-major `sample_count × config_dim` configuration points.
    samples: Vec<f32>,
    /// CSR offsets into `obs`; `sample_count + 1` entries, first is 0.
    sample_start: Vec<u32>,
    /// Frame of each sample ([`ObservationStore::sample_frames`]).
    #[serde(default)]
    sample_frame: Vec<u32>,
    obs: Vec<PackedObservation>,
}

impl PrimitiveTable {
    fn sample_count(&self) -> usize {
        self.sample_start.len() - 1
    }
}

/// Per-needle view of one primitive's observations, in CSR form: what prototype shape
/// estimation (§5.3) consumes. [`ObservationStore::by_needle`] returns it; other sources build
/// it with [`NeedleObservations::from_lists`] or [`NeedleObservations::from_csr`].
///
/// Observations of needle `j` are [`Self::needle`]`(j)`: sample indices (rows of the
/// primitive's configuration points) and lengths, in the order given (increasing sample order
/// when built by the store).
///
/// Valid by construction: the offsets start at 0, never decrease and end at the number of
/// observations; there is one sample index per length; every length is finite. (Whether the
/// sample indices fit a given set of configuration points is checked where both meet, in
/// [`crate::prototype_shapes`].)
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NeedleObservations {
    /// CSR offsets, `needle_count + 1` entries.
    start: Vec<u32>,
    /// Sample index (row of [`ObservationStore::samples`]) of each observation.
    sample: Vec<u32>,
    /// Observed length of each observation, metres.
    length_m: Vec<f32>,
}

impl NeedleObservations {
    /// Builds the table from one list of `(sample index, length)` per needle, e.g. for
    /// synthetic data or other sources than the store.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if there are more than `u32::MAX` observations;
    /// [`Error::NonFinite`] for a NaN/∞ length.
    ///
    /// # Example
    /// ```
    /// use needle_model::NeedleObservations;
    /// let obs = NeedleObservations::from_lists(&[vec![(0, 0.05), (2, 0.06)], vec![]])?;
    /// assert_eq!(obs.needle_count(), 2);
    /// assert_eq!(obs.needle(0), (&[0u32, 2][..], &[0.05f32, 0.06][..]));
    /// # Ok::<(), needle_model::Error>(())
    /// ```
    pub fn from_lists(per_needle: &[Vec<(u32, f32)>]) -> Result<Self> {
        let total: usize = per_needle.iter().map(Vec::len).sum();
        if u32::try_from(total).is_err() {
            return Err(Error::SizeMismatch {
                what: "observations of one primitive (at most u32::MAX)",
                expected: u32::MAX as usize,
                got: total,
            });
        }
        if per_needle.iter().flatten().any(|(_, l)| !l.is_finite()) {
            return Err(Error::NonFinite {
                what: "observed needle lengths",
            });
        }
        let mut start = Vec::with_capacity(per_needle.len() + 1);
        start.push(0u32);
        let mut sample = Vec::with_capacity(total);
        let mut length_m = Vec::with_capacity(total);
        for list in per_needle {
            for &(s, l) in list {
                sample.push(s);
                length_m.push(l);
            }
            start.push(sample.len() as u32); // ≤ total ≤ u32::MAX, checked above
        }
        Ok(Self {
            start,
            sample,
            length_m,
        })
    }

    /// Builds the table from its CSR arrays: `start` has `needle_count + 1` offsets into
    /// `sample` and `length_m` (observations of needle `j` are `start[j]..start[j + 1]`).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] if `start` is empty, does not begin at 0, decreases or does not
    /// end at `sample.len()`, or if `sample` and `length_m` differ in length;
    /// [`Error::NonFinite`] for a NaN/∞ length.
    pub fn from_csr(start: Vec<u32>, sample: Vec<u32>, length_m: Vec<f32>) -> Result<Self> {
        if sample.len() != length_m.len() {
            return Err(Error::SizeMismatch {
                what: "per-needle observations (lengths vs sample indices)",
                expected: sample.len(),
                got: length_m.len(),
            });
        }
        let consistent = start.first() == Some(&0)
            && start.windows(2).all(|w| w[0] <= w[1])
            && start.last().map(|&e| e as usize) == Some(sample.len());
        if !consistent {
            return Err(Error::SizeMismatch {
                what: "per-needle observation offsets (must start at 0, not decrease and end at the observation count)",
                expected: sample.len(),
                got: start.last().map_or(0, |&e| e as usize),
            });
        }
        if length_m.iter().any(|l| !l.is_finite()) {
            return Err(Error::NonFinite {
                what: "observed needle lengths",
            });
        }
        Ok(Self {
            start,
            sample,
            length_m,
        })
    }

    /// Number of needles (one list each, possibly empty).
    pub fn needle_count(&self) -> usize {
        self.start.len() - 1
    }

    /// Total number of observations over all needles.
    pub fn observation_count(&self) -> usize {
        self.sample.len()
    }

    /// Sample indices and lengths of needle `j` (empty slices if `j` is out of range).
    pub fn needle(&self, j: usize) -> (&[u32], &[f32]) {
        if j + 1 >= self.start.len() {
            return (&[], &[]);
        }
        let r = self.start[j] as usize..self.start[j + 1] as usize;
        (&self.sample[r.clone()], &self.length_m[r])
    }

    /// CSR offsets, `needle_count() + 1` entries, first 0, last `observation_count()`.
    pub fn offsets(&self) -> &[u32] {
        &self.start
    }

    /// Sample index of every observation, needle by needle.
    pub fn samples(&self) -> &[u32] {
        &self.sample
    }

    /// Length of every observation (finite), needle by needle; metres when built by the store.
    pub fn lengths_m(&self) -> &[f32] {
        &self.length_m
    }
}

impl<'de> Deserialize<'de> for NeedleObservations {
    /// Deserialises the three arrays and checks them as [`NeedleObservations::from_csr`].
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        struct Raw {
            start: Vec<u32>,
            sample: Vec<u32>,
            length_m: Vec<f32>,
        }
        let r = Raw::deserialize(d)?;
        Self::from_csr(r.start, r.sample, r.length_m).map_err(serde::de::Error::custom)
    }
}

/// All needle observations of a body, compact (3 bytes per observation plus one configuration
/// row and one offset per sample).
///
/// Compact storage of needle-length observations (Sand 2003 §4.3).
///
/// "For each needle length observation, we also record the bone's current position in
/// configuration space" (§4.3). Eight minutes of three-camera video give tens of millions of
/// observations, so the store keeps them compact:
///
/// * the configuration point of a primitive is stored **once per sample** — one sample is one
///   (frame, camera) pair in which the primitive produced at least one observation — as a
///   row of `config_dim` `f32` values (row-major);
/// * each observation is **3 bytes** (a private packed record): the needle index within its
///   primitive (12 bits) and the length quantised to 12 bits with a per-primitive scale
///   `length_step_m = max_length_m / 4095` (see [`ObservationStore::length_step_m`]); with the
///   Table 3.1 maxima (10–30 cm) the step is 0.02–0.07 mm, far below a pixel's footprint;
/// * observations are grouped by sample (CSR offsets, one `u32` per sample), so the sample
///   index of an observation is implicit.
///
/// Samples are appended in a deterministic order (frame-major, then camera), so a store built
/// in parallel and merged in frame order is bit-identical to one built serially.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObservationStore {
    primitives: Vec<PrimitiveTable>,
    /// Frames ended so far ([`ObservationStore::end_frame`]).
    #[serde(default)]
    frames: u32,
}

impl ObservationStore {
    /// An empty store for primitives of the given shapes.
    ///
    /// # Errors
    /// [`Error::At`] with [`Context::Primitive`] around [`Error::InvalidParam`] (possibly as
    /// [`Error::Core`]) if a primitive has `config_dim == 0`, more than
    /// [`MAX_NEEDLES_PER_PRIMITIVE`] needles, or a
    /// maximum length that is not finite and positive.
    pub fn new(shapes: &[PrimitiveShape]) -> Result<Self> {
        let mut primitives = Vec::with_capacity(shapes.len());
        for (p, s) in shapes.iter().enumerate() {
            let check = || -> Result<()> {
                skin_core::check::nonzero("config_dim", s.config_dim)?;
                if s.needle_count == 0 || s.needle_count > MAX_NEEDLES_PER_PRIMITIVE {
                    return Err(Error::InvalidParam {
                        name: "needle_count",
                        reason: format!(
                            "must be in 1..={MAX_NEEDLES_PER_PRIMITIVE}, got {}",
                            s.needle_count
                        ),
                    });
                }
                skin_core::check::positive("max_length_m", s.max_length_m)?;
                Ok(())
            };
            check().at(Context::Primitive(p))?;
            primitives.push(PrimitiveTable {
                config_dim: s.config_dim,
                needle_count: s.needle_count,
                length_step_m: (s.max_length_m as f32) / LENGTH_STEPS,
                samples: Vec::new(),
                sample_start: vec![0],
                sample_frame: Vec::new(),
                obs: Vec::new(),
            });
        }
        Ok(Self {
            primitives,
            frames: 0,
        })
    }

    /// Number of primitives.
    pub fn primitive_count(&self) -> usize {
        self.primitives.len()
    }

    fn table(&self, p: usize) -> Result<&PrimitiveTable> {
        self.primitives.get(p).ok_or(Error::IndexOutOfRange {
            what: "primitive",
            index: p,
            len: self.primitives.len(),
        })
    }

    /// Dimension of primitive `p`'s configuration space (0 if `p` is out of range).
    pub fn config_dim(&self, p: usize) -> usize {
        self.primitives.get(p).map_or(0, |t| t.config_dim)
    }

    /// Number of needles of primitive `p` (0 if `p` is out of range).
    pub fn needle_count(&self, p: usize) -> usize {
        self.primitives.get(p).map_or(0, |t| t.needle_count)
    }

    /// Quantisation step of primitive `p`'s lengths, metres: `max_length_m / 4095`
    /// (0 if `p` is out of range). Stored lengths are within half a step of the input.
    pub fn length_step_m(&self, p: usize) -> f32 {
        self.primitives.get(p).map_or(0.0, |t| t.length_step_m)
    }

    /// Number of samples (configuration rows) of primitive `p` (0 if out of range).
    pub fn sample_count(&self, p: usize) -> usize {
        self.primitives.get(p).map_or(0, |t| t.sample_count())
    }

    /// Configuration points of primitive `p`: row-major, `sample_count(p) × config_dim(p)`
    /// (empty if `p` is out of range).
    pub fn samples(&self, p: usize) -> &[f32] {
        self.primitives.get(p).map_or(&[], |t| &t.samples)
    }

    /// Configuration point of sample `s` of primitive `p` (empty if out of range).
    pub fn sample(&self, p: usize, s: usize) -> &[f32] {
        match self.primitives.get(p) {
            Some(t) if s < t.sample_count() => &t.samples[s * t.config_dim..(s + 1) * t.config_dim],
            _ => &[],
        }
    }

    /// CSR offsets of primitive `p`'s samples into its observations (in the order of
    /// [`Self::observations`]): `sample_count(p) + 1` entries (empty if out of range).
    pub fn sample_offsets(&self, p: usize) -> &[u32] {
        self.primitives.get(p).map_or(&[], |t| &t.sample_start)
    }

    /// Number of observations of primitive `p` (0 if out of range).
    pub fn observation_count(&self, p: usize) -> usize {
        self.primitives.get(p).map_or(0, |t| t.obs.len())
    }

    /// Total number of observations.
    pub fn total_observations(&self) -> usize {
        self.primitives.iter().map(|t| t.obs.len()).sum()
    }

    /// Decoded observations of primitive `p`, in storage order (sample-major)
    /// (empty if `p` is out of range).
    pub fn observations(&self, p: usize) -> impl Iterator<Item = Observation> + '_ {
        let table = self.primitives.get(p);
        let step = table.map_or(0.0, |t| t.length_step_m);
        let offsets: &[u32] = table.map_or(&[], |t| &t.sample_start);
        let obs: &[PackedObservation] = table.map_or(&[], |t| &t.obs);
        offsets.windows(2).enumerate().flat_map(move |(s, w)| {
            obs[w[0] as usize..w[1] as usize]
                .iter()
                .map(move |o| Observation {
                    sample: s as u32,
                    needle: o.needle(),
                    length_m: f32::from(o.length_q()) * step,
                })
        })
    }

    /// Observations of primitive `p` regrouped per needle (what prototype shape estimation,
    /// §5.3, consumes). Within a needle, observations are in increasing sample order.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] if `p` is out of range.
    pub fn by_needle(&self, p: usize) -> Result<NeedleObservations> {
        let t = self.table(p)?;
        let mut start = vec![0u32; t.needle_count + 1];
        for o in &t.obs {
            start[usize::from(o.needle()) + 1] += 1;
        }
        for j in 0..t.needle_count {
            start[j + 1] += start[j];
        }
        let n = t.obs.len();
        let mut sample = vec![0u32; n];
        let mut length_m = vec![0f32; n];
        let mut cursor: Vec<u32> = start[..t.needle_count].to_vec();
        for (s, w) in t.sample_start.windows(2).enumerate() {
            for o in &t.obs[w[0] as usize..w[1] as usize] {
                let c = &mut cursor[usize::from(o.needle())];
                sample[*c as usize] = s as u32;
                length_m[*c as usize] = f32::from(o.length_q()) * t.length_step_m;
                *c += 1;
            }
        }
        // Offsets from a counting sort of the packed needles; lengths dequantised.
        Ok(NeedleObservations {
            start,
            sample,
            length_m,
        })
    }

    /// Bytes stored per observation, amortised over the whole store: packed observations plus
    /// configuration rows, sample offsets and frame tags, divided by the number of observations
    /// (`size_of::<PackedObservation>()` = 3 if the store is empty).
    pub fn bytes_per_observation(&self) -> f64 {
        let n = self.total_observations();
        let per_obs = std::mem::size_of::<PackedObservation>();
        if n == 0 {
            return per_obs as f64;
        }
        let bytes: usize = self
            .primitives
            .iter()
            .map(|t| {
                t.obs.len() * per_obs
                    + (t.samples.len() + t.sample_start.len() + t.sample_frame.len()) * 4
            })
            .sum();
        bytes as f64 / n as f64
    }

    /// Append one sample of primitive `p`: its configuration point and its observations
    /// `(needle, length_m)`. A sample without observations is not stored (returns `Ok(false)`);
    /// otherwise returns `Ok(true)`.
    ///
    /// # Errors
    /// * [`Error::IndexOutOfRange`] if `p` is out of range or a needle index is
    ///   `>= needle_count(p)`; [`Error::SizeMismatch`] if `config.len() != config_dim(p)`;
    /// * [`Error::NonFinite`] if the configuration or a length is NaN/infinite;
    /// * [`Error::InvalidParam`] if a length is negative or above the primitive's maximum
    ///   (by more than half a quantisation step).
    ///
    /// Nothing is appended when an error is returned.
    pub fn push_sample(&mut self, p: usize, config: &[f64], obs: &[(u16, f32)]) -> Result<bool> {
        let n_prim = self.primitives.len();
        let t = self.primitives.get_mut(p).ok_or(Error::IndexOutOfRange {
            what: "primitive",
            index: p,
            len: n_prim,
        })?;
        if config.len() != t.config_dim {
            return Err(Error::SizeMismatch {
                what: "configuration point",
                expected: t.config_dim,
                got: config.len(),
            });
        }
        if config.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "configuration point",
            });
        }
        if obs.is_empty() {
            return Ok(false);
        }
        let mut packed = Vec::with_capacity(obs.len());
        for &(needle, length_m) in obs {
            if usize::from(needle) >= t.needle_count {
                return Err(Error::IndexOutOfRange {
                    what: "needle",
                    index: usize::from(needle),
                    len: t.needle_count,
                });
            }
            if !length_m.is_finite() {
                return Err(Error::NonFinite {
                    what: "needle length",
                });
            }
            let q = (length_m / t.length_step_m).round();
            if !(0.0..=LENGTH_STEPS).contains(&q) {
                return Err(Error::InvalidParam {
                    name: "length_m",
                    reason: format!(
                        "{length_m} m outside [0, {} m]",
                        t.length_step_m * LENGTH_STEPS
                    ),
                });
            }
            // In range 0..=LENGTH_STEPS by the check above; the needle by the one before.
            packed.push(PackedObservation::pack(needle, q as u16));
        }
        let end = t.obs.len() + packed.len();
        let end = u32::try_from(end).map_err(|_| Error::InvalidParam {
            name: "observation count",
            reason: "more than u32::MAX observations in one primitive".into(),
        })?;
        t.samples.extend(config.iter().map(|&v| v as f32));
        t.obs.extend_from_slice(&packed);
        t.sample_start.push(end);
        t.sample_frame.push(self.frames);
        Ok(true)
    }

    /// Ends the current frame: later samples belong to the next one. Samples are tagged with
    /// the frame they were pushed in ([`Self::sample_frames`]), counted from 0 in the order
    /// frames were ended; an appended store's frames follow this store's.
    pub fn end_frame(&mut self) {
        self.frames += 1;
    }

    /// Number of frames ended ([`Self::end_frame`]).
    pub fn frame_count(&self) -> usize {
        self.frames as usize
    }

    /// The frame of each sample of primitive `p` (empty if `p` is out of range): what ties a
    /// sample to its pose θ, for the model over skinning ([`crate::PoseSpaceModel`]).
    pub fn sample_frames(&self, p: usize) -> &[u32] {
        self.primitives.get(p).map_or(&[], |t| &t.sample_frame)
    }

    /// Append all samples of `other` after this store's samples (used to merge per-frame
    /// stores built in parallel, in frame order).
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] / [`Error::InvalidParam`] if the two stores do not have the
    /// same primitive shapes.
    pub fn append(&mut self, other: &ObservationStore) -> Result<()> {
        if other.primitives.len() != self.primitives.len() {
            return Err(Error::SizeMismatch {
                what: "primitive count of appended store",
                expected: self.primitives.len(),
                got: other.primitives.len(),
            });
        }
        for (a, b) in self.primitives.iter().zip(&other.primitives) {
            if a.config_dim != b.config_dim
                || a.needle_count != b.needle_count
                || a.length_step_m.to_bits() != b.length_step_m.to_bits()
            {
                return Err(Error::InvalidParam {
                    name: "appended store",
                    reason: "primitive shapes differ".into(),
                });
            }
            if u32::try_from(a.obs.len() + b.obs.len()).is_err() {
                return Err(Error::InvalidParam {
                    name: "observation count",
                    reason: "more than u32::MAX observations in one primitive".into(),
                });
            }
        }
        let frames = self
            .frames
            .checked_add(other.frames)
            .ok_or(Error::InvalidParam {
                name: "frame count",
                reason: "more than u32::MAX frames".into(),
            })?;
        for (a, b) in self.primitives.iter_mut().zip(&other.primitives) {
            let base = a.obs.len() as u32;
            a.samples.extend_from_slice(&b.samples);
            a.obs.extend_from_slice(&b.obs);
            a.sample_start
                .extend(b.sample_start[1..].iter().map(|&o| o + base));
            a.sample_frame
                .extend(b.sample_frame.iter().map(|&f| f + self.frames));
        }
        self.frames = frames;
        Ok(())
    }
}

#[cfg(test)]
mod tests;
