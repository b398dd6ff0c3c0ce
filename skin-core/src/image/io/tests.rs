use super::*;
use proptest::prelude::*;
use std::path::PathBuf;

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("skin_core_image_io_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]
    #[test]
    fn mask_png_round_trip_is_exact(
        (w, h, flags) in (1u32..24, 1u32..24).prop_flat_map(|(w, h)| {
            (Just(w), Just(h), proptest::collection::vec(any::<bool>(), (w * h) as usize))
        }),
        id in 0u32..1_000_000,
    ) {
        let m = Mask::from_bools(w, h, &flags).unwrap();
        let p = tmp(&format!("mask_{id}.png"));
        write_mask_png(&m, &p).unwrap();
        prop_assert_eq!(read_mask_png(&p).unwrap(), m);
        std::fs::remove_file(&p).ok();
    }
}

#[test]
fn depth_png16_round_trip_within_quantisation() {
    for enc in [
        DepthEncoding::default(),
        DepthEncoding {
            scale_m: 1e-3,
            offset_m: 0.5,
        },
    ] {
        let (lo, hi) = enc.range_m();
        let depth = GrayF32Image::from_fn(37, 23, |x, y| {
            let v = match (x + 3 * y) % 11 {
                0 => f32::NAN,
                1 => 0.0,
                2 => f32::INFINITY,
                3 => -1.0,
                _ => (lo + (hi - lo) * 0.999 * f64::from(x * 23 + y) / (37.0 * 23.0)) as f32,
            };
            Luma([v])
        });
        let p = tmp(&format!("depth_{}.png", enc.scale_m));
        write_depth_png16(&depth, &p, &enc).unwrap();
        let back = read_depth_png16(&p, &enc).unwrap();
        assert_eq!(back.dimensions(), depth.dimensions());
        for (&a, &b) in depth.as_raw().iter().zip(back.as_raw()) {
            if is_valid_depth(a) {
                let err = (f64::from(a) - f64::from(b)).abs();
                // Half a quantum plus f32 rounding of values up to ~66 m.
                assert!(err <= 0.5 * enc.scale_m + 1e-5 * f64::from(a), "{a} vs {b}");
            } else {
                assert!(b.is_nan(), "no data must read back as NaN, got {b}");
            }
        }
    }
}

