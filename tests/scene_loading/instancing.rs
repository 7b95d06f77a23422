//! Meshes that glTF nodes share are stored once and placed by instances (a two-level scene,
//! `tracer/src/scene/gltf_loader/placement.rs`), under the rule stated there; the instanced
//! scene holds the same triangles as the flattened one.

use super::*;

/// A wavy grid of `n` x `n` quads in mesh space: positions (xyz) and u16 indices.
fn grid(n: u16) -> (Vec<f32>, Vec<u16>) {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            positions.extend([x, 0.1 * (7.0 * x).sin() * (5.0 * z).cos() + 0.3 * x * z, z]);
        }
    }
    let mut indices = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            indices.extend([a, a + n + 1, a + 1, a + 1, a + n + 1, a + n + 2]);
        }
    }
    (positions, indices)
}

/// Mesh 0 (the grid, diffuse) on nodes 0..6 (one mirrored, one scaled non-uniformly) and 8
/// times through `EXT_mesh_gpu_instancing` on node 6; mesh 1 (the same grid, emissive) on
/// nodes 7 and 8; mesh 2 (the grid, diffuse) on node 9 only.
fn shared_meshes_json(n: u16) -> String {
    let (positions, indices) = grid(n);
    let mut bytes = f32_bytes(&positions);
    let pos_len = bytes.len();
    bytes.extend(u16_bytes(&indices));
    while !bytes.len().is_multiple_of(4) {
        bytes.push(0);
    }
    let idx_len = indices.len() * 2;
    let inst_offset = bytes.len();
    let translations: Vec<f32> = (0..8).flat_map(|i| [i as f32 * 1.5, 3.0, 0.0]).collect();
    let scales: Vec<f32> =
        (0..8).flat_map(|i| if i == 3 { [1.0, 1.0, -1.0] } else { [1.0, 0.5 + 0.1 * i as f32, 1.0] }).collect();
    bytes.extend(f32_bytes(&translations));
    bytes.extend(f32_bytes(&scales));
    let nodes = r#"[
    {"mesh": 0, "translation": [0, 0, 0]},
    {"mesh": 0, "translation": [1.5, 0, 0], "rotation": [0, 0.3826834, 0, 0.9238795]},
    {"mesh": 0, "translation": [3, 0, 0], "scale": [-1, 1, 1]},
    {"mesh": 0, "translation": [4.5, 0, 0], "scale": [1, 2, 0.5]},
    {"mesh": 0, "translation": [6, 0, 0], "rotation": [0.258819, 0, 0, 0.9659258]},
    {"mesh": 0, "translation": [7.5, 0, 0]},
    {"mesh": 0, "translation": [0, 0, 3],
     "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 2, "SCALE": 3}}}},
    {"mesh": 1, "translation": [0, 2, -3]},
    {"mesh": 1, "translation": [2, 2, -3]},
    {"mesh": 2, "translation": [0, -1, 0], "scale": [9, 1, 6]}
  ]"#;
    let count = positions.len() / 3;
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0,1,2,3,4,5,6,7,8,9]}}],
  "extensionsUsed": ["EXT_mesh_gpu_instancing"],
  "nodes": {nodes},
  "materials": [{{"name": "diffuse"}}, {{"name": "light", "emissiveFactor": [1, 1, 1]}}],
  "meshes": [
    {{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}},
    {{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 1}}]}},
    {{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}
  ],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{b64}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": {pos_len}}},
    {{"buffer": 0, "byteOffset": {pos_len}, "byteLength": {idx_len}}},
    {{"buffer": 0, "byteOffset": {inst_offset}, "byteLength": 96}},
    {{"buffer": 0, "byteOffset": {scale_offset}, "byteLength": 96}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": {count}, "type": "VEC3", "min": [0,-1,0], "max": [1,1,1]}},
    {{"bufferView": 1, "componentType": 5123, "count": {ni}, "type": "SCALAR"}},
    {{"bufferView": 2, "componentType": 5126, "count": 8, "type": "VEC3"}},
    {{"bufferView": 3, "componentType": 5126, "count": 8, "type": "VEC3"}}
  ]
}}"#,
        len = bytes.len(),
        b64 = base64(&bytes),
        ni = indices.len(),
        scale_offset = inst_offset + 96,
    )
}

