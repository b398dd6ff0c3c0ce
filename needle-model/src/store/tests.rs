use super::*;
use proptest::prelude::*;

fn shapes() -> Vec<PrimitiveShape> {
    vec![
        PrimitiveShape {
            config_dim: 3,
            needle_count: 400,
            max_length_m: 0.10,
        },
        PrimitiveShape {
            config_dim: 9,
            needle_count: 900,
            max_length_m: 0.30,
        },
    ]
}

#[test]
fn packed_observation_is_three_bytes_and_round_trips() {
    assert_eq!(std::mem::size_of::<PackedObservation>(), 3);
    for (needle, q) in [(0, 0), (4095, 4095), (900, 1), (1, 2048)] {
        let o = PackedObservation::pack(needle, q);
        assert_eq!((o.needle(), o.length_q()), (needle, q));
    }
    let too_many = PrimitiveShape {
        config_dim: 3,
        needle_count: MAX_NEEDLES_PER_PRIMITIVE + 1,
        max_length_m: 0.1,
    };
    assert!(ObservationStore::new(&[too_many]).is_err());
}

#[test]
fn samples_know_their_frames_across_appends() {
    let mut a = ObservationStore::new(&shapes()).unwrap();
    a.push_sample(0, &[0.0; 3], &[(1, 0.05)]).unwrap();
    a.end_frame();
    a.push_sample(0, &[1.0; 3], &[(1, 0.05)]).unwrap();
    a.push_sample(1, &[1.0; 9], &[(2, 0.05)]).unwrap();
    a.end_frame();
    let mut b = ObservationStore::new(&shapes()).unwrap();
    b.end_frame(); // a frame without observations
    b.push_sample(0, &[2.0; 3], &[(3, 0.05)]).unwrap();
    b.end_frame();
    a.append(&b).unwrap();
    assert_eq!(a.frame_count(), 4);
    assert_eq!(a.sample_frames(0), &[0, 1, 3]);
    assert_eq!(a.sample_frames(1), &[1]);
    assert!(a.sample_frames(2).is_empty());
}

#[test]
fn push_and_read_back() {
    let mut st = ObservationStore::new(&shapes()).unwrap();
    assert!(st
        .push_sample(0, &[0.1, 0.2, 0.3], &[(5, 0.05), (7, 0.0999)])
        .unwrap());
    assert!(!st.push_sample(0, &[0.0, 0.0, 0.0], &[]).unwrap());
    assert!(st.push_sample(0, &[1.0, 2.0, 3.0], &[(5, 0.02)]).unwrap());
    assert_eq!(st.primitive_count(), 2);
    assert_eq!(st.config_dim(1), 9);
    assert_eq!(st.sample_count(0), 2);
    assert_eq!(st.samples(0), &[0.1f32, 0.2, 0.3, 1.0, 2.0, 3.0]);
    let obs: Vec<_> = st.observations(0).collect();
    assert_eq!(obs.len(), 3);
    assert_eq!((obs[2].sample, obs[2].needle), (1, 5));
    let step = st.length_step_m(0);
    assert!((obs[1].length_m - 0.0999).abs() <= step * 0.51);
    let bn = st.by_needle(0).unwrap();
    let (s, l) = bn.needle(5);
    assert_eq!(s, &[0, 1]);
    assert!((l[1] - 0.02).abs() <= step * 0.51);
    assert_eq!(bn.needle(6).0.len(), 0);
    assert_eq!(st.observations(7).count(), 0);
}

