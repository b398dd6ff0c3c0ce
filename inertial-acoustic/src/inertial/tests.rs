use super::*;
const TAU_F: f64 = std::f64::consts::TAU;

#[test]
fn hamming_corrects_one_and_flags_two_errors() {
    for d in 0..64u8 {
        let w = hamming_encode(d);
        assert_eq!(hamming_decode(w), Some(d));
        for i in 0..11 {
            assert_eq!(hamming_decode(w ^ (1 << i)), Some(d), "data {d} bit {i}");
            for k in i + 1..11 {
                assert_eq!(hamming_decode(w ^ (1 << i) ^ (1 << k)), None);
            }
        }
    }
}

#[test]
fn delta_stream_round_trips_and_keeps_precision() {
    let (mut enc, mut dec) = (DeltaCodec::new(), DeltaCodec::new());
    let mut sum_in = 0i64;
    let mut sum_out = 0i64;
    for k in 0..400 {
        let t = k as f64 / 140.0;
        let v = (2048.0 + 900.0 * (2.0 * t).sin()) as i32;
        let counts = [v, 4095 - v, 2048, v / 2 + 1000, 3000, 100 + k % 7];
        let mut bits = enc.encode(&counts).unwrap();
        bits[(k as usize * 13) % FRAME_BITS] ^= true; // one bit error per frame: corrected
        let (out, corrected) = dec.decode(&bits).unwrap();
        assert_eq!(corrected, 1);
        // Slew-limited tracking: within a few counts once locked on.
        if k > 40 {
            assert!((out[0] - v).abs() <= 32, "frame {k}: {} vs {v}", out[0]);
            sum_in += i64::from(v);
            sum_out += i64::from(out[0]);
        }
    }
    // Delta modulation carries round-off forward: the sums agree to a code step.
    assert!((sum_in - sum_out).abs() < 64);
}

/// A step larger than the code's slew is flagged on every frame the decoder lags it; a
/// count at full scale is flagged as clipped; a slowly moving count is flagged nowhere.
#[test]
fn saturated_samples_are_flagged_and_others_not() {
    let (mut enc, mut dec) = (DeltaCodec::new(), DeltaCodec::new());
    // Lock both ends onto the first counts (as the simulator does), then a slow sine of
    // ±200 counts at 1 Hz moves at most 9 counts per 140 Hz frame.
    for _ in 0..160 {
        let bits = enc.encode(&[2048, 2048, 2048, 100, 3000, 2048]).unwrap();
        let _ = dec.decode(&bits).unwrap();
    }
    for k in 0..280 {
        let v = 2048 + (200.0 * (TAU_F * k as f64 / 140.0).sin()) as i32;
        let bits = enc.encode(&[v, v, 2048, 100, 3000, 2048]).unwrap();
        let (out, _) = dec.decode(&bits).unwrap();
        assert_eq!(out[0], v);
        assert!(dec.saturation().iter().all(|s| !s.any()), "frame {k}");
    }
    // A jump of 200 counts on channel 0: 31 per frame, so 6 frames saturated, then exact.
    let target = [2248, 2048, 2048, 2048, 2048, 2048];
    let (mut enc, mut dec) = (DeltaCodec::new(), DeltaCodec::new());
    let mut slewed = 0;
    for _ in 0..20 {
        let bits = enc.encode(&target).unwrap();
        let (out, _) = dec.decode(&bits).unwrap();
        let s = dec.saturation();
        assert!(s[1..].iter().all(|s| !s.any()));
        assert!(!s[0].clipped);
        if s[0].slew {
            slewed += 1;
            assert!(out[0] < target[0], "a saturated delta lags");
        } else {
            assert_eq!(out[0], target[0]);
        }
    }
    assert_eq!(slewed, 200 / 31);
    // Downwards the extreme is −32.
    let (mut enc, mut dec) = (DeltaCodec::new(), DeltaCodec::new());
    let bits = enc.encode(&[1948, 2048, 2048, 2048, 2048, 2048]).unwrap();
    let _ = dec.decode(&bits).unwrap();
    assert!(dec.saturation()[0].slew && !dec.saturation()[0].clipped);
    // Full scale: once the decoder reaches 4092 or 0 the channel is clipped.
    let (mut enc, mut dec) = (DeltaCodec::new(), DeltaCodec::new());
    for _ in 0..100 {
        let bits = enc.encode(&[4092, 0, 4091, 1, 2048, 2048]).unwrap();
        let _ = dec.decode(&bits).unwrap();
    }
    let s = dec.saturation();
    assert!(s[0].clipped && s[1].clipped && !s[0].slew && !s[1].slew);
    assert!(!s[2].any() && !s[3].any() && !s[4].any());
}

