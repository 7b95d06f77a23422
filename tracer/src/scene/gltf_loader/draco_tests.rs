//! `KHR_draco_mesh_compression`: a mesh made here, compressed with draco-core's encoder and
//! wrapped in a GLB that requires the extension, loads to the same triangles (within
//! quantisation) as the same mesh stored uncompressed; corrupt streams and inconsistent
//! accessors are errors naming the primitive, and no mutation of the stream panics.

use draco_core::{
    DataType, DecoderBuffer, EncoderBuffer, EncoderOptions, FaceIndex, GeometryAttributeType, Mesh, MeshDecoder,
    MeshEncoder, PointAttribute,
};
use serde_json::json;

use crate::scene::{load_gltf_slice, LoadOptions, Scene, SceneError, Triangle};

/// Grid side in vertices: 12 x 12 vertices, 242 triangles.
const SIDE: usize = 12;
/// Quantisation of the positions (over the grid's extent of 2), normals and UVs.
const POSITION_BITS: i32 = 14;
const NORMAL_BITS: i32 = 10;
const UV_BITS: i32 = 12;

/// A bumpy square (positions, analytic normals, UVs) and its triangles.
struct Grid {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

fn grid() -> Grid {
    let mut g = Grid { positions: Vec::new(), normals: Vec::new(), uvs: Vec::new(), indices: Vec::new() };
    for y in 0..SIDE {
        for x in 0..SIDE {
            let (u, v) = (x as f32 / (SIDE - 1) as f32, y as f32 / (SIDE - 1) as f32);
            let (px, py) = (2.0 * u - 1.0, 2.0 * v - 1.0);
            let h = 0.3 * (3.0 * px).sin() * (2.0 * py).cos();
            g.positions.push([px, h, py]);
            let (dx, dz) = (0.9 * (3.0 * px).cos() * (2.0 * py).cos(), -0.6 * (3.0 * px).sin() * (2.0 * py).sin());
            let len = (dx * dx + 1.0 + dz * dz).sqrt();
            g.normals.push([-dx / len, 1.0 / len, -dz / len]);
            g.uvs.push([u, v]);
        }
    }
    for y in 0..SIDE - 1 {
        for x in 0..SIDE - 1 {
            let a = (y * SIDE + x) as u32;
            let (b, c, d) = (a + 1, a + SIDE as u32, a + SIDE as u32 + 1);
            // Counter-clockwise seen from +Y.
            g.indices.extend_from_slice(&[a, c, b, b, c, d]);
        }
    }
    g
}

fn attribute(kind: GeometryAttributeType, values: &[f32], components: u8) -> PointAttribute {
    let mut a = PointAttribute::new();
    a.init(kind, components, DataType::Float32, false, values.len() / components as usize);
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    a.buffer_mut().write(0, &bytes);
    a
}

/// The grid as a Draco stream (EdgeBreaker, the encoder's default speed), and the unique ids of
/// its POSITION, NORMAL and TEXCOORD_0 attributes.
fn encode(g: &Grid) -> (Vec<u8>, [u32; 3]) {
    let mut mesh = Mesh::new();
    let ids = [
        mesh.add_attribute(attribute(GeometryAttributeType::Position, g.positions.as_flattened(), 3)),
        mesh.add_attribute(attribute(GeometryAttributeType::Normal, g.normals.as_flattened(), 3)),
        mesh.add_attribute(attribute(GeometryAttributeType::TexCoord, g.uvs.as_flattened(), 2)),
    ];
    mesh.set_num_faces(g.indices.len() / 3);
    for (f, t) in g.indices.chunks_exact(3).enumerate() {
        mesh.set_face(FaceIndex(f as u32), [t[0].into(), t[1].into(), t[2].into()]);
    }
    let mut options = EncoderOptions::new();
    for (id, bits) in ids.iter().zip([POSITION_BITS, NORMAL_BITS, UV_BITS]) {
        options.set_attribute_int(*id, "quantization_bits", bits);
    }
    let mut encoder = MeshEncoder::new();
    encoder.set_mesh(mesh);
    let mut out = EncoderBuffer::new();
    encoder.encode(&options, &mut out).expect("the grid encodes");
    let ids = ids.map(|id| id as u32);
    (out.data().to_vec(), ids)
}

/// What the stream decodes to: (points, faces).
fn decoded_counts(stream: &[u8]) -> (usize, usize) {
    let mut mesh = Mesh::new();
    MeshDecoder::new().decode(&mut DecoderBuffer::new(stream), &mut mesh).expect("the stream decodes");
    (mesh.num_points(), mesh.num_faces())
}

/// A GLB of `json` and `bin`.
fn glb(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(json).unwrap();
    json.resize(json.len().div_ceil(4) * 4, b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().div_ceil(4) * 4, 0);
    let mut out = b"glTF".to_vec();
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// The grid stored uncompressed.
fn plain_glb(g: &Grid) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let parts: [Vec<u8>; 4] = [
        g.positions.as_flattened().iter().flat_map(|v| v.to_le_bytes()).collect(),
        g.normals.as_flattened().iter().flat_map(|v| v.to_le_bytes()).collect(),
        g.uvs.as_flattened().iter().flat_map(|v| v.to_le_bytes()).collect(),
        g.indices.iter().flat_map(|v| v.to_le_bytes()).collect(),
    ];
    for p in &parts {
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": p.len()}));
        bin.extend_from_slice(p);
    }
    let n = g.positions.len();
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3", "min": [-1, -1, -1], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": n, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5125, "count": g.indices.len(), "type": "SCALAR"}
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}]
    });
    glb(&doc, &bin)
}

