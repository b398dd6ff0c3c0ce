//! Validation of the needle model (Sand, McMillan and Popović 2003) on the synthetic studio.
//!
//! Trains on a range-of-motion capture (3 cameras at 720×480, 30 fps, 3 minutes of motion),
//! then tests on a fast motion the model never saw, against ground truth from the performer's
//! true posed mesh (see `needle_model::truth`). Baselines on the same test needles: a static
//! model (`f_near = 1`, thesis Figure 6-2c) and the rest shape skinned with LBS. Figures of
//! §6: error vs prototype count N (10, 30, 100, 300) and a short (30 s, every DOF compressed)
//! vs long (3 min) range-of-motion
//! training.
//!
//! Writes under `out/needle_capture/`: `error_vs_n.png` (median error vs N: all needles in
//! blue, near elbows/knees in red; grey/orange dashes: static and LBS baselines) and
//! `figures.json`. Progress on stderr; last stdout line one JSON object.
//!
//! `cargo run --release --example needle_capture [-- --quick]` (`--quick`: procedural
//! performer, 360×240 views, 24 s of training, 15 test frames; under a minute).

use std::time::Instant;

use dynamic_shapes::core::mesh::TriMesh;
use dynamic_shapes::core::skeleton::Motion;
use dynamic_shapes::core::studio::{
    fast_motion, makehuman_performer, procedural_performer, range_of_motion, FastMotionParams,
    Performer, ProceduralBodyParams, RangeOfMotionParams,
};
use dynamic_shapes::needle::truth::{self, mean, median, TestSet};
use dynamic_shapes::needle::{
    BodyLayout, FrameInput, NeedleBody, NeedleModel, ObservationStore, ObserveParams, Observer,
    ReconstructionParams,
};
use image::{Rgb, RgbImage};
use rayon::prelude::*;
use serde_json::json;

const OUT_DIR: &str = "out/needle_capture";

type Res<T> = Result<T, Box<dyn std::error::Error>>;

struct Setup {
    width: u32,
    height: u32,
    train_s: f64,
    short_s: f64,
    test_s: f64,
    test_stride: usize,
}

fn performer(quick: bool) -> Res<Performer> {
    if !quick {
        if let Ok(dir) = dynamic_shapes::core::data::shared_data_path("makehuman") {
            eprintln!("performer: MakeHuman");
            return Ok(makehuman_performer(dir, &Default::default())?);
        }
    }
    eprintln!("performer: procedural");
    Ok(procedural_performer(&ProceduralBodyParams::default())?)
}

/// Range of motion stretched so it lasts at least `seconds`.
fn training_motion(p: &Performer, seconds: f64) -> Res<Motion> {
    let base = RangeOfMotionParams::default();
    let d = range_of_motion(&p.skeleton, &base)?.duration_s();
    let params = RangeOfMotionParams {
        seconds_per_dof: base.seconds_per_dof * (seconds / d).max(0.05) * 1.001,
        ..base
    };
    Ok(range_of_motion(&p.skeleton, &params)?)
}

