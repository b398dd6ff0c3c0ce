//! Loader of the MakeHuman rig files (CC0): the `default.mhskel` skeleton (bones whose head and
//! tail are *joints*, each a list of base-mesh vertices whose mean is the joint position) and
//! the `default_weights.mhw` linear-blend-skinning weights (keyed by bone name and by
//! **original** `base.obj` vertex index).
//!
//! The studio's MakeHuman performer keeps a 19-joint subset of the 163-bone rig with the joint
//! names and DOFs of [`human_skeleton`](skin_core::skeleton::human_skeleton) (see
//! [`MAKEHUMAN_SUBSET`]) and merges the weight of every dropped bone into its nearest kept
//! ancestor ([`MhSkeleton::subset_weights`]). MakeHuman files are in **decimetres**
//! ([`MAKEHUMAN_METRES_PER_UNIT`]); everything this module returns is in metres except the raw
//! vertex lists.

use super::deformation::DeformationParams;
use super::performer::Performer;
use serde::Deserialize;
use skin_core::math::{DQuat, DVec3};
use skin_core::mesh::{ObjFile, SkinWeights, TriMesh};
use skin_core::skeleton::{human_skeleton, HumanParams, Skeleton};
use skin_core::{Error, Result};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// Metres per MakeHuman length unit: the base mesh, the rig and its BVH files are in
/// decimetres (body spans y = −8.17 … 8.49, a 1.67 m person; data/makehuman/SOURCE.md).
pub const MAKEHUMAN_METRES_PER_UNIT: f64 = 0.1;

/// The performer's 19-joint subset of the MakeHuman rig: `(performer joint, kept MakeHuman
/// bone, MakeHuman joint giving the performer joint's position)`. Performer joints are those of
/// [`human_skeleton`](skin_core::skeleton::human_skeleton), in its order. The pelvis sits at the
/// root bone's tail (the top of the sacrum; the root's head lies behind the body); limb joints
/// at the head of the bone they rotate (hip = `upperleg01` head, knee = `lowerleg01` head, ...).
pub const MAKEHUMAN_SUBSET: [(&str, &str, &str); 19] = [
    ("pelvis", "root", "root____tail"),
    ("spine", "spine04", "spine04____head"),
    ("chest", "spine02", "spine02____head"),
    ("neck", "neck01", "neck01____head"),
    ("head", "head", "head____head"),
    ("l_clavicle", "clavicle.L", "clavicle.L____head"),
    ("l_shoulder", "upperarm01.L", "upperarm01.L____head"),
    ("l_elbow", "lowerarm01.L", "lowerarm01.L____head"),
    ("l_wrist", "wrist.L", "wrist.L____head"),
    ("r_clavicle", "clavicle.R", "clavicle.R____head"),
    ("r_shoulder", "upperarm01.R", "upperarm01.R____head"),
    ("r_elbow", "lowerarm01.R", "lowerarm01.R____head"),
    ("r_wrist", "wrist.R", "wrist.R____head"),
    ("l_hip", "upperleg01.L", "upperleg01.L____head"),
    ("l_knee", "lowerleg01.L", "lowerleg01.L____head"),
    ("l_ankle", "foot.L", "foot.L____head"),
    ("r_hip", "upperleg01.R", "upperleg01.R____head"),
    ("r_knee", "lowerleg01.R", "lowerleg01.R____head"),
    ("r_ankle", "foot.R", "foot.R____head"),
];

/// End sites of the subset's leaf joints: `(performer joint, MakeHuman joint at the bone tip)`
/// — top of the head, middle fingertip, tip of the big toe.
pub const MAKEHUMAN_END_SITES: [(&str, &str); 5] = [
    ("head", "head____tail"),
    ("l_wrist", "finger3-3.L____tail"),
    ("r_wrist", "finger3-3.R____tail"),
    ("l_ankle", "toe1-2.L____tail"),
    ("r_ankle", "toe1-2.R____tail"),
];

const SKEL_FORMAT: &str = "MHSKEL";
const WEIGHTS_FORMAT: &str = "MHW";

/// One bone of a MakeHuman skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct MhBone {
    /// Bone name, e.g. `"upperarm01.L"`.
    pub name: String,
    /// Index of the parent bone in [`MhSkeleton::bones`] (always smaller), `None` for the root.
    pub parent: Option<usize>,
    /// Name of the joint at the bone's head (a key of [`MhSkeleton::joints`]).
    pub head: String,
    /// Name of the joint at the bone's tail.
    pub tail: String,
}

