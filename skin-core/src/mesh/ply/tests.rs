use super::*;
use proptest::prelude::*;

const ENCODINGS: [PlyEncoding; 3] = [
    PlyEncoding::Ascii,
    PlyEncoding::BinaryLittleEndian,
    PlyEncoding::BinaryBigEndian,
];

fn tri() -> TriMesh {
    TriMesh::new(
        vec![DVec3::ZERO, DVec3::X, DVec3::new(0.25, 0.5, -1.0), DVec3::Y],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
}

fn bytes(mesh: &TriMesh, enc: PlyEncoding) -> Vec<u8> {
    let mut buf = Vec::new();
    write_ply_to(&mut buf, mesh, enc).unwrap();
    buf
}

#[test]
fn reads_foreign_ascii_with_quads_types_and_extra_data() {
    let text = "ply\nformat ascii 1.0\ncomment made by hand\n\
        element vertex 5\nproperty float x\nproperty float y\nproperty double z\n\
        property uchar red\nproperty float nx\n\
        element face 2\nproperty list uchar int vertex_index\nproperty int flags\n\
        element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n\
        0 0 0 255 1\n1 0 0 0 1\n1 1 0 0 1\n0 1 0 0 1\n0 2 0.5 0 1\n\
        4 0 1 2 3 7\n3 3 2 4 0\n0 1\n";
    let m = read_ply_from_reader(text.as_bytes()).unwrap();
    assert_eq!(m.vertex_count(), 5);
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [3, 2, 4]]);
    assert_eq!(m.vertices[4], DVec3::new(0.0, 2.0, 0.5));
}

#[test]
fn reads_binary_with_short_indices() {
    // Hand-built big-endian file: float coords, ushort count, short indices.
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list ushort short vertex_indices\nend_header\n"
        .to_vec();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            b.extend(c.to_be_bytes());
        }
    }
    b.extend(3u16.to_be_bytes());
    for i in [2i16, 1, 0] {
        b.extend(i.to_be_bytes());
    }
    let m = read_ply_from_reader(&b[..]).unwrap();
    assert_eq!(m.faces, vec![[2, 1, 0]]);
    assert_eq!(m.vertices[1], DVec3::X);
}