fn main() -> Res<()> {
    let t0 = Instant::now();
    let quick = std::env::args().any(|a| a == "--quick");
    let s = if quick {
        Setup {
            width: 360,
            height: 240,
            train_s: 24.0,
            short_s: 6.0,
            test_s: 2.0,
            test_stride: 8,
        }
    } else {
        Setup {
            width: 720,
            height: 480,
            train_s: 180.0,
            short_s: 30.0,
            test_s: 4.0,
            test_stride: 4,
        }
    };
    std::fs::create_dir_all(OUT_DIR)?;
    let performer = performer(quick)?;
    let sk = performer.skeleton.clone();
    let body = NeedleBody::new(&sk, &BodyLayout::table_3_1())?;
    let cameras = truth::ring_cameras(3, s.width, s.height)?;
    let observer = Observer::new(
        body.clone(),
        sk.clone(),
        cameras.clone(),
        ObserveParams::default(),
    )?;

    // --- Training capture, streamed in chunks (masks are not kept). ---
    let train = training_motion(&performer, s.train_s)?;
    let n_train = train.frame_count();
    eprintln!(
        "training: range of motion, {n_train} frames ({:.1} s) at {:.0} fps, {} needles, 3 cameras {}×{}",
        train.duration_s(),
        1.0 / train.frame_time_s,
        body.needle_count(),
        s.width,
        s.height
    );
    let long = capture(&performer, &observer, &cameras, &train)?;
    let store = long.store;
    let (acc_s, render_s) = (long.accumulate_s, long.render_s);
    // Short training: a separate range of motion over every DOF, compressed into `short_s`.
    let short_motion = training_motion(&performer, s.short_s)?;
    eprintln!(
        "short training: range of motion, {} frames ({:.1} s)",
        short_motion.frame_count(),
        short_motion.duration_s()
    );
    let short_store = Some(capture(&performer, &observer, &cameras, &short_motion)?.store);
    eprintln!();
    let accumulate_fps = n_train as f64 / acc_s;
    let bpo = store.bytes_per_observation();
    eprintln!(
        "accumulate {accumulate_fps:.1} frames/s (render {:.1} frames/s), {} observations, {bpo:.2} B/observation",
        n_train as f64 / render_s,
        store.total_observations()
    );

    // --- Test truth: a fast motion never seen in training. ---
    let test_motion = fast_motion(
        &sk,
        &FastMotionParams {
            duration_s: s.test_s,
            seed: 11,
            ..Default::default()
        },
    )?;
    let mut test = TestSet::default();
    let frames: Vec<&[f64]> = (0..test_motion.frame_count())
        .map(|k| test_motion.frame(k))
        .collect();
    truth::for_each_posed(
        &performer,
        frames,
        test_motion.frame_time_s,
        s.test_stride,
        |_, th, tv, lv| test.push_frame(&body, &performer, th, tv, lv),
    )?;
    let scored: usize = test.frames.iter().map(|f| f.needles.len()).sum();
    eprintln!(
        "test: {} frames of fast motion, {scored} scored needles",
        test.frames.len()
    );

    // --- Reconstructions. ---
    let base = ReconstructionParams::default();
    let tr = Instant::now();
    let main = NeedleModel::reconstruct(&store, &body, &base)?;
    let reconstruct_s = tr.elapsed().as_secs_f64();
    let reconstruct_s_24min = reconstruct_s * (24.0 * 60.0) / train.duration_s();
    eprintln!("reconstruct (N = 100): {reconstruct_s:.2} s");
    let mut m = test.errors(&main.model)?;
    let stat = NeedleModel::reconstruct(&store, &body, &base.with_f_near(1.0))?;
    let mut st = test.errors(&stat.model)?;
    let mut lbs = test.lbs_errors();
    let test_mean_mm = mean(&m.all_mm);
    let fig = json!({
        "test_median_mm": median(&mut m.all_mm),
        "test_mean_mm": test_mean_mm,
        "test_median_near_joints_mm": median(&mut m.near_joints_mm),
        "static_median_mm": median(&mut st.all_mm),
        "static_median_near_joints_mm": median(&mut st.near_joints_mm),
        "lbs_median_mm": median(&mut lbs.all_mm),
        "lbs_median_near_joints_mm": median(&mut lbs.near_joints_mm),
        "test_median_deforming_mm": median(&mut m.deforming_mm),
        "static_median_deforming_mm": median(&mut st.deforming_mm),
        "lbs_median_deforming_mm": median(&mut lbs.deforming_mm),
        "deforming_needles": m.deforming_mm.len(),
        "near_joint_needles": m.near_joints_mm.len(),
        "scored_needles": scored,
    });
    eprintln!("{fig}");

    // Error vs N.
    let mut sweep = vec![];
    for n in [10usize, 30, 100, 300] {
        let mut e = if n == 100 {
            m.clone()
        } else {
            test.errors(
                &NeedleModel::reconstruct(&store, &body, &base.with_prototype_count_n(n))?.model,
            )?
        };
        let (a, b) = (median(&mut e.all_mm), median(&mut e.near_joints_mm));
        eprintln!("N = {n}: median {a:.2} mm, near joints {b:.2} mm");
        sweep.push((n, a, b));
    }
    // Short vs long training.
    let short_store = short_store.ok_or("training shorter than the short prefix")?;
    // A primitive never seen in the short prefix makes its reconstruction fail: reported,
    // not fatal.
    let (short_median, short_near, short_error) =
        match NeedleModel::reconstruct(&short_store, &body, &base)
            .and_then(|r| test.errors(&r.model))
        {
            Ok(mut sh) => (
                Some(median(&mut sh.all_mm)),
                Some(median(&mut sh.near_joints_mm)),
                None,
            ),
            Err(e) => (None, None, Some(e.to_string())),
        };
    eprintln!(
        "{:.0} s training: median {short_median:?} mm, near joints {short_near:?} mm {}",
        s.short_s,
        short_error.as_deref().unwrap_or("")
    );

    plot(
        &sweep,
        fig["static_median_mm"].as_f64(),
        fig["lbs_median_mm"].as_f64(),
    )?;
    let mut out = fig;
    let o = out.as_object_mut().ok_or("json")?;
    o.insert("quick".into(), json!(quick));
    o.insert("train_s".into(), json!(train.duration_s()));
    o.insert("train_frames".into(), json!(n_train));
    o.insert("test_frames".into(), json!(test.frames.len()));
    o.insert(
        "median_vs_n".into(),
        json!(sweep
            .iter()
            .map(|&(n, a, b)| json!({"n": n, "median_mm": a, "near_joints_mm": b}))
            .collect::<Vec<_>>()),
    );
    o.insert("short_train_s".into(), json!(s.short_s));
    o.insert("short_train_median_mm".into(), json!(short_median));
    o.insert(
        "short_train_median_near_joints_mm".into(),
        json!(short_near),
    );
    o.insert("short_train_error".into(), json!(short_error));
    o.insert("accumulate_frames_per_s".into(), json!(accumulate_fps));
    o.insert(
        "render_frames_per_s".into(),
        json!(n_train as f64 / render_s),
    );
    o.insert("reconstruct_s".into(), json!(reconstruct_s));
    o.insert("reconstruct_s_24min".into(), json!(reconstruct_s_24min));
    o.insert("bytes_per_observation".into(), json!(bpo));
    o.insert("observations".into(), json!(store.total_observations()));
    o.insert("seconds".into(), json!(t0.elapsed().as_secs_f64()));
    std::fs::write(
        format!("{OUT_DIR}/figures.json"),
        serde_json::to_string_pretty(&out)?,
    )?;
    println!("{out}");
    Ok(())
}

