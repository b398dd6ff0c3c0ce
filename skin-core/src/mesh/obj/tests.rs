use super::*;
use proptest::prelude::*;

fn parse_err_line(r: Result<TriMesh>) -> (usize, String) {
    match r {
        Err(Error::Parse { line, message, .. }) => (line, message),
        other => panic!("expected parse error, got {other:?}"),
    }
}

#[test]
fn texture_coordinates_follow_the_group_faces_and_are_checked() {
    let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                g a\nf 1/1 2/2 3/3 4/4\ng b\nf 1/4 2/3 3/2\nf 1 3 4\n";
    let obj = ObjFile::parse_str(text).unwrap();
    assert_eq!(obj.texcoords.len(), 4);
    let a = obj.group_mesh("a").unwrap();
    let uvs = a.uvs.unwrap();
    assert_eq!(uvs.faces, vec![[0, 1, 2], [0, 2, 3]]);
    uvs.validate(&a.mesh).unwrap();
    // A group with a corner without `vt` has no layout.
    assert!(obj.group_mesh("b").unwrap().uvs.is_none());
    // Relative indices resolve like vertex indices.
    let rel = ObjFile::parse_str(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf -3/-3 -2/-2 -1/-1\n",
    )
    .unwrap();
    assert_eq!(
        rel.group_mesh(ObjFile::DEFAULT_GROUP)
            .unwrap()
            .uvs
            .unwrap()
            .faces,
        vec![[0, 1, 2]]
    );
    for (bad, line) in [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n", 5),
        ("v 0 0 0\nvt 0\n", 2),
        ("v 0 0 0\nvt 0 nan\n", 2),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/-1 2 3\n", 4),
    ] {
        let (l, m) = parse_err_line(ObjFile::parse_str(bad).and_then(|o| o.to_mesh()));
        assert_eq!(l, line, "{m}");
    }
}

#[test]
fn triangulates_polygons_and_skips_other_directives() {
    let text = "# comment\nmtllib x.mtl\nv 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\n\
                vt 0 0\nvn 0 0 1\ns off\nusemtl skin\nf 1/1/1 2//1 3/1 4 # quad\nl 1 2\n";
    let m = read_obj_from_str(text).unwrap();
    assert_eq!(m.vertex_count(), 4);
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3]]);
    let m =
        read_obj_from_str("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 2 0\nf 1 2 3 4 5\n").unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    // Windows line endings and tabs.
    let m = read_obj_from_str("v\t0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\ng  body \r\nf 1 2 3\r\n").unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2]]);
    let g = ObjFile::parse_str("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\ng body\r\nf 1 2 3\r\n").unwrap();
    assert_eq!(g.group_names(), vec!["body"]);
}

#[test]
fn relative_indices_resolve_where_they_appear() {
    let m =
        read_obj_from_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -4 -3 -1\n").unwrap();
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 1, 3]]);
    let (line, msg) = parse_err_line(read_obj_from_str("v 0 0 0\nv 1 0 0\nf -1 -2 -3\n"));
    assert_eq!(line, 3);
    assert!(msg.contains("-3"), "{msg}");
}

#[test]
fn malformed_input_gives_line_numbers() {
    let cases: [(&str, usize, &str); 9] = [
        ("v 0 0 0\nv 1 x 0\n", 2, "coordinate"),
        ("v 0 0\n", 1, "2 coordinates"),
        ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 1, "non-finite"),
        ("v 0 0 inf\n", 1, "non-finite"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n", 5, "2 corners"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n",
            4,
            "bad vertex index",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999\n",
            4,
            "too large",
        ),
    ];
    for (text, want_line, want_msg) in cases {
        let (line, msg) = parse_err_line(read_obj_from_str(text));
        assert_eq!(line, want_line, "{text:?}: {msg}");
        assert!(msg.contains(want_msg), "{text:?}: {msg}");
    }
}

#[test]
fn truncated_and_empty_files_are_errors() {
    // A file cut in the middle of a face line: the last face refers to a missing vertex.
    let full = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n";
    let cut = &full[..full.len() - 3]; // "f 1 " : too few corners
    assert!(matches!(
        read_obj_from_str(cut),
        Err(Error::Parse { line: 6, .. })
    ));
    // Faces that reference vertices a truncated file never defines.
    assert!(matches!(
        read_obj_from_str("f 1 2 3\nv 0 0 0\n"),
        Err(Error::Parse { line: 1, .. })
    ));
    assert!(matches!(read_obj_from_str(""), Err(Error::Empty { .. })));
    assert!(matches!(
        read_obj_from_str("v 0 0 0\nv 1 0 0\n"),
        Err(Error::Empty { .. })
    ));
    // Binary garbage never panics.
    let garbage: Vec<u8> = (0..2000u32).map(|i| (i * 7919 % 251) as u8).collect();
    let _ = read_obj_from_reader(&garbage[..]);
}

