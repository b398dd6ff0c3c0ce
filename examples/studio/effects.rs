//! The studio's non-skinning effects measured over its motions, and their pictures: the
//! free exercise's coverage, each effect of the ground truth (pose-driven shapes, dynamic
//! garment and flap, render-time wrinkles) on the CMU walk and on the exercise, the skirt's
//! hem lag, the cost of the whole deformation, and the effect, skirt and wrinkle pictures.

use std::ops::Range;
use std::path::Path;
use std::time::Instant;

use dynamic_shapes::core::camera::{Camera, Intrinsics};
use dynamic_shapes::core::image::normals_rgb8;
use dynamic_shapes::core::math::{DQuat, DVec3};
use dynamic_shapes::core::mesh::TriMesh;
use dynamic_shapes::core::raster::{Buffers, Rasterizer, RenderParams, RenderedView, NO_TRIANGLE};
use dynamic_shapes::core::skeleton::{read_bvh, BvhParams, Motion};
use dynamic_shapes::core::stats::{median, percentile};
use dynamic_shapes_studio::{
    exercise_motion, fast_motion, max_pose_share, preview, procedural_performer, range_coverage,
    range_of_motion, retarget, DeformationParams, DeformationState, ExerciseParams,
    FastMotionParams, GarmentParams, JointMap, Paint, Performer, PosedFrame, PreviewPanel,
    ProceduralBodyParams, RangeOfMotionParams, RetargetParams, SkirtParams, WrinkleParams,
};
use example_kit::data_path;
use example_kit::plot::{self as kplot, ColourBar};
use image::{Rgb32FImage, RgbImage};
use serde_json::{json, Map, Value};

use crate::contact_sheet::ramp;
use crate::AnyResult;

/// Top of the colour scale of `nonskinning_pose.png`, mm.
const POSE_SCALE_MM: f64 = 30.0;
/// Elbow flexion of `wrinkle_closeup.png`, degrees: the crease open enough to see into.
const CLOSEUP_FLEXION_DEG: f64 = 60.0;
/// The wrinkles are measured on every `FINE_EVERY`-th measured frame (the refined surface with
/// the skirt has 1.5 M vertices: about 0.2 s a frame on one core).
const FINE_EVERY: usize = 10;
/// Thresholds of the per-effect vertex counts, mm (the goals' 2, 5 and 10 mm, docs/studio.md).
const LIMITS_MM: [f64; 3] = [2.0, 5.0, 10.0];

/// The deformation of the performer with every effect on: the default pose-driven shapes,
/// the skirt (instead of the hip flap, its skin-tight stand-in) and the render-time wrinkles.
pub(crate) fn full_deformation() -> DeformationParams {
    DeformationParams::default()
        .with_flap(None)
        .with_garment(Some(GarmentParams::Skirt(SkirtParams::default())))
        .with_wrinkles(Some(WrinkleParams::default()))
}

/// The size of one effect over a motion: its largest displacement and, per threshold of
/// [`LIMITS_MM`], the largest number of vertices moved more than that in one frame.
#[derive(Debug, Clone, Copy, Default)]
struct EffectSize {
    max_mm: f64,
    over: [usize; 3],
}

impl EffectSize {
    fn add(&mut self, displacement: &[DVec3]) {
        let mm: Vec<f64> = displacement.iter().map(|d| d.length() * 1e3).collect();
        self.max_mm = mm.iter().copied().fold(self.max_mm, f64::max);
        for (o, limit) in self.over.iter_mut().zip(LIMITS_MM) {
            *o = (*o).max(mm.iter().filter(|&&d| d > limit).count());
        }
    }

    fn write(&self, out: &mut Map<String, Value>, prefix: &str) {
        out.insert(format!("{prefix}_max_mm"), json!(self.max_mm));
        for (o, limit) in self.over.iter().zip(LIMITS_MM) {
            out.insert(format!("{prefix}_vertices_over_{limit}mm"), json!(o));
        }
    }
}

/// The largest displacement of the garment's vertices from the skinned garment, m: the hem
/// lag (the hem moves furthest).
fn garment_lag_m(f: &PosedFrame, garment: &Range<usize>) -> f64 {
    f.dynamic_displacement[garment.clone()]
        .iter()
        .map(|d| d.length())
        .fold(0.0, f64::max)
}