/// The noise-shaped code (§4.2.3's "compensate by overestimating in the next frame"): on
/// a swing that slews the whole-count code (up to 150 counts per frame), each frame is
/// within a step and the running sum of the decoded counts — what integrating a
/// gyroscope sees — stays within one step of the true sum, where the whole-count code's
/// lag adds up to thousands of counts.
#[test]
fn noise_shaped_deltas_keep_the_running_sum() {
    let step = 8;
    let signal: Vec<i32> = (0..400)
        .map(|k| 2048 + (1500.0 * (TAU_F * k as f64 / 64.0).sin()).round() as i32)
        .collect();
    let run = |mut enc: DeltaCodec, mut dec: DeltaCodec| {
        let (mut worst_frame, mut worst_sum, mut sum) = (0i32, 0i64, 0i64);
        for &x in &signal {
            let bits = enc.encode(&[x, 2048, 2048, 2048, 2048, 2048]).unwrap();
            let (out, _) = dec.decode(&bits).unwrap();
            sum += i64::from(out[0] - x);
            worst_frame = worst_frame.max((out[0] - x).abs());
            worst_sum = worst_sum.max(sum.abs());
        }
        (worst_frame, worst_sum)
    };
    let (frame, sum) = run(
        DeltaCodec::noise_shaped(step).unwrap(),
        DeltaCodec::noise_shaped(step).unwrap(),
    );
    assert!(frame <= step, "frame error {frame} counts");
    assert!(sum <= i64::from(step), "running-sum error {sum} counts");
    let (frame_whole, sum_whole) = run(DeltaCodec::new(), DeltaCodec::new());
    assert!(
        frame_whole > 100 && sum_whole > 1000,
        "{frame_whole} {sum_whole}"
    );
    // Step 1 with feedback equals the whole-count code while nothing slews.
    let slow: Vec<i32> = (0..200).map(|k| 2048 + (k % 20) - 10).collect();
    let (mut a, mut b) = (DeltaCodec::new(), DeltaCodec::noise_shaped(1).unwrap());
    for &x in &slow {
        let c = [x, 2048, 2048, 2048, 2048, 2048];
        assert_eq!(a.encode(&c).unwrap(), b.encode(&c).unwrap());
    }
    for bad in [0, -1, 129] {
        assert!(DeltaCodec::noise_shaped(bad).is_err());
    }
}

