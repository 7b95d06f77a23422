//! Geometry beyond `scene::WORLD_LIMIT` (1e12 units): finite, but where the renderer's f32
//! arithmetic overflows. A static scene there is refused, naming the limit, whether flattened
//! or instanced; within it, it loads. Poses that carry a part there drop it (the CLI's
//! `a_placement_a_pose_cannot_place_is_dropped_with_one_warning`), and a light or the camera
//! too, with a warning (below).

use super::{expect_error, gltf_json, load_str, TRI};
use tracer::scene;

#[test]
fn a_static_scene_beyond_the_world_is_refused_naming_the_limit() {
    // Finite, but where the renderer's f32 arithmetic overflows (it failed as "invalid camera",
    // the framing's squared diagonal being infinite): refused, naming the limit.
    let mut far = TRI;
    far[0] = 1e20;
    let e = expect_error("a vertex at 1e20", load_str(&gltf_json(&far, &[0, 1, 2], r#"[{"mesh": 0}]"#, "")));
    assert!(e.to_string().contains(&format!("beyond {:e} units", scene::WORLD_LIMIT)), "{e}");
    let scaled = r#"[{"mesh": 0, "scale": [1e20, 1e20, 1e20]}, {"mesh": 0}]"#;
    let e = expect_error("a placement scaled by 1e20", load_str(&gltf_json(&TRI, &[0, 1, 2], scaled, "")));
    assert!(e.to_string().contains(&format!("beyond {:e} units", scene::WORLD_LIMIT)), "{e}");
    // The same placement of a mesh large enough to be instanced (placed twice, it saves 4,097
    // triangles): it read as "cannot be inverted" (the determinant overflowed) and was dropped.
    let many: Vec<u16> = [0, 1, 2].repeat(4097);
    let nodes = r#"[{"children": [1, 2]}, {"mesh": 0, "scale": [1e20, 1e20, 1e20]}, {"mesh": 0}]"#;
    let e = expect_error("an instance scaled by 1e20", load_str(&gltf_json(&TRI, &many, nodes, "")));
    assert!(e.to_string().contains(&format!("beyond {:e} units", scene::WORLD_LIMIT)), "{e}");
    let nodes = r#"[{"children": [1, 2]}, {"mesh": 0, "scale": [2, 2, 2]}, {"mesh": 0}]"#;
    let placed = load_str(&gltf_json(&TRI, &many, nodes, "")).expect("the same at scale 2 loads");
    assert_eq!(placed.instances.len(), 2, "instanced");
    let near = TRI.map(|v| v * 0.9e12);
    load_str(&gltf_json(&near, &[0, 1, 2], r#"[{"mesh": 0}]"#, "")).expect("within the limit it loads");
}

/// A light or camera that the animation's pose carries beyond the world is left out with a
/// warning, as a mesh placement there is, instead of refusing the scene: at 1 s the light's node
/// stands at 1e20 and the camera's at 1e20 (beyond `scene::CAMERA_LIMIT` too); at 0 s both are
/// where the file puts them. A static light there is still refused.
#[test]
fn a_light_or_camera_the_pose_carries_beyond_the_world_is_left_out_with_a_warning() {
    use super::{base64, f32_bytes};
    // Keyframes: times 0 and 1, then each node's translation at both.
    let mut bytes = f32_bytes(&TRI);
    let times = bytes.len();
    bytes.extend(f32_bytes(&[0.0, 1.0]));
    let light_at = bytes.len();
    bytes.extend(f32_bytes(&[0.5, 3.0, 3.0, 1e20, 3.0, 3.0]));
    let camera_at = bytes.len();
    bytes.extend(f32_bytes(&[0.4, 1.0, 2.5, 0.4, 1e20, 2.5]));
    let view =
        |offset: usize, length: usize| format!(r#"{{"buffer": 0, "byteOffset": {offset}, "byteLength": {length}}}"#);
    let json = format!(
        r#"{{
  "asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0, 1, 2]}}],
  "nodes": [
    {{"mesh": 0}},
    {{"translation": [0.5, 3, 3], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}},
    {{"camera": 0, "translation": [0.4, 1, 2.5]}}
  ],
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "point", "intensity": 60}}]}}}},
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.8, "znear": 0.01}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
  "animations": [{{"channels": [
      {{"sampler": 0, "target": {{"node": 1, "path": "translation"}}}},
      {{"sampler": 1, "target": {{"node": 2, "path": "translation"}}}}],
    "samplers": [{{"input": 1, "output": 2}}, {{"input": 1, "output": 3}}]}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{b64}"}}],
  "bufferViews": [{v0}, {v1}, {v2}, {v3}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]}},
    {{"bufferView": 2, "componentType": 5126, "count": 2, "type": "VEC3"}},
    {{"bufferView": 3, "componentType": 5126, "count": 2, "type": "VEC3"}}
  ]
}}"#,
        len = bytes.len(),
        b64 = base64(&bytes),
        v0 = view(0, times),
        v1 = view(times, 8),
        v2 = view(light_at, 24),
        v3 = view(camera_at, 24),
    );
    let at = |time: f32| {
        let options = scene::LoadOptions { time, ..Default::default() };
        scene::load_gltf_slice(json.as_bytes(), None, &options)
    };
    let rest = at(0.0).expect("at rest the scene loads");
    assert_eq!(rest.point_lights.len(), 1, "the light at rest");
    assert_eq!(rest.camera.position, glam::Vec3::new(0.4, 1.0, 2.5), "the file's camera at rest");
    let far =
        at(1.0).unwrap_or_else(|e| panic!("a pose that carries a light and the camera away refused the scene: {e}"));
    assert!(far.point_lights.is_empty(), "the light beyond the world is left out");
    let limit = format!("beyond {:e} units", scene::WORLD_LIMIT);
    assert!(
        far.warnings.iter().any(|w| w.contains("node 1's light 0") && w.contains(&limit)),
        "a warning names the light and the limit: {:?}",
        far.warnings
    );
    assert!(
        far.warnings.iter().any(|w| w.contains("node 2's camera") && w.contains("a framing of the scene")),
        "a warning names the camera: {:?}",
        far.warnings
    );
    assert!(far.camera.position.abs().max_element() < 1e3, "the scene is framed instead: {:?}", far.camera.position);
    // Static (no channel moves it), a light there is refused with the scene.
    let fixed = json.replace(r#"{"translation": [0.5, 3, 3], "ext"#, r#"{"translation": [0.5, 3e20, 3], "ext"#);
    assert_ne!(fixed, json);
    let unanimated = fixed.replace(r#"{"sampler": 0, "target": {"node": 1, "path": "translation"}},"#, "");
    let e = expect_error(
        "a static light at 3e20",
        scene::load_gltf_slice(unanimated.as_bytes(), None, &scene::LoadOptions::default()),
    );
    assert!(e.to_string().contains(&limit), "{e}");
}
