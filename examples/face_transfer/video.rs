//! Tracking from rendered video and textured face transfer (§5.4, Figures 5-1 / 5-7).
//!
//! Two people the model never saw (bilinear generator, seeds 99 and 123) are rendered into
//! 640 × 480 videos with the validation texture (freckled skin, a light at the camera, 1 grey
//! level of noise), changing expression under head motion. Each is tracked by
//! `track_video` (symmetric KLT of 1,000 vertices tied to the bilinear 6 × 9 model,
//! initialised from 12 feature points with 1 px error). The source's expression weights are
//! then put on the target's identity, and the result is rendered with the target's camera and
//! the target's texture lifted from its own frame back into the target frame.

use serde_json::{json, Value};

use dynamic_shapes::core::math::DVec3;
use dynamic_shapes::core::mesh::{vertex_normals, NormalWeighting, TriMesh};
use dynamic_shapes::face::validation::{
    aligned_rms, bilinear_face_set, face_width, feature_vertices, render_face_video, FaceSet,
    FaceSetParams, FaceVideo, FaceVideoParams, IctBasis,
};
use dynamic_shapes::face::{
    lift_texture, mean_weights, render_textured, track_points, track_video, FaceTexture,
    MultilinearModel, TrackParams, VideoTrack, VideoTrackParams, WeakPerspective,
};
use example_kit::plot::{label_rows, side_by_side, stacked, titled, Chart, Series, Style};
use example_kit::Run;

use crate::MM;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

fn avg(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn series(label: &str, colour: [u8; 3], style: Style, v: &[f64]) -> Series {
    Series::new(
        label,
        colour,
        style,
        v.iter().enumerate().map(|(t, y)| (t as f64, *y)).collect(),
    )
}

/// The thesis's tracking speed, frames per second (§5.4.1: "averages at one frame per
/// second").
const THESIS_FPS: f64 = 1.0;

/// The tracking goal (1 % of the face width) over `frames` frames.
pub(crate) fn goal_line(frames: usize) -> Series {
    Series::new(
        "goal 1 %",
        [230, 30, 30],
        Style::Dashed,
        vec![(0.0, 1.0), ((frames - 1) as f64, 1.0)],
    )
}

/// Per-frame vertex RMS after similarity alignment, % of the face width.
fn errors(model: &MultilinearModel, track: &VideoTrack, video: &FaceVideo) -> Res<Vec<f64>> {
    let width = face_width(&video.truth[0]);
    let mut out = Vec::new();
    for (w, truth) in track.weights.iter().zip(&video.truth) {
        out.push(100.0 * aligned_rms(&model.face(w)?, truth)? / width);
    }
    Ok(out)
}

/// A grey picture of `face` under `cam` (per-vertex Lambertian shading with a light at the
/// camera) over `background`.
fn shaded(
    face: &[DVec3],
    triangles: &[[u32; 3]],
    cam: &WeakPerspective,
    background: &image::RgbImage,
) -> Res<image::RgbImage> {
    let normals = vertex_normals(
        &TriMesh::new(face.to_vec(), triangles.to_vec())?,
        NormalWeighting::Area,
    )?;
    let r0 = DVec3::from_array(cam.rows[0]);
    let r1 = DVec3::from_array(cam.rows[1]);
    let toward = -r0.cross(r1);
    let colours = normals
        .iter()
        .map(|n| {
            let c = 60.0 + 170.0 * n.dot(toward).abs() as f32;
            [c, c, 0.95 * c]
        })
        .collect();
    let tex = FaceTexture {
        colours,
        visible: vec![true; face.len()],
    };
    Ok(render_textured(face, triangles, cam, &tex, background)?)
}

/// Draws the tracked vertices' projections (green dots) on a frame.
fn with_points(frame: &image::RgbImage, points: &[[f64; 2]]) -> image::RgbImage {
    let mut img = frame.clone();
    for p in points {
        let (x, y) = (p[0].round() as i64, p[1].round() as i64);
        for (dx, dy) in (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (dx, dy))) {
            let (u, v) = (x + dx, y + dy);
            if u >= 0 && v >= 0 && (u as u32) < img.width() && (v as u32) < img.height() {
                img.put_pixel(u as u32, v as u32, image::Rgb([40, 230, 60]));
            }
        }
    }
    img
}

fn half(img: &image::RgbImage) -> image::RgbImage {
    image::imageops::resize(
        img,
        img.width() / 2,
        img.height() / 2,
        image::imageops::FilterType::Triangle,
    )
}