/// The noise-shaped code's per-frame error is what its docs derive and what the filter is
/// told (`frame_error_sigma_counts`): on a slow swing plus a per-frame jitter of ±3 steps
/// (so successive round-offs are independent, and nothing slews), the decoded counts'
/// error has σ = step/√6, mean ≈ 0, lag-1 correlation −½, lag 2 ≈ 0, every frame within
/// `frame_error_bound_counts`, and the mean of two successive frames σ ≈ step/(2√6) —
/// all to 6 % (integer counts make the round-off discrete: at step 8, σ is 4 % above
/// step/√6 and ρ₁ −0.54). Plain rounding without feedback would give step/√12 and no
/// correlation; the whole-count code gives 0 and says so.
#[test]
fn noise_shaped_frame_error_has_the_documented_sigma_and_correlation() {
    use rand::{RngExt, SeedableRng};
    for step in [8, 16, 32] {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (mut enc, mut dec) = (
            DeltaCodec::noise_shaped(step).unwrap(),
            DeltaCodec::noise_shaped(step).unwrap(),
        );
        let mut err = Vec::new();
        for k in 0..20_000 {
            let x = 2048.0
                + 800.0 * (TAU_F * f64::from(k) / 500.0).sin()
                + (6.0 * rng.random::<f64>() - 3.0) * f64::from(step);
            let c = x.round() as i32;
            let bits = enc.encode(&[c, 2048, 2048, 2048, 2048, 2048]).unwrap();
            let (out, _) = dec.decode(&bits).unwrap();
            assert!((out[0] - c).abs() <= enc.frame_error_bound_counts());
            err.push(f64::from(out[0] - c));
        }
        let n = err.len() as f64;
        let mean = err.iter().sum::<f64>() / n;
        let var = err.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n;
        let lag = |l: usize| {
            err.windows(l + 1)
                .map(|w| (w[0] - mean) * (w[l] - mean))
                .sum::<f64>()
                / (n - l as f64)
                / var
        };
        let sigma = enc.frame_error_sigma_counts();
        assert!((sigma - f64::from(step) / 6f64.sqrt()).abs() < 1e-12);
        assert!(
            (var.sqrt() / sigma - 1.0).abs() < 0.06,
            "step {step}: σ {} vs {sigma}",
            var.sqrt()
        );
        assert!(mean.abs() < 0.05 * sigma, "step {step}: mean {mean}");
        assert!((lag(1) + 0.5).abs() < 0.06, "step {step}: ρ1 {}", lag(1));
        assert!(lag(2).abs() < 0.06, "step {step}: ρ2 {}", lag(2));
        let pair = err
            .windows(2)
            .map(|w| (0.5 * (w[0] + w[1])).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        assert!(
            (pair.sqrt() / (sigma / 2.0) - 1.0).abs() < 0.06,
            "step {step}: two-frame mean σ {}",
            pair.sqrt()
        );
    }
    let whole = DeltaCodec::new();
    assert_eq!(whole.frame_error_sigma_counts(), 0.0);
    assert_eq!(whole.frame_error_bound_counts(), 0);
    assert!(!whole.is_noise_shaped() && whole.step() == 1);
}

/// A random walk of counts with per-frame jitter, six channels.
fn random_counts(n: usize, seed: u64) -> Vec<[i32; CHANNELS]> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut x = [2048.0f64; CHANNELS];
    let mut v = [0.0f64; CHANNELS];
    (0..n)
        .map(|_| {
            std::array::from_fn(|c| {
                v[c] = 0.97 * v[c] + 12.0 * (rng.random::<f64>() - 0.5);
                x[c] = (x[c] + v[c]).clamp(300.0, 3800.0);
                (x[c] + 40.0 * (rng.random::<f64>() - 0.5)).round() as i32
            })
        })
        .collect()
}

/// Flips two bits of channel `c`'s code: uncorrectable.
fn lose(bits: &mut [bool; FRAME_BITS], c: usize) {
    bits[c] ^= true;
    bits[CHANNELS + c] ^= true;
}