/// The free multi-DOF exercise (5 minutes at 30 fps, the acceptance length in
/// docs/studio.md) measured by its range coverage and largest held-pose share, against the
/// range of motion's.
pub(crate) fn exercise_figures(p: &Performer) -> AnyResult<(Motion, Value)> {
    let exercise = exercise_motion(&p.skeleton, &ExerciseParams::default())?;
    let coverage = range_coverage(&p.skeleton, &exercise)?
        .iter()
        .map(|c| c.coverage)
        .fold(1.0, f64::min);
    let share = max_pose_share(&p.skeleton, &exercise, 5.0)?;
    let rom_share = max_pose_share(
        &p.skeleton,
        &range_of_motion(&p.skeleton, &RangeOfMotionParams::default())?,
        5.0,
    )?;
    let fig = json!({
        "exercise_frames": exercise.frame_count(),
        "exercise_range_coverage_min": coverage,
        "exercise_max_pose_share": share.share,
        "exercise_max_pose_share_joint": p.skeleton.joints()[share.joint].name,
        "rom_max_pose_share": rom_share.share,
    });
    Ok((exercise, fig))
}

/// Each effect of the ground truth on the walk and on the exercise (every `stride`-th frame,
/// the wrinkles on every [`FINE_EVERY`]-th of those; every frame is posed, so the dynamics are
/// exact), for `full`, the performer with every effect on ([`full_deformation`]): their
/// sizes, the skirt's hem lag (also over the fast motion) and the walk's frame where it is
/// largest (`walk_skirt_hem_lag_frame`), the wrinkles' amplitude, and the cost per frame on one core of
/// the deformation (posing with every effect, the skirt's simulation included) and, apart, of
/// the render-time refinement with its wrinkles.
pub(crate) fn effect_figures(
    full: &Performer,
    walk: &Motion,
    exercise: &Motion,
    stride: usize,
) -> AnyResult<Value> {
    let garment = full.garment_vertices();
    let mut out = Map::new();
    let (mut deform_ms, mut fine_ms) = (Vec::new(), Vec::new());
    let (mut pose_all, mut wrinkle_max_mm, mut lag_max_mm) =
        (EffectSize::default(), 0.0f64, 0.0f64);
    let one_core = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    for (name, motion, step) in [("walk", walk, 1), ("exercise", exercise, stride)] {
        let (mut pose, mut dynamic, mut wrinkle) = Default::default();
        let (mut lag_mm, mut lag_frame) = (0.0f64, 0);
        let mut state = DeformationState::default();
        for k in 0..motion.frame_count() {
            // The deformation of one frame, timed on one core: posing (skinning, the
            // pose-driven shapes and the garment's simulation); then, on the measured frames,
            // the render-time refinement with its wrinkles, timed apart.
            let t = Instant::now();
            let f =
                one_core.install(|| full.pose(motion.frame(k), &mut state, motion.frame_time_s))?;
            if k % step != 0 {
                continue;
            }
            deform_ms.push(t.elapsed().as_secs_f64() * 1e3);
            EffectSize::add(&mut pose, &f.pose_displacement);
            EffectSize::add(&mut dynamic, &f.dynamic_displacement);
            if k % (step * FINE_EVERY) == 0 {
                let t = Instant::now();
                let fine = one_core.install(|| full.fine_surface(motion.frame(k), &f))?;
                fine_ms.push(t.elapsed().as_secs_f64() * 1e3);
                if let Some(fine) = &fine {
                    EffectSize::add(&mut wrinkle, &fine.wrinkle_displacement);
                }
            }
            let lag = garment_lag_m(&f, &garment) * 1e3;
            if lag > lag_mm {
                (lag_mm, lag_frame) = (lag, k);
            }
        }
        pose.write(&mut out, &format!("{name}_pose_deform"));
        dynamic.write(&mut out, &format!("{name}_dynamic"));
        wrinkle.write(&mut out, &format!("{name}_wrinkle"));
        out.insert(format!("{name}_skirt_hem_lag_max_mm"), json!(lag_mm));
        out.insert(format!("{name}_skirt_hem_lag_frame"), json!(lag_frame));
        pose_all.max_mm = pose_all.max_mm.max(pose.max_mm);
        pose_all.over[1] = pose_all.over[1].max(pose.over[1]);
        wrinkle_max_mm = wrinkle_max_mm.max(wrinkle.max_mm);
        lag_max_mm = lag_max_mm.max(lag_mm);
    }
    // The fast motion: the skirt's largest lag.
    let fast = fast_motion(&full.skeleton, &FastMotionParams::default())?;
    let mut fast_lag_mm = 0.0f64;
    full.perform(&fast, |_, f| {
        fast_lag_mm = fast_lag_mm.max(garment_lag_m(f, &garment) * 1e3);
        Ok(())
    })?;
    out.insert("fast_skirt_hem_lag_max_mm".into(), json!(fast_lag_mm));
    out.insert("pose_deform_max_mm".into(), json!(pose_all.max_mm));
    out.insert(
        "pose_deform_vertices_over_5mm".into(),
        json!(pose_all.over[1]),
    );
    out.insert(
        "skirt_hem_lag_max_mm".into(),
        json!(lag_max_mm.max(fast_lag_mm)),
    );
    out.insert("wrinkle_amplitude_mm".into(), json!(wrinkle_max_mm));
    out.insert("deform_ms_per_frame".into(), json!(median(&deform_ms)));
    out.insert("fine_surface_ms_per_frame".into(), json!(median(&fine_ms)));
    out.insert("full_vertices".into(), json!(full.vertex_count()));
    out.insert("garment_vertices".into(), json!(garment.len()));
    if let Some(w) = full.wrinkles() {
        out.insert("fine_vertices".into(), json!(w.fine_vertex_count()));
        out.insert("fine_faces".into(), json!(w.fine_faces().len()));
    }
    Ok(Value::Object(out))
}

