//! The generator behind [`crate::validation`]: reading the ICT basis, building the bilinear,
//! trilinear and pure-ICT data tensors, hold-out masks and the imputation metric.

use std::borrow::Cow;

use nalgebra::DMatrix;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Uniform};
use skin_core::math::{fit_similarity, Alignment, DVec3};
use skin_core::mesh::TriMesh;

use super::ict_basis::{IctBasis, Recipe};
use crate::face_data::{FaceTensor, KnownFaces};
use crate::impute::averaging_can_fill;
use crate::{Error, Result};

/// The 10 expressions of the bilinear set (thesis §5.3.1: "neutral, smile, frown, surprise,
/// anger, and others").
pub const BILINEAR_EXPRESSIONS: [Recipe; 10] = [
    ("neutral", &[]),
    ("smile", &[("mouthSmile_L", 1.0), ("mouthSmile_R", 1.0)]),
    ("frown", &[("mouthFrown_L", 1.0), ("browDown_L", 0.6)]),
    (
        "surprise",
        &[
            ("browInnerUp_L", 1.0),
            ("browInnerUp_R", 1.0),
            ("jawOpen", 0.5),
        ],
    ),
    (
        "anger",
        &[
            ("browDown_L", 1.0),
            ("noseSneer_L", 0.8),
            ("mouthStretch_L", 0.5),
        ],
    ),
    ("blink", &[("eyeBlink_L", 1.0), ("eyeBlink_R", 1.0)]),
    ("pucker", &[("mouthPucker", 1.0), ("mouthFunnel", 0.3)]),
    ("cheek puff", &[("cheekPuff_L", 1.0), ("mouthClose", 0.5)]),
    ("jaw left", &[("jawLeft", 1.0), ("jawOpen", 0.2)]),
    (
        "yell",
        &[
            ("jawOpen", 1.0),
            ("mouthStretch_L", 0.5),
            ("browInnerUp_L", 0.4),
            ("browInnerUp_R", 0.4),
        ],
    ),
];

/// The 5 expressions of the trilinear set (thesis: neutral, smiling, scowling, surprised,
/// sad).
pub const TRILINEAR_EXPRESSIONS: [Recipe; 5] = [
    ("neutral", &[]),
    ("smiling", &[("mouthSmile_L", 0.8), ("mouthSmile_R", 0.8)]),
    (
        "scowling",
        &[
            ("browDown_L", 1.0),
            ("noseSneer_L", 0.6),
            ("mouthFrown_L", 0.4),
        ],
    ),
    (
        "surprised",
        &[
            ("browInnerUp_L", 1.0),
            ("browInnerUp_R", 1.0),
            ("eyeBlink_L", -0.3),
            ("eyeBlink_R", -0.3),
        ],
    ),
    (
        "sad",
        &[
            ("mouthFrown_L", 0.8),
            ("browInnerUp_L", 0.6),
            ("browInnerUp_R", 0.6),
        ],
    ),
];

/// The 5 visemes of the trilinear set (thesis: the bold sounds of *man, car, eel, too, she*).
pub const VISEMES: [Recipe; 5] = [
    ("m (man)", &[("mouthClose", 0.8), ("jawOpen", 0.1)]),
    ("aa (car)", &[("jawOpen", 0.7)]),
    (
        "ee (eel)",
        &[
            ("mouthStretch_L", 0.8),
            ("mouthSmile_L", 0.3),
            ("mouthSmile_R", 0.3),
            ("jawOpen", 0.15),
        ],
    ),
    ("oo (too)", &[("mouthPucker", 0.9), ("mouthFunnel", 0.6)]),
    ("sh (she)", &[("mouthFunnel", 0.8), ("jawOpen", 0.25)]),
];

/// Parameters of the generators.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceSetParams {
    /// Number of people. Default: the thesis's 15 (bilinear); [`trilinear_face_set`] is
    /// usually called with 16.
    pub identities: usize,
    /// σ of the identity-mode coefficients `αₐ ~ N(0, σ²)`. Default 1.
    pub identity_sigma: f64,
    /// The interaction strength `γ` (see [`crate::validation`]). Default 0.3.
    pub interaction: f64,
    /// σ of i.i.d. Gaussian scan noise per coordinate, in the data's units (≈ cm). Default 0.
    pub noise: f64,
    /// Seed of the people, the interaction matrices and the noise. Default 16.
    pub seed: u64,
    /// Identity modes the generator uses: `None` (default) every mode of the basis; `Some(n)`
    /// the basis's first `n`, or, for `n` above the basis's count, the basis's modes plus
    /// `n − count` synthetic ones (see [`crate::validation`]). The identity mode of a
    /// generated tensor has rank `min(n + 1, people)` (the interaction is linear in `α`).
    pub identity_modes: Option<usize>,
}