/// Key frames: random counts through the 16-count code with
/// codes lost at random (single channels and whole frames). A lost channel is flagged
/// unsynced on every frame until its next key frame whose halves both arrive; from then
/// on the decoder equals the encoder exactly; every unflagged reading is the encoder's
/// count and within the code's bound of the true count. The same link without key
/// frames (the baseline) ends off the encoder on the lost channels.
#[test]
fn key_frames_resynchronise_the_decoder_after_lost_codes() {
    use rand::{RngExt, SeedableRng};
    let step = 16;
    let key = 28u32;
    let counts = random_counts(6000, 11);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let losses: Vec<Vec<usize>> = (0..counts.len())
        .map(|k| {
            if k < 50 || !rng.random_bool(0.03) {
                Vec::new()
            } else if rng.random_bool(0.2) {
                (0..CHANNELS).collect()
            } else {
                vec![rng.random_range(0..CHANNELS)]
            }
        })
        .collect();
    let keyed = DeltaCodec::noise_shaped(step)
        .unwrap()
        .with_key_interval(key)
        .unwrap();
    let (mut enc, mut dec) = (keyed.clone(), keyed);
    let (mut enc0, mut dec0) = (
        DeltaCodec::noise_shaped(step).unwrap(),
        DeltaCodec::noise_shaped(step).unwrap(),
    );
    // The frame of the delta whose loss unsynced the channel (None: in step), and
    // whether the current key's first half was lost.
    let mut lost_at: [Option<usize>; CHANNELS] = [None; CHANNELS];
    let mut half_lost = [false; CHANNELS];
    let (mut resyncs, mut flagged_lost, mut checked) = (0, 0, 0);
    for (k, (x, lost)) in counts.iter().zip(&losses).enumerate() {
        let phases: [Option<u8>; CHANNELS] = std::array::from_fn(|c| enc.key_phase(c));
        let mut bits = enc.encode(x).unwrap();
        let mut bits0 = enc0.encode(x).unwrap();
        for &c in lost {
            lose(&mut bits, c);
            lose(&mut bits0, c);
            match phases[c] {
                None => lost_at[c] = Some(k),
                Some(0) => half_lost[c] = true,
                Some(_) => {}
            }
        }
        let _ = dec0.decode(&bits0);
        let out = dec.decode(&bits);
        assert_eq!(out.is_none(), !lost.is_empty(), "frame {k}");
        let flags = dec.saturation();
        for c in 0..CHANNELS {
            if phases[c] == Some(1) {
                // An unsynced channel resynchronises if both halves and the delta before
                // them (the extrapolation through the key) arrived; a channel in step
                // stays in step whatever the key's halves.
                let halves = !half_lost[c] && !lost.contains(&c);
                if lost_at[c].is_some_and(|l| !halves || l + 2 == k) {
                    assert!(flags[c].unsynced);
                } else {
                    if lost_at[c].is_some() {
                        resyncs += 1;
                    }
                    lost_at[c] = None;
                    assert_eq!(dec.recon[c], enc.recon[c], "frame {k} channel {c}");
                }
                half_lost[c] = false;
            }
            if phases[c].is_some() {
                assert!(flags[c].unsynced, "key frame {k} channel {c} is flagged");
            } else if lost_at[c].is_some() {
                flagged_lost += 1;
                assert!(flags[c].unsynced, "frame {k}: lost channel {c} flagged");
            } else {
                assert!(!flags[c].unsynced, "frame {k} channel {c}");
                assert_eq!(dec.recon[c], enc.recon[c], "frame {k} channel {c}");
                if let Some((o, _)) = out {
                    if !flags[c].slew {
                        assert!((o[c] - x[c]).abs() <= step, "frame {k} channel {c}");
                        checked += 1;
                    }
                }
            }
        }
    }
    assert!(
        resyncs > 100 && flagged_lost > 1000,
        "{resyncs} {flagged_lost}"
    );
    assert!(checked > 25_000, "{checked}");
    // The baseline: without key frames the lost channels stay off for good.
    let off = (0..CHANNELS)
        .filter(|&c| dec0.recon[c] != enc0.recon[c])
        .count();
    assert!(off >= 5, "{off} channels off without key frames");
    // A lost key half: a channel in step stays in step (the key's count is the one both
    // ends hold), flagged only on its key frames.
    let keyed = DeltaCodec::noise_shaped(step)
        .unwrap()
        .with_key_interval(key)
        .unwrap();
    let (mut enc, mut dec) = (keyed.clone(), keyed);
    let mut lost_key = 0;
    for (k, x) in counts.iter().take(6 * key as usize).enumerate() {
        let phase = enc.key_phase(2);
        let mut bits = enc.encode(x).unwrap();
        if k > key as usize && phase.is_some() && k % 3 == 0 {
            lose(&mut bits, 2);
            lost_key += 1;
            assert!(dec.decode(&bits).is_none());
        } else {
            let _ = dec.decode(&bits).unwrap();
        }
        assert_eq!(dec.saturation()[2].unsynced, phase.is_some(), "frame {k}");
        assert_eq!(dec.recon[2], enc.recon[2], "frame {k}");
    }
    assert!(lost_key >= 2);
}

/// Three bit errors in one code pass the extended Hamming code as a single error (a
/// mis-correction, undetectable in itself): in a key's high half or in a delta, the
/// decoder's count would be off unflagged. A key checks a channel in step (its count is
/// the one the decoder holds): the channel is flagged from the first key after the
/// error until the next key confirms it; a wrong key is not taken for good.
#[test]
fn a_key_checks_a_channel_in_step_against_mis_corrected_codes() {
    let key = 28usize;
    let counts = random_counts(10 * key, 5);
    // Code bits 3, 5, 6 (data bits 0, 1, 2) of channel 2: syndrome 0, odd parity.
    let miscorrect = |bits: &mut [bool; FRAME_BITS]| {
        for i in [3, 5, 6] {
            bits[i * CHANNELS + 2] ^= true;
        }
    };
    for in_key in [true, false] {
        let keyed = DeltaCodec::noise_shaped(16)
            .unwrap()
            .with_key_interval(key as u32)
            .unwrap();
        let (mut enc, mut dec) = (keyed.clone(), keyed);
        let mut hit: Option<usize> = None;
        let mut key_ends = Vec::new();
        for (k, x) in counts.iter().enumerate() {
            let phase = enc.key_phase(2);
            let mut bits = enc.encode(x).unwrap();
            let target = if in_key { Some(0) } else { None };
            if hit.is_none() && k > 2 * key && phase == target {
                miscorrect(&mut bits);
                hit = Some(k);
            }
            let (_, fixed) = dec.decode(&bits).unwrap();
            if hit == Some(k) {
                assert_eq!(fixed, 1, "passes as one corrected error");
            }
            if phase == Some(1) {
                key_ends.push(k);
            }
            let flagged = dec.saturation()[2].unsynced;
            let Some(h) = hit else {
                assert_eq!(flagged, phase.is_some(), "frame {k}");
                assert_eq!(dec.recon[2], enc.recon[2], "frame {k}");
                continue;
            };
            // The first key end after the hit exposes it, the second confirms.
            match key_ends.iter().filter(|&&e| e >= h).count() {
                0 if in_key => {
                    // The wrong high half is held until the second half.
                    assert_eq!(dec.recon[2], enc.recon[2], "frame {k}");
                    assert!(flagged, "frame {k}");
                }
                0 => {
                    // A wrong delta: off, unflagged (not detectable yet).
                    assert_ne!(dec.recon[2], enc.recon[2], "frame {k}");
                    assert_eq!(flagged, phase.is_some(), "frame {k}");
                }
                1 => {
                    assert!(flagged, "frame {k}: flagged until confirmed");
                    assert_eq!(dec.recon[2] != enc.recon[2], in_key, "frame {k}");
                }
                _ => {
                    assert_eq!(flagged, phase.is_some(), "frame {k}");
                    assert_eq!(dec.recon[2], enc.recon[2], "frame {k}");
                }
            }
        }
        assert!(hit.is_some());
    }
}