/// The glTF document of a Draco-compressed primitive: accessors without buffer views (counts
/// from the decoded stream), the extension required. Tests edit it before [`draco_glb`].
fn draco_json(stream: &[u8], ids: [u32; 3]) -> serde_json::Value {
    let (points, faces) = decoded_counts(stream);
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_draco_mesh_compression"],
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3,
            "extensions": {"KHR_draco_mesh_compression": {
                "bufferView": 0, "attributes": {"POSITION": ids[0], "NORMAL": ids[1], "TEXCOORD_0": ids[2]}}}
        }]}],
        "accessors": [
            {"componentType": 5126, "count": points, "type": "VEC3", "min": [-1, -1, -1], "max": [1, 1, 1]},
            {"componentType": 5126, "count": points, "type": "VEC3"},
            {"componentType": 5126, "count": points, "type": "VEC2"},
            {"componentType": 5125, "count": faces * 3, "type": "SCALAR"}
        ],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": stream.len()}],
        "buffers": [{"byteLength": stream.len()}]
    })
}

fn draco_glb(doc: &serde_json::Value, stream: &[u8]) -> Vec<u8> {
    let mut doc = doc.clone();
    doc["bufferViews"][0]["byteLength"] = json!(stream.len());
    doc["buffers"][0]["byteLength"] = json!(stream.len());
    glb(&doc, stream)
}

fn load(bytes: &[u8]) -> Result<Scene, SceneError> {
    load_gltf_slice(bytes, None, &LoadOptions::default())
}

/// Whether `a`'s corners, starting at corner `shift`, are `b`'s within the tolerances
/// (positions, normals, UVs), keeping the winding.
fn same_triangle(a: &Triangle, b: &Triangle, shift: usize) -> bool {
    let p = 2.0 / ((1 << POSITION_BITS) - 1) as f32 * 1.01;
    (0..3).all(|k| {
        let i = (k + shift) % 3;
        (a.positions[i] - b.positions[k]).abs().max_element() <= p
            && (a.normals[i] - b.normals[k]).length() <= 0.01
            && (a.uvs[i] - b.uvs[k]).abs().max_element() <= 1.0 / ((1 << UV_BITS) - 1) as f32 * 1.01
    })
}

/// Pairs every triangle of `draco` with one of `plain` (each used once) whose corners match
/// in order (any rotation); the largest position difference.
fn match_triangles(plain: &Scene, draco: &Scene) -> f32 {
    assert_eq!(plain.triangles.len(), draco.triangles.len(), "triangle counts");
    let mut used = vec![false; plain.triangles.len()];
    let mut worst = 0.0f32;
    for (t, d) in draco.triangles.iter().enumerate() {
        let found = plain.triangles.iter().enumerate().find_map(|(i, p)| {
            if used[i] {
                return None;
            }
            (0..3).find(|&s| same_triangle(d, p, s)).map(|s| (i, s))
        });
        let Some((i, s)) = found else {
            panic!("Draco triangle {t} {:?} matches no uncompressed triangle", d.positions);
        };
        used[i] = true;
        for k in 0..3 {
            worst = worst.max((d.positions[(k + s) % 3] - plain.triangles[i].positions[k]).abs().max_element());
        }
    }
    worst
}

#[test]
fn draco_primitive_loads_as_the_uncompressed_mesh() {
    let g = grid();
    let plain = load(&plain_glb(&g)).expect("the uncompressed grid loads");
    let (stream, ids) = encode(&g);
    let draco = load(&draco_glb(&draco_json(&stream, ids), &stream)).expect("the Draco grid loads");
    assert_eq!(plain.triangles.len(), 2 * (SIDE - 1) * (SIDE - 1));
    let worst = match_triangles(&plain, &draco);
    assert!(worst > 0.0, "positions went through quantisation");
    assert!(!draco.warnings.iter().any(|w| w.contains("draco")), "{:?}", draco.warnings);
    let (a, b) = (plain.bounds(), draco.bounds());
    assert!((a.min - b.min).abs().max_element() < 1e-3 && (a.max - b.max).abs().max_element() < 1e-3);
}

