use super::*;

// Lines: 1 ply .. 10 end_header, 11-15 vertices, 16-17 faces.
const ASCII_CUBE: &str = "ply\n\
    format ascii 1.0\n\
    comment a unit square with a roof point\n\
    element vertex 5\n\
    property float x\n\
    property float y\n\
    property float z\n\
    element face 2\n\
    property list uchar int vertex_indices\n\
    end_header\n\
    0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n\
    4 0 1 2 3\n\
    3 0 1 4\n";

const VERTS: [[f32; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.5, 0.5, 1.0],
];
const FACES: [&[u32]; 2] = [&[0, 1, 2, 3], &[0, 1, 4]];

macro_rules! put {
    ($out:expr, $big:expr, $v:expr) => {{
        let v = $v;
        $out.extend_from_slice(&if $big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        });
    }};
}

/// ASCII_CUBE in binary, with mixed types, an ignored colour and CRLF header lines.
fn binary_cube(big: bool) -> Vec<u8> {
    let name = if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut out = format!(
        "ply\r\nformat {name} 1.0\r\nelement vertex 5\r\nproperty float x\r\nproperty double y\r\n\
         property float z\r\nproperty uchar red\r\nelement face 2\r\n\
         property list uchar uint vertex_indices\r\nend_header\r\n"
    )
    .into_bytes();
    for [x, y, z] in VERTS {
        put!(out, big, x);
        put!(out, big, f64::from(y));
        put!(out, big, z);
        out.push(200);
    }
    for face in FACES {
        out.push(face.len() as u8);
        for &i in face {
            put!(out, big, i);
        }
    }
    out
}

fn err(bytes: &[u8]) -> String {
    parse_ply(bytes).unwrap_err().to_string()
}

fn cube_err(from: &str, to: &str) -> String {
    err(ASCII_CUBE.replacen(from, to, 1).as_bytes())
}

#[test]
fn quad_and_triangle_in_all_formats() {
    let mesh = parse_ply(ASCII_CUBE.as_bytes()).unwrap();
    assert_eq!(mesh.positions, VERTS.to_vec());
    assert_eq!(mesh.indices, vec![0, 1, 4]);
    assert_eq!(mesh.quads, vec![0, 1, 3, 2]);
    assert_eq!((mesh.normals.as_ref(), mesh.uvs.as_ref()), (None, None));
    assert_eq!(
        parse_ply(ASCII_CUBE.replace('\n', "\r\n").as_bytes()).unwrap(),
        mesh
    );
    assert_eq!(
        parse_ply(&binary_cube(false)).unwrap(),
        mesh,
        "little endian"
    );
    assert_eq!(parse_ply(&binary_cube(true)).unwrap(), mesh, "big endian");
}

fn triangle(props: &[&str], rows: [&str; 3]) -> PlyMesh {
    let props: String = props
        .iter()
        .map(|p| format!("property float {p}\n"))
        .collect();
    let text = format!(
        "ply\nformat ascii 1.0\nelement vertex 3\n{props}element face 1\n\
         property list uchar int vertex_indices\nend_header\n{}\n3 0 1 2\n",
        rows.join("\n")
    );
    parse_ply(text.as_bytes()).unwrap()
}