/// A parsed `.mhskel` file.
#[derive(Debug, Clone, PartialEq)]
pub struct MhSkeleton {
    /// Bones, parents before children.
    pub bones: Vec<MhBone>,
    /// Joint name → original `base.obj` vertex indices (0-based) whose mean is the joint.
    pub joints: HashMap<String, Vec<u32>>,
}

/// One `(vertex, weight)` entry of a `.mhw` file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MhVertexWeight {
    /// Original `base.obj` vertex index (0-based).
    pub vertex: u32,
    /// Skinning weight (the file's values; a vertex's weights sum to about 1).
    pub weight: f64,
}

/// A parsed `.mhw` weights file: bone name → weighted vertices.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MhWeights {
    /// Bone name → its vertices and weights.
    pub bones: BTreeMap<String, Vec<MhVertexWeight>>,
}

#[derive(Deserialize)]
struct RawBone {
    head: String,
    tail: String,
    parent: Option<String>,
}

#[derive(Deserialize)]
struct RawSkeleton {
    bones: BTreeMap<String, RawBone>,
    joints: HashMap<String, Vec<u32>>,
}

#[derive(Deserialize)]
struct RawWeights {
    weights: BTreeMap<String, Vec<(u32, f64)>>,
}

fn json_err(format: &'static str, e: serde_json::Error) -> Error {
    Error::Parse {
        format,
        line: e.line(),
        message: e.to_string(),
    }
}

fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| Error::io(path, e))
}

/// Parses the JSON text of a `.mhskel` file.
///
/// # Errors
/// [`Error::Parse`] (format `"MHSKEL"`) for malformed JSON, a bone whose parent is missing, a
/// parent cycle, a bone head/tail naming no joint, or a joint without vertices.
pub fn parse_mhskel(text: &str) -> Result<MhSkeleton> {
    let raw: RawSkeleton = serde_json::from_str(text).map_err(|e| json_err(SKEL_FORMAT, e))?;
    let perr = |message: String| Error::Parse {
        format: SKEL_FORMAT,
        line: 0,
        message,
    };
    if raw.bones.is_empty() {
        return Err(perr("no bones".into()));
    }
    for (name, b) in &raw.bones {
        for j in [&b.head, &b.tail] {
            match raw.joints.get(j) {
                None => return Err(perr(format!("bone '{name}' names unknown joint '{j}'"))),
                Some(v) if v.is_empty() => {
                    return Err(perr(format!("joint '{j}' has no vertices")))
                }
                Some(_) => {}
            }
        }
        if let Some(p) = &b.parent {
            if !raw.bones.contains_key(p) {
                return Err(perr(format!("bone '{name}' has unknown parent '{p}'")));
            }
        }
    }
    // Topological order: repeatedly emit bones whose parent is already placed.
    let mut index: HashMap<&str, usize> = HashMap::new();
    let mut bones: Vec<MhBone> = Vec::with_capacity(raw.bones.len());
    while bones.len() < raw.bones.len() {
        let before = bones.len();
        for (name, b) in &raw.bones {
            if index.contains_key(name.as_str()) {
                continue;
            }
            let parent = match &b.parent {
                None => None,
                Some(p) => match index.get(p.as_str()) {
                    Some(&i) => Some(i),
                    None => continue,
                },
            };
            index.insert(name, bones.len());
            bones.push(MhBone {
                name: name.clone(),
                parent,
                head: b.head.clone(),
                tail: b.tail.clone(),
            });
        }
        if bones.len() == before {
            return Err(perr("bone parents form a cycle".into()));
        }
    }
    Ok(MhSkeleton {
        bones,
        joints: raw.joints,
    })
}

/// Reads a `.mhskel` file.
///
/// # Errors
/// [`Error::Io`] if unreadable; as [`parse_mhskel`].
pub fn read_mhskel(path: impl AsRef<Path>) -> Result<MhSkeleton> {
    parse_mhskel(&read_text(path.as_ref())?)
}

/// Parses the JSON text of a `.mhw` weights file.
///
/// # Errors
/// [`Error::Parse`] (format `"MHW"`) for malformed JSON or a negative or non-finite weight.
pub fn parse_mhw(text: &str) -> Result<MhWeights> {
    let raw: RawWeights = serde_json::from_str(text).map_err(|e| json_err(WEIGHTS_FORMAT, e))?;
    let mut bones = BTreeMap::new();
    for (name, list) in raw.weights {
        if let Some((v, w)) = list.iter().find(|(_, w)| !(w.is_finite() && *w >= 0.0)) {
            return Err(Error::Parse {
                format: WEIGHTS_FORMAT,
                line: 0,
                message: format!("bone '{name}' has invalid weight {w} on vertex {v}"),
            });
        }
        let list = list
            .into_iter()
            .map(|(vertex, weight)| MhVertexWeight { vertex, weight })
            .collect();
        bones.insert(name, list);
    }
    Ok(MhWeights { bones })
}