#[test]
fn depth_out_of_range_and_bad_encodings_are_errors() {
    let d = GrayF32Image::from_pixel(2, 2, Luma([10.0]));
    let p = tmp("depth_bad.png");
    assert!(matches!(
        write_depth_png16(&d, &p, &DepthEncoding::default()),
        Err(Error::InvalidParam { .. })
    ));
    let bad = DepthEncoding {
        scale_m: 0.0,
        offset_m: 0.0,
    };
    assert!(matches!(
        write_depth_png16(&d, &p, &bad),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(
        write_depth_png16(&GrayF32Image::new(0, 2), &p, &DepthEncoding::default()),
        Err(Error::Empty { .. })
    ));
    // An 8-bit PNG is not a depth PNG.
    write_mask_png(&Mask::new(3, 3), &p).unwrap();
    assert!(matches!(
        read_depth_png16(&p, &DepthEncoding::default()),
        Err(Error::Parse { .. })
    ));
    assert!(matches!(read_normal_png(&p), Err(Error::Parse { .. })));
}

#[test]
fn false_colour_depth_marks_no_data_black_and_orders_depth() {
    let d = GrayF32Image::from_fn(10, 1, |x, _| {
        Luma([if x == 0 {
            f32::NAN
        } else {
            1.0 + x as f32 * 0.1
        }])
    });
    let range = DepthRange {
        near_m: 1.1,
        far_m: 1.9,
    };
    let img = depth_false_colour(&d, &range).unwrap();
    assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
    for x in 1..10 {
        assert_ne!(img.get_pixel(x, 0).0, [0, 0, 0]);
    }
    // Near is bluer than far, far is redder than near.
    let (n, f) = (img.get_pixel(1, 0).0, img.get_pixel(9, 0).0);
    assert!(n[2] > f[2] && f[0] > n[0]);
    let p = tmp("depth_colour.png");
    write_depth_false_colour_png(&d, &p, &range).unwrap();
    assert_eq!(::image::open(&p).unwrap().to_rgb8(), img);
    let inverted = DepthRange {
        near_m: 2.0,
        far_m: 1.0,
    };
    assert!(matches!(
        depth_false_colour(&d, &inverted),
        Err(Error::InvalidParam { .. })
    ));
}

#[test]
fn normal_png_round_trip() {
    let normals = Rgb32FImage::from_fn(19, 13, |x, y| {
        if (x + y) % 7 == 0 {
            return Rgb([f32::NAN, 0.0, 0.0]);
        }
        if (x + y) % 7 == 1 {
            return Rgb([0.0, 0.0, 0.0]);
        }
        let th = x as f32 * 0.31 + 0.1;
        let ph = y as f32 * 0.23 - 1.4;
        // Include non-unit input: it is normalised on write.
        let s = 1.0 + 0.5 * ((x % 3) as f32);
        Rgb([
            s * ph.cos() * th.cos(),
            s * ph.cos() * th.sin(),
            s * ph.sin(),
        ])
    });
    for (bits, tol) in [
        (NormalBits::Eight, 1.2 / 255.0),
        (NormalBits::Sixteen, 1e-4),
    ] {
        let p = tmp(&format!("normals_{bits:?}.png"));
        write_normal_png(&normals, &p, bits).unwrap();
        let back = read_normal_png(&p).unwrap();
        for (a, b) in normals.pixels().zip(back.pixels()) {
            match unit_normal(a) {
                None => assert!(b.0.iter().all(|v| v.is_nan())),
                Some(n) => {
                    for i in 0..3 {
                        assert!((n[i] - b.0[i]).abs() < 2.0 * tol, "{n:?} vs {:?}", b.0);
                    }
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Randomly corrupted PNG bytes never panic: every reader returns a value or an error.
    #[test]
    fn corrupted_png_bytes_never_panic(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<prop::sample::Index>(),
        id in 0u32..1_000_000,
    ) {
        let src = tmp(&format!("fuzz_src_{id}.png"));
        let depth = GrayF32Image::from_fn(9, 7, |x, y| Luma([0.5 + (x * y) as f32 * 0.01]));
        write_depth_png16(&depth, &src, &DepthEncoding::default()).unwrap();
        let mut bytes = std::fs::read(&src).unwrap();
        for (i, v) in &edits {
            let k = i.index(bytes.len());
            bytes[k] = *v;
        }
        bytes.truncate(cut.index(bytes.len()) + 1);
        let p = tmp(&format!("fuzz_{id}.png"));
        std::fs::write(&p, &bytes).unwrap();
        let _ = read_mask_png(&p);
        let _ = read_depth_png16(&p, &DepthEncoding::default());
        let _ = read_normal_png(&p);
        std::fs::remove_file(&p).ok();
        std::fs::remove_file(&src).ok();
    }
}

#[test]
fn corrupt_and_missing_files_are_errors() {
    let p = tmp("corrupt.png");
    std::fs::write(&p, b"\x89PNG\r\n\x1a\nthis is not a png at all").unwrap();
    assert!(matches!(read_mask_png(&p), Err(Error::Image(_))));
    assert!(matches!(
        read_depth_png16(&p, &DepthEncoding::default()),
        Err(Error::Image(_))
    ));
    assert!(matches!(read_normal_png(&p), Err(Error::Image(_))));
    // A valid PNG cut in half.
    let good = tmp("good.png");
    write_mask_png(&Mask::from_fn(40, 40, |x, y| (x ^ y) & 1 == 1), &good).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    assert!(read_mask_png(&p).is_err());
    std::fs::write(&p, b"").unwrap();
    assert!(read_mask_png(&p).is_err());
    let missing = tmp("does_not_exist.png");
    assert!(matches!(read_mask_png(&missing), Err(Error::Io { .. })));
    assert!(matches!(
        write_mask_png(&Mask::new(0, 0), &p),
        Err(Error::Empty { .. })
    ));
    let bad_dir = tmp("no_such_dir").join("x.png");
    assert!(matches!(
        write_mask_png(&Mask::new(2, 2), &bad_dir),
        Err(Error::Io { .. })
    ));
}