/// Every triangle's corners, rounded, as a sorted list: the same geometry in any order.
fn corner_set(triangles: &[tracer::scene::Triangle]) -> Vec<[i64; 9]> {
    let mut set: Vec<[i64; 9]> = triangles
        .iter()
        .map(|t| {
            let mut c = t.positions;
            // Start each triangle at its smallest corner (winding kept).
            let first = (0..3).min_by(|&a, &b| c[a].to_array().partial_cmp(&c[b].to_array()).unwrap()).unwrap();
            c.rotate_left(first);
            let r = |x: f32| (x * 1e4).round() as i64;
            [c[0].x, c[0].y, c[0].z, c[1].x, c[1].y, c[1].z, c[2].x, c[2].y, c[2].z].map(r)
        })
        .collect();
    set.sort_unstable();
    set
}

#[test]
fn shared_meshes_are_placed_by_instances() {
    let json = shared_meshes_json(24);
    let grid_triangles = 24 * 24 * 2;
    let s = load_str(&json).unwrap();
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // Mesh 0 is placed 6 + 8 times: stored once. The emissive mesh 1 (lights stay static) and
    // mesh 2 (placed once) are flattened.
    assert_eq!(s.meshes.len(), 1);
    assert_eq!(s.meshes[0].triangles.len(), grid_triangles);
    assert_eq!(s.instances.len(), 14);
    assert_eq!(s.triangles.len(), 3 * grid_triangles);
    assert_eq!(s.placed_triangle_count(), 17 * grid_triangles);
    assert!(s.instances.iter().any(|i| i.transform.determinant() < 0.0), "the mirrored placements");

    // The same triangles as the flattened load, mirrored placements' winding included.
    let flat =
        scene::load_gltf_slice(json.as_bytes(), None, &LoadOptions { flatten: true, ..Default::default() }).unwrap();
    assert!(flat.instances.is_empty() && flat.meshes.is_empty());
    let mut baked = s.clone();
    baked.bake_instances().expect("bakes");
    assert_eq!(baked.triangles.len(), flat.triangles.len());
    assert!(
        corner_set(&baked.triangles) == corner_set(&flat.triangles),
        "baked instances differ from the flattened load"
    );
    // Their bounds agree too (the camera frames the placed meshes).
    let (a, b) = (s.bounds(), flat.bounds());
    assert!((a.min - b.min).abs().max_element() < 1e-4 && (a.max - b.max).abs().max_element() < 1e-4, "{a:?} {b:?}");
}

/// Below the rule's threshold (few triangles saved) sharing is flattened: a small mesh placed
/// twice keeps the one-level scene.
#[test]
fn small_shared_meshes_stay_flattened() {
    let s = load_str(&shared_meshes_json(4)).unwrap();
    assert!(s.instances.is_empty(), "{} instances", s.instances.len());
    assert_eq!(s.triangles.len(), 17 * 4 * 4 * 2);
}

/// A placement whose transform cannot be inverted (a zero scale) is dropped with a warning
/// (which `--strict` refuses, as it refuses every warning), never placed: rays could not be
/// moved into its space.
#[test]
fn a_singular_placement_is_dropped_with_a_warning() {
    let json = shared_meshes_json(24)
        .replace(r#""translation": [7.5, 0, 0]}"#, r#""translation": [7.5, 0, 0], "scale": [1, 0, 1]}"#);
    let s = load_str(&json).unwrap();
    assert_eq!(s.instances.len(), 13, "the zero-scaled placement is dropped");
    assert!(s.warnings.iter().any(|w| w.contains("cannot be inverted")), "{:?}", s.warnings);
}
