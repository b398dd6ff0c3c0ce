//! The rigged template (Vlasic 2010 §2.2, §2.5.1): a mesh, the skeleton embedded in it and
//! linear-blend-skinning weights, valid by construction.

use serde::{Deserialize, Serialize};
use skin_core::math::{DAffine3, DVec3};
use skin_core::mesh::{resize_rest, skin, EdgeTopology, SkinBinding, SkinWeights, TriMesh};
use skin_core::skeleton::{ForwardKinematics, Skeleton};

use crate::error::{Error, Result};

/// A template mesh rigged with a skeleton (§2.2): "the skeleton is positioned within the
/// template mesh and each vertex is assigned a weight that is used to deform the template
/// with linear blend skinning". The mesh is in the skeleton's rest pose θ = 0.
///
/// Invariants (checked by [`Template::new`]): a valid mesh with faces and no non-manifold
/// edge, one weight row per vertex, one weight column per joint. Open boundaries (a skirt's
/// hem and waistband) and several components (a body and its garment) are allowed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Template {
    mesh: TriMesh,
    skeleton: Skeleton,
    weights: SkinWeights,
    /// The LBS bind matrices.
    binding: SkinBinding,
    /// Vertices marked as loose cloth ([`Template::with_loose_vertices`]); empty: none.
    #[serde(default)]
    loose: Vec<bool>,
}

impl Template {
    /// Checks and binds a template: the bind matrices are the inverse joint frames of the
    /// rest pose θ = 0.
    ///
    /// # Errors
    /// As [`SkinBinding::new`] (invalid mesh, weights of another mesh or skeleton);
    /// [`Error::Empty`] for a mesh without faces; [`Error::InvalidParam`] for a mesh with an
    /// edge shared by three or more faces: the cotangent Laplacian coordinates of §2.4.1 (each
    /// vertex against its one-ring) and the inside tests of the depth term's radii (§2.3.1)
    /// need a surface whose every edge borders one or two faces.
    pub fn new(mesh: TriMesh, skeleton: Skeleton, weights: SkinWeights) -> Result<Self> {
        let binding = SkinBinding::new(&mesh, &skeleton, &weights)?;
        if mesh.faces.is_empty() {
            return Err(Error::Empty {
                what: "template mesh faces (give a triangle mesh, not a point cloud)",
            });
        }
        let non_manifold = EdgeTopology::new(&mesh)?.non_manifold_edges();
        if let Some(e) = non_manifold.first() {
            return Err(Error::InvalidParam {
                name: "template",
                reason: format!(
                    "{} edges are shared by three or more faces (the first joins vertices {} \
                     and {}); split or remove the extra faces",
                    non_manifold.len(),
                    e[0],
                    e[1]
                ),
            });
        }
        Ok(Template {
            mesh,
            skeleton,
            weights,
            binding,
            loose: Vec::new(),
        })
    }

    /// This template with `loose[v]` marking loose cloth: a skirt below its waistband, a
    /// coat's tails. Beyond the thesis: its nearly-rigid rule (§2.4.2) pins every vertex
    /// with a bone weight ≥ 0.95 at its skinned position in Eq. 2.1, and a rigger's skirt
    /// weights bind most of the skirt rigidly to one thigh or the pelvis, so Eq. 2.1 would
    /// start the cloth where the leg, not the cloth, is (and the tracker seldom recovers:
    /// the 5 cm limit of §2.4.2 rejects the contour constraints that would free it). A loose
    /// vertex is never nearly rigid ([`Template::nearly_rigid`]); Eq. 2.1 interpolates it
    /// from the pinned body and waistband, and the silhouettes move it from there.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] unless `loose` has one entry per vertex.
    pub fn with_loose_vertices(mut self, loose: Vec<bool>) -> Result<Self> {
        skin_core::check::same_size(
            "loose vertices vs template vertices",
            self.vertex_count(),
            loose.len(),
        )?;
        self.loose = loose;
        Ok(self)
    }

    /// Whether vertex `v` is marked as loose cloth ([`Template::with_loose_vertices`]).
    pub fn is_loose(&self, v: usize) -> bool {
        self.loose.get(v).copied().unwrap_or(false)
    }