impl Default for FaceSetParams {
    fn default() -> Self {
        FaceSetParams {
            identities: 15,
            identity_sigma: 1.0,
            interaction: 0.3,
            noise: 0.0,
            seed: 16,
            identity_modes: None,
        }
    }
}

impl FaceSetParams {
    /// With `n` people.
    pub fn with_identities(mut self, n: usize) -> Self {
        self.identities = n;
        self
    }

    /// With interaction strength `γ`.
    pub fn with_interaction(mut self, gamma: f64) -> Self {
        self.interaction = gamma;
        self
    }

    /// With scan noise σ (data units).
    pub fn with_noise(mut self, sigma: f64) -> Self {
        self.noise = sigma;
        self
    }

    /// With another seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// With `n` identity modes (see [`FaceSetParams::identity_modes`]).
    pub fn with_identity_modes(mut self, n: usize) -> Self {
        self.identity_modes = Some(n);
        self
    }
}

/// A generated data set.
#[derive(Clone, Debug)]
pub struct FaceSet {
    /// The data tensor `[3V, …attributes…, identity]`.
    pub faces: FaceTensor,
    /// The triangles of every face (the ICT neutral face's).
    pub triangles: Vec<[u32; 3]>,
    /// The attribute modes' names (e.g. `["expression", "identity"]`).
    pub mode_names: Vec<&'static str>,
    /// The names of each mode's values.
    pub value_names: Vec<Vec<String>>,
    /// Per non-identity mode, the blendshape weights of each value (`dₙ ×` the basis's
    /// blendshape count): the labels for [`crate::Dials`].
    pub labels: Vec<DMatrix<f64>>,
    /// Each person's identity-mode coefficients `α` (one per identity mode used).
    pub identity_coefficients: Vec<Vec<f64>>,
    /// Measured strength of the interaction term (see [`crate::validation`]).
    pub interaction_fraction: f64,
}

fn check_params(p: &FaceSetParams) -> Result<()> {
    skin_core::check::nonzero("identities", p.identities)?;
    skin_core::check::non_negative("identity_sigma", p.identity_sigma)?;
    skin_core::check::non_negative("interaction", p.interaction)?;
    skin_core::check::non_negative("noise", p.noise)?;
    if let Some(n) = p.identity_modes {
        skin_core::check::nonzero("identity_modes", n)?;
    }
    Ok(())
}

fn uniform(lo: f64, hi: f64) -> Result<Uniform<f64>> {
    Uniform::new(lo, hi).map_err(|e| Error::InvalidParam {
        name: "uniform range",
        reason: e.to_string(),
    })
}

fn normal(sigma: f64) -> Result<Normal<f64>> {
    Normal::new(0.0, sigma).map_err(|e| Error::InvalidParam {
        name: "sigma",
        reason: e.to_string(),
    })
}

/// Faces, the people's identity coefficients, the measured interaction fraction.
type Generated = (Vec<Vec<DVec3>>, Vec<Vec<f64>>, f64);