#[test]
fn groups_select_compact_and_map_back() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 9 9 9\nv 1 1 0\nv 2 2 2\n\
                f 1 2 3\ng body\nf 2 5 3\ng hair\nf 4 6 1\ng body extra\nf 1 2 5\n\
                o thing\ng hair\nf 6 5 4\n";
    let obj = ObjFile::parse_str(text).unwrap();
    assert_eq!(
        obj.group_names(),
        vec!["default", "body", "hair", "extra", "thing"]
    );
    let body = obj.group_mesh("body").unwrap();
    // Repeated group occurrences are merged; the compacted vertices keep file order.
    assert_eq!(body.original_index, vec![0, 1, 2, 4]);
    assert_eq!(body.mesh.faces, vec![[1, 3, 2], [0, 1, 3]]);
    for (i, &o) in body.original_index.iter().enumerate() {
        assert_eq!(body.mesh.vertices[i], obj.vertices[o as usize]);
    }
    let hair = obj.group_mesh("hair").unwrap();
    assert_eq!(hair.original_index, vec![0, 3, 4, 5]);
    assert_eq!(hair.mesh.face_count(), 2);
    let thing = obj.group_mesh("thing").unwrap();
    assert_eq!(thing.mesh.face_count(), 1);
    assert_eq!(obj.group_mesh("default").unwrap().mesh.face_count(), 1);
    match obj.group_mesh("skin") {
        Err(Error::InvalidParam { reason, .. }) => {
            assert!(
                reason.contains("'skin'") && reason.contains("body, hair"),
                "{reason}"
            )
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn missing_file_is_io_error_with_path() {
    match read_obj("/nonexistent/dir/x.obj") {
        Err(Error::Io { path, .. }) => assert!(path.ends_with("x.obj")),
        other => panic!("{other:?}"),
    }
}

#[test]
fn write_rejects_invalid_mesh() {
    let m = TriMesh {
        vertices: vec![DVec3::ZERO, DVec3::X, DVec3::new(f64::NAN, 0.0, 0.0)],
        faces: vec![[0, 1, 2]],
    };
    assert!(matches!(
        write_obj_to(Vec::new(), &m),
        Err(Error::NonFinite { .. })
    ));
}

/// The MakeHuman base mesh, group `body` (see data/makehuman/SOURCE.md).
#[test]
fn makehuman_body_group() {
    let path = example_kit::data_path("makehuman/base.obj").unwrap();
    let obj = ObjFile::read(&path).unwrap();
    assert_eq!(obj.vertices.len(), 19_158);
    assert_eq!(obj.polygon_count(), 18_486);
    let names = obj.group_names();
    assert!(names.contains(&"body") && names.contains(&"helper-tights"));
    let body = obj.group_mesh("body").unwrap();
    // SOURCE.md: 13,380 vertices are referenced by `body` faces (all quads).
    assert_eq!(body.mesh.vertex_count(), 13_380);
    assert_eq!(body.original_index.len(), 13_380);
    assert_eq!(body.mesh.face_count() % 2, 0);
    eprintln!(
        "MakeHuman body: {} vertices, {} triangles",
        body.mesh.vertex_count(),
        body.mesh.face_count()
    );
    let bb = body.mesh.bounding_box().unwrap();
    // Decimetres: body spans y = -8.17 .. 8.49.
    assert!(
        (bb.min.y + 8.17).abs() < 0.01 && (bb.max.y - 8.49).abs() < 0.01,
        "{bb:?}"
    );
    let direct = read_obj_group(&path, "body").unwrap();
    assert_eq!(direct, body.mesh);
    assert!(matches!(
        read_obj_group(&path, "no-such-group"),
        Err(Error::InvalidParam { .. })
    ));
}

fn arb_mesh() -> impl Strategy<Value = TriMesh> {
    (3usize..40).prop_flat_map(|n| {
        let v = prop::collection::vec(
            (
                -1e6f64..1e6,
                -1e-6f64..1e-6,
                any::<f64>().prop_filter("finite", |x| x.is_finite()),
            ),
            n,
        );
        let f = prop::collection::vec(
            (0..n as u32, 0..n as u32, 0..n as u32).prop_map(|(a, b, c)| [a, b, c]),
            1..60,
        );
        (v, f).prop_map(|(v, f)| TriMesh {
            vertices: v.into_iter().map(|(x, y, z)| DVec3::new(x, y, z)).collect(),
            faces: f,
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn obj_round_trip_is_exact(mesh in arb_mesh()) {
        let mut buf = Vec::new();
        write_obj_to(&mut buf, &mesh).unwrap();
        let back = read_obj_from_reader(&buf[..]).unwrap();
        prop_assert_eq!(back, mesh);
    }

    #[test]
    fn arbitrary_text_never_panics(s in "[vfgo0-9 ./#\\-\nae]{0,200}") {
        let _ = read_obj_from_str(&s);
    }
}

#[test]
fn file_round_trip() {
    let dir = std::env::temp_dir().join(format!("skin_core_obj_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("tri.obj");
    let m = TriMesh::new(
        vec![DVec3::ZERO, DVec3::X, DVec3::new(0.1, 0.7, -3.0)],
        vec![[0, 1, 2]],
    )
    .unwrap();
    write_obj(&path, &m).unwrap();
    assert_eq!(read_obj(&path).unwrap(), m);
    std::fs::remove_dir_all(&dir).unwrap();
}