/// The non-skinning deformation of the performers over the studio's motions (the figures of
/// the former ignored test `studio::tests::figures`).
pub(crate) fn deformation_figures(p: &Performer) -> AnyResult<Value> {
    let rom = range_of_motion(&p.skeleton, &RangeOfMotionParams::default())?;
    let fast = fast_motion(&p.skeleton, &FastMotionParams::default())?;
    let t = Instant::now();
    let d_rom = p.max_nonskinning_m(&rom)?;
    let per_frame_ms = t.elapsed().as_secs_f64() * 1e3 / rom.frame_count() as f64;
    let d_fast = p.max_nonskinning_m(&fast)?;
    eprintln!(
        "deformation: makehuman {} vertices; range of motion {} frames, max non-skinning {:.1} mm ({per_frame_ms:.2} ms/frame); fast motion {:.1} mm",
        p.vertex_count(),
        rom.frame_count(),
        d_rom * 1e3,
        d_fast * 1e3
    );
    let mut fig = json!({
        "rom_frames": rom.frame_count(),
        "rom_max_nonskinning_mm": d_rom * 1e3,
        "nonskinning_ms_per_frame": per_frame_ms,
        "fast_max_nonskinning_mm": d_fast * 1e3,
    });
    let obj = fig.as_object_mut().ok_or("json object")?;
    // The MakeHuman walk (CMU 131_01 is the capture above), retargeted at 30 Hz.
    let bvh = read_bvh(
        data_path("makehuman/walk1.bvh")?,
        &BvhParams {
            metres_per_unit: 0.1,
        },
    )?;
    let map = JointMap::detect(&bvh.skeleton)?;
    let r = retarget(
        &bvh.skeleton,
        &bvh.motion,
        &p.skeleton,
        &map,
        &RetargetParams::default(),
    )?;
    let m = r.motion.resample(&p.skeleton, 1.0 / 30.0)?;
    let d_walk1 = p.max_nonskinning_m(&m)?;
    eprintln!(
        "deformation: makehuman/walk1.bvh scale {:.3}, {} frames at 30 Hz, max non-skinning {:.1} mm",
        r.scale,
        m.frame_count(),
        d_walk1 * 1e3
    );
    obj.insert("walk1_scale".into(), json!(r.scale));
    obj.insert("walk1_frames".into(), json!(m.frame_count()));
    obj.insert("walk1_max_nonskinning_mm".into(), json!(d_walk1 * 1e3));
    // The procedural performer: built at its default 2 cm grid (timed); the 3 cm grid of the
    // tests over the range of motion.
    let t = Instant::now();
    let q = procedural_performer(&ProceduralBodyParams::default())?;
    obj.insert(
        "procedural_build_s".into(),
        json!(t.elapsed().as_secs_f64()),
    );
    obj.insert("procedural_vertices".into(), json!(q.vertex_count()));
    let q3 = procedural_performer(&ProceduralBodyParams {
        grid_spacing_m: 0.03,
        ..Default::default()
    })?;
    let d = q3.max_nonskinning_m(&range_of_motion(
        &q3.skeleton,
        &RangeOfMotionParams::default(),
    )?)?;
    obj.insert("procedural_3cm_vertices".into(), json!(q3.vertex_count()));
    obj.insert(
        "procedural_3cm_rom_max_nonskinning_mm".into(),
        json!(d * 1e3),
    );
    Ok(fig)
}