/// The identity modes of the generator ([`FaceSetParams::identity_modes`]): the basis's first
/// `n`, or all of them followed by synthetic modes. Synthetic mode `k` is basis mode
/// `j = k mod n₀` modulated by a plane wave over the neutral face,
/// `√2 cos(2π (1 + ⌊k / n₀⌋) u_k·p / W + φ_k) I_j(p)` (`u_k` a random direction, `φ_k` a
/// random phase, `W` the face's width; the √2 keeps the mode's RMS): a smooth, face-shaped
/// displacement linearly independent of the others.
fn identity_modes<'a>(
    basis: &'a IctBasis,
    params: &FaceSetParams,
) -> Result<Cow<'a, [Vec<DVec3>]>> {
    let base = basis.identity_modes();
    let n0 = base.len();
    let n = params.identity_modes.unwrap_or(n0);
    if n <= n0 {
        return Ok(Cow::Borrowed(&base[..n]));
    }
    let neutral = &basis.neutral().vertices;
    let width = face_width(neutral).max(f64::MIN_POSITIVE);
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed ^ 0x1d_0de5);
    let unit = normal(1.0)?;
    let phase = uniform(0.0, std::f64::consts::TAU)?;
    let mut modes = base.to_vec();
    for k in 0..n - n0 {
        let u = DVec3::from_array([0; 3].map(|_| unit.sample(&mut rng))).normalize_or(DVec3::X);
        let omega = std::f64::consts::TAU * (1 + k / n0) as f64 / width;
        let phi = phase.sample(&mut rng);
        modes.push(
            base[k % n0]
                .iter()
                .zip(neutral)
                .map(|(d, p)| *d * (2f64.sqrt() * (omega * u.dot(*p) + phi).cos()))
                .collect(),
        );
    }
    Ok(Cow::Owned(modes))
}

/// Builds the faces for `combos` (blendshape weights of the expression part `β` and of the
/// viseme part `ν` with its expression scale `hₑ`) × people.
fn generate(
    basis: &IctBasis,
    combos: &[(Vec<f64>, Vec<f64>, f64)],
    params: &FaceSetParams,
) -> Result<Generated> {
    check_params(params)?;
    let modes = identity_modes(basis, params)?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let nb = basis.blendshapes().len();
    let na = modes.len();
    let g_dist = uniform(-3f64.sqrt(), 3f64.sqrt())?;
    let g: Vec<Vec<f64>> = (0..na)
        .map(|_| (0..nb).map(|_| g_dist.sample(&mut rng)).collect())
        .collect();
    let unit = normal(1.0)?;
    let alphas: Vec<Vec<f64>> = (0..params.identities)
        .map(|_| {
            (0..na)
                .map(|_| params.identity_sigma * unit.sample(&mut rng))
                .collect()
        })
        .collect();
    let v = basis.neutral().vertices.len();
    let (mut inter2, mut disp2) = (0.0, 0.0);
    let mut faces = Vec::with_capacity(combos.len() * params.identities);
    for (beta, nu, h) in combos {
        for alpha in &alphas {
            let mut f = basis.neutral().vertices.clone();
            for (a, m) in alpha.iter().zip(modes.iter()) {
                for (p, d) in f.iter_mut().zip(m) {
                    *p += *a * *d;
                }
            }
            let mut extra = vec![DVec3::ZERO; v];
            let mut plain = vec![DVec3::ZERO; v];
            for b in 0..nb {
                let w0 = beta[b] + (1.0 + params.interaction * h) * nu[b];
                let w_plain = beta[b] + nu[b];
                if w0 == 0.0 && w_plain == 0.0 {
                    continue;
                }
                let gb: f64 = (0..na).map(|a| g[a][b] * alpha[a]).sum::<f64>() / (na as f64).sqrt();
                let w = (1.0 + params.interaction * gb) * w0;
                for (((p, e), q), d) in f
                    .iter_mut()
                    .zip(extra.iter_mut())
                    .zip(plain.iter_mut())
                    .zip(&basis.blendshapes()[b])
                {
                    *p += w * *d;
                    *e += (w - w_plain) * *d;
                    *q += w_plain * *d;
                }
            }
            inter2 += extra.iter().map(|e| e.length_squared()).sum::<f64>();
            disp2 += plain.iter().map(|e| e.length_squared()).sum::<f64>();
            if params.noise > 0.0 {
                for p in f.iter_mut() {
                    let n = [0; 3].map(|_| params.noise * unit.sample(&mut rng));
                    *p += DVec3::from_array(n);
                }
            }
            faces.push(f);
        }
    }
    let fraction = if disp2 > 0.0 {
        (inter2 / disp2).sqrt()
    } else {
        0.0
    };
    Ok((faces, alphas, fraction))
}

fn labels_of(basis: &IctBasis, recipes: &[Recipe]) -> Result<DMatrix<f64>> {
    let rows: Vec<Vec<f64>> = recipes
        .iter()
        .map(|r| basis.weights(r))
        .collect::<Result<_>>()?;
    Ok(DMatrix::from_fn(
        rows.len(),
        basis.blendshapes().len(),
        |i, j| rows[i][j],
    ))
}