#[test]
fn round_trip_all_encodings_via_files() {
    let dir = std::env::temp_dir().join(format!("skin_core_ply_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for enc in ENCODINGS {
        let path = dir.join(format!("{enc:?}.ply"));
        write_ply(&path, &tri(), enc).unwrap();
        assert_eq!(read_ply(&path).unwrap(), tri(), "{enc:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(matches!(
        read_ply(dir.join("missing.ply")),
        Err(Error::Io { .. })
    ));
}

fn expect_parse(data: &[u8], needle: &str) {
    match read_ply_from_reader(data) {
        Err(Error::Parse { message, .. }) => {
            assert!(message.contains(needle), "wanted '{needle}' in: {message}")
        }
        other => panic!("wanted parse error with '{needle}', got {other:?}"),
    }
}

const HEADER: &str =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

#[test]
fn malformed_ascii_is_a_parse_error() {
    let bad_number = format!("{HEADER}0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n");
    expect_parse(bad_number.as_bytes(), "'1 x 0");
    assert!(matches!(
        read_ply_from_reader(bad_number.as_bytes()),
        Err(Error::Parse { line: 11, .. })
    ));
    // Fewer vertices than declared: the face line is read as a vertex, then EOF.
    expect_parse(
        format!("{HEADER}0 0 0\n1 0 0\n3 0 1 2\n").as_bytes(),
        "end of file",
    );
    // Truncated before the faces.
    expect_parse(
        format!("{HEADER}0 0 0\n1 0 0\n0 1 0\n").as_bytes(),
        "end of file",
    );
    // ASCII 'nan' is rejected by the grammar; binary NaN reaches our own check.
    expect_parse(
        format!("{HEADER}0 0 nan\n1 0 0\n0 1 0\n3 0 1 2\n").as_bytes(),
        "'0 0 nan",
    );
    let mut b = bytes(&tri(), PlyEncoding::BinaryLittleEndian);
    let start = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    b[start + 8..start + 16].copy_from_slice(&f64::NAN.to_le_bytes());
    expect_parse(&b, "vertex 0 has a non-finite coordinate");
    expect_parse(
        format!("{HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n").as_bytes(),
        "negative",
    );
    expect_parse(
        format!("{HEADER}0 0 0\n1 0 0\n0 1 0\n2 0 1\n").as_bytes(),
        "2 corners",
    );
    expect_parse(
        b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n",
        "end_header",
    );
    expect_parse(b"not a ply file\n", "magic");
    expect_parse(b"", "end of file");
    expect_parse(
        b"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n3 0 1 2\n",
        "no 'vertex' element",
    );
    expect_parse(
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
        "no 'z'",
    );
    expect_parse(
        format!(
            "{}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
            HEADER.replace("list uchar int", "list uchar float")
        )
        .as_bytes(),
        "list of integers",
    );
}

#[test]
fn out_of_range_index_and_empty_mesh() {
    let r = read_ply_from_reader(format!("{HEADER}0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").as_bytes());
    assert!(
        matches!(
            r,
            Err(Error::IndexOutOfRange {
                index: 3,
                len: 3,
                ..
            })
        ),
        "{r:?}"
    );
    let no_faces = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nend_header\n0 0 0\n";
    assert!(matches!(
        read_ply_from_reader(no_faces.as_bytes()),
        Err(Error::Empty { .. })
    ));
    let empty = TriMesh::default();
    let back = read_ply_from_reader(&bytes(&empty, PlyEncoding::Ascii)[..]);
    assert!(matches!(back, Err(Error::Empty { .. })));
}

#[test]
fn truncated_binary_is_a_parse_error_at_every_cut() {
    for enc in [
        PlyEncoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian,
    ] {
        let full = bytes(&tri(), enc);
        let header_len = full.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        for cut in header_len..full.len() {
            match read_ply_from_reader(&full[..cut]) {
                Err(Error::Parse { message, .. }) => {
                    assert!(message.contains("end of file"), "{message}")
                }
                other => panic!("{enc:?} cut at {cut}: {other:?}"),
            }
        }
    }
}

#[test]
fn write_rejects_invalid_mesh() {
    let mut m = tri();
    m.faces.push([0, 1, 9]);
    assert!(matches!(
        write_ply_to(Vec::new(), &m, PlyEncoding::Ascii),
        Err(Error::IndexOutOfRange { .. })
    ));
}

fn arb_mesh() -> impl Strategy<Value = TriMesh> {
    (3usize..30).prop_flat_map(|n| {
        let coord = any::<f64>().prop_filter("finite", |x| x.is_finite());
        let v = prop::collection::vec((coord.clone(), coord.clone(), coord), n);
        let f = prop::collection::vec(
            (0..n as u32, 0..n as u32, 0..n as u32).prop_map(|(a, b, c)| [a, b, c]),
            1..40,
        );
        (v, f).prop_map(|(v, f)| TriMesh {
            vertices: v.into_iter().map(|(x, y, z)| DVec3::new(x, y, z)).collect(),
            faces: f,
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn round_trip_is_exact(mesh in arb_mesh(), e in 0usize..3) {
        let back = read_ply_from_reader(&bytes(&mesh, ENCODINGS[e])[..]).unwrap();
        prop_assert_eq!(back, mesh);
    }

    #[test]
    fn corrupted_bytes_never_panic(mesh in arb_mesh(), e in 0usize..3, pos in any::<prop::sample::Index>(), byte in any::<u8>()) {
        let mut b = bytes(&mesh, ENCODINGS[e]);
        let i = pos.index(b.len());
        b[i] = byte;
        let _ = read_ply_from_reader(&b[..]);
    }
}