/// `nonskinning_pose.png` (the former ignored test `studio::tests::picture`): the performer
/// with four joints flexed, coloured by |truth − LBS|, front and side; returns its figures.
pub(crate) fn pose_picture(p: &Performer, out: &Path) -> AnyResult<Value> {
    let mut theta = p.skeleton.rest_pose();
    for (n, v) in [
        ("l_elbow.flexion", 2.0),
        ("r_knee.flexion", 1.5),
        ("r_hip.flexion", 0.8),
        ("l_shoulder.flexion", 0.6),
    ] {
        theta[p.skeleton.dof_index(n).ok_or("the performer has the DOF")?] = v;
    }
    let f = p.pose(&theta, &mut DeformationState::default(), 0.05)?;
    let dist_mm: Vec<f64> = f
        .lbs_vertices
        .iter()
        .zip(&f.true_vertices)
        .map(|(a, b)| a.distance(*b) * 1e3)
        .collect();
    let max_mm = dist_mm.iter().copied().fold(0.0, f64::max);
    let above_10mm = dist_mm.iter().filter(|&&d| d > 10.0).count();
    let colours: Vec<[u8; 3]> = dist_mm
        .iter()
        .map(|d| ramp(d / POSE_SCALE_MM).map(|c| (255.0 * c) as u8))
        .collect();
    let front = p.mesh(f.true_vertices.clone());
    let turn = DQuat::from_rotation_y(-std::f64::consts::FRAC_PI_2);
    let side = p.mesh(f.true_vertices.iter().map(|v| turn * *v).collect());
    let img = preview(
        &[
            PreviewPanel {
                mesh: &front,
                paint: Paint::PerVertex(&colours),
            },
            PreviewPanel {
                mesh: &side,
                paint: Paint::PerVertex(&colours),
            },
        ],
        480,
    )?;
    let ramp_u8 = |t: f64| ramp(t).map(|c| (255.0 * c) as u8);
    let img = kplot::with_colour_bar(
        &img,
        &ColourBar {
            label: "|truth − LBS| (mm)",
            min: 0.0,
            max: POSE_SCALE_MM,
            ramp: &ramp_u8,
            note: Some(&format!("top: ≥ {POSE_SCALE_MM} mm")),
        },
    )?;
    let img = kplot::titled(
        &img,
        "Non-skinning deformation in a test pose",
        Some(&format!(
            "left elbow, right knee, right hip and left shoulder flexed; front and side; largest {max_mm:.1} mm, {above_10mm} vertices above 10 mm"
        )),
    )?;
    kplot::save(&img, out.join("nonskinning_pose.png"))?;
    Ok(json!({
        "pose_max_nonskinning_mm": max_mm,
        "pose_vertices_above_10mm": above_10mm,
    }))
}

/// Poses `p` through `motion` up to frame `k` (the dynamics need every earlier frame) and
/// returns that frame.
pub(crate) fn posed_at(p: &Performer, motion: &Motion, k: usize) -> AnyResult<PosedFrame> {
    let mut state = DeformationState::default();
    let mut last = None;
    for j in 0..=k.min(motion.frame_count().saturating_sub(1)) {
        last = Some(p.pose(motion.frame(j), &mut state, motion.frame_time_s)?);
    }
    Ok(last.ok_or("the motion has frames")?)
}