/// The bilinear set (§5.3.1): `3V × 10 expressions × P people` (thesis: 15), expressions
/// [`BILINEAR_EXPRESSIONS`].
///
/// # Errors
/// [`Error::UnknownName`] if the basis lacks a blendshape the expressions use;
/// [`Error::InvalidParam`] for zero people, zero identity modes or a negative σ, γ or noise.
pub fn bilinear_face_set(basis: &IctBasis, params: &FaceSetParams) -> Result<FaceSet> {
    let zero = vec![0.0; basis.blendshapes().len()];
    let combos: Vec<_> = BILINEAR_EXPRESSIONS
        .iter()
        .map(|r| Ok((basis.weights(r)?, zero.clone(), 0.0)))
        .collect::<Result<_>>()?;
    let (faces, alphas, fraction) = generate(basis, &combos, params)?;
    Ok(FaceSet {
        faces: FaceTensor::from_faces(&[combos.len(), params.identities], &faces)?,
        triangles: basis.neutral().faces.clone(),
        mode_names: vec!["expression", "identity"],
        value_names: vec![
            BILINEAR_EXPRESSIONS
                .iter()
                .map(|r| r.0.to_string())
                .collect(),
            (0..params.identities)
                .map(|i| format!("person {i}"))
                .collect(),
        ],
        labels: vec![labels_of(basis, &BILINEAR_EXPRESSIONS)?],
        identity_coefficients: alphas,
        interaction_fraction: fraction,
    })
}

/// The trilinear set (§5.3.1): `3V × 5 visemes × 5 expressions × P people` (thesis: 16),
/// [`VISEMES`] × [`TRILINEAR_EXPRESSIONS`].
///
/// # Errors
/// As [`bilinear_face_set`].
pub fn trilinear_face_set(basis: &IctBasis, params: &FaceSetParams) -> Result<FaceSet> {
    check_params(params)?;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed ^ 0x5eed_0f7e);
    let hd = uniform(-1.0, 1.0)?;
    let hb: Vec<f64> = (0..basis.blendshapes().len())
        .map(|_| hd.sample(&mut rng))
        .collect();
    let mut combos = Vec::new();
    for vis in &VISEMES {
        for ex in &TRILINEAR_EXPRESSIONS {
            let beta = basis.weights(ex)?;
            let h: f64 = beta.iter().zip(&hb).map(|(b, h)| b * h).sum();
            combos.push((beta, basis.weights(vis)?, h));
        }
    }
    let (faces, alphas, fraction) = generate(basis, &combos, params)?;
    Ok(FaceSet {
        faces: FaceTensor::from_faces(
            &[
                VISEMES.len(),
                TRILINEAR_EXPRESSIONS.len(),
                params.identities,
            ],
            &faces,
        )?,
        triangles: basis.neutral().faces.clone(),
        mode_names: vec!["viseme", "expression", "identity"],
        value_names: vec![
            VISEMES.iter().map(|r| r.0.to_string()).collect(),
            TRILINEAR_EXPRESSIONS
                .iter()
                .map(|r| r.0.to_string())
                .collect(),
            (0..params.identities)
                .map(|i| format!("person {i}"))
                .collect(),
        ],
        labels: vec![
            labels_of(basis, &VISEMES)?,
            labels_of(basis, &TRILINEAR_EXPRESSIONS)?,
        ],
        identity_coefficients: alphas,
        interaction_fraction: fraction,
    })
}