/// Reads a `.mhw` file.
///
/// # Errors
/// [`Error::Io`] if unreadable; as [`parse_mhw`].
pub fn read_mhw(path: impl AsRef<Path>) -> Result<MhWeights> {
    parse_mhw(&read_text(path.as_ref())?)
}

impl MhSkeleton {
    /// Index of the bone called `name`.
    pub fn bone_index(&self, name: &str) -> Option<usize> {
        self.bones.iter().position(|b| b.name == name)
    }

    /// Position of joint `name`: the mean of its vertices taken from `vertices` (the full
    /// `base.obj` vertex list, original indices), times `metres_per_unit`.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] for an unknown joint; [`Error::IndexOutOfRange`] if one of its
    /// vertices is past `vertices`.
    pub fn joint_position(
        &self,
        name: &str,
        vertices: &[DVec3],
        metres_per_unit: f64,
    ) -> Result<DVec3> {
        let list = self.joints.get(name).ok_or_else(|| Error::InvalidParam {
            name: "joint",
            reason: format!("the MakeHuman skeleton has no joint '{name}'"),
        })?;
        let mut sum = DVec3::ZERO;
        for &i in list {
            sum += *vertices.get(i as usize).ok_or(Error::IndexOutOfRange {
                what: "MakeHuman joint vertex",
                index: i as usize,
                len: vertices.len(),
            })?;
        }
        // `parse_mhskel` rejects joints without vertices, so `list` is not empty.
        Ok(sum / list.len().max(1) as f64 * metres_per_unit)
    }

    /// For every bone, the index into `kept` of its nearest kept ancestor-or-self, `None` if no
    /// kept bone lies on its path to the root.
    ///
    /// # Errors
    /// [`Error::InvalidParam`] naming a kept bone that does not exist.
    pub fn nearest_kept(&self, kept: &[&str]) -> Result<Vec<Option<usize>>> {
        let mut kept_of_bone: Vec<Option<usize>> = vec![None; self.bones.len()];
        for (k, name) in kept.iter().enumerate() {
            let b = self.bone_index(name).ok_or_else(|| Error::InvalidParam {
                name: "kept bones",
                reason: format!("the MakeHuman skeleton has no bone '{name}'"),
            })?;
            kept_of_bone[b] = Some(k);
        }
        // Parents precede children, so one forward sweep propagates.
        let mut out = vec![None; self.bones.len()];
        for (b, bone) in self.bones.iter().enumerate() {
            out[b] = kept_of_bone[b].or_else(|| bone.parent.and_then(|p| out[p]));
        }
        Ok(out)
    }

    /// Re-targets `weights` onto the kept bones: each dropped bone's weight goes to its nearest
    /// kept ancestor, then every vertex's weights are normalised to sum 1.
    ///
    /// `original_to_local` maps an original `base.obj` vertex index to the performer's vertex
    /// index (`None` for vertices not in the performer mesh, whose weights are ignored);
    /// `vertex_count` is the performer's vertex count. Returns, per performer vertex, the
    /// `(kept index, weight)` pairs sorted by kept index (ready for
    /// [`SkinWeights::from_lists`](skin_core::mesh::SkinWeights::from_lists)).
    ///
    /// # Errors
    /// [`Error::InvalidParam`] naming a weighted bone missing from the skeleton or without kept
    /// ancestor, or a kept bone that does not exist; [`Error::Degenerate`] naming the first
    /// performer vertex left without weight.
    pub fn subset_weights(
        &self,
        weights: &MhWeights,
        kept: &[&str],
        original_to_local: &dyn Fn(u32) -> Option<usize>,
        vertex_count: usize,
    ) -> Result<Vec<Vec<(u32, f64)>>> {
        let nearest = self.nearest_kept(kept)?;
        let mut acc: Vec<BTreeMap<usize, f64>> = vec![BTreeMap::new(); vertex_count];
        for (bone, list) in &weights.bones {
            let b = self.bone_index(bone).ok_or_else(|| Error::InvalidParam {
                name: "weights",
                reason: format!("weights name bone '{bone}', which the skeleton lacks"),
            })?;
            let k = nearest[b].ok_or_else(|| Error::InvalidParam {
                name: "kept bones",
                reason: format!("bone '{bone}' has no kept ancestor; keep the root bone"),
            })?;
            for e in list {
                if let Some(v) = original_to_local(e.vertex).filter(|&v| v < vertex_count) {
                    *acc[v].entry(k).or_insert(0.0) += e.weight;
                }
            }
        }
        acc.into_iter()
            .enumerate()
            .map(|(v, m)| {
                let total: f64 = m.values().sum();
                if total.is_finite() && total > 0.0 {
                    Ok(m.into_iter()
                        .filter(|&(_, w)| w > 0.0)
                        .map(|(k, w)| (k as u32, w / total))
                        .collect())
                } else {
                    Err(Error::Degenerate {
                        what: format!("performer vertex {v} has no skin weight"),
                    })
                }
            })
            .collect()
    }
}

