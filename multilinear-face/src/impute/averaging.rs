//! The averaging baseline of §5.3.4 (Figure 5-6: Blanz et al.'s copied displacement,
//! generalised to the mean over every identity that has the face), and which masks it can
//! fill.

use nalgebra::{DMatrix, DVector};

use super::moments::{AffineFill, CentredKnown};
use crate::face_data::{FaceTensor, KnownFaces};
use crate::{Error, Result};

/// `known` must describe `faces`' attribute shape.
pub(super) fn check_shapes(faces: &FaceTensor, known: &KnownFaces) -> Result<()> {
    if faces.attribute_sizes() != known.attribute_sizes() {
        return Err(Error::SizeMismatch {
            what: "known-face flags (attribute sizes)",
            expected: faces.face_count(),
            got: known.attribute_sizes().iter().product(),
        });
    }
    Ok(())
}

/// The references of missing face `f = (c, i)` (`c` the non-identity attributes, `i` the
/// identity, the last mode): each known face `(c', i)` of the same person with the identities
/// `i'` that have both `(c, i')` and `(c', i')`, lazily, references without such identities
/// skipped.
fn references(known: &KnownFaces, f: usize) -> impl Iterator<Item = (usize, Vec<usize>)> + '_ {
    let sizes = known.attribute_sizes();
    let d_id = sizes[sizes.len() - 1];
    let d_c = sizes.iter().product::<usize>() / d_id;
    let (c, i) = (f / d_id, f % d_id);
    (0..d_c)
        .filter(move |&cp| cp != c && known.is_known(cp * d_id + i))
        .filter_map(move |cp| {
            let others: Vec<usize> = (0..d_id)
                .filter(|&ip| known.is_known(c * d_id + ip) && known.is_known(cp * d_id + ip))
                .collect();
            (!others.is_empty()).then_some((cp, others))
        })
}

/// Whether [`impute_by_averaging`] can fill every missing face of `known` (each has a
/// reference: a known face of the same person whose attributes another person has together
/// with the missing face's).
pub(crate) fn averaging_can_fill(known: &KnownFaces) -> bool {
    known
        .missing()
        .into_iter()
        .all(|f| references(known, f).next().is_some())
}

/// The averaging baseline as an [`AffineFill`]: each missing face a weighted sum of known
/// faces whose weights sum to 1 (so `a = 0`).
///
/// # Errors
/// [`Error::Empty`] if a missing face has no usable reference.
pub(super) fn averaging_fill(known: &KnownFaces) -> Result<AffineFill> {
    let sizes = known.attribute_sizes();
    let d_id = sizes[sizes.len() - 1];
    let k: usize = sizes.iter().product();
    let observed = known.known();
    let missing = known.missing();
    let mut position = vec![usize::MAX; k];
    for (j, &f) in observed.iter().enumerate() {
        position[f] = j;
    }
    let mut b = DMatrix::zeros(missing.len(), observed.len());
    for (row, &f) in missing.iter().enumerate() {
        let (c, i) = (f / d_id, f % d_id);
        let pairs: Vec<(usize, Vec<usize>)> = references(known, f).collect();
        if pairs.is_empty() {
            return Err(Error::Empty {
                what: "reference faces for the averaging baseline",
            });
        }
        let np = pairs.len() as f64;
        for (cp, others) in &pairs {
            b[(row, position[cp * d_id + i])] += 1.0 / np;
            let w = 1.0 / (np * others.len() as f64);
            for &ip in others {
                b[(row, position[c * d_id + ip])] += w;
                b[(row, position[cp * d_id + ip])] -= w;
            }
        }
    }
    Ok(AffineFill {
        a: DVector::zeros(missing.len()),
        b,
    })
}

/// The averaging baseline (Figure 5-6, "a simple averaging scheme"; Blanz et al.'s copy of
/// one person's displacement, generalised to the mean over every identity that has both
/// faces): a missing face `(c, i)` (`c` the non-identity attributes, `i` the identity, the
/// last mode) is `x(c', i) + mean_{i'} [x(c, i') − x(c', i')]` averaged over the known
/// reference faces `c'` of `i`, with `i'` over the identities that have both `c` and `c'`.
/// Exact when the faces are additive in identity and the other attributes (the additive
/// candidate of [`crate::impute`]).
///
/// # Errors
/// [`Error::SizeMismatch`] if `known` is for another shape; [`Error::Empty`] if a missing face
/// has no usable reference (no identity has both it and one of the person's known faces).
pub fn impute_by_averaging(faces: &FaceTensor, known: &KnownFaces) -> Result<FaceTensor> {
    check_shapes(faces, known)?;
    let fill = averaging_fill(known)?;
    CentredKnown::new(faces, known)?.apply(faces, known, &fill)
}