#[test]
fn bad_input_is_rejected_without_side_effects() {
    let mut st = ObservationStore::new(&shapes()).unwrap();
    assert!(matches!(
        st.push_sample(0, &[0.0; 2], &[(0, 0.01)]),
        Err(Error::SizeMismatch { .. })
    ));
    assert!(matches!(
        st.push_sample(0, &[f64::NAN, 0.0, 0.0], &[(0, 0.01)]),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        st.push_sample(0, &[0.0; 3], &[(0, 0.01), (400, 0.01)]),
        Err(Error::IndexOutOfRange { .. })
    ));
    assert!(matches!(
        st.push_sample(0, &[0.0; 3], &[(0, 0.2)]),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(
        st.push_sample(0, &[0.0; 3], &[(0, -0.01)]),
        Err(Error::InvalidParam { .. })
    ));
    assert!(matches!(
        st.push_sample(0, &[0.0; 3], &[(0, f32::NAN)]),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        st.push_sample(2, &[0.0; 3], &[(0, 0.01)]),
        Err(Error::IndexOutOfRange { .. })
    ));
    assert_eq!(st.total_observations(), 0);
    assert_eq!(st.sample_count(0), 0);
    for bad in [
        PrimitiveShape {
            config_dim: 0,
            needle_count: 1,
            max_length_m: 0.1,
        },
        PrimitiveShape {
            config_dim: 1,
            needle_count: 70_000,
            max_length_m: 0.1,
        },
        PrimitiveShape {
            config_dim: 1,
            needle_count: 1,
            max_length_m: f64::NAN,
        },
    ] {
        assert!(ObservationStore::new(&[bad]).is_err());
    }
}

#[test]
fn append_mismatched_shapes_fails() {
    let mut a = ObservationStore::new(&shapes()).unwrap();
    let b = ObservationStore::new(&shapes()[..1]).unwrap();
    assert!(a.append(&b).is_err());
}

#[test]
fn lists_build_the_store_layout() {
    let per_needle = vec![vec![(0u32, 1.0f32), (2, 1.5)], vec![], vec![(1, 2.0)]];
    let a = NeedleObservations::from_lists(&per_needle).unwrap();
    assert_eq!(a.offsets(), &[0, 2, 2, 3]);
    assert_eq!(a.needle_count(), 3);
    assert_eq!(a.observation_count(), 3);
    assert_eq!(a.needle(0), (&[0u32, 2][..], &[1.0f32, 1.5][..]));
    assert_eq!(a.needle(1), (&[][..], &[][..]));
    assert_eq!(a.needle(7), (&[][..], &[][..]));
}

#[test]
fn needle_observations_are_checked_on_construction() {
    assert!(matches!(
        NeedleObservations::from_lists(&[vec![(0, f32::NAN)]]),
        Err(Error::NonFinite { .. })
    ));
    let ok = NeedleObservations::from_csr(vec![0, 1, 1], vec![4], vec![0.5]).unwrap();
    assert_eq!(ok.needle(0), (&[4u32][..], &[0.5f32][..]));
    for (start, sample, length) in [
        (vec![], vec![], vec![]),
        (vec![1, 1], vec![0], vec![0.5]),
        (vec![0, 3], vec![0], vec![0.5]),
        (vec![0, 1, 0], vec![0], vec![0.5]),
        (vec![0, 1], vec![0], vec![]),
    ] {
        assert!(matches!(
            NeedleObservations::from_csr(start, sample, length),
            Err(Error::SizeMismatch { .. })
        ));
    }
    assert!(matches!(
        NeedleObservations::from_csr(vec![0, 1], vec![0], vec![f32::INFINITY]),
        Err(Error::NonFinite { .. })
    ));
    let json = serde_json::to_string(&ok).unwrap();
    assert_eq!(
        serde_json::from_str::<NeedleObservations>(&json).unwrap(),
        ok
    );
    let broken = json.replace("[0,1,1]", "[0,3,1]");
    assert!(serde_json::from_str::<NeedleObservations>(&broken).is_err());
}

proptest! {
    /// Quantisation error is at most half a step; serde and append round-trip exactly.
    #[test]
    fn roundtrip(lengths in proptest::collection::vec((0u16..400, 0.0f32..0.1), 1..60),
                 split in 0usize..60) {
        let mut whole = ObservationStore::new(&shapes()).unwrap();
        let mut a = ObservationStore::new(&shapes()).unwrap();
        let mut b = ObservationStore::new(&shapes()).unwrap();
        for (k, chunk) in lengths.chunks(7).enumerate() {
            let cfg = [k as f64, 0.5, -1.0];
            whole.push_sample(0, &cfg, chunk).unwrap();
            let target = if k * 7 < split { &mut a } else { &mut b };
            target.push_sample(0, &cfg, chunk).unwrap();
        }
        a.append(&b).unwrap();
        prop_assert_eq!(&a, &whole);
        let step = whole.length_step_m(0);
        for (o, &(n, l)) in whole.observations(0).zip(&lengths) {
            prop_assert_eq!(o.needle, n);
            prop_assert!((o.length_m - l).abs() <= 0.5 * step + 1e-7);
        }
        let json = serde_json::to_string(&whole).unwrap();
        let back: ObservationStore = serde_json::from_str(&json).unwrap();
        prop_assert_eq!(back, whole);
    }
}