/// The ICT shapes themselves as a bilinear data set: `1 + B` expressions (neutral and the
/// basis's `B` blendshapes at weight 1) × `1 + I` identities (the generic face and the basis's
/// `I` identity modes at coefficient 1) — 17 × 11 for the shipped basis:
/// `mesh(e, i) = N + Iᵢ + E_e`, what the ICT linear model does. Additive, so its interaction
/// fraction is 0. Any basis gives a valid set (the counts come from the basis).
///
/// # Errors
/// None for a basis built by [`IctBasis::new`] or read; the `Result` carries
/// [`FaceTensor::from_faces`]'s checks.
pub fn ict_face_set(basis: &IctBasis) -> Result<FaceSet> {
    let neutral = &basis.neutral().vertices;
    let zero = vec![DVec3::ZERO; neutral.len()];
    let ids: Vec<&Vec<DVec3>> = std::iter::once(&zero)
        .chain(basis.identity_modes())
        .collect();
    let exs: Vec<&Vec<DVec3>> = std::iter::once(&zero).chain(basis.blendshapes()).collect();
    let mut faces = Vec::with_capacity(exs.len() * ids.len());
    for e in &exs {
        for i in &ids {
            faces.push(
                neutral
                    .iter()
                    .zip(e.iter())
                    .zip(i.iter())
                    .map(|((n, a), b)| *n + *a + *b)
                    .collect(),
            );
        }
    }
    let nb = basis.blendshapes().len();
    let labels = DMatrix::from_fn(exs.len(), nb, |e, b| if e == b + 1 { 1.0 } else { 0.0 });
    let na = basis.identity_modes().len();
    Ok(FaceSet {
        faces: FaceTensor::from_faces(&[exs.len(), ids.len()], &faces)?,
        triangles: basis.neutral().faces.clone(),
        mode_names: vec!["expression", "identity"],
        value_names: vec![
            std::iter::once("neutral".to_string())
                .chain(basis.blendshape_names().iter().cloned())
                .collect(),
            std::iter::once("generic".to_string())
                .chain(basis.identity_names().iter().cloned())
                .collect(),
        ],
        labels: vec![labels],
        identity_coefficients: (0..ids.len())
            .map(|i| {
                (0..na)
                    .map(|a| if i == a + 1 { 1.0 } else { 0.0 })
                    .collect()
            })
            .collect(),
        interaction_fraction: 0.0,
    })
}

/// Holds out `round(fraction · Π dₙ)` faces at random (seeded), redrawing until every
/// attribute value keeps a known face and every missing face has a reference for the
/// averaging baseline (a person's known face whose attributes another person also has).
///
/// # Errors
/// [`Error::InvalidParam`] for a fraction outside `[0, 1)` or no valid mask in 1000 draws.
pub fn hold_out(attribute_sizes: &[usize], fraction: f64, seed: u64) -> Result<KnownFaces> {
    if !(0.0..1.0).contains(&fraction) {
        return Err(Error::InvalidParam {
            name: "fraction",
            reason: format!("must be in [0, 1), got {fraction}"),
        });
    }
    let k: usize = attribute_sizes.iter().product();
    let m = (fraction * k as f64).round() as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut ids: Vec<usize> = (0..k).collect();
    for _ in 0..1000 {
        ids.shuffle(&mut rng);
        let mut flags = vec![true; k];
        for &f in &ids[..m] {
            flags[f] = false;
        }
        let Ok(known) = KnownFaces::new(attribute_sizes, flags) else {
            continue;
        };
        if averaging_can_fill(&known) {
            return Ok(known);
        }
    }
    Err(Error::InvalidParam {
        name: "fraction",
        reason: format!("no valid hold-out of {m} of {k} faces found"),
    })
}

/// The RMS distance from `face`'s vertices to `truth`'s after the least-squares similarity
/// alignment (Umeyama) of `face` onto `truth`, in `truth`'s units: the 3D tracking error
/// before it is divided by [`face_width`].
///
/// # Errors
/// As [`skin_core::math::fit_similarity`] (lists of different lengths, fewer than three
/// points, non-finite or collinear points).
pub fn aligned_rms(face: &[DVec3], truth: &[DVec3]) -> Result<f64> {
    let s = fit_similarity(face, truth, None, Alignment::Similarity)?;
    let sum: f64 = face
        .iter()
        .zip(truth)
        .map(|(a, b)| s.apply(*a).distance_squared(*b))
        .sum();
    Ok((sum / face.len() as f64).sqrt())
}

/// A face's width: the extent of its vertices along x (0 for no vertex).
pub fn face_width(face: &[DVec3]) -> f64 {
    let xs = face.iter().map(|p| p.x);
    (xs.clone().fold(f64::MIN, f64::max) - xs.fold(f64::MAX, f64::min)).max(0.0)
}

