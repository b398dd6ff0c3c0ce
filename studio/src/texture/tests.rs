use super::*;

/// Albedo samples on a `size`-metre square patch of the plane through `origin` with
/// normal `n` (a 1 mm grid).
fn patch(t: &AlbedoTexture, m: Material, origin: DVec3, size: f64) -> Vec<[f32; 3]> {
    let n = (size / 0.001) as usize;
    let mut out = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            let p = origin
                + DVec3::new(1.0, 0.2, 0.1).normalize() * (i as f64 * 0.001)
                + DVec3::new(-0.1, 1.0, 0.3).normalize() * (j as f64 * 0.001);
            out.push(t.eval(m, p));
        }
    }
    out
}

/// (mean, std) of the luminance-like mean of the channels.
fn stats(v: &[[f32; 3]]) -> (f64, f64) {
    let l: Vec<f64> = v
        .iter()
        .map(|c| c.iter().map(|&x| f64::from(x)).sum::<f64>() / 3.0)
        .collect();
    let mean = l.iter().sum::<f64>() / l.len() as f64;
    let var = l.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / l.len() as f64;
    (mean, var.sqrt())
}

#[test]
fn contrast_of_skin_and_print() {
    let t = AlbedoTexture::new(TextureParams::default()).unwrap();
    let mut skin_rel = Vec::new();
    let mut print_rel = Vec::new();
    for (k, origin) in [
        DVec3::new(0.1, 1.2, 0.05),
        DVec3::new(-0.3, 0.5, -0.1),
        DVec3::new(0.0, 0.9, 0.12),
    ]
    .into_iter()
    .enumerate()
    {
        let (m, s) = stats(&patch(&t, Material::Skin, origin, 0.10));
        skin_rel.push(s / m);
        assert!(
            (0.01..0.15).contains(&(s / m)),
            "skin patch {k}: std/mean {}",
            s / m
        );
        let (m, s) = stats(&patch(&t, Material::Garment, origin, 0.10));
        print_rel.push(s / m);
        assert!(s / m > 0.4, "print patch {k}: std/mean {}", s / m);
        // Everything physical.
        assert!(patch(&t, Material::Garment, origin, 0.02)
            .iter()
            .chain(&patch(&t, Material::Skin, origin, 0.02))
            .flatten()
            .all(|x| (0.0..=1.0).contains(x)));
    }
    eprintln!("texture contrast std/mean: skin {skin_rel:.3?}, print {print_rel:.3?}");
    // The skin varies smoothly (freckle edges aside): millimetre neighbours differ little.
    let s = patch(&t, Material::Skin, DVec3::new(0.1, 1.2, 0.05), 0.05);
    let mut steps: Vec<f32> = s
        .chunks(50)
        .flat_map(|row| row.windows(2).map(|w| (w[0][0] - w[1][0]).abs()))
        .collect();
    steps.sort_by(f32::total_cmp);
    let (median, max) = (steps[steps.len() / 2], steps[steps.len() - 1]);
    assert!(median < 0.01 && max < 0.2, "{median} {max}");
    // The check print is two colours.
    let check = AlbedoTexture::new(TextureParams {
        print: Print::Check,
        ..TextureParams::default()
    })
    .unwrap();
    let (m, s) = stats(&patch(
        &check,
        Material::Garment,
        DVec3::new(0.1, 1.2, 0.05),
        0.1,
    ));
    assert!(s / m > 0.5, "{}", s / m);
}

#[test]
fn deterministic_and_seeded() {
    let a = AlbedoTexture::new(TextureParams::default()).unwrap();
    let b = AlbedoTexture::new(TextureParams::default()).unwrap();
    let c = AlbedoTexture::new(TextureParams {
        seed: 9,
        ..TextureParams::default()
    })
    .unwrap();
    let o = DVec3::new(0.05, 1.0, 0.1);
    for m in [Material::Skin, Material::Garment] {
        assert_eq!(patch(&a, m, o, 0.03), patch(&b, m, o, 0.03));
        assert_ne!(patch(&a, m, o, 0.03), patch(&c, m, o, 0.03));
    }
    let pos = vec![o, o + DVec3::X * 0.01];
    let v = a
        .per_vertex(&pos, &[Material::Skin, Material::Garment])
        .unwrap();
    assert_eq!(v[0], a.skin(pos[0]));
    assert_eq!(v[1], a.garment(pos[1]));
}