/// Tracks a rendered video of a person not in the trilinear model whose visemes and
/// expressions change (viseme and expression per frame, identity constant); returns the
/// figures.
pub(crate) fn trilinear_video(
    run: &mut Run,
    basis: &IctBasis,
    triangles: &[[u32; 3]],
    model: &MultilinearModel,
    quick: bool,
) -> Res<Value> {
    let stage = run.stage("trilinear video", None);
    let frame_count = if quick { 24 } else { 60 };
    let person = dynamic_shapes::face::validation::trilinear_face_set(
        basis,
        &FaceSetParams::default().with_identities(1).with_seed(77),
    )?;
    // (viseme, expression): m/neutral → aa/smiling → oo/neutral → ee/scowling → sh/surprised →
    // m/neutral.
    let order: Vec<usize> = [(0, 0), (1, 1), (3, 0), (2, 2), (4, 3), (0, 0)]
        .iter()
        .map(|&(v, e)| person.faces.face_index(&[v, e, 0]))
        .collect::<Result<_, _>>()?;
    let tracked = feature_vertices(basis.neutral(), 1000)?;
    let features = feature_vertices(basis.neutral(), 12)?;
    let video = render_face_video(
        &person.faces,
        &order,
        frame_count,
        triangles,
        &basis.neutral().vertices,
        &features,
        &FaceVideoParams::default(),
    )?;
    let track = track_video(
        model,
        triangles,
        &tracked,
        &video.frames,
        &video.features,
        &[false, false, true],
        &VideoTrackParams::default(),
    )?;
    let pct = errors(model, &track, &video)?;
    let exact = exact_tracks(&video, &tracked);
    let fit = track_points(
        model,
        &tracked,
        &exact,
        &[false, false, true],
        &TrackParams::default(),
    )?;
    let width = face_width(&video.truth[0]);
    let mean_face = model.face(&mean_weights(model)?)?;
    let (mut bound, mut mean) = (Vec::new(), Vec::new());
    for (w, truth) in fit.weights.iter().zip(&video.truth) {
        bound.push(100.0 * aligned_rms(&model.face(w)?, truth)? / width);
        mean.push(100.0 * aligned_rms(&mean_face, truth)? / width);
    }
    stage.finish(format!(
        "{:.2} % (bound {:.2} %, mean face {:.2} %), {:.1} fps",
        avg(&pct),
        avg(&bound),
        avg(&mean),
        frame_count as f64 / track.seconds
    ));
    Ok(json!({
        "track_vertex_rms_pct_trilinear": avg(&pct),
        "track_vertex_rms_pct_trilinear_exact_tracks": avg(&bound),
        "track_mean_face_rms_pct_trilinear": avg(&mean),
        "track_fps_trilinear": frame_count as f64 / track.seconds,
    }))
}

