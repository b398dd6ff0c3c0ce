//! The Rust side of the binding-overhead measurement (`benches/overhead.py` is the Python
//! side, on the same inputs): `overhead project CALLS` projects the 1,000 points of the
//! fixtures CALLS times; `overhead normals CALLS` estimates the normal map of the 256 × 256
//! pattern images of the fixtures CALLS times (a quick-size photometric view). Time whole
//! runs with CALLS and with 0: the difference over CALLS is the time of one call. Needs the
//! fixtures (`cargo test --release -p dynamic-shapes-py --test python_fixtures`).
#![allow(clippy::print_stdout, clippy::unwrap_used, clippy::expect_used)] // a bench program

use std::hint::black_box;
use std::path::{Path, PathBuf};

use glam::DVec3;
use photometric_normals::{
    estimate_normals, CalibrationParams, CalibrationSphere, HeightCalibration, LookupTable,
    NormalParams, PatternImages, PATTERNS,
};
use skin_core::camera::Camera;
use skin_core::image::GrayF32Image;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/tmp/python-fixtures")
}

/// The values of a little-endian float64 `.npy` file.
fn read_f64(name: &str) -> Vec<f64> {
    let bytes = std::fs::read(fixtures().join(format!("{name}.npy")))
        .expect("fixtures: run the python_fixtures test");
    let header = usize::from(u16::from_le_bytes([bytes[8], bytes[9]]));
    bytes[10 + header..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

fn camera(name: &str) -> Camera {
    serde_json::from_str(&std::fs::read_to_string(fixtures().join(name)).unwrap()).unwrap()
}

fn images(name: &str, side: u32) -> PatternImages {
    let v = read_f64(name);
    let n = (side * side) as usize;
    let list = PATTERNS
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let raw: Vec<f32> = v[i * n..(i + 1) * n].iter().map(|&x| x as f32).collect();
            (p, GrayF32Image::from_raw(side, side, raw).unwrap())
        })
        .collect();
    PatternImages::new(list).unwrap()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let what = args.get(1).map_or("project", String::as_str);
    let calls: usize = args.get(2).map_or(1000, |c| c.parse().unwrap());
    match what {
        "project" => {
            let cam = camera("camera.json");
            let pts: Vec<DVec3> = read_f64("camera_points")
                .chunks_exact(3)
                .map(|c| DVec3::new(c[0], c[1], c[2]))
                .collect();
            let mut sum = 0.0;
            for _ in 0..calls {
                let px: Vec<_> = black_box(&pts)
                    .iter()
                    .map(|&p| cam.project(p))
                    .collect::<Result<_, _>>()
                    .unwrap();
                sum += black_box(px)[0].x;
            }
            println!("{sum}");
        }
        "normals" => {
            let cam = camera("overhead_camera.json");
            let sphere = CalibrationSphere {
                centre: DVec3::new(0.0, 1.0, 0.0),
                radius_m: 0.2,
            };
            let table = LookupTable::from_sphere(
                &cam,
                &sphere,
                &images("overhead_sphere_images", 256),
                DVec3::Y,
                &CalibrationParams::default(),
            )
            .unwrap();
            let calibration = HeightCalibration::new(vec![table]).unwrap();
            let probe = images("overhead_probe_images", 256);
            let mut valid = 0;
            for _ in 0..calls {
                let map = estimate_normals(
                    &cam,
                    &calibration,
                    black_box(&probe),
                    None,
                    &NormalParams::default(),
                )
                .unwrap();
                valid += map.valid.iter().filter(|&&v| v).count();
            }
            println!("{valid}");
        }
        other => panic!("unknown bench {other}: project or normals"),
    }
}
