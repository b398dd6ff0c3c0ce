//! Validation equipment (feature `validation`): the face data-set generator from the real ICT
//! face basis with a documented identity × expression interaction, hold-out masks, the
//! imputation metric, re-meshed noisy scans with feature vertices (§5.3.2) and
//! synthetic point-track sequences under head motion (§5.4.1), and the same sequences
//! rendered into textured 640 × 480 videos ([`render_face_video`]).
//!
//! ## The data sets
//!
//! The ICT face model (USC ICT, MIT licence; `data/ict-face/` in the repository) gives a
//! generic neutral face (6,706 vertices, ≈ cm), 10 identity modes and 16 ARKit-style
//! expression blendshapes, all in full correspondence. A synthetic person is the neutral face
//! plus `Σₐ αₐ Iₐ` with `αₐ ~ N(0, σ²)` (σ = [`FaceSetParams::identity_sigma`]).
//!
//! **Interaction term** (the ICT basis alone is additive, so copying the mean displacement —
//! the averaging baseline — would be exact on it). Each person performs each blendshape `b`
//! with their own amplitude: the displacement `E_b` is scaled by
//! `s_b(α) = 1 + γ · gᵦ(α)`, `gᵦ(α) = Σₐ G_{ab} αₐ / √10`, with `G_{ab}` drawn once from
//! `U(−√3, √3)` (unit variance, seeded) and `γ` = [`FaceSetParams::interaction`] (default
//! 0.3: a person one σ away smiles ≈ 30 % more or less than the average person). In the
//! trilinear set the viseme's blendshapes are also scaled by the expression
//! (`1 + γ hₑ`, `hₑ = Σ_b H_b βₑ_b`, `H_b ~ U(−1, 1)`: a smiling "oo" is not a neutral "oo"
//! plus a smile). The face of person `α` with expression weights `β` (and viseme weights `ν`):
//!
//! `f = N + Σₐ αₐ Iₐ + Σ_b s_b(α) (βᵦ + (1 + γ hₑ) νᵦ) E_b` (+ optional i.i.d. scan noise).
//!
//! Its strength is measured and returned: [`FaceSet::interaction_fraction`] is
//! `‖f − f|_{γ=0}‖ / ‖f|_{γ=0} − N − Σ αI‖` over all faces (the interaction over the
//! expression and viseme displacements it modulates).
//!
//! **Identity rank.** The identity mode of a generated tensor has rank
//! `min(modes + 1, people)`. [`FaceSetParams::identity_modes`] takes fewer of the basis's
//! modes, or more: synthetic mode `k` is basis mode `k mod n₀` modulated by a plane wave over
//! the neutral face, `√2 cos(2π (1 + ⌊k / n₀⌋) u_k·p / W + φ_k) I_{k mod n₀}(p)` (random
//! direction and phase, `W` the face's width), so that as many modes as people give a full-rank
//! identity mode (the case where the thesis's low-rank argument has nothing to use).
//!
//! **Reading the basis.** [`IctBasis::read`] takes every identity and blendshape file a folder
//! holds, [`IctBasis::read_named`] a caller's lists; every mismatch is a typed error, and the
//! sets take their counts from the basis ([`Error::UnknownName`](crate::Error::UnknownName) for
//! a blendshape a recipe needs and the basis lacks).
//!
//! **Which blendshapes make each attribute value**: [`BILINEAR_EXPRESSIONS`],
//! [`TRILINEAR_EXPRESSIONS`], [`VISEMES`] (names and weights, `docs/multilinear-face.md`
//! lists them).

mod dataset;
mod ict_basis;
mod tracking;
mod video;

pub use dataset::{
    aligned_rms, bilinear_face_set, face_width, feature_vertices, hold_out, ict_face_set,
    impute_rel_error, point_track_sequence, remeshed_scan, trilinear_face_set, FaceSet,
    FaceSetParams, PointTrackSequence, BILINEAR_EXPRESSIONS, TRILINEAR_EXPRESSIONS, VISEMES,
};
pub use ict_basis::{IctBasis, NamedShape, Recipe, ICT_BLENDSHAPES};
pub use tracking::TrackingScenario;
pub use video::{render_face_frame, render_face_video, FaceVideo, FaceVideoParams};