/// Runs the video tracking and transfer; returns the figures.
pub(crate) fn video_tracking(
    run: &mut Run,
    basis: &IctBasis,
    bi: &FaceSet,
    model: &MultilinearModel,
    quick: bool,
) -> Res<Value> {
    let frame_count = if quick { 24 } else { 60 };
    let tracked = feature_vertices(basis.neutral(), 1000)?;
    let features = feature_vertices(basis.neutral(), 12)?;
    let person = |seed| {
        bilinear_face_set(
            basis,
            &FaceSetParams::default().with_identities(1).with_seed(seed),
        )
    };
    let (source, target) = (person(99)?, person(123)?);
    let stage = run.stage("render videos", None);
    let render = |p: &FaceSet, order: &[usize], fp: &FaceVideoParams| {
        render_face_video(
            &p.faces,
            order,
            frame_count,
            &bi.triangles,
            &basis.neutral().vertices,
            &features,
            fp,
        )
    };
    let src_order: &[usize] = if quick {
        &[0, 1, 3, 5, 2, 0]
    } else {
        &[0, 1, 3, 5, 2, 7, 4, 9, 6, 8, 0]
    };
    let params = FaceVideoParams::default();
    let src = render(&source, src_order, &params)?;
    let tgt = render(
        &target,
        &[0, 9, 4, 0],
        &FaceVideoParams {
            seed: 12,
            ..params.clone()
        },
    )?;
    let render_s = stage.finish(format!("2 × {frame_count} frames of 640 × 480"));

    let stage = run.stage("track videos", None);
    let track = |v: &FaceVideo, f| {
        track_video(
            model,
            &bi.triangles,
            &tracked,
            &v.frames,
            f,
            &[false, true],
            &VideoTrackParams::default(),
        )
    };
    let st = track(&src, &src.features)?;
    // The same tracking on one core: on a one-thread pool the KLT's parallel loop stays on
    // the thread that runs `track_video`, so that thread's CPU time is the whole cost.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let (st_one, cpu_s) = pool.install(|| {
        let cpu = cpu_time::ThreadTime::now();
        let track = track(&src, &src.features);
        (track, cpu.elapsed().as_secs_f64())
    });
    let st_one = st_one?;
    let track_fps_cpu = frame_count as f64 / cpu_s;
    let tt = track(&tgt, &tgt.features)?;
    // The same with exact feature points (the initialisation's share of the error).
    let exact = dynamic_shapes::face::FeaturePoints {
        vertices: features.clone(),
        pixels: features
            .iter()
            .map(|&v| src.cameras[0].project(src.truth[0][v].to_array()))
            .collect(),
    };
    let st_exact = track(&src, &exact)?;
    // The model's bound: the point tracker on exact projections of all 1,000 vertices.
    let bound = |v: &FaceVideo| -> Res<Vec<f64>> {
        let fit = track_points(
            model,
            &tracked,
            &exact_tracks(v, &tracked),
            &[false, true],
            &TrackParams::default(),
        )?;
        let width = face_width(&v.truth[0]);
        let mut out = Vec::new();
        for (w, truth) in fit.weights.iter().zip(&v.truth) {
            out.push(100.0 * aligned_rms(&model.face(w)?, truth)? / width);
        }
        Ok(out)
    };
    let floor_pct = bound(&src)?;
    let tgt_floor_pct = bound(&tgt)?;
    let src_pct = errors(model, &st, &src)?;
    let tgt_pct = errors(model, &tt, &tgt)?;
    let exact_pct = errors(model, &st_exact, &src)?;
    let width = face_width(&src.truth[0]);
    let mean_face = model.face(&mean_weights(model)?)?;
    let mut mean_pct = Vec::new();
    for truth in &src.truth {
        mean_pct.push(100.0 * aligned_rms(&mean_face, truth)? / width);
    }
    let neutral_w = model.training_weights(0, 0)?;
    let id_face = model.face(&[neutral_w.clone(), st.weights[0][1].clone()])?;
    let identity_rms_mm = MM * aligned_rms(&id_face, &source.faces.face(0)?)?;
    let mean_id_face = model.face(&[neutral_w, mean_weights(model)?[1].clone()])?;
    let mean_identity_rms_mm = MM * aligned_rms(&mean_id_face, &source.faces.face(0)?)?;
    let track_fps = frame_count as f64 / st.seconds;
    let chart = Chart::new(
        "Tracking an unseen person from rendered video (KLT, 1,000 vertices)",
        "frame",
        "vertex RMS after similarity alignment (% of face width)",
    )
    .with(series(
        "video, 12 feature points with 1 px error",
        [40, 90, 200],
        Style::Line,
        &src_pct,
    ))
    .with(series(
        "video, exact feature points",
        [40, 170, 90],
        Style::Line,
        &exact_pct,
    ))
    .with(series(
        "exact 2D tracks of all 1,000 vertices (model bound)",
        [120, 120, 120],
        Style::Dashed,
        &floor_pct,
    ))
    .with(series(
        "mean face (no tracking)",
        [220, 120, 40],
        Style::Dashed,
        &mean_pct,
    ))
    .with(goal_line(frame_count));
    run.save_picture(
        "tracking_video.png",
        &chart.draw()?,
        "Per-frame 3D vertex error of the faces tracked from rendered video (similarity-aligned, \
         % of face width): with the 12 initial feature points marked with 1 px error, with exact \
         ones, the model's bound (exact 2D positions of all tracked vertices) and the mean face",
    )?;
    stage.finish(format!(
        "source {:.2} % (exact features {:.2} %, bound {:.2} %, mean face {:.2} %), target {:.2} %, {track_fps:.1} fps, {track_fps_cpu:.1} fps of one core's CPU time",
        avg(&src_pct),
        avg(&exact_pct),
        avg(&floor_pct),
        avg(&mean_pct),
        avg(&tgt_pct)
    ));

    // Frames with the tracked vertices and the transfer (Figures 5-1 / 5-7).
    let stage = run.stage("transfer", None);
    let shown: Vec<usize> = [1, 3, 5, 7].iter().map(|k| k * frame_count / 8).collect();
    let mut rows = Vec::new();
    let mut track_rows = Vec::new();
    for &t in &shown {
        let src_face = model.face(&st.weights[t])?;
        let tgt_face = model.face(&tt.weights[t])?;
        let new_face = model.face(&[st.weights[t][0].clone(), tt.weights[t][1].clone()])?;
        let texture = lift_texture(&tgt_face, &bi.triangles, &tt.cameras[t], &tgt.frames[t])?;
        let composite = render_textured(
            &new_face,
            &bi.triangles,
            &tt.cameras[t],
            &texture,
            &tgt.frames[t],
        )?;
        let blank = image::RgbImage::from_pixel(640, 480, image::Rgb([255, 255, 255]));
        let geometry = shaded(&new_face, &bi.triangles, &tt.cameras[t], &blank)?;
        rows.push(side_by_side(&[
            half(&src.frames[t]),
            half(&tgt.frames[t]),
            half(&geometry),
            half(&composite),
        ])?);
        let pts = |face: &[DVec3], cam: &WeakPerspective| -> Vec<[f64; 2]> {
            tracked
                .iter()
                .map(|&v| cam.project(face[v].to_array()))
                .collect()
        };
        track_rows.push(side_by_side(&[
            half(&with_points(
                &src.frames[t],
                &pts(&src_face, &st.cameras[t]),
            )),
            half(&with_points(
                &tgt.frames[t],
                &pts(&tgt_face, &tt.cameras[t]),
            )),
        ])?);
    }
    let labels: Vec<String> = shown.iter().map(|t| format!("frame {t}")).collect();
    let label_refs: Vec<&str> = labels.iter().map(String::as_str).collect();
    run.save_picture(
        "transfer.png",
        &titled(
            &label_rows(&stacked(&rows)?, &label_refs, 90)?,
            "Face transfer from video (like Vlasic 2010 Figures 5-1 / 5-7)",
            Some("columns: source frame; target frame; transferred geometry (source expression, target identity and pose); composited result (target texture lifted from its frame)"),
        )?,
        "Textured face transfer: source and target frames (rendered, people not in the model), \
         the source's tracked expression on the target's tracked identity in the target's pose, \
         and that face rendered with the target's lifted texture back into the target frame",
    )?;
    run.save_picture(
        "tracked_frames.png",
        &titled(
            &label_rows(&stacked(&track_rows)?, &label_refs, 90)?,
            "Tracked vertices in the video frames (model projections, green)",
            Some("columns: source video; target video"),
        )?,
        "The 1,000 tracked vertices of the fitted model projected into source and target frames",
    )?;
    stage.finish(format!("{} frames composited", shown.len()));

    Ok(json!({
        "track_vertex_rms_pct": avg(&src_pct),
        "track_vertex_rms_pct_target": avg(&tgt_pct),
        "track_vertex_rms_pct_exact_features": avg(&exact_pct),
        "track_vertex_rms_pct_exact_tracks": avg(&floor_pct),
        "track_vertex_rms_pct_target_exact_tracks": avg(&tgt_floor_pct),
        "track_mean_face_rms_pct": avg(&mean_pct),
        "track_identity_rms_mm": identity_rms_mm,
        "track_mean_identity_rms_mm": mean_identity_rms_mm,
        "track_fps": track_fps,
        "track_klt_share": st.klt_seconds / st.seconds,
        "track_fps_cpu": track_fps_cpu,
        "track_fps_cpu_thesis_ratio": track_fps_cpu / THESIS_FPS,
        "track_klt_share_one_core": st_one.klt_seconds / st_one.seconds,
        "track_frames": frame_count,
        "track_points": tracked.len(),
        "track_feature_points": features.len(),
        "track_tracked_fraction": avg(&st.tracked_fraction),
        "track_reprojection_rms_px": avg(&st.reprojection_rms_px),
        "render_s": render_s,
    }))
}

/// The true image positions of the `tracked` vertices in every frame of `video` (each frame's
/// true face through its true camera): point tracks without KLT error.
fn exact_tracks(video: &FaceVideo, tracked: &[usize]) -> Vec<Vec<[f64; 2]>> {
    video
        .truth
        .iter()
        .zip(&video.cameras)
        .map(|(f, c)| {
            tracked
                .iter()
                .map(|&i| c.project(f[i].to_array()))
                .collect()
        })
        .collect()
}
