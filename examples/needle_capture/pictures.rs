//! The error colouring of `needle_capture`'s preview renders (`example_kit::plot::error_colour`,
//! its scale drawn by `example_kit::plot::with_colour_bar`), and the flexed-elbow figure.

use dynamic_shapes::core::mesh::TriMesh;
use dynamic_shapes::needle::baseline::SkinnedShape;
use dynamic_shapes::needle::truth::TestSet;
use dynamic_shapes::needle::{animate, merged_mesh, primitive_meshes, NeedleBody, NeedleModel};
use dynamic_shapes_studio::{preview, DeformationState, Paint, Performer, PreviewPanel};
use example_kit::plot::{self as kplot, error_colour, ColourBar};
use example_kit::Run;
use image::RgbImage;

use super::{Res, Test, ERROR_MAP_MAX_MM};

/// Per-vertex colours of the per-primitive `meshes` from each primitive's needle errors (mm;
/// `None`: not scored). Needle endpoints come first in each primitive mesh; cap centres are
/// unscored.
pub fn needle_error_colours(meshes: &[TriMesh], err: &[Vec<Option<f64>>]) -> Vec<[u8; 3]> {
    let mut colours = vec![];
    for (m, e) in meshes.iter().zip(err) {
        colours.extend(
            (0..m.vertices.len())
                .map(|v| error_colour(e.get(v).copied().flatten(), ERROR_MAP_MAX_MM)),
        );
    }
    colours
}

/// `img` with the needle-error colour bar, a title and a subtitle.
pub fn with_error_bar(img: &RgbImage, title: &str, subtitle: &str) -> Res<RgbImage> {
    let ramp = |t: f64| error_colour(Some(t * ERROR_MAP_MAX_MM), ERROR_MAP_MAX_MM);
    let img = kplot::with_colour_bar(
        img,
        &ColourBar {
            label: "needle-length error (mm)",
            min: 0.0,
            max: ERROR_MAP_MAX_MM,
            ramp: &ramp,
            note: Some("top: ≥ 20 mm; grey: not scored"),
        },
    )?;
    Ok(kplot::titled(&img, title, Some(subtitle))?)
}

/// One predictor of the flexed-elbow figure.
pub enum Predictor<'a> {
    /// A needle model (all its needles drawn from it).
    Model(&'a NeedleModel),
    /// A closed surface skinned to the pose: its needle lengths where the needles leave it.
    Surface(&'a SkinnedShape),
}

/// `flexed_elbow.png`, like Figure 12 of Sand 2003: the test frame of the most flexed elbow,
/// one panel per predictor coloured by needle error, and the true body.
pub struct Figure12<'a> {
    pub performer: &'a Performer,
    pub body: &'a NeedleBody,
    pub test: &'a Test,
    /// The model whose needles fill in the geometry of needles not scored in this frame.
    pub base: &'a NeedleModel,
}

impl Figure12<'_> {
    /// Index of the test frame with the largest elbow flexion (either side).
    pub fn frame(&self) -> usize {
        let sk = &self.performer.skeleton;
        let dofs: Vec<usize> = ["l_elbow.flexion", "r_elbow.flexion"]
            .iter()
            .filter_map(|n| sk.dof_index(n))
            .collect();
        let flex = |k: usize| {
            let th = &self.test.set.frames[k].theta;
            dofs.iter().map(|&d| th[d].abs()).fold(0.0, f64::max)
        };
        (0..self.test.set.frames.len())
            .max_by(|&a, &b| flex(a).total_cmp(&flex(b)))
            .unwrap_or(0)
    }

    /// Draws and saves the figure; returns the frame drawn.
    pub fn render(&self, run: &mut Run, predictors: &[(&str, Predictor)]) -> Res<usize> {
        let k = self.frame();
        let sk = &self.performer.skeleton;
        let frame = &self.test.set.frames[k];
        let one = TestSet {
            frames: vec![frame.clone()],
        };
        let mut panels = vec![];
        let mut names = vec![];
        for (name, predictor) in predictors {
            let (mut posed, errors) = match predictor {
                Predictor::Model(m) => (animate(self.body, m, sk, &frame.theta)?, one.errors(m)?),
                Predictor::Surface(shape) => {
                    let fk = sk.forward_kinematics(&frame.theta)?;
                    let e = one.surface_errors(self.body, sk, |_| {
                        shape.pose(self.performer, fk.world_from_joint())
                    })?;
                    (animate(self.body, self.base, sk, &frame.theta)?, e)
                }
            };
            let mut err: Vec<Vec<Option<f64>>> = posed
                .primitives
                .iter()
                .map(|p| vec![None; p.endpoints.len()])
                .collect();
            for s in &errors.samples {
                let (p, j) = (s.key.0 as usize, s.key.1 as usize);
                let prim = &mut posed.primitives[p];
                prim.lengths[j] = s.predicted_m;
                prim.endpoints[j] = prim.origins[j] + prim.directions[j] * s.predicted_m;
                err[p][j] = Some((s.predicted_m - s.true_m).abs() * 1e3);
            }
            let colours = needle_error_colours(&primitive_meshes(&posed)?, &err);
            let mean = dynamic_shapes::core::stats::mean(&errors.all_mm);
            names.push(format!("{name}: mean {mean:.1} mm"));
            panels.push((merged_mesh(&posed)?, colours));
        }
        let posed = self
            .performer
            .pose(&frame.theta, &mut DeformationState::default(), 1.0)?;
        let truth = self.performer.mesh(posed.true_vertices);
        let mut views: Vec<PreviewPanel> = panels
            .iter()
            .map(|(mesh, colours)| PreviewPanel {
                mesh,
                paint: Paint::PerVertex(colours),
            })
            .collect();
        views.push(PreviewPanel {
            mesh: &truth,
            paint: Paint::Flat([150, 150, 150]),
        });
        names.push("truth".into());
        let img = with_error_bar(
            &preview(&views, 400)?,
            "The most flexed elbow of the test exercise (like Sand 2003 Figure 12)",
            &format!("left to right: {}", names.join("; ")),
        )?;
        run.save_picture(
            "flexed_elbow.png",
            &img,
            &format!(
                "Test exercise frame {k} (largest elbow flexion), front view: {}. Each \
                 predictor's needle surface is coloured by |predicted − true| needle length \
                 (colour bar in mm; grey: needle not scored in this frame — for LBS those \
                 needles are drawn from the needle model); right: the true body.",
                names.join("; ")
            ),
        )?;
        Ok(k)
    }
}