#[test]
fn normals_and_uvs_detected() {
    let props = ["u", "x", "nx", "y", "ny", "z", "nz", "v", "quality"];
    let mesh = triangle(
        &props,
        [
            "0.25 0 0 0 0 0 1 0.75 9",
            "1 1 0 0 1 0 0 0 9",
            "0 0 1 1 0 0 0 1 9",
        ],
    );
    assert_eq!(
        mesh.positions,
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    );
    assert_eq!(
        mesh.normals,
        Some(vec![[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    );
    assert_eq!(mesh.uvs, Some(vec![[0.25, 0.75], [1.0, 0.0], [0.0, 1.0]]));

    let mesh = triangle(
        &["x", "y", "z", "nx", "ny", "s", "t"],
        ["0 0 0 1 1 0.5 0.5"; 3],
    );
    assert_eq!(mesh.normals, None, "nz is missing");
    assert_eq!(mesh.uvs, Some(vec![[0.5, 0.5]; 3]));
    let mesh = triangle(&["texture_u", "x", "y", "z", "texture_v"], ["1 0 0 0 2"; 3]);
    assert_eq!(mesh.uvs, Some(vec![[1.0, 2.0]; 3]));
    let mesh = triangle(&["x", "y", "z", "texture_s", "texture_t"], ["0 0 0 3 4"; 3]);
    assert_eq!(mesh.uvs, Some(vec![[3.0, 4.0]; 3]));
}

const EXTRAS_HEADER: &str = "element material 1\nproperty list uchar uchar name\nproperty float roughness\n\
    element vertex 5\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n\
    property list uchar float weights\n\
    element edge 2\nproperty int vertex1\nproperty int vertex2\n\
    element face 2\nproperty uchar flags\nproperty list uchar int vertex_index\n\
    property list ushort int face_indices\nend_header\n";

#[test]
fn extra_elements_and_properties_skipped() {
    let expected = parse_ply(ASCII_CUBE.as_bytes()).unwrap();
    let ascii = format!(
        "ply\nformat ascii 1.0\n{EXTRAS_HEADER}3 97 98 99 0.5\n0 0 0 255 1 0.5\n1 0 0 255 0\n1 1 0 255 2 1 2\n\
         0 1 0 255 0\n0.5 0.5 1 255 1 9\n0 1\n1 2\n7 4 0 1 2 3 1 42\n7 3 0 1 4 0\n"
    );
    assert_eq!(parse_ply(ascii.as_bytes()).unwrap(), expected);

    let mut bin = format!("ply\nformat binary_little_endian 1.0\n{EXTRAS_HEADER}").into_bytes();
    bin.extend_from_slice(&[3, b'a', b'b', b'c']);
    bin.extend_from_slice(&0.5f32.to_le_bytes());
    for v in VERTS {
        v.iter()
            .for_each(|c| bin.extend_from_slice(&c.to_le_bytes()));
        // A list in the vertex element forces the record-by-record path.
        bin.extend_from_slice(&[255, 1]);
        bin.extend_from_slice(&0.25f32.to_le_bytes());
    }
    [0i32, 1, 1, 2]
        .iter()
        .for_each(|e| bin.extend_from_slice(&e.to_le_bytes()));
    for face in FACES {
        bin.extend_from_slice(&[7, face.len() as u8]);
        face.iter()
            .for_each(|&i| bin.extend_from_slice(&(i as i32).to_le_bytes()));
        bin.extend_from_slice(&1u16.to_le_bytes());
        bin.extend_from_slice(&42i32.to_le_bytes());
    }
    assert_eq!(parse_ply(&bin).unwrap(), expected);
    bin.truncate(bin.len() - 1); // now the last face_indices item is cut short
    assert_eq!(err(&bin), "file ends in the middle of face 1 of 2");
}

#[test]
fn truncation_names_the_record() {
    let bytes = binary_cube(false);
    let body = bytes
        .windows(12)
        .position(|w| w == b"end_header\r\n")
        .unwrap()
        + 12;
    // 17 bytes per vertex: cut inside vertex 2.
    assert_eq!(
        err(&bytes[..body + 17 * 2 + 5]),
        "file ends in the middle of vertex 2 of 5"
    );
    assert_eq!(
        err(&bytes[..bytes.len() - 3]),
        "file ends in the middle of face 1 of 2"
    );
    assert_eq!(
        cube_err("3 0 1 4\n", ""),
        "line 16: file ends in the middle of face 1 of 2"
    );
}

#[test]
fn index_out_of_range() {
    assert_eq!(
        cube_err("3 0 1 4", "3 0 1 9"),
        "line 17: face 1 refers to vertex 9 but there are 5 vertices"
    );
    let msg = cube_err("3 0 1 4", "3 0 1 -1");
    assert!(
        msg.starts_with("line 17: face 1 refers to vertex -1"),
        "{msg}"
    );
    let mut bytes = binary_cube(true);
    let n = bytes.len();
    bytes[n - 4..].copy_from_slice(&9u32.to_be_bytes());
    assert_eq!(
        err(&bytes),
        "face 1 refers to vertex 9 but there are 5 vertices"
    );
}

#[test]
fn header_and_token_errors_give_lines() {
    assert_eq!(
        cube_err("1 0 0\n", "1 zero 0\n"),
        "line 12: \"zero\" is not a valid float"
    );
    assert_eq!(
        cube_err("end_header\n", ""),
        "line 16: the file ends without an \"end_header\" line"
    );
    assert!(err(b"solid cube\nfacet normal 0 0 1\n").starts_with("line 1: not a PLY file"));
    assert_eq!(
        cube_err("property float z\n", ""),
        "line 4: element \"vertex\" has no \"z\" property"
    );
    assert!(cube_err("ascii", "binary_middle_endian").starts_with("line 2: unknown format"));
    assert_eq!(
        cube_err("float y", "float128 y"),
        "line 6: unknown property type \"float128\""
    );
    assert_eq!(
        cube_err("3 0 1 4", "2 0 1"),
        "line 17: face 1 has 2 vertices; a face needs at least 3"
    );
    assert!(cube_err("element face 2", "element face -2").starts_with("line 8: element count"));
}

#[test]
fn huge_counts_fail_cleanly() {
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\n\
        property float x\nproperty float y\nproperty float z\nend_header\n"
        .to_vec();
    bytes.extend_from_slice(&[0; 30]);
    assert_eq!(
        err(&bytes),
        "file ends in the middle of vertex 2 of 18446744073709551615"
    );

    let mut bytes = b"ply\nformat binary_big_endian 1.0\nelement vertex 0\nproperty float x\n\
        property float y\nproperty float z\nelement face 1000000000\n\
        property list uint uint vertex_indices\nend_header\n"
        .to_vec();
    bytes.extend_from_slice(&u32::MAX.to_be_bytes());
    assert_eq!(
        err(&bytes),
        "file ends in the middle of face 0 of 1000000000"
    );

    let msg = cube_err("element face 2", "element face 99999999999");
    assert_eq!(
        msg,
        "line 17: file ends in the middle of face 2 of 99999999999"
    );
}

#[test]
fn damaged_input_never_panics() {
    for bytes in [
        binary_cube(false),
        binary_cube(true),
        ASCII_CUBE.as_bytes().to_vec(),
    ] {
        for end in 0..bytes.len() {
            let _ = parse_ply(&bytes[..end]);
        }
        for at in 0..bytes.len() {
            for flip in [0x00, 0xff, b'9', b'-', b'\n'] {
                let mut damaged = bytes.clone();
                damaged[at] = flip;
                let _ = parse_ply(&damaged);
            }
        }
    }
}