/// Loads the MakeHuman performer from a folder holding `base.obj`, `default.mhskel` and
/// `default_weights.mhw` (e.g. `data/makehuman`); see [`makehuman_performer_from_parts`].
///
/// # Errors
/// [`Error::Io`] for a missing file; as the parsers and [`makehuman_performer_from_parts`].
pub fn makehuman_performer(dir: impl AsRef<Path>, params: &DeformationParams) -> Result<Performer> {
    let dir = dir.as_ref();
    let obj = ObjFile::read(dir.join("base.obj"))?;
    let skel = read_mhskel(dir.join("default.mhskel"))?;
    let weights = read_mhw(dir.join("default_weights.mhw"))?;
    makehuman_performer_from_parts(&obj, &skel, &weights, params)
}

/// Builds the MakeHuman performer: the `body` group of the base mesh converted to metres
/// (13,380 vertices for hm08), the skeleton of
/// [`human_skeleton`](skin_core::skeleton::human_skeleton) (same joint names, DOFs, axes and
/// limits) with its joints moved to the MakeHuman joint positions of [`MAKEHUMAN_SUBSET`] and
/// end sites at [`MAKEHUMAN_END_SITES`], and the `.mhw` weights merged onto the subset.
///
/// **Rest pose.** θ = 0 is the base mesh's own pose: the MakeHuman "A-pose" (arms about 45°
/// from the body, elbows slightly bent). Joint frames stay world-aligned at rest as in
/// `human_skeleton`, so DOF limits are measured from that pose.
///
/// # Errors
/// [`Error::InvalidParam`] if the OBJ has no `body` group or the rig lacks a subset bone or
/// joint; [`Error::Degenerate`] for a body vertex without weight; as [`Performer::new`].
pub fn makehuman_performer_from_parts(
    obj: &ObjFile,
    rig: &MhSkeleton,
    weights: &MhWeights,
    params: &DeformationParams,
) -> Result<Performer> {
    let body = obj.group_mesh("body")?;
    let s = MAKEHUMAN_METRES_PER_UNIT;
    let template = TriMesh::new(
        body.mesh.vertices.iter().map(|v| *v * s).collect(),
        body.mesh.faces.clone(),
    )?;
    let base = human_skeleton(&HumanParams::default())?;
    let joint_of = |name: &str| {
        base.joint_index(name).ok_or_else(|| Error::InvalidParam {
            name: "MAKEHUMAN_SUBSET",
            reason: format!("human skeleton has no joint '{name}'"),
        })
    };
    let mut world = vec![DVec3::ZERO; base.joint_count()];
    let mut joint_of_kept = Vec::with_capacity(MAKEHUMAN_SUBSET.len());
    for (pj, _, mj) in MAKEHUMAN_SUBSET {
        let j = joint_of(pj)?;
        world[j] = rig.joint_position(mj, &obj.vertices, s)?;
        joint_of_kept.push(j as u32);
    }
    let mut joints = base.joints().to_vec();
    for (j, joint) in joints.iter_mut().enumerate() {
        joint.offset = joint.parent.map_or(world[j], |p| world[j] - world[p]);
        joint.end_site = None;
    }
    for (pj, mj) in MAKEHUMAN_END_SITES {
        let j = joint_of(pj)?;
        joints[j].end_site = Some(rig.joint_position(mj, &obj.vertices, s)? - world[j]);
    }
    align_dof_axes(&base, &mut joints)?;
    let skeleton = Skeleton::new(joints)?;
    let local: HashMap<u32, usize> = body
        .original_index
        .iter()
        .enumerate()
        .map(|(i, &o)| (o, i))
        .collect();
    let kept: Vec<&str> = MAKEHUMAN_SUBSET.iter().map(|t| t.1).collect();
    let lists = rig.subset_weights(
        weights,
        &kept,
        &|o| local.get(&o).copied(),
        template.vertex_count(),
    )?;
    let lists: Vec<Vec<(u32, f64)>> = lists
        .into_iter()
        .map(|l| {
            l.into_iter()
                .map(|(k, w)| (joint_of_kept[k as usize], w))
                .collect()
        })
        .collect();
    let weights = SkinWeights::from_lists(&lists, skeleton.joint_count())?;
    let performer = Performer::new("makehuman", template, skeleton, weights, params)?;
    match body.uvs {
        Some(uvs) => performer.with_body_uvs(uvs),
        None => Ok(performer),
    }
}

