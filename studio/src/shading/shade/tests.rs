use super::*;
use crate::shading::{dome_lights, vertices_seen, DomeParams};
use skin_core::camera::{Camera, Intrinsics};
use skin_core::math::DVec3;
use skin_core::mesh::TriMesh;
use skin_core::raster::{Buffers, Rasterizer, RenderParams};

fn uv_sphere(centre: DVec3, radius: f64, n_lat: usize, n_lon: usize) -> TriMesh {
    skin_core::mesh::shapes::uv_sphere(centre, radius, n_lat, n_lon).unwrap()
}

/// A square floor grid in the y = 0 plane, normals +Y, `n × n` cells of side `2·half / n`.
fn floor_grid(half: f64, n: usize) -> TriMesh {
    let mut v = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let s = 2.0 * half / n as f64;
            v.push(DVec3::new(-half + j as f64 * s, 0.0, -half + i as f64 * s));
        }
    }
    let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
    let mut f = Vec::new();
    for i in 0..n {
        for j in 0..n {
            // Counter-clockwise seen from +Y.
            f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh::new(v, f).unwrap()
}

fn merge(a: &TriMesh, b: &TriMesh) -> TriMesh {
    let off = a.vertex_count() as u32;
    let mut v = a.vertices.clone();
    v.extend(&b.vertices);
    let mut f = a.faces.clone();
    f.extend(b.faces.iter().map(|t| t.map(|i| i + off)));
    TriMesh::new(v, f).unwrap()
}

fn top_camera(w: u32) -> Camera {
    let k = Intrinsics::from_horizontal_fov(0.9, w, w).unwrap();
    Camera::look_at(k, DVec3::new(0.0, 3.0, 0.001), DVec3::ZERO, DVec3::Z).unwrap()
}

fn render_all(cam: &Camera, mesh: &TriMesh) -> RenderedView {
    Rasterizer::new(cam)
        .render(
            mesh,
            &RenderParams::default()
                .with_buffers(Buffers::ALL)
                .with_cull_back_faces(false),
        )
        .unwrap()
}

#[test]
fn point_light_follows_inverse_square_and_lambert() {
    let floor = floor_grid(1.0, 4);
    let cam = top_camera(33);
    let view = render_all(&cam, &floor);
    let c = view.index(16, 16);
    assert_eq!(view.mask[c], 1);
    let p = cam.ray(skin_core::math::DVec2::new(16.0, 16.0)).unwrap();
    let p = p.at(view.depth_m[c] as f64);
    let rho = [0.5f32, 0.25, 1.0];
    for (h, off) in [(1.0, 0.0), (2.0, 0.0), (1.0, 1.0)] {
        let light = Light::Point {
            position: p + DVec3::new(off, h, 0.0),
            intensity: 3.0,
        };
        let s = shade(
            &view,
            &floor,
            &[light],
            &Albedo::Uniform(rho),
            &Shadows::None,
        )
        .unwrap();
        let r2 = h * h + off * off;
        let cos = h / r2.sqrt();
        let expect = 3.0 * cos / r2 / std::f64::consts::PI;
        for (&got, &r) in s.radiance[c].iter().zip(&rho) {
            let (got, want) = (got as f64, r as f64 * expect);
            assert!((got - want).abs() < 1e-5 * expect, "{got} vs {want}");
        }
        assert_eq!(s.radiance[0], [0.0; 3], "background stays black");
    }
}

#[test]
fn dome_matches_the_thesis_layout_and_acts_as_a_continuous_emitter() {
    let p = DomeParams::default();
    let lights = dome_lights(&p).unwrap();
    assert_eq!(lights.len(), 1200);
    // Sphere centre r/3 above the floor; floor lights outside the reserved area.
    let centre = DVec3::new(0.0, 4.0 / 3.0, 0.0);
    for l in &lights[..901] {
        assert!(((l.position() - centre).length() - 4.0).abs() < 1e-9);
        assert!(l.position().y >= -1e-9);
    }
    for l in &lights[901..] {
        let q = l.position();
        assert!(q.y.abs() < 1e-12 && q.length() > 1.5);
    }
    // An upward patch at the sphere centre sees the upper hemisphere of uniform radiance L:
    // irradiance π L (the lights' areas partition the surface).
    let e: f64 = lights[..901]
        .iter()
        .map(|l| l.irradiance(centre, DVec3::Y))
        .sum();
    let expect = std::f64::consts::PI * p.radiance;
    assert!((e - expect).abs() < 0.01 * expect, "{e} vs {expect}");
    // Bad parameters.
    for bad in [
        DomeParams { radius_m: 0.0, ..p },
        DomeParams {
            height_fraction: 1.5,
            ..p
        },
        DomeParams {
            clear_radius_m: 10.0,
            ..p
        },
        DomeParams {
            up: DVec3::ZERO,
            ..p
        },
        DomeParams {
            sphere_lights: 0,
            floor_lights: 0,
            ..p
        },
        DomeParams {
            radius_m: f64::NAN,
            ..p
        },
    ] {
        assert!(dome_lights(&bad).is_err(), "{bad:?}");
    }
}

/// True when the segment from `q` to `l` passes through the sphere `(c, r)`.
fn segment_hits_sphere(q: DVec3, l: DVec3, c: DVec3, r: f64) -> bool {
    let d = l - q;
    let t = ((c - q).dot(d) / d.length_squared()).clamp(0.0, 1.0);
    (q + d * t - c).length() < r
}

#[test]
fn cast_shadows_match_analytic_sphere_shadow() {
    let (c, r) = (DVec3::new(0.1, 0.5, 0.0), 0.3);
    let ball = uv_sphere(c, r, 24, 32);
    let scene = merge(&floor_grid(1.0, 60), &ball);
    let query = MeshQuery::new(&scene).unwrap();
    let light_pos = DVec3::new(0.6, 2.0, 0.3);
    let lights = [Light::Point {
        position: light_pos,
        intensity: 4.0,
    }];
    let cam = top_camera(64);
    let view = render_all(&cam, &scene);
    let vis = LightVisibility::compute(
        &scene,
        &query,
        &lights,
        LightVisibility::DEFAULT_SHADOW_BIAS_M,
    )
    .unwrap();
    let alb = Albedo::Uniform([1.0; 3]);
    let per_vertex = shade(&view, &scene, &lights, &alb, &Shadows::PerVertex(&vis)).unwrap();
    let per_pixel = shade(
        &view,
        &scene,
        &lights,
        &alb,
        &Shadows::PerPixel {
            query: &query,
            bias_m: LightVisibility::DEFAULT_SHADOW_BIAS_M,
        },
    )
    .unwrap();
    let unshadowed = shade(&view, &scene, &lights, &alb, &Shadows::None).unwrap();
    let (mut dark, mut lit) = (0, 0);
    for y in 0..64 {
        for x in 0..64 {
            let i = view.index(x, y);
            if view.mask[i] == 0 || view.triangle[i] as usize >= 2 * 60 * 60 {
                continue; // background or the ball itself
            }
            let ray = cam
                .ray(skin_core::math::DVec2::new(x as f64, y as f64))
                .unwrap();
            let q = ray.at(view.depth_m[i] as f64);
            // Skip floor points whose shadow status changes within `m` (per pixel: 1 cm;
            // per vertex: a grid cell's diagonal, 4.7 cm).
            let near_edge = |m: f64| {
                [
                    DVec3::X,
                    DVec3::NEG_X,
                    DVec3::Z,
                    DVec3::NEG_Z,
                    DVec3::X + DVec3::Z,
                ]
                .iter()
                .any(|&o| {
                    segment_hits_sphere(q + o * m, light_pos, c, r)
                        != segment_hits_sphere(q, light_pos, c, r)
                })
            };
            if near_edge(0.01) {
                continue;
            }
            let vertex_ok = !near_edge(0.05);
            let shadowed = segment_hits_sphere(q, light_pos, c, r);
            let full = unshadowed.radiance[i][0];
            assert!(full > 0.0);
            if shadowed {
                dark += 1;
                assert_eq!(per_pixel.radiance[i][0], 0.0);
                assert!(!vertex_ok || per_vertex.radiance[i][0] < 1e-6 * full);
            } else {
                lit += 1;
                assert_eq!(per_pixel.radiance[i], unshadowed.radiance[i]);
                assert!(!vertex_ok || (per_vertex.radiance[i][0] - full).abs() < 1e-6 * full);
            }
        }
    }
    assert!(dark > 50 && lit > 500, "dark {dark} lit {lit}");
    // Rays from the vertices the view sees only: fewer rays, identical shading.
    let seen = vertices_seen(&scene, &[&view]).unwrap();
    assert!(seen.iter().filter(|&&s| s).count() < scene.vertex_count());
    let part = LightVisibility::compute_for(
        &scene,
        &query,
        &lights,
        LightVisibility::DEFAULT_SHADOW_BIAS_M,
        Some(&seen),
    )
    .unwrap();
    assert_eq!(
        shade(&view, &scene, &lights, &alb, &Shadows::PerVertex(&part)).unwrap(),
        per_vertex
    );
    assert!(LightVisibility::compute_for(&scene, &query, &lights, 1e-4, Some(&seen[1..])).is_err());
    // Deterministic across thread counts.
    let run = |t: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap()
            .install(|| {
                let v = LightVisibility::compute(&scene, &query, &lights, 1e-4).unwrap();
                (
                    v.clone(),
                    shade(&view, &scene, &lights, &alb, &Shadows::PerVertex(&v)).unwrap(),
                )
            })
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn lights_inside_the_body_are_rejected() {
    let ball = uv_sphere(DVec3::new(0.0, 1.0, 0.0), 0.5, 16, 24);
    let query = MeshQuery::new(&ball).unwrap();
    let inside = Light::Point {
        position: DVec3::new(0.1, 1.1, 0.05),
        intensity: 1.0,
    };
    let outside = Light::Point {
        position: DVec3::new(0.0, 3.0, 0.0),
        intensity: 1.0,
    };
    assert!(check_lights_outside(&query, &[outside]).is_ok());
    assert!(matches!(
        check_lights_outside(&query, &[outside, inside]),
        Err(Error::InvalidParam { name: "lights", .. })
    ));
    assert!(LightVisibility::compute(&ball, &query, &[inside], 1e-4).is_err());
    let cam = top_camera(16);
    let view = render_all(&cam, &ball);
    let pp = Shadows::PerPixel {
        query: &query,
        bias_m: 1e-4,
    };
    assert!(shade(&view, &ball, &[inside], &Albedo::Uniform([1.0; 3]), &pp).is_err());
    // The dome around a body-sized ball is entirely outside.
    assert!(check_lights_outside(&query, &dome_lights(&DomeParams::default()).unwrap()).is_ok());
}

#[test]
fn albedo_modes_agree_and_bad_inputs_are_errors() {
    let ball = uv_sphere(DVec3::new(0.0, 0.5, 0.0), 0.5, 16, 24);
    let cam = top_camera(24);
    let view = render_all(&cam, &ball);
    let lights = [Light::Area {
        position: DVec3::new(0.3, 3.0, 0.2),
        normal: DVec3::NEG_Y,
        area_m2: 0.01,
        radiance: 100.0,
    }];
    // A linear texture of the rest position: per-vertex interpolation is then exact.
    let rest: Vec<DVec3> = ball.vertices.iter().map(|v| *v * 1.3).collect();
    let tex = |p: DVec3| [(0.5 + 0.2 * p.x) as f32, (0.5 - 0.1 * p.z) as f32, 0.7];
    let per_vertex: Vec<[f32; 3]> = rest.iter().map(|&p| tex(p)).collect();
    let a = shade(
        &view,
        &ball,
        &lights,
        &Albedo::PerVertex(&per_vertex),
        &Shadows::None,
    )
    .unwrap();
    let b = shade(
        &view,
        &ball,
        &lights,
        &Albedo::Procedural {
            rest_positions: &rest,
            texture: &tex,
        },
        &Shadows::None,
    )
    .unwrap();
    let mut lit = 0;
    for (x, y) in a.radiance.iter().zip(&b.radiance) {
        for c in 0..3 {
            assert!((x[c] - y[c]).abs() <= 1e-5 * x[c].abs().max(1e-3));
        }
        lit += (x[0] > 0.0) as usize;
    }
    assert!(lit > 50);
    assert_eq!(a.to_image().unwrap().dimensions(), (24, 24));
    let picture = srgb8(&a.to_image().unwrap(), 1.0);
    assert_eq!(picture.dimensions(), (24, 24));
    assert!(picture.pixels().any(|p| p.0 != [0; 3]));
    // Errors.
    let alb = Albedo::Uniform([1.0; 3]);
    assert!(matches!(
        shade(&view, &ball, &[], &alb, &Shadows::None),
        Err(Error::Empty { .. })
    ));
    assert!(matches!(
        shade(
            &view,
            &ball,
            &lights,
            &Albedo::PerVertex(&per_vertex[1..]),
            &Shadows::None
        ),
        Err(Error::SizeMismatch { .. })
    ));
    let no_ids = Rasterizer::new(&cam)
        .render(&ball, &RenderParams::default())
        .unwrap();
    assert!(matches!(
        shade(&no_ids, &ball, &lights, &alb, &Shadows::None),
        Err(Error::Empty { .. })
    ));
    let nan = Light::Point {
        position: DVec3::new(f64::NAN, 0.0, 0.0),
        intensity: 1.0,
    };
    assert!(matches!(
        shade(&view, &ball, &[nan], &alb, &Shadows::None),
        Err(Error::NonFinite { .. })
    ));
    let neg = Light::Area {
        position: DVec3::Y,
        normal: DVec3::ZERO,
        area_m2: 1.0,
        radiance: 1.0,
    };
    assert!(shade(&view, &ball, &[neg], &alb, &Shadows::None).is_err());
    let small = TriMesh::new(ball.vertices.clone(), ball.faces[..10].to_vec()).unwrap();
    assert!(matches!(
        shade(&view, &small, &lights, &alb, &Shadows::None),
        Err(Error::IndexOutOfRange { .. })
    ));
    let query = MeshQuery::new(&ball).unwrap();
    assert!(LightVisibility::compute(&ball, &query, &lights, -1.0).is_err());
    assert!(LightVisibility::compute(&small, &query, &lights, 1e-4).is_err());
}