    /// The template mesh in the rest pose, metres.
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// The embedded skeleton.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// The skinning weights (bones = joints).
    pub fn weights(&self) -> &SkinWeights {
        &self.weights
    }

    /// The template's faces with other vertex positions (a shape estimate, a skinned pose).
    pub fn mesh_with(&self, vertices: Vec<DVec3>) -> TriMesh {
        TriMesh {
            vertices,
            faces: self.mesh.faces.clone(),
        }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.mesh.vertex_count()
    }

    /// The skinning transforms `world_from_rest[j] = world_from_joint[j] ·
    /// joint_from_world_rest[j]` of a posed skeleton.
    pub fn world_from_rest(&self, fk: &ForwardKinematics) -> Vec<DAffine3> {
        self.binding.world_from_rest(fk.world_from_joint())
    }

    /// The template posed at θ by linear blend skinning ("LBS" of Figure 2-3).
    ///
    /// # Errors
    /// As [`Skeleton::check_pose`].
    pub fn skin(&self, theta: &[f64]) -> Result<Vec<DVec3>> {
        let fk = self.skeleton.forward_kinematics(theta)?;
        Ok(skin(
            &self.mesh.vertices,
            &self.weights,
            &self.world_from_rest(&fk),
        )?)
    }

    /// A shape of this template at pose `from` (a molded frame) carried to pose `to` by the
    /// pose change: each vertex moves with its skin weights' blend of the bones' moves,
    /// `v' = Σ_j w_ij M_j(to) M_j(from)⁻¹ v` with `M_j` the skinning transforms. What the
    /// shape adds to skinning (cloth hanging off its skinned place, a bulge) rides along with
    /// the bones; `carry(template vertices, rest, θ)` is [`Template::skin`].
    ///
    /// # Errors
    /// [`Error::Core`] with a size mismatch for `vertices` of another mesh; as
    /// [`Skeleton::check_pose`] for either pose.
    pub fn carry(&self, vertices: &[DVec3], from: &[f64], to: &[f64]) -> Result<Vec<DVec3>> {
        let (a, b) = (
            self.skeleton.forward_kinematics(from)?,
            self.skeleton.forward_kinematics(to)?,
        );
        let moves: Vec<DAffine3> = self
            .world_from_rest(&b)
            .iter()
            .zip(self.world_from_rest(&a))
            .map(|(to, from)| *to * from.inverse())
            .collect();
        Ok(skin(vertices, &self.weights, &moves)?)
    }

    /// This template re-rigged to `skeleton`, the same joint tree with other bone lengths (a
    /// performer sized by [`crate::size_performer`]): each rest vertex moves with its skin
    /// weights' blend of the joints' rest-frame moves (linear blend skinning from this
    /// skeleton's rest frames, θ = 0, to the new one's), so a vertex carried by one bone
    /// follows its joint and the limbs keep their cross-sections. Weights and loose vertices
    /// are kept.
    ///
    /// The rule is skin-core's [`resize_rest`] (the studio's `Performer::with_bone_scales`
    /// uses it too).
    ///
    /// # Errors
    /// As [`resize_rest`] (a skeleton with another joint count or other parents); as
    /// [`Template::new`].
    pub fn resized(&self, skeleton: Skeleton) -> Result<Template> {
        let vertices = resize_rest(
            &self.mesh.vertices,
            &self.weights,
            &self.skeleton,
            &skeleton,
        )?;
        let loose = self.loose.clone();
        Template::new(self.mesh_with(vertices), skeleton, self.weights.clone())?
            .with_loose_vertices(if loose.is_empty() {
                vec![false; self.vertex_count()]
            } else {
                loose
            })
    }