/// The imputation metric: `‖X̂_held − X_held‖_F / ‖X_held − x̄‖_F` over the held-out faces, `x̄`
/// the mean face of the full (true) data set — the Frobenius norm of the error over the norm of the
/// held-out faces' variation from the mean face (thesis §5.3.4).
///
/// # Errors
/// [`Error::SizeMismatch`] if the tensors' or the mask's shapes differ; [`Error::Empty`] if
/// nothing is held out.
pub fn impute_rel_error(
    truth: &FaceTensor,
    estimate: &FaceTensor,
    known: &KnownFaces,
) -> Result<f64> {
    if truth.tensor().shape() != estimate.tensor().shape() {
        return Err(Error::SizeMismatch {
            what: "estimate tensor",
            expected: truth.tensor().len(),
            got: estimate.tensor().len(),
        });
    }
    if truth.attribute_sizes() != known.attribute_sizes() {
        return Err(Error::SizeMismatch {
            what: "known-face flags",
            expected: truth.face_count(),
            got: known.attribute_sizes().iter().product(),
        });
    }
    let missing = known.missing();
    if missing.is_empty() {
        return Err(Error::Empty {
            what: "held-out faces",
        });
    }
    let all: Vec<usize> = (0..truth.face_count()).collect();
    let mean = truth.mean_of(&all);
    let k = truth.face_count();
    let (t, e) = (truth.tensor().data(), estimate.tensor().data());
    let (mut num, mut den) = (0.0, 0.0);
    for (r, m) in mean.iter().enumerate() {
        for &f in &missing {
            num += (e[r * k + f] - t[r * k + f]).powi(2);
            den += (t[r * k + f] - m).powi(2);
        }
    }
    Ok((num / den.max(f64::MIN_POSITIVE)).sqrt())
}

/// A re-meshed, noisy copy of `mesh` for validating correspondence (§5.3.2): every triangle
/// split in four at its edge midpoints, every vertex of that mesh moved by an isotropic
/// Gaussian step of `slide` (data units) and projected back onto `mesh`'s surface (so no
/// vertex keeps a template position), then i.i.d. Gaussian scan noise of σ `noise`.
///
/// # Errors
/// The mesh-query errors of `skin-core` (an empty or invalid mesh); [`Error::InvalidParam`]
/// for a negative `slide` or `noise`.
pub fn remeshed_scan(mesh: &TriMesh, slide: f64, noise: f64, seed: u64) -> Result<TriMesh> {
    skin_core::check::non_negative("slide", slide)?;
    skin_core::check::non_negative("noise", noise)?;
    let query = skin_core::mesh::MeshQuery::new(mesh)?;
    let mut vertices = mesh.vertices.clone();
    let mut mid = std::collections::HashMap::new();
    let mut faces = Vec::with_capacity(4 * mesh.faces.len());
    for f in &mesh.faces {
        let mut m = [0u32; 3];
        for (k, (a, b)) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])]
            .into_iter()
            .enumerate()
        {
            let key = (a.min(b), a.max(b));
            m[k] = *mid.entry(key).or_insert_with(|| {
                vertices.push((mesh.vertices[a as usize] + mesh.vertices[b as usize]) * 0.5);
                (vertices.len() - 1) as u32
            });
        }
        faces.extend_from_slice(&[
            [f[0], m[0], m[2]],
            [m[0], f[1], m[1]],
            [m[2], m[1], f[2]],
            [m[0], m[1], m[2]],
        ]);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = normal(1.0)?;
    let moved: Vec<DVec3> = vertices
        .iter()
        .map(|p| *p + DVec3::from_array([0; 3].map(|_| slide * unit.sample(&mut rng))))
        .collect();
    let projected = query.closest_points(&moved)?;
    let vertices = projected
        .iter()
        .map(|c| c.position + DVec3::from_array([0; 3].map(|_| noise * unit.sample(&mut rng))))
        .collect();
    Ok(TriMesh::new(vertices, faces)?)
}

/// `count` well-spread vertices of `mesh` (farthest-point sampling from vertex 0): the
/// "manually specified reference points" of §5.3.2 (the thesis marked 42).
///
/// # Errors
/// [`Error::Empty`] for a mesh without vertices; [`Error::InvalidParam`] for more points than
/// vertices.
pub fn feature_vertices(mesh: &TriMesh, count: usize) -> Result<Vec<usize>> {
    let v = mesh.vertices.len();
    if v == 0 {
        return Err(Error::Empty {
            what: "mesh vertices",
        });
    }
    if count > v {
        return Err(Error::InvalidParam {
            name: "count",
            reason: format!("{count} feature points on {v} vertices"),
        });
    }
    let mut out = vec![0usize];
    let mut dist: Vec<f64> = mesh
        .vertices
        .iter()
        .map(|p| p.distance_squared(mesh.vertices[0]))
        .collect();
    while out.len() < count {
        let (far, _) =
            dist.iter().enumerate().fold(
                (0, -1.0),
                |best, (i, &d)| if d > best.1 { (i, d) } else { best },
            );
        out.push(far);
        for (d, p) in dist.iter_mut().zip(&mesh.vertices) {
            *d = d.min(p.distance_squared(mesh.vertices[far]));
        }
    }
    Ok(out)
}