/// Minimum |sin| of the rest bend for a hinge's plane to be well defined (10°).
const MIN_HINGE_BEND_SIN: f64 = 0.17;

/// Rest direction of joint `j`'s bone (to its first child, else its end site; zero if none).
fn bone_direction(joints: &[skin_core::skeleton::Joint], j: usize) -> DVec3 {
    joints
        .iter()
        .find(|c| c.parent == Some(j))
        .map(|c| c.offset)
        .or(joints[j].end_site)
        .unwrap_or(DVec3::ZERO)
        .normalize_or_zero()
}

/// Adapts the DOF axes of `human_skeleton` (`base`, bones along the world axes) to the
/// MakeHuman rest pose in `joints`: every non-root joint's axes are rotated by the shortest
/// arc taking the canonical bone direction onto the MakeHuman one (so flexion stays
/// perpendicular to the bone, e.g. for the 45°-abducted A-pose arms). For the elbows and
/// knees, the axes are further twisted about the bone so that flexion is about the normal of
/// the plane of the two segments, and the flexion limits are shifted by the rest bend (the
/// MakeHuman elbows are bent ≈ 45° at rest), keeping the anatomical range about the straight
/// limb. Axes stay orthonormal, as retargeting requires.
fn align_dof_axes(base: &Skeleton, joints: &mut [skin_core::skeleton::Joint]) -> Result<()> {
    for j in 0..joints.len() {
        if joints[j].parent.is_none() || joints[j].dofs.is_empty() {
            continue;
        }
        let canon = bone_direction(base.joints(), j);
        let mh = bone_direction(joints, j);
        if canon == DVec3::ZERO || mh == DVec3::ZERO {
            continue;
        }
        let r = DQuat::from_rotation_arc(canon, mh);
        for d in &mut joints[j].dofs {
            d.axis = r * d.axis;
        }
        let name = joints[j].name.clone();
        if !(name.ends_with("_elbow") || name.ends_with("_knee")) {
            continue;
        }
        let Some(p) = joints[j].parent else { continue };
        let upper = bone_direction(joints, p);
        let n = upper.cross(mh);
        if n.length() < MIN_HINGE_BEND_SIN {
            continue;
        }
        let a = joints[j].dofs[0].axis;
        let t = n.normalize() * n.dot(a).signum();
        let twist = DQuat::from_rotation_arc(a, t);
        for d in &mut joints[j].dofs {
            d.axis = (twist * d.axis).normalize();
        }
        let bend = upper.angle_between(mh);
        let flexed = (DQuat::from_axis_angle(t, bend) * upper).distance(mh) < 1e-6;
        let shift = if flexed { bend } else { -bend };
        if let Some(l) = joints[j].dofs[0].limits.as_mut() {
            l.min = (l.min - shift).min(0.0);
            l.max -= shift;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) const TINY_SKEL: &str = r#"{"bones": {
        "root": {"head": "r_h", "tail": "r_t", "parent": null},
        "leg": {"head": "r_t", "tail": "l_t", "parent": "root"},
        "toe": {"head": "l_t", "tail": "t_t", "parent": "leg"}},
      "joints": {"r_h": [0], "r_t": [1, 2], "l_t": [3], "t_t": [3]}}"#;

    #[test]
    fn parses_and_orders_bones() {
        let s = parse_mhskel(TINY_SKEL).unwrap();
        assert_eq!(s.bones.len(), 3);
        for (i, b) in s.bones.iter().enumerate() {
            assert!(b.parent.is_none_or(|p| p < i));
        }
        let v = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let p = s.joint_position("r_t", &v, 0.1).unwrap();
        assert!((p - DVec3::new(0.05, 0.05, 0.0)).length() < 1e-15);
        assert!(s.joint_position("nope", &v, 0.1).is_err());
        assert!(matches!(
            s.joint_position("r_t", &v[..2], 0.1),
            Err(Error::IndexOutOfRange { .. })
        ));
    }

    #[test]
    fn merges_dropped_bones_into_kept_ancestor() {
        let s = parse_mhskel(TINY_SKEL).unwrap();
        let w = parse_mhw(
            r#"{"weights": {"root": [[0, 1.0], [1, 0.25]], "toe": [[1, 0.5], [2, 2.0]]}}"#,
        )
        .unwrap();
        let out = s
            .subset_weights(&w, &["root", "leg"], &|i| Some(i as usize), 3)
            .unwrap();
        assert_eq!(out[0], vec![(0, 1.0)]);
        // Vertex 1: root 0.25 and toe→leg 0.5, normalised.
        assert!((out[1][0].1 - 1.0 / 3.0).abs() < 1e-12 && out[1][1] == (1, 2.0 / 3.0));
        assert_eq!(out[2], vec![(1, 1.0)]);
        // A vertex without weight is an error naming it.
        let err = s
            .subset_weights(&w, &["root", "leg"], &|i| Some(i as usize), 4)
            .unwrap_err();
        assert!(err.to_string().contains("vertex 3"), "{err}");
        // Without the root kept, the root's weight has nowhere to go.
        assert!(s
            .subset_weights(&w, &["leg"], &|i| Some(i as usize), 3)
            .is_err());
        assert!(s
            .subset_weights(&w, &["femur"], &|i| Some(i as usize), 3)
            .is_err());
    }

    #[test]
    fn rejects_malformed_files() {
        assert!(matches!(
            parse_mhskel("{"),
            Err(Error::Parse {
                format: "MHSKEL",
                ..
            })
        ));
        let cyc = r#"{"bones": {"a": {"head": "j", "tail": "j", "parent": "b"},
                                "b": {"head": "j", "tail": "j", "parent": "a"}}, "joints": {"j": [0]}}"#;
        assert!(parse_mhskel(cyc).unwrap_err().to_string().contains("cycle"));
        let missing =
            r#"{"bones": {"a": {"head": "j", "tail": "k", "parent": null}}, "joints": {"j": [0]}}"#;
        assert!(parse_mhskel(missing)
            .unwrap_err()
            .to_string()
            .contains("'k'"));
        let orphan =
            r#"{"bones": {"a": {"head": "j", "tail": "j", "parent": "zz"}}, "joints": {"j": [0]}}"#;
        assert!(parse_mhskel(orphan).is_err());
        let empty_joint =
            r#"{"bones": {"a": {"head": "j", "tail": "j", "parent": null}}, "joints": {"j": []}}"#;
        assert!(parse_mhskel(empty_joint).is_err());
        assert!(matches!(
            parse_mhw("[]"),
            Err(Error::Parse { format: "MHW", .. })
        ));
        assert!(parse_mhw(r#"{"weights": {"a": [[0, -1.0]]}}"#).is_err());
        let s = parse_mhskel(TINY_SKEL).unwrap();
        let w = parse_mhw(r#"{"weights": {"ghost": [[0, 1.0]]}}"#).unwrap();
        assert!(s
            .subset_weights(&w, &["root"], &|i| Some(i as usize), 1)
            .unwrap_err()
            .to_string()
            .contains("ghost"));
    }

    #[test]
    fn real_rig_files_parse_and_merge() {
        let dir = example_kit::data_path("makehuman").unwrap();
        let s = read_mhskel(dir.join("default.mhskel")).unwrap();
        let w = read_mhw(dir.join("default_weights.mhw")).unwrap();
        assert_eq!(s.bones.len(), 163);
        let kept: Vec<&str> = MAKEHUMAN_SUBSET.iter().map(|t| t.1).collect();
        let out = s
            .subset_weights(&w, &kept, &|i| (i < 13380).then_some(i as usize), 13380)
            .unwrap();
        for vw in &out {
            let sum: f64 = vw.iter().map(|p| p.1).sum();
            assert!((sum - 1.0).abs() < 1e-12);
        }
        for (_, _, j) in MAKEHUMAN_SUBSET {
            assert!(s.joints.contains_key(j), "{j}");
        }
        for (_, j) in MAKEHUMAN_END_SITES {
            assert!(s.joints.contains_key(j), "{j}");
        }
    }
}