/// The same stream read without the extension being required, beside the file's uncompressed
/// fallback (accessors with buffer views holding zeros): the Draco data is used, as the
/// specification asks of a loader that supports it.
#[test]
fn draco_data_wins_over_the_uncompressed_fallback() {
    let g = grid();
    let (stream, ids) = encode(&g);
    let mut doc = draco_json(&stream, ids);
    doc.as_object_mut().unwrap().remove("extensionsRequired");
    let (points, _) = decoded_counts(&stream);
    let zeros = points * 12;
    let mut bin = stream.clone();
    bin.resize(bin.len().div_ceil(4) * 4, 0);
    let fallback_at = bin.len();
    bin.resize(fallback_at + zeros, 0);
    doc["bufferViews"] = json!([
        {"buffer": 0, "byteOffset": 0, "byteLength": stream.len()},
        {"buffer": 0, "byteOffset": fallback_at, "byteLength": zeros}
    ]);
    doc["buffers"][0]["byteLength"] = json!(bin.len());
    doc["accessors"][0]["bufferView"] = json!(1);
    let draco = load(&glb(&doc, &bin)).expect("loads");
    let plain = load(&plain_glb(&g)).unwrap();
    match_triangles(&plain, &draco);
}

/// An error that names the primitive and the extension, and contains `needle`.
fn assert_refused(bytes: &[u8], needle: &str) {
    match load(bytes) {
        Ok(_) => panic!("loaded; expected an error containing {needle:?}"),
        Err(e) => {
            let m = e.to_string();
            assert!(
                m.contains("mesh 0 primitive 0") && m.contains("KHR_draco_mesh_compression") && m.contains(needle),
                "{m}"
            );
        }
    }
}

#[test]
fn corrupt_or_truncated_streams_are_errors() {
    let (stream, ids) = encode(&grid());
    let doc = draco_json(&stream, ids);
    assert_refused(&draco_glb(&doc, &stream[..stream.len() / 2]), "cannot be decoded");
    assert_refused(&draco_glb(&doc, &stream[..8]), "cannot be decoded");
    let mut garbage = stream.clone();
    garbage[..5].copy_from_slice(b"DRACX");
    assert_refused(&draco_glb(&doc, &garbage), "cannot be decoded");
    // The header of the file Lightport refused before it read Draco: a version 2.2 mesh, and nothing.
    assert_refused(&draco_glb(&doc, b"DRACO\x02\x02\x01\x01\0\0\0\0\0\0\0"), "cannot be decoded");
}

#[test]
fn attribute_ids_and_counts_must_match_the_stream() {
    let (stream, ids) = encode(&grid());
    let doc = draco_json(&stream, ids);

    let mut bad = doc.clone();
    bad["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]["NORMAL"] = json!(7);
    assert_refused(&draco_glb(&bad, &stream), "Draco attribute 7");

    let mut bad = doc.clone();
    bad["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]["TEXCOORD_1"] =
        json!(2);
    assert_refused(&draco_glb(&bad, &stream), "TEXCOORD_1");

    let mut bad = doc.clone();
    bad["accessors"][1]["count"] = json!(doc["accessors"][1]["count"].as_u64().unwrap() - 1);
    assert_refused(&draco_glb(&bad, &stream), "Draco stream");

    let mut bad = doc.clone();
    bad["accessors"][3]["count"] = json!(doc["accessors"][3]["count"].as_u64().unwrap() + 3);
    assert_refused(&draco_glb(&bad, &stream), "indices");

    // NORMAL read as a VEC2: the stream's attribute has three components.
    let mut bad = doc.clone();
    bad["accessors"][1]["type"] = json!("VEC2");
    assert_refused(&draco_glb(&bad, &stream), "components");

    let mut bad = doc.clone();
    bad["meshes"][0]["primitives"][0]["mode"] = json!(5);
    assert_refused(&draco_glb(&bad, &stream), "TRIANGLES");

    let mut bad = doc.clone();
    bad["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"] = json!(9);
    assert_refused(&draco_glb(&bad, &stream), "bufferView 9");

    // Counts the accessors cannot have: refused before anything is decoded.
    let mut bad = doc.clone();
    for a in 0..3 {
        bad["accessors"][a]["count"] = json!(1u64 << 40);
    }
    assert!(matches!(load(&draco_glb(&bad, &stream)), Err(SceneError::TooLarge(_))));
}

/// Every single-byte change and every truncation of the stream loads or is an error: none
/// panics (the test fails on a panic) and none takes long.
#[test]
fn no_mutation_of_the_stream_panics() {
    let (stream, ids) = encode(&grid());
    let doc = draco_json(&stream, ids);
    let start = std::time::Instant::now();
    let mut errors = 0;
    let mut run = |bytes: &[u8]| {
        let t = std::time::Instant::now();
        if load(&draco_glb(&doc, bytes)).is_err() {
            errors += 1;
        }
        assert!(t.elapsed().as_secs_f64() < 2.0, "an input took {:?}", t.elapsed());
    };
    for i in 0..stream.len() {
        for value in [0x00, 0xff, stream[i] ^ 0x10] {
            let mut m = stream.clone();
            m[i] = value;
            run(&m);
        }
        run(&stream[..i]);
    }
    assert!(errors > stream.len(), "{errors} errors: mutations are refused");
    eprintln!("{} inputs in {:?}, {errors} refused", 4 * stream.len(), start.elapsed());
}