/// Result of [`capture`].
struct Captured {
    store: ObservationStore,
    accumulate_s: f64,
    render_s: f64,
}

/// Poses the performer along `motion`, renders the true mesh's silhouettes and accumulates
/// the observations, streamed in chunks of 48 frames (masks are not kept).
fn capture(
    performer: &Performer,
    observer: &Observer,
    cameras: &[dynamic_shapes::core::camera::Camera],
    motion: &Motion,
) -> Res<Captured> {
    let n = motion.frame_count();
    let mut store = observer.empty_store()?;
    let (mut accumulate_s, mut render_s) = (0.0, 0.0);
    let chunk = 48usize;
    let mut pending: Vec<(Vec<f64>, TriMesh)> = vec![];
    let mut state = dynamic_shapes::core::studio::DeformationState::default();
    for k in 0..n {
        let theta = motion.frame(k).to_vec();
        let posed = performer.pose(&theta, &mut state, motion.frame_time_s)?;
        let mesh = TriMesh {
            vertices: posed.true_vertices,
            faces: performer.template.faces.clone(),
        };
        pending.push((theta, mesh));
        if pending.len() == chunk || k + 1 == n {
            let tr = Instant::now();
            let masks: Vec<_> = pending
                .par_iter()
                .map(|(_, m)| truth::render_masks(cameras, m))
                .collect::<Result<_, _>>()?;
            render_s += tr.elapsed().as_secs_f64();
            let frames: Vec<FrameInput> = pending
                .iter()
                .zip(&masks)
                .map(|((t, _), m)| FrameInput { theta: t, masks: m })
                .collect();
            let ta = Instant::now();
            let acc = observer.accumulate(&frames)?;
            accumulate_s += ta.elapsed().as_secs_f64();
            store.append(&acc.store)?;
            pending.clear();
            eprint!(
                "\r  frame {}/{n}, {} observations",
                k + 1,
                store.total_observations()
            );
        }
    }
    eprintln!();
    Ok(Captured {
        store,
        accumulate_s,
        render_s,
    })
}

/// Median error vs log N as two polylines, baselines as horizontal dashes.
fn plot(sweep: &[(usize, f64, f64)], stat: Option<f64>, lbs: Option<f64>) -> Res<()> {
    let (w, h) = (480u32, 320u32);
    let mut img = RgbImage::from_pixel(w, h, Rgb([255, 255, 255]));
    let vals = sweep
        .iter()
        .flat_map(|&(_, a, b)| [a, b])
        .chain(stat)
        .chain(lbs)
        .filter(|v| v.is_finite());
    let ymax = vals.fold(1.0f64, f64::max) * 1.1;
    let (x0, x1, y0, y1) = (40.0, w as f64 - 20.0, h as f64 - 30.0, 20.0);
    let px = |n: usize| x0 + (x1 - x0) * ((n as f64).log10() - 1.0) / (300f64.log10() - 1.0);
    let py = |v: f64| y0 + (y1 - y0) * v / ymax;
    line(&mut img, (x0, y0), (x1, y0), Rgb([0, 0, 0]), false);
    line(&mut img, (x0, y0), (x0, y1), Rgb([0, 0, 0]), false);
    for (v, c) in [(stat, Rgb([128, 128, 128])), (lbs, Rgb([230, 140, 0]))] {
        if let Some(v) = v.filter(|v| v.is_finite()) {
            line(&mut img, (x0, py(v)), (x1, py(v)), c, true);
        }
    }
    for (sel, c) in [(1usize, Rgb([0, 60, 220])), (2, Rgb([220, 0, 0]))] {
        let pts: Vec<(f64, f64)> = sweep
            .iter()
            .map(|&(n, a, b)| (px(n), py(if sel == 1 { a } else { b })))
            .filter(|p| p.1.is_finite())
            .collect();
        for win in pts.windows(2) {
            line(&mut img, win[0], win[1], c, false);
        }
        for &(x, y) in &pts {
            for dx in -3..=3 {
                for dy in -3..=3 {
                    put(&mut img, x + dx as f64, y + dy as f64, c);
                }
            }
        }
    }
    img.save(format!("{OUT_DIR}/error_vs_n.png"))?;
    Ok(())
}

fn put(img: &mut RgbImage, x: f64, y: f64, c: Rgb<u8>) {
    if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, c);
    }
}

fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), c: Rgb<u8>, dashed: bool) {
    let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()) as usize).max(1);
    for i in 0..=steps {
        if dashed && (i / 6) % 2 == 1 {
            continue;
        }
        let t = i as f64 / steps as f64;
        put(img, a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t, c);
    }
}