/// False colours of per-vertex magnitudes (mm) on `0..=top_mm`; `grey` for vertices where
/// `grey(v)` holds.
fn paint_mm(d: &[DVec3], top_mm: f64, grey: impl Fn(usize) -> bool) -> Vec<[u8; 3]> {
    d.iter()
        .enumerate()
        .map(|(v, d)| {
            if grey(v) {
                [150, 150, 150]
            } else {
                ramp(d.length() * 1e3 / top_mm).map(|c| (255.0 * c) as u8)
            }
        })
        .collect()
}

/// One panel: `mesh` painted `colours`, front view (or from the performer's left side), with
/// its colour bar and title.
fn panel(
    mesh: &TriMesh,
    colours: &[[u8; 3]],
    side: bool,
    title: &str,
    bar: Option<(&str, f64)>,
) -> AnyResult<RgbImage> {
    let turned;
    let mesh = if side {
        let turn = DQuat::from_rotation_y(-std::f64::consts::FRAC_PI_2);
        turned = TriMesh {
            vertices: mesh.vertices.iter().map(|v| turn * *v).collect(),
            faces: mesh.faces.clone(),
        };
        &turned
    } else {
        mesh
    };
    let img = preview(
        &[PreviewPanel {
            mesh,
            paint: Paint::PerVertex(colours),
        }],
        440,
    )?;
    let ramp_u8 = |t: f64| ramp(t).map(|c| (255.0 * c) as u8);
    let img = match bar {
        Some((label, max)) => kplot::with_colour_bar(
            &img,
            &ColourBar {
                label,
                min: 0.0,
                max,
                ramp: &ramp_u8,
                note: None,
            },
        )?,
        None => img,
    };
    Ok(kplot::titled(&img, title, None)?)
}

/// `effects.png`: the performer with every effect on, at frame `k` of `motion`, coloured by
/// each part of the ground truth beyond skinning (pose-driven, dynamic, wrinkles).
pub(crate) fn effects_picture(
    full: &Performer,
    motion: &Motion,
    k: usize,
    out: &Path,
) -> AnyResult<()> {
    let f = posed_at(full, motion, k)?;
    let mesh = full.mesh(f.true_vertices.clone());
    let pose_top = 20.0;
    let dyn_top = (f
        .dynamic_displacement
        .iter()
        .map(|d| d.length() * 1e3)
        .fold(0.0, f64::max))
    .max(1.0);
    let mut panels = vec![
        panel(
            &mesh,
            &paint_mm(&f.pose_displacement, pose_top, |_| false),
            false,
            "pose-driven shapes",
            Some(("|pose displacement| (mm)", pose_top)),
        )?,
        panel(
            &mesh,
            &paint_mm(&f.dynamic_displacement, dyn_top, |_| false),
            true,
            "dynamic: the skirt (side)",
            Some(("|dynamic displacement| (mm)", dyn_top)),
        )?,
    ];
    if let Some(fine) = full.fine_surface(motion.frame(k), &f)? {
        let top = 3.0;
        panels.push(panel(
            &fine.mesh,
            &paint_mm(&fine.wrinkle_displacement, top, |_| false),
            false,
            "wrinkles (refined surface)",
            Some(("|wrinkle displacement| (mm)", top)),
        )?);
    }
    let img = kplot::side_by_side(&panels)?;
    let img = kplot::titled(
        &img,
        "The ground truth beyond skinning, one effect per panel",
        Some(&format!(
            "frame {k} of the walk; each effect is recorded separately in PosedFrame / FineSurface"
        )),
    )?;
    kplot::save(&img, out.join("effects.png"))?;
    Ok(())
}