#[test]
fn rejects_bad_input() {
    let d = TextureParams::default();
    for bad in [
        TextureParams {
            skin_albedo: [1.2, 0.5, 0.5],
            ..d
        },
        TextureParams {
            garment_inks: [[f32::NAN, 0.0, 0.0], [0.0; 3]],
            ..d
        },
        TextureParams {
            skin_variation: -0.1,
            ..d
        },
        TextureParams {
            print_period_m: 0.0,
            ..d
        },
        TextureParams {
            blotch_scale_m: f64::INFINITY,
            ..d
        },
    ] {
        assert!(matches!(
            AlbedoTexture::new(bad),
            Err(Error::InvalidParam { .. })
        ));
    }
    let t = AlbedoTexture::new(d).unwrap();
    assert!(matches!(
        t.per_vertex(&[DVec3::ZERO], &[]),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        t.per_vertex(&[DVec3::NAN], &[Material::Skin]),
        Err(Error::NonFinite { .. })
    ));
}
#[test]
fn shades_through_albedo_textured() {
    use crate::shading::{shade, Albedo, Light, Shadows};
    use skin_core::camera::{Camera, Intrinsics};
    use skin_core::raster::{Buffers, Rasterizer, RenderParams};
    let ball = skin_core::mesh::shapes::uv_sphere(DVec3::new(0.0, 1.0, 0.0), 0.15, 24, 36).unwrap();
    let k = Intrinsics::from_horizontal_fov(0.5, 96, 96).unwrap();
    let cam = Camera::look_at(
        k,
        DVec3::new(0.0, 1.0, 1.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::Y,
    )
    .unwrap();
    let params = RenderParams::default().with_buffers(Buffers {
        triangle: true,
        ..Buffers::default()
    });
    let view = Rasterizer::new(&cam).render(&ball, &params).unwrap();
    let lights = [Light::Area {
        position: DVec3::new(0.0, 1.0, 3.0),
        normal: DVec3::NEG_Z,
        area_m2: 0.01,
        radiance: 300.0,
    }];
    let t = AlbedoTexture::new(TextureParams::default()).unwrap();
    // Upper half printed cloth, lower half skin.
    let materials: Vec<Material> = (0..ball.face_count())
        .map(|f| {
            if ball.triangle(f).iter().map(|v| v.y).sum::<f64>() > 3.0 {
                Material::Garment
            } else {
                Material::Skin
            }
        })
        .collect();
    let albedo = Albedo::Textured {
        rest_positions: &ball.vertices,
        face_materials: &materials,
        texture: &t,
    };
    assert!(format!("{albedo:?}").contains("Textured"));
    let s = shade(&view, &ball, &lights, &albedo, &Shadows::None).unwrap();
    let lum = |r: &[f32; 3]| f64::from(r[0] + r[1] + r[2]);
    let half = |upper: bool| {
        let v: Vec<[f32; 3]> = (0..96 * 96)
            .filter(|&i| s.radiance[i][0] > 0.0 && ((i / 96) < 48) == upper)
            .map(|i| s.radiance[i])
            .collect();
        stats(&v)
    };
    let ((mg, sg), (ms, ss)) = (half(true), half(false));
    assert!(
        sg / mg > 2.0 * ss / ms,
        "print {} vs skin {}",
        sg / mg,
        ss / ms
    );
    assert!(s.radiance.iter().any(|r| lum(r) > 0.0));
    // Wrong sizes are errors.
    let bad = Albedo::Textured {
        rest_positions: &ball.vertices,
        face_materials: &materials[1..],
        texture: &t,
    };
    assert!(shade(&view, &ball, &lights, &bad, &Shadows::None).is_err());
    let bad = Albedo::Textured {
        rest_positions: &ball.vertices[1..],
        face_materials: &materials,
        texture: &t,
    };
    assert!(shade(&view, &ball, &lights, &bad, &Shadows::None).is_err());
}