/// With no bit errors the keyed code decodes as before: every unflagged frame within one
/// step of the count (σ step/√6 to 6 %, as the type's docs derive), exactly two of
/// every K readings per channel flagged (its key frames), never two channels' keys in
/// one frame; bad intervals are errors.
#[test]
fn key_frames_cost_two_readings_per_interval_and_keep_the_frame_error() {
    let step = 16;
    for key in [12u32, 70, 140] {
        let counts = random_counts(14_000, 7);
        let keyed = DeltaCodec::noise_shaped(step)
            .unwrap()
            .with_key_interval(key)
            .unwrap();
        assert_eq!(keyed.key_interval(), key);
        let (mut enc, mut dec) = (keyed.clone(), keyed);
        let mut flagged = [0usize; CHANNELS];
        let mut err = Vec::new();
        for (k, x) in counts.iter().enumerate() {
            let bits = enc.encode(x).unwrap();
            let (out, _) = dec.decode(&bits).unwrap();
            let flags = dec.saturation();
            assert!(
                flags.iter().filter(|s| s.unsynced).count() <= 1,
                "frame {k}"
            );
            for c in 0..CHANNELS {
                assert_eq!(dec.recon[c], enc.recon[c]);
                if flags[c].unsynced {
                    flagged[c] += 1;
                } else if !flags[c].slew {
                    assert!((out[c] - x[c]).abs() <= enc.frame_error_bound_counts());
                    err.push(f64::from(out[c] - x[c]));
                }
            }
        }
        for f in flagged {
            let expected = 2 * counts.len() / key as usize;
            assert!(f.abs_diff(expected) <= 2, "K {key}: {f} vs {expected}");
        }
        let n = err.len() as f64;
        let sigma = (err.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        let documented = enc.frame_error_sigma_counts();
        assert!(
            (sigma / documented - 1.0).abs() < 0.06,
            "K {key}: σ {sigma} vs {documented}"
        );
    }
    let base = DeltaCodec::noise_shaped(step).unwrap();
    for bad in [1, 4, 11, 1_000_001] {
        assert!(base.clone().with_key_interval(bad).is_err(), "{bad}");
    }
    assert_eq!(base.clone().with_key_interval(0).unwrap(), base);
}

#[test]
fn double_errors_are_flagged_and_bad_counts_rejected() {
    let (mut enc, mut dec) = (DeltaCodec::new(), DeltaCodec::new());
    let mut bits = enc.encode(&[2060, 2048, 2048, 2048, 2048, 2048]).unwrap();
    bits[0] ^= true;
    bits[CHANNELS] ^= true; // the same code (channel 0), two bits
    assert!(dec.decode(&bits).is_none());
    assert!(enc.encode(&[5000, 0, 0, 0, 0, 0]).is_err());
    assert!(AxisCalibration::from_opposite(1.0, 1.0, 9.8).is_err());
    let cal = AxisCalibration::from_opposite(2548.0, 1548.0, 9.8).unwrap();
    assert!((cal.value(2048.0)).abs() < 1e-12 && (cal.value(2548.0) - 9.8).abs() < 1e-12);
}