/// A synthetic tracking sequence (stand-in for KLT tracks of a 640 × 480 video): pixel
/// positions of tracked vertices under a weak-perspective camera with head motion, plus the
/// true 3D faces.
#[derive(Clone, Debug)]
pub struct PointTrackSequence {
    /// Per frame, the pixel position of each tracked vertex (with noise).
    pub frames: Vec<Vec<[f64; 2]>>,
    /// Per frame, the true face (all vertices).
    pub truth: Vec<Vec<DVec3>>,
    /// Per frame, the true camera.
    pub cameras: Vec<crate::WeakPerspective>,
}

/// A sequence of `frame_count` frames of one person (`person`: a data set with one identity,
/// e.g. [`bilinear_face_set`] with `identities = 1` and a seed the model never saw): the
/// expression moves linearly through the person's faces in the order `order` (indices of
/// faces), the head turns (yaw ±23°, pitch ±14°, roll ±9°), moves (±30 × ±20 px around the
/// centre of a 640 × 480 image) and scales (20 px per unit ± 10 %); each tracked vertex's
/// projection gets i.i.d. Gaussian noise of `noise_px` (KLT error).
///
/// # Errors
/// [`Error::Empty`] for fewer than 2 frames or an order of fewer than 2 faces;
/// [`Error::IndexOutOfRange`] for a face or tracked vertex out of range;
/// [`Error::InvalidParam`] for negative noise.
pub fn point_track_sequence(
    person: &FaceTensor,
    order: &[usize],
    tracked: &[usize],
    frame_count: usize,
    noise_px: f64,
    seed: u64,
) -> Result<PointTrackSequence> {
    if frame_count < 2 || order.len() < 2 {
        return Err(Error::Empty {
            what: "frames or expression order (at least 2)",
        });
    }
    skin_core::check::non_negative("noise_px", noise_px)?;
    let faces: Vec<Vec<DVec3>> = order
        .iter()
        .map(|&f| person.face(f))
        .collect::<Result<_>>()?;
    for &v in tracked {
        skin_core::check::index("tracked vertex", v, person.vertex_count())?;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = normal(1.0)?;
    let mut seq = PointTrackSequence {
        frames: Vec::new(),
        truth: Vec::new(),
        cameras: Vec::new(),
    };
    for t in 0..frame_count {
        let x = t as f64 / (frame_count - 1) as f64 * (order.len() - 1) as f64;
        let k = (x.floor() as usize).min(order.len() - 2);
        let u = x - k as f64;
        let f: Vec<DVec3> = faces[k]
            .iter()
            .zip(&faces[k + 1])
            .map(|(a, b)| *a * (1.0 - u) + *b * u)
            .collect();
        let tt = t as f64 / 10.0;
        use skin_core::math::DMat3;
        let r = DMat3::from_rotation_y(0.4 * tt.sin())
            * DMat3::from_rotation_x(0.25 * (0.7 * tt).sin())
            * DMat3::from_rotation_z(0.15 * (1.3 * tt).cos());
        // Image y points down: the second row is −(R's second row).
        let cam = crate::WeakPerspective {
            scale: 20.0 * (1.0 + 0.1 * (0.5 * tt).sin()),
            rows: [r.row(0).to_array(), (-r.row(1)).to_array()],
            translation: [
                320.0 + 30.0 * (0.3 * tt).sin(),
                240.0 + 20.0 * (0.4 * tt).cos(),
            ],
        };
        seq.frames.push(
            tracked
                .iter()
                .map(|&v| {
                    let p = cam.project(f[v].to_array());
                    [
                        p[0] + noise_px * unit.sample(&mut rng),
                        p[1] + noise_px * unit.sample(&mut rng),
                    ]
                })
                .collect(),
        );
        seq.truth.push(f);
        seq.cameras.push(cam);
    }
    Ok(seq)
}