/// `skirt_swing.png`: frame `best_k` of `motion` (the frame where the skirt departs most from
/// the skinned skirt, found by [`effect_figures`]) from the side: the skinned skirt (what
/// linear blend skinning of the scanned rest shape gives) and the simulated one, the garment
/// coloured by its lag.
pub(crate) fn skirt_picture(
    full: &Performer,
    motion: &Motion,
    best_k: usize,
    out: &Path,
) -> AnyResult<()> {
    let garment = full.garment_vertices();
    let f = posed_at(full, motion, best_k)?;
    let best = garment_lag_m(&f, &garment);
    let top = (best * 1e3).max(1.0);
    let colours = paint_mm(&f.dynamic_displacement, top, |v| !garment.contains(&v));
    let mut skinned = f.true_vertices.clone();
    skinned[garment.clone()].copy_from_slice(&f.lbs_vertices[garment.clone()]);
    let zero = vec![[150u8, 150, 150]; f.true_vertices.len()];
    let panels = [
        panel(
            &full.mesh(skinned),
            &zero,
            true,
            "skinned skirt (LBS)",
            None,
        )?,
        panel(
            &full.mesh(f.true_vertices.clone()),
            &colours,
            true,
            "simulated skirt",
            Some(("|simulated − skinned| (mm)", top)),
        )?,
    ];
    let img = kplot::titled(
        &kplot::side_by_side(&panels)?,
        "The skirt in mid-swing, from the performer's left",
        Some(&format!(
            "frame {best_k}: the hem {:.0} mm from where skinning puts it",
            best * 1e3
        )),
    )?;
    kplot::save(&img, out.join("skirt_swing.png"))?;
    Ok(())
}

/// The wrinkle displacement at pixel `i` of view `v` of `mesh` (interpolated with the
/// barycentrics; the pixel must be covered).
fn fold_at(mesh: &TriMesh, fold: &[DVec3], v: &RenderedView, i: usize) -> DVec3 {
    let f = mesh.faces[v.triangle[i] as usize].map(|c| fold[c as usize]);
    let [b1, b2] = v.bary[i].map(f64::from);
    f[0] * (1.0 - b1 - b2) + f[1] * b1 + f[2] * b2
}