    /// The vertices whose largest weight is at least `min_weight` (the *nearly-rigid*
    /// vertices of §2.4.2 for `min_weight` = 0.95), with that bone; loose vertices
    /// ([`Template::with_loose_vertices`]) excepted.
    pub fn nearly_rigid(&self, min_weight: f64) -> Vec<(usize, usize)> {
        (0..self.vertex_count())
            .filter(|&i| !self.is_loose(i))
            .filter_map(|i| {
                self.weights
                    .influences(i)
                    .find(|&(_, w)| w >= min_weight)
                    .map(|(b, _)| (i, b as usize))
            })
            .collect()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use skin_core::mesh::shapes;
    use skin_core::skeleton::{Dof, Joint};

    /// A two-joint skeleton (root with a translation and a bend about z; a child 0.5 m up)
    /// in a capsule-like subdivided box, weights by height.
    pub(crate) fn bendy() -> Template {
        let mut mesh = shapes::icosphere(3).unwrap();
        for v in &mut mesh.vertices {
            *v = DVec3::new(0.15 * v.x, 0.5 + 0.5 * v.y, 0.15 * v.z);
        }
        let root = Joint::new(
            "root",
            None,
            DVec3::ZERO,
            vec![
                Dof::translation("tx", DVec3::X, None),
                Dof::rotation("rz", DVec3::Z, None),
            ],
        );
        let child = Joint::new(
            "child",
            Some(0),
            DVec3::new(0.0, 0.5, 0.0),
            vec![Dof::rotation("bend", DVec3::Z, None)],
        );
        let skeleton = Skeleton::new(vec![root, child]).unwrap();
        let lists: Vec<Vec<(u32, f64)>> = mesh
            .vertices
            .iter()
            .map(|v| {
                let t = ((v.y - 0.4) / 0.2).clamp(0.0, 1.0);
                vec![(0, 1.0 - t), (1, t)]
            })
            .collect();
        let weights = SkinWeights::from_lists(&lists, 2).unwrap();
        Template::new(mesh, skeleton, weights).unwrap()
    }

    #[test]
    fn rest_pose_skins_to_the_template_and_rigid_vertices_follow_their_bone() {
        let t = bendy();
        let rest = t.skin(&t.skeleton().rest_pose()).unwrap();
        for (a, b) in rest.iter().zip(&t.mesh().vertices) {
            assert!((*a - *b).length() < 1e-12);
        }
        let rigid = t.nearly_rigid(0.95);
        assert!(!rigid.is_empty() && rigid.len() < t.vertex_count());
        assert!(rigid
            .iter()
            .all(|&(i, b)| (b == 0) == (t.mesh().vertices[i].y < 0.5)));
    }

    #[test]
    fn a_non_manifold_template_is_rejected_and_an_open_one_accepted() {
        let t = bendy();
        // A fin: a new vertex and a face on an existing edge make it shared by three faces.
        let mut mesh = t.mesh().clone();
        let [a, b, _] = mesh.faces[0];
        mesh.vertices.push(DVec3::new(0.5, 0.5, 0.5));
        let fin = (mesh.vertices.len() - 1) as u32;
        mesh.faces.push([a, b, fin]);
        let mut lists: Vec<Vec<(u32, f64)>> = (0..t.vertex_count())
            .map(|i| t.weights().influences(i).collect())
            .collect();
        lists.push(vec![(0, 1.0)]);
        let weights = SkinWeights::from_lists(&lists, 2).unwrap();
        let e = Template::new(mesh, t.skeleton().clone(), weights).unwrap_err();
        assert!(
            matches!(&e, Error::InvalidParam { name: "template", reason } if reason.contains("three or more faces")),
            "{e}"
        );
        // Removing a face opens a hole: an open template (a skirt) is fine.
        let mut open = t.mesh().clone();
        open.faces.pop();
        assert!(Template::new(open, t.skeleton().clone(), t.weights().clone()).is_ok());
    }

    #[test]
    fn a_resized_template_follows_its_longer_bone() {
        let t = bendy();
        let mut joints = t.skeleton().joints().to_vec();
        joints[1].offset *= 1.2; // the child 0.6 m up instead of 0.5
        let r = t.resized(Skeleton::new(joints).unwrap()).unwrap();
        for (a, b) in t.mesh().vertices.iter().zip(&r.mesh().vertices) {
            // Below the blend region: unmoved; above it: 0.1 m up; in between: a blend.
            let expected = a.y + 0.1 * ((a.y - 0.4) / 0.2).clamp(0.0, 1.0);
            assert!((b.y - expected).abs() < 1e-12 && (b.x - a.x).abs() < 1e-12);
        }
        // The rest pose still skins to the (resized) template.
        let rest = r.skin(&r.skeleton().rest_pose()).unwrap();
        assert!(rest
            .iter()
            .zip(&r.mesh().vertices)
            .all(|(a, b)| (*a - *b).length() < 1e-12));
        let other = Skeleton::new(t.skeleton().joints()[..1].to_vec()).unwrap();
        assert!(matches!(
            t.resized(other),
            Err(Error::Core(skin_core::Error::InvalidParam {
                name: "skeleton",
                ..
            }))
        ));
    }

    #[test]
    fn carry_moves_a_shape_with_the_pose_change_and_composes() {
        let t = bendy();
        let rest = t.skeleton().rest_pose();
        let (a, b) = (vec![0.1, 0.3, -0.4], vec![-0.05, 0.1, 0.6]);
        // From the rest pose, carrying is skinning.
        let skinned = t.skin(&a).unwrap();
        let carried = t.carry(&t.mesh().vertices, &rest, &a).unwrap();
        assert!(skinned
            .iter()
            .zip(&carried)
            .all(|(p, q)| p.distance(*q) < 1e-12));
        // A bulge off the skinned surface at `a` keeps its size along a rigid part at `b`.
        let mut shape = skinned.clone();
        let v = (0..shape.len())
            .find(|&i| t.mesh().vertices[i].y < 0.2)
            .unwrap();
        shape[v] += DVec3::new(0.02, 0.0, 0.0);
        let there = t.carry(&shape, &a, &b).unwrap();
        let lbs_b = t.skin(&b).unwrap();
        assert!((there[v].distance(lbs_b[v]) - 0.02).abs() < 1e-9);
        // Carrying a → b → rest returns the shape's rest-frame vertices for rigid ones.
        let back = t.carry(&there, &b, &rest).unwrap();
        let rest_shape = t.carry(&shape, &a, &rest).unwrap();
        assert!(back[v].distance(rest_shape[v]) < 1e-9);
        assert!(t.carry(&shape[..3], &a, &b).is_err());
        assert!(t.carry(&shape, &a, &[0.0]).is_err());
    }

    #[test]
    fn mismatched_weights_are_rejected() {
        let t = bendy();
        let short = SkinWeights::from_lists(&[vec![(0, 1.0)]], 2).unwrap();
        let e = Template::new(t.mesh().clone(), t.skeleton().clone(), short).unwrap_err();
        assert!(
            matches!(e, Error::Core(skin_core::Error::SizeMismatch { .. })),
            "{e}"
        );
        let no_faces = TriMesh {
            vertices: t.mesh().vertices.clone(),
            faces: vec![],
        };
        let e = Template::new(no_faces, t.skeleton().clone(), t.weights().clone()).unwrap_err();
        assert!(matches!(e, Error::Empty { .. }), "{e}");
    }

    #[test]
    fn loose_vertices_are_never_nearly_rigid() {
        let t = bendy();
        let rigid = t.nearly_rigid(0.95);
        assert!(!rigid.is_empty());
        // Everything above 0.8 m is loose cloth.
        let loose: Vec<bool> = t.mesh().vertices.iter().map(|v| v.y > 0.8).collect();
        let marked = t.clone().with_loose_vertices(loose.clone()).unwrap();
        let kept = marked.nearly_rigid(0.95);
        assert!(kept.iter().all(|&(v, _)| !loose[v]));
        assert_eq!(
            kept.len(),
            rigid.iter().filter(|&&(v, _)| !loose[v]).count()
        );
        assert!(kept.len() < rigid.len());
        assert!(marked.is_loose(loose.iter().position(|&l| l).unwrap()));
        let e = t.with_loose_vertices(vec![true; 3]).unwrap_err();
        assert!(e.to_string().contains("size mismatch"), "{e}");
    }
}