/// `wrinkle_closeup.png`: the left elbow bent to [`CLOSEUP_FLEXION_DEG`], seen from 20 cm by
/// the camera (of 26 around it) that sees most of its folds: the normal map of the refined surface with its wrinkles,
/// the wrinkle displacement, and the normal map without them (the same fine mesh minus the
/// recorded wrinkle displacement). Returns the close-up's figures.
pub(crate) fn wrinkle_closeup(full: &Performer, out: &Path) -> AnyResult<Value> {
    let s = &full.skeleton;
    let mut theta = s.rest_pose();
    theta[s
        .dof_index("l_elbow.flexion")
        .ok_or("the performer has the DOF")?] = CLOSEUP_FLEXION_DEG.to_radians();
    let f = full.pose(&theta, &mut DeformationState::default(), 0.0)?;
    let fine = full
        .fine_surface(&theta, &f)?
        .ok_or("the full performer has wrinkles")?;
    let at = |n: &str| -> AnyResult<DVec3> {
        Ok(f.joint_positions[s.joint_index(n).ok_or("the performer has the joint")?])
    };
    // Of 26 cameras 20 cm from the left elbow (the directions of a cube's faces, edges and
    // corners), the one seeing most pixels of fold (> 0.5 mm).
    let elbow = at("l_elbow")?;
    let params = RenderParams::default().with_buffers(Buffers::ALL);
    let k = Intrinsics::from_horizontal_fov(0.9, 560, 420)?;
    let mut best: Option<(usize, Camera)> = None;
    for i in 0..27 {
        let d = DVec3::new(
            (i % 3) as f64 - 1.0,
            ((i / 3) % 3) as f64 - 1.0,
            (i / 9) as f64 - 1.0,
        );
        if d == DVec3::ZERO {
            continue;
        }
        let up = if d.normalize().dot(DVec3::Y).abs() > 0.9 {
            DVec3::Z
        } else {
            DVec3::Y
        };
        let cam = Camera::look_at(k, elbow + d.normalize() * 0.2, elbow, up)?;
        let v = Rasterizer::new(&cam).render(&fine.mesh, &params.with_allow_empty(true))?;
        let seen = (0..v.triangle.len())
            .filter(|&i| {
                v.triangle[i] != NO_TRIANGLE
                    && fold_at(&fine.mesh, &fine.wrinkle_displacement, &v, i).length() > 0.5e-3
            })
            .count();
        if best.as_ref().is_none_or(|(n, _)| seen > *n) {
            best = Some((seen, cam));
        }
    }
    let (_, cam) = best.ok_or("26 candidate cameras")?;
    let r = Rasterizer::new(&cam);
    let smooth = TriMesh {
        vertices: fine
            .mesh
            .vertices
            .iter()
            .zip(&fine.wrinkle_displacement)
            .map(|(v, d)| *v - *d)
            .collect(),
        faces: fine.mesh.faces.clone(),
    };
    let with = r.render(&fine.mesh, &params)?;
    let without = r.render(&smooth, &params)?;
    let ramp_u8 = |t: f64| ramp(t).map(|c| (255.0 * c) as u8);
    let false_colour = |values: &[Option<f64>], top: f64, label: &str| -> AnyResult<RgbImage> {
        let mut map = RgbImage::new(with.width, with.height);
        for (p, v) in map.pixels_mut().zip(values) {
            if let Some(v) = v {
                *p = image::Rgb(ramp_u8(v / top));
            }
        }
        Ok(kplot::with_colour_bar(
            &map,
            &ColourBar {
                label,
                min: 0.0,
                max: top,
                ramp: &ramp_u8,
                note: None,
            },
        )?)
    };
    // Per pixel: the fold's displacement (mm), and the angle between the normals with and
    // without the folds (degrees) where both views see the same face's refinement.
    let covered = |i: usize| with.triangle[i] != NO_TRIANGLE && without.triangle[i] != NO_TRIANGLE;
    let fold_mm: Vec<Option<f64>> = (0..with.triangle.len())
        .map(|i| {
            (with.triangle[i] != NO_TRIANGLE)
                .then(|| fold_at(&fine.mesh, &fine.wrinkle_displacement, &with, i).length() * 1e3)
        })
        .collect();
    let angle_deg: Vec<Option<f64>> = (0..with.triangle.len())
        .map(|i| {
            covered(i).then(|| {
                let [a, b] = [&with, &without].map(|v| {
                    DVec3::from_array(v.normal_camera[i].map(f64::from)).normalize_or_zero()
                });
                a.dot(b).clamp(-1.0, 1.0).acos().to_degrees()
            })
        })
        .collect();
    let on_folds: Vec<f64> = fold_mm
        .iter()
        .zip(&angle_deg)
        .filter_map(|(f, a)| (f.is_some_and(|f| f > 0.5)).then_some(*a).flatten())
        .collect();
    let p90 = if on_folds.is_empty() {
        0.0
    } else {
        percentile(&on_folds, 0.9)
    };
    let normals = |v: &RenderedView, title: &str| -> AnyResult<RgbImage> {
        let img = Rgb32FImage::from_raw(v.width, v.height, v.normal_camera.concat())
            .ok_or("normal buffer of the view's size")?;
        Ok(kplot::titled(&normals_rgb8(&img), title, None)?)
    };
    let panels = [
        normals(&with, "normals with wrinkles")?,
        normals(&without, "normals without wrinkles")?,
        kplot::titled(
            &false_colour(&fold_mm, 2.0, "|wrinkle displacement| (mm)")?,
            "fold displacement",
            None,
        )?,
        kplot::titled(
            &false_colour(&angle_deg, 30.0, "normal change (°)")?,
            "angle between the two normal maps",
            None,
        )?,
    ];
    let img = kplot::titled(
        &kplot::stacked(&[
            kplot::side_by_side(&panels[..2])?,
            kplot::side_by_side(&panels[2..])?,
        ])?,
        &format!(
            "Elbow crease at {CLOSEUP_FLEXION_DEG}° flexion: normal maps of the refined surface"
        ),
        Some(&format!(
            "normal maps: camera-frame normal x → red, y → green, z → blue; folds up to {:.1} mm; on fold pixels (> 0.5 mm) the normal turns by up to {p90:.0}° (90th percentile)",
            fine.max_wrinkle_m() * 1e3
        )),
    )?;
    kplot::save(&img, out.join("wrinkle_closeup.png"))?;
    Ok(json!({
        "closeup_wrinkle_max_mm": fine.max_wrinkle_m() * 1e3,
        "closeup_fold_pixels": on_folds.len(),
        "closeup_normal_change_p90_deg": p90,
    }))
}
