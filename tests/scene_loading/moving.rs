//! Scenes that move, as loaded: `EXT_mesh_gpu_instancing`, animations, skins and morph
//! targets (`tracer/src/scene/gltf_loader/{nodes,animation,skin,morph}.rs`), each on a small
//! glTF written here.

use super::*;

/// The buffer of [`gltf_json`]'s triangle (POSITION accessor 0, u16 indices accessor 1) and the
/// FLOAT accessors appended to it, as the `buffers`, `bufferViews` and `accessors` members.
struct TriangleData {
    bytes: Vec<u8>,
    views: Vec<String>,
    accessors: Vec<String>,
}

impl TriangleData {
    fn new() -> Self {
        let mut bytes = f32_bytes(&TRI);
        bytes.extend(u16_bytes(&[0, 1, 2, 0]));
        let views = vec![
            r#"{"buffer": 0, "byteOffset": 0, "byteLength": 36}"#.to_string(),
            r#"{"buffer": 0, "byteOffset": 36, "byteLength": 6}"#.to_string(),
        ];
        let accessors = vec![
            r#"{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}"#
                .to_string(),
            r#"{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}"#.to_string(),
        ];
        Self { bytes, views, accessors }
    }

    /// Appends `values` as a FLOAT accessor of type `ty` ("SCALAR", "VEC3", "VEC4"); its index.
    fn floats(&mut self, ty: &str, values: &[f32]) -> usize {
        let n = match ty {
            "SCALAR" => 1,
            "VEC3" => 3,
            _ => 4,
        };
        let (offset, len) = (self.bytes.len(), values.len() * 4);
        self.bytes.extend(f32_bytes(values));
        self.views.push(format!(r#"{{"buffer": 0, "byteOffset": {offset}, "byteLength": {len}}}"#));
        let (view, count) = (self.views.len() - 1, values.len() / n);
        self.accessors
            .push(format!(r#"{{"bufferView": {view}, "componentType": 5126, "count": {count}, "type": "{ty}"}}"#));
        self.accessors.len() - 1
    }

    /// The `buffers`, `bufferViews` and `accessors` members.
    fn json(&self) -> String {
        format!(
            r#""buffers": [{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}],
  "bufferViews": [{}], "accessors": [{}]"#,
            self.bytes.len(),
            base64(&self.bytes),
            self.views.join(", "),
            self.accessors.join(", ")
        )
    }
}

/// [`gltf_json`]'s triangle placed by `EXT_mesh_gpu_instancing` on a node translated by
/// (0, 0, -5): `attributes` maps TRANSLATION / ROTATION / SCALE to their per-instance floats
/// (vec3, vec4 xyzw, vec3), each written as a FLOAT accessor; `required` lists the extension
/// in `extensionsRequired` too.
fn instanced_json(attributes: &[(&str, &[f32])], required: bool) -> String {
    let mut data = TriangleData::new();
    let names: Vec<String> = attributes
        .iter()
        .map(|(name, values)| {
            let accessor = data.floats(if *name == "ROTATION" { "VEC4" } else { "VEC3" }, values);
            format!(r#""{name}": {accessor}"#)
        })
        .collect();
    let required = if required { r#""extensionsRequired": ["EXT_mesh_gpu_instancing"],"# } else { "" };
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
  "extensionsUsed": ["EXT_mesh_gpu_instancing"], {required}
  "nodes": [{{"mesh": 0, "translation": [0, 0, -5],
              "extensions": {{"EXT_mesh_gpu_instancing": {{"attributes": {{{}}}}}}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  {}}}"#,
        names.join(", "),
        data.json()
    )
}

/// `EXT_mesh_gpu_instancing` loads (it was refused when required, ignored otherwise): each
/// instance is the mesh under node × T × R × S, with the spec's defaults for a missing attribute;
/// bad instancing data is a clear error.
#[test]
fn gpu_instancing_places_each_instance() {
    let quarter = std::f32::consts::FRAC_1_SQRT_2;
    let translation: &[f32] = &[0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 20.0, 0.0];
    // Identity, a quarter turn about +Z, an unnormalised identity (normalised on load).
    let rotation: &[f32] = &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, quarter, quarter, 0.0, 0.0, 0.0, 2.0];
    let scale: &[f32] = &[1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 1.0, 1.0, 1.0];
    let json = instanced_json(&[("TRANSLATION", translation), ("ROTATION", rotation), ("SCALE", scale)], true);
    let s = load_str(&json).unwrap();
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    assert_eq!(s.triangles.len(), 3);
    let corners: Vec<[Vec3; 3]> = s.triangles.iter().map(|t| t.positions).collect();
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
    // Instance 0: the triangle at the node's translation.
    assert!(corners.iter().any(|c| close(c[0], Vec3::new(0.0, 0.0, -5.0)) && close(c[1], Vec3::new(1.0, 0.0, -5.0))));
    // Instance 1: scaled 2, turned a quarter about +Z (x -> y), moved by (10, 0, 0).
    assert!(
        corners.iter().any(|c| close(c[0], Vec3::new(10.0, 0.0, -5.0)) && close(c[1], Vec3::new(10.0, 2.0, -5.0))),
        "{corners:?}"
    );
    // Instance 2: unit scale, identity, moved by (0, 20, 0).
    assert!(corners.iter().any(|c| close(c[2], Vec3::new(0.0, 21.0, -5.0))), "{corners:?}");

    // A missing attribute takes its default: translation only.
    let s = load_str(&instanced_json(&[("TRANSLATION", translation)], false)).unwrap();
    assert_eq!(s.triangles.len(), 3);
    assert!(s.triangles.iter().any(|t| close(t.positions[1], Vec3::new(11.0, 0.0, -5.0))));

    // Bad instancing data: counts that differ, a zero quaternion, no attributes.
    for (attributes, mentions) in [
        (vec![("TRANSLATION", translation), ("SCALE", &scale[..6])], "counts differ"),
        (vec![("ROTATION", &[0.0f32, 0.0, 0.0, 0.0][..])], "not a rotation"),
        (vec![], "none of TRANSLATION"),
    ] {
        let err = load_str(&instanced_json(&attributes, true)).unwrap_err();
        assert!(err.to_string().contains(mentions), "{err}");
    }
}

/// [`gltf_json`]'s triangle on node 0 (rest translation (0, 0, -5)) with `animations` (JSON)
/// whose samplers read `accessors`: FLOAT accessors 2, 3, ... of the given type ("SCALAR",
/// "VEC3", "VEC4") and values.
fn animated_json(animations: &str, accessors: &[(&str, &[f32])]) -> String {
    let mut data = TriangleData::new();
    for (ty, values) in accessors {
        data.floats(ty, values);
    }
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"mesh": 0, "translation": [0, 0, -5]}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "animations": {animations},
  {}}}"#,
        data.json()
    )
}

/// glTF animations pose the scene: the first by default, another by name or index, none for
/// the rest pose, at a time clamped to the keyframes; LINEAR (slerp for rotations), STEP and
/// CUBICSPLINE as the specification defines them; bad animation data is a clear error.
#[test]
fn animations_pose_the_scene_at_a_time() {
    use tracer::scene::AnimationChoice;
    let channel =
        |sampler: u32, path: &str| format!(r#"{{"sampler": {sampler}, "target": {{"node": 0, "path": "{path}"}}}}"#);
    let animation = |name: &str, path: &str, input: u32, output: u32, interpolation: &str| {
        format!(
            r#"{{"name": "{name}", "channels": [{}], "samplers": [{{"input": {input}, "output": {output}, "interpolation": "{interpolation}"}}]}}"#,
            channel(0, path)
        )
    };
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let animations = format!(
        "[{}, {}, {}, {}]",
        animation("slide", "translation", 2, 3, "LINEAR"),
        animation("turn", "rotation", 4, 5, "LINEAR"),
        animation("hop", "scale", 4, 6, "STEP"),
        animation("spline", "translation", 2, 7, "CUBICSPLINE")
    );
    let quarter_turn = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, h, h];
    let accessors: Vec<(&str, &[f32])> = vec![
        ("SCALAR", &[0.0, 2.0]),
        ("VEC3", &[0.0, 0.0, -5.0, 4.0, 0.0, -5.0]),
        ("SCALAR", &[0.0, 1.0]),
        // Identity to a quarter turn about +Z.
        ("VEC4", &quarter_turn),
        ("VEC3", &[1.0, 1.0, 1.0, 2.0, 2.0, 2.0]),
        // Per key: in-tangent, value, out-tangent.
        ("VEC3", &[0.0, 0.0, 0.0, 0.0, 0.0, -5.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -5.0, 0.0, 0.0, 0.0]),
    ];
    let json = animated_json(&animations, &accessors);
    let posed = |animation: AnimationChoice, time: f32| {
        let options = LoadOptions { animation, time, ..Default::default() };
        let s = scene::load_gltf_slice(json.as_bytes(), None, &options).unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        (s.triangles[0].positions[0], s.triangles[0].positions[1])
    };
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
    // The first animation by default: linear, clamped before and after its keyframes.
    for (time, x) in [(-1.0, 0.0), (0.0, 0.0), (0.5, 1.0), (1.0, 2.0), (2.0, 4.0), (9.0, 4.0)] {
        let (p0, _) = posed(AnimationChoice::First, time);
        assert!(close(p0, Vec3::new(x, 0.0, -5.0)), "slide at {time}: {p0}");
    }
    // The rest pose ignores the animations.
    assert!(close(posed(AnimationChoice::Rest, 1.0).0, Vec3::new(0.0, 0.0, -5.0)));
    // Rotation by slerp: halfway is an eighth of a turn.
    let (_, p1) = posed(AnimationChoice::Named("turn".into()), 0.5);
    assert!(close(p1, Vec3::new(h, h, -5.0)), "turn at 0.5: {p1}");
    // STEP, chosen by index: the first value until the second key.
    assert!(close(posed(AnimationChoice::Named("2".into()), 0.99).1, Vec3::new(1.0, 0.0, -5.0)));
    assert!(close(posed(AnimationChoice::Named("2".into()), 1.0).1, Vec3::new(2.0, 0.0, -5.0)));
    // CUBICSPLINE over keys 2 s apart: at u = 1/2, (v0 + v1) / 2 + dt (b0 - a1) / 8 = 0.5 + 2 x 2 / 8
    // in x (the tangents scaled by the interval, as the specification says).
    assert!(close(posed(AnimationChoice::Named("spline".into()), 1.0).0, Vec3::new(1.0, 0.0, -5.0)));

    // Errors: an unknown name lists the animations; bad keyframes.
    let options = LoadOptions { animation: AnimationChoice::Named("dance".into()), ..Default::default() };
    let err = scene::load_gltf_slice(json.as_bytes(), None, &options).unwrap_err().to_string();
    assert!(err.contains("dance") && err.contains("slide, turn, hop, spline"), "{err}");
    let nan = LoadOptions { time: f32::NAN, ..Default::default() };
    assert!(scene::load_gltf_slice(json.as_bytes(), None, &nan).is_err());
    for (accessors, mentions) in [
        (vec![("SCALAR", &[2.0f32, 0.0][..]), ("VEC3", &[0.0f32; 6][..])], "decrease"),
        (vec![("SCALAR", &[0.0f32, 1.0][..]), ("VEC3", &[0.0f32; 9][..])], "need 2 output elements"),
    ] {
        let json = animated_json(&format!("[{}]", animation("bad", "translation", 2, 3, "LINEAR")), &accessors);
        let err = load_str(&json).unwrap_err().to_string();
        assert!(err.contains(mentions), "{err}");
    }
}

/// A skinned triangle: node 0 holds the mesh and skin 0 (its own translation (100, 0, 0) is
/// ignored, as glTF says), nodes 1 (root joint, at the origin) and 2 (its child, at (0, 3, 0))
/// are the joints. Vertex 0 follows joint 0, vertex 1 joint 1, vertex 2 both equally.
/// `inverse_bind` gives joint 1's inverse bind translation; `animation` is spliced in as-is
/// (its samplers may read accessor 6, times [0, 1], and 7, two VEC3s).
fn skinned_json(inverse_bind: Option<Vec3>, animation: &str) -> String {
    skinned_json_keyed(inverse_bind, animation, [0.0, 3.0, 0.0, 0.0, 5.0, 0.0])
}

/// [`skinned_json`] with accessor 7's two VEC3s `keys`.
fn skinned_json_keyed(inverse_bind: Option<Vec3>, animation: &str, keys: [f32; 6]) -> String {
    let mut buf = f32_bytes(&TRI);
    buf.extend(u16_bytes(&[0, 1, 2, 0]));
    buf.extend([0u8, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0]); // JOINTS_0, unsigned bytes
    buf.extend(f32_bytes(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0])); // WEIGHTS_0
    let t = inverse_bind.unwrap_or(Vec3::ZERO);
    let identity = glam::Mat4::IDENTITY.to_cols_array();
    buf.extend(f32_bytes(&identity));
    buf.extend(f32_bytes(&glam::Mat4::from_translation(t).to_cols_array()));
    buf.extend(f32_bytes(&[0.0, 1.0]));
    buf.extend(f32_bytes(&keys));
    let ibm = if inverse_bind.is_some() { r#", "inverseBindMatrices": 5"# } else { "" };
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0, 1]}}],
  "nodes": [{{"mesh": 0, "skin": 0, "translation": [100, 0, 0]}}, {{"children": [2]}}, {{"translation": [0, 3, 0]}}],
  "skins": [{{"joints": [1, 2]{ibm}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3}}, "indices": 1}}]}}],
  "animations": [{animation}],
  "buffers": [{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 6}},
    {{"buffer": 0, "byteOffset": 44, "byteLength": 12}}, {{"buffer": 0, "byteOffset": 56, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 104, "byteLength": 128}}, {{"buffer": 0, "byteOffset": 232, "byteLength": 8}},
    {{"buffer": 0, "byteOffset": 240, "byteLength": 24}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}},
    {{"bufferView": 2, "componentType": 5121, "count": 3, "type": "VEC4"}},
    {{"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"}},
    {{"bufferView": 4, "componentType": 5126, "count": 2, "type": "MAT4"}},
    {{"bufferView": 4, "componentType": 5126, "count": 2, "type": "MAT4"}},
    {{"bufferView": 5, "componentType": 5126, "count": 2, "type": "SCALAR"}},
    {{"bufferView": 6, "componentType": 5126, "count": 2, "type": "VEC3"}}]}}"#,
        buf.len(),
        base64(&buf)
    )
}

/// Skins deform their meshes on the host: each vertex moved by its joints' world × inverse bind
/// matrices, weighted; the skinned node's own transform ignored; joints posed by animations.
#[test]
fn skins_deform_their_meshes() {
    let corners = |json: &str, time: f32| {
        let options = LoadOptions { time, ..Default::default() };
        let s = scene::load_gltf_slice(json.as_bytes(), None, &options).unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(s.triangles.len(), 1);
        let mut p = s.triangles[0].positions;
        p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        p
    };
    let close = |a: [Vec3; 3], b: [Vec3; 3]| a.iter().zip(&b).all(|(a, b)| (*a - *b).length() < 1e-5);
    // Joint 1 at (0, 3, 0), no inverse bind matrices: vertex 1 follows it, vertex 2 half way.
    let p = corners(&skinned_json(None, ""), 0.0);
    assert!(close(p, [Vec3::ZERO, Vec3::new(0.0, 2.5, 0.0), Vec3::new(1.0, 3.0, 0.0)]), "{p:?}");
    // An inverse bind matrix undoing joint 1's rest translation: the rest shape.
    let p = corners(&skinned_json(Some(Vec3::new(0.0, -3.0, 0.0)), ""), 0.0);
    assert!(close(p, [Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 0.0, 0.0)]), "{p:?}");
    // An animation moving joint 1 from (0, 3, 0) to (0, 5, 0) over a second.
    let animation = r#"{"channels": [{"sampler": 0, "target": {"node": 2, "path": "translation"}}],
        "samplers": [{"input": 6, "output": 7}]}"#;
    let p = corners(&skinned_json(None, animation), 1.0);
    assert!(close(p, [Vec3::ZERO, Vec3::new(0.0, 3.5, 0.0), Vec3::new(1.0, 5.0, 0.0)]), "{p:?}");
    // A joint index beyond the skin's joints is a clear error.
    let bad = skinned_json(None, "").replace(r#""joints": [1, 2]"#, r#""joints": [1]"#);
    let err = load_str(&bad).unwrap_err().to_string();
    assert!(err.contains("joint 1 of 1 does not exist"), "{err}");
}

/// Morph targets: positions displaced by the weighted targets, the weights of the animation's
/// `weights` channel, else the node's, else the mesh's; bad weights a clear error.
#[test]
fn morph_targets_follow_their_weights() {
    let animation = r#"[{"channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
        "samplers": [{"input": 3, "output": 4}]}]"#;
    // Accessor 2: one target moving vertex 2 by (0, 0, 2); 3: times; 4: a weight per key.
    let accessors: Vec<(&str, &[f32])> = vec![
        ("VEC3", &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0]),
        ("SCALAR", &[0.0, 1.0]),
        ("SCALAR", &[0.0, 1.0]),
    ];
    let base = animated_json(animation, &accessors).replace(
        r#""meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}]"#,
        r#""meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "targets": [{"POSITION": 2}]}], "weights": [0.5]}]"#,
    );
    assert!(base.contains("targets"), "the mesh was rewritten");
    let vertex_2 = |json: &str, animation: AnimationChoice, time: f32| {
        let options = LoadOptions { animation, time, ..Default::default() };
        let s = scene::load_gltf_slice(json.as_bytes(), None, &options).unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        s.triangles[0].positions[2].z
    };
    use tracer::scene::AnimationChoice;
    // The mesh's default weight 0.5 in the rest pose; the animation's weight at a quarter second.
    assert!((vertex_2(&base, AnimationChoice::Rest, 0.0) - -4.0).abs() < 1e-6);
    assert!((vertex_2(&base, AnimationChoice::First, 0.25) - -4.5).abs() < 1e-6);
    // A node's weights override the mesh's.
    let node_weights = base.replace(
        r#"{"mesh": 0, "translation": [0, 0, -5]}"#,
        r#"{"mesh": 0, "translation": [0, 0, -5], "weights": [1.0]}"#,
    );
    assert!((vertex_2(&node_weights, AnimationChoice::Rest, 0.0) - -3.0).abs() < 1e-6);
    // A weights channel whose output does not hold one weight per target and key.
    let bad = base.replace(r#""samplers": [{"input": 3, "output": 4}]"#, r#""samplers": [{"input": 3, "output": 2}]"#);
    let err = load_str(&bad).unwrap_err().to_string();
    assert!(err.contains("output"), "{err}");
}

/// `json` with one more triangle (node and mesh), static at (0, 0, -7): a scene that keeps
/// a triangle where a pose drops its others.
fn with_static_triangle(json: &str) -> String {
    let mut v: serde_json::Value = serde_json::from_str(json).unwrap();
    let meshes = v["meshes"].as_array_mut().unwrap();
    meshes.push(serde_json::json!({"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}));
    let mesh = meshes.len() - 1;
    let nodes = v["nodes"].as_array_mut().unwrap();
    nodes.push(serde_json::json!({"mesh": mesh, "translation": [0, 0, -7]}));
    let node = nodes.len() - 1;
    v["scenes"][0]["nodes"].as_array_mut().unwrap().push(node.into());
    v.to_string()
}

/// [`skinned_json`] whose joint 1 (node 2, at (0, 3, 0), its inverse bind matrix undoing
/// that: the rest shape at rest) an animation scales by 1 until 1 s, then by 2e38 (STEP): its
/// matrix, (0, 3, 0) + scale x (0, -3, 0) in translation, is not finite from 1 s on; with a
/// static triangle beside it (node 3, mesh 1).
fn overflowing_skin_json() -> String {
    let scale = r#"{"channels": [{"sampler": 0, "target": {"node": 2, "path": "scale"}}],
        "samplers": [{"input": 6, "output": 7, "interpolation": "STEP"}]}"#;
    let keys = [1.0, 1.0, 1.0, 2e38, 2e38, 2e38];
    with_static_triangle(&skinned_json_keyed(Some(Vec3::new(0.0, -3.0, 0.0)), scale, keys))
}

/// [`animated_json`]'s triangle (node 0) with a morph target moving vertex 2 by (0, 0, 2),
/// its weight animated from 0 until 1 s to 3e38 from 1 s on (STEP): the morphed vertex is not
/// finite from 1 s on; with a static triangle beside it.
fn overflowing_morph_json() -> String {
    let animation = r#"[{"channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
        "samplers": [{"input": 3, "output": 4, "interpolation": "STEP"}]}]"#;
    // Accessor 5: translations for a channel that moves the static triangle instead.
    let accessors: Vec<(&str, &[f32])> = vec![
        ("VEC3", &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0]),
        ("SCALAR", &[0.0, 1.0]),
        ("SCALAR", &[0.0, 3e38]),
        ("VEC3", &[0.0, 0.0, -7.0, 0.0, 1.0, -7.0]),
    ];
    let json = animated_json(animation, &accessors).replace(
        r#""meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}]"#,
        r#""meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "targets": [{"POSITION": 2}]}]}]"#,
    );
    assert!(json.contains("targets"), "the mesh was rewritten");
    with_static_triangle(&json)
}

/// A skinned mesh whose joint's matrix the animation makes non-finite at 1 s (by the joint's
/// scale, or its parent's: then the joint's own world transform is not finite), and a morphed
/// one whose weight overflows its vertex there, are dropped from that pose with one warning
/// naming the node and mesh, the time and why, on every posing path: loaded at 1 s
/// (flattened: the static triangle alone), and a kept motion posed there (`Scene::pose`, its
/// `MovingScene` and its bundle's moving parts: the mesh keeps its number of triangles, a
/// millionth of its size at the origin, all finite; posed back, the rest shape again); the
/// warning is not repeated. Where the pose is finite (0 s, 0.5 s) nothing is said.
#[test]
fn a_skinned_or_morphed_mesh_a_pose_cannot_make_finite_is_dropped_with_one_warning() {
    use tracer::bundle::{encode, encode_scene, Bundle};
    // The root joint (node 1) scaled instead: joint 1's own world transform (node 2, a bare
    // joint below it) is not finite; only the mesh is warned about.
    let root_joint = overflowing_skin_json().replace(r#"{"node":2,"path":"scale"}"#, r#"{"node":1,"path":"scale"}"#);
    assert!(root_joint.contains(r#"{"node":1,"path":"scale"}"#), "the channel was retargeted");
    for (name, json, why) in [
        ("skin", overflowing_skin_json(), "is not finite (a joint's matrix"),
        ("skin, its joint's own transform", root_joint, "is not finite (a joint's matrix"),
        ("morph", overflowing_morph_json(), "is not finite (its morph weights"),
    ] {
        let load = |time: f32, keep_motion: bool| {
            let options = LoadOptions { time, keep_motion, animation: AnimationChoice::First, ..Default::default() };
            scene::load_gltf_slice(json.as_bytes(), None, &options)
                .unwrap_or_else(|e| panic!("{name}: loading at {time} s (keep_motion {keep_motion}): {e}"))
        };
        let one_warning = |s: &Scene, time: &str| {
            assert_eq!(s.warnings.len(), 1, "{name}: {:?}", s.warnings);
            let w = &s.warnings[0];
            assert!(
                w.starts_with("node 0 mesh 0: at ") && w.contains(&format!("at {time} s")) && w.contains(why),
                "{name}: {w}"
            );
        };
        // Flattened at a time: the static triangle alone where the mesh cannot be made finite.
        for time in [0.0, 0.5] {
            let s = load(time, false);
            assert!(s.warnings.is_empty(), "{name} at {time}: {:?}", s.warnings);
            assert_eq!(s.triangles.len(), 2, "{name} at {time}");
        }
        let s = load(1.0, false);
        one_warning(&s, "1");
        assert_eq!(s.triangles.len(), 1, "{name}: the mesh is dropped");
        assert_eq!(s.triangles[0].positions[0], Vec3::new(0.0, 0.0, -7.0), "{name}: the static triangle stays");

        // A kept motion, posed.
        let mut moving = load(0.0, true);
        assert!(moving.warnings.is_empty(), "{name}: {:?}", moving.warnings);
        let deformed = moving.motion.as_ref().unwrap().deformed_mesh_indices();
        assert_eq!(deformed.len(), 1, "{name}");
        let (d, rest) = (deformed[0], moving.meshes.clone());
        assert!(moving.pose(0.5).unwrap() && moving.warnings.is_empty(), "{name}: {:?}", moving.warnings);
        assert!(moving.pose(1.0).unwrap(), "{name}");
        one_warning(&moving, "1");
        let dropped = &moving.meshes[d].triangles;
        assert_eq!(dropped.len(), rest[d].triangles.len(), "{name}: the number of triangles changed");
        let tiny = dropped.iter().flat_map(|t| t.positions).all(|p| p.is_finite() && p.length() < 1e-5);
        assert!(tiny, "{name}: the dropped mesh is not a millionth of its size at the origin: {dropped:?}");
        assert!(dropped.iter().all(|t| t.normals.iter().all(|n| n.is_finite())), "{name}");
        let packable = moving.clone();
        assert!(moving.pose(7.0).unwrap(), "{name}");
        assert_eq!(moving.warnings.len(), 1, "{name}: warned again: {:?}", moving.warnings);
        assert!(moving.pose(0.0).unwrap(), "{name}");
        assert_eq!(moving.meshes, rest, "{name}: posed back at 0 s, the mesh is not at rest");
        // Loaded with its motion at 1 s: dropped by the load-time pose.
        one_warning(&load(1.0, true), "1");

        // Packed (`MovingScene`) and from its bundle (the first pose's arrays and the moving
        // parts): the pose at 1 s packs, to the same arrays both ways.
        let settings = tracer::kernel::RenderSettings { width: 16, height: 12, ..Default::default() };
        let (mut loaded, first) = tracer::pack::MovingScene::new(load(0.0, true), &settings).unwrap();
        let bundle = Bundle::decode(&encode_scene(name, &first, loaded.scene())).unwrap();
        let parts = bundle.moving.unwrap();
        let mut served = tracer::pack::MovingScene::from_bundle(&bundle.packed, parts).unwrap();
        let a = loaded.packed_at(1.0).unwrap_or_else(|e| panic!("{name}: {e}"));
        let b = served.packed_at(1.0).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(loaded.scene().meshes, packable.meshes, "{name}");
        assert_eq!(served.scene().meshes, packable.meshes, "{name}: the bundle's moving parts pose otherwise");
        one_warning(served.scene(), "1");
        assert!(encode(&a) == encode(&b), "{name}: the bundle's pose packs otherwise");
    }
}

/// Flattened at a time, a moving node whose world transform is not finite drops itself and
/// everything below it with one warning naming it where a mesh lies below (here node 1, bare,
/// above the mesh's node 0; node 2 above it scales by 1e20, node 1 by 1e-20 until 1 s, then by
/// 1e20: 1e40 overflows); a bare node with nothing below is dropped without a word (a skinned
/// mesh that needs it as a joint is warned about itself, as above).
#[test]
fn a_moving_node_a_pose_cannot_place_is_warned_about_where_a_mesh_lies_below() {
    let animation = r#"[{"channels": [{"sampler": 0, "target": {"node": 1, "path": "scale"}}],
        "samplers": [{"input": 2, "output": 3, "interpolation": "STEP"}]}]"#;
    let accessors: Vec<(&str, &[f32])> =
        vec![("SCALAR", &[0.0, 1.0]), ("VEC3", &[1e-20, 1e-20, 1e-20, 1e20, 1e20, 1e20])];
    let mut v: serde_json::Value = serde_json::from_str(&animated_json(animation, &accessors)).unwrap();
    let nodes = v["nodes"].as_array_mut().unwrap();
    nodes.push(serde_json::json!({"children": [0]}));
    nodes.push(serde_json::json!({"children": [1], "scale": [1e20, 1e20, 1e20]}));
    v["scenes"][0]["nodes"] = serde_json::json!([2]);
    let json = with_static_triangle(&v.to_string());
    let load = |time: f32| {
        let options = LoadOptions { time, ..Default::default() };
        scene::load_gltf_slice(json.as_bytes(), None, &options).unwrap()
    };
    let s = load(0.5);
    assert!(s.warnings.is_empty() && s.triangles.len() == 2, "{:?}", s.warnings);
    let s = load(1.0);
    assert_eq!(s.triangles.len(), 1, "the mesh below is dropped");
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(s.warnings[0].starts_with("node 1: at 1 s") && s.warnings[0].contains("is not finite"), "{:?}", s.warnings);
}

/// What no animation moves stays an error: a skin whose joint is scaled by 2e38 at rest (its
/// matrix not finite at any time), loaded without its animation or with one that moves
/// another node (here the static triangle), kept or not; a morph with the same weight, fixed.
#[test]
fn a_skin_or_morph_that_no_pose_can_make_finite_is_an_error() {
    let mut skin: serde_json::Value = serde_json::from_str(&overflowing_skin_json()).unwrap();
    skin["nodes"][2]["scale"] = serde_json::json!([2e38, 2e38, 2e38]);
    skin["animations"][0]["channels"][0]["target"]["node"] = 3.into();
    let mut morph: serde_json::Value = serde_json::from_str(&overflowing_morph_json()).unwrap();
    morph["meshes"][0]["weights"] = serde_json::json!([3e38]);
    morph["animations"][0]["channels"][0]["target"] = serde_json::json!({"node": 1, "path": "translation"});
    morph["animations"][0]["samplers"][0]["output"] = 5.into();
    for (name, json, says) in
        [("skin", skin, "joint node 2 has a non-finite transform"), ("morph", morph, "morphed vertex is not finite")]
    {
        let json = json.to_string();
        for (animation, keep_motion) in
            [(AnimationChoice::Rest, false), (AnimationChoice::First, false), (AnimationChoice::First, true)]
        {
            let options = LoadOptions { animation: animation.clone(), keep_motion, ..Default::default() };
            let err = match scene::load_gltf_slice(json.as_bytes(), None, &options) {
                Ok(s) => panic!("{name}, {animation:?}, keep_motion {keep_motion}: loaded ({:?})", s.warnings),
                Err(e) => e.to_string(),
            };
            assert!(err.contains(says), "{name}, {animation:?}, keep_motion {keep_motion}: {err}");
        }
    }
}

/// `tests/data/scenes/generated/animated-skinned-instanced.gltf`, a seed of the glTF fuzz target
/// with every moving-scene feature at once (a skinned, morphed triangle whose joints and
/// weights are animated, LINEAR, CUBICSPLINE and STEP, and a triangle instanced three times):
/// it loads with no warning at any time, with all four triangles.
#[test]
fn the_moving_scene_seed_loads_at_any_time() {
    let path = common::test_data("scenes/generated/animated-skinned-instanced.gltf");
    for time in [-1.0, 0.0, 0.3, 1.0, 7.5] {
        let options = LoadOptions { time, ..Default::default() };
        let s = scene::load_with(&path, &options).unwrap();
        assert!(s.warnings.is_empty(), "{time}: {:?}", s.warnings);
        assert_eq!(s.triangles.len(), 4, "{time}");
    }
}

/// A scene's triangles as placed in the world (instances baked), zero-area ones left out, in
/// a canonical order: what two ways of posing a scene must agree on.
fn placed_triangles(mut s: Scene) -> Vec<[Vec3; 3]> {
    s.bake_instances().unwrap();
    let mut t: Vec<[Vec3; 3]> =
        s.triangles.iter().map(|t| t.positions).filter(|p| (p[1] - p[0]).cross(p[2] - p[0]) != Vec3::ZERO).collect();
    let key = |p: &[Vec3; 3]| p.map(|v| v.to_array()).concat();
    t.sort_by(|a, b| key(a).partial_cmp(&key(b)).unwrap());
    t
}

/// A scene that keeps its animation (`LoadOptions::keep_motion`) and is posed at a time
/// (`Scene::pose`) has the triangles of the scene loaded at that time: nodes (LINEAR, STEP,
/// CUBICSPLINE), skins with animated joints, morph weights and `EXT_mesh_gpu_instancing` under
/// a moving node; the moving meshes are instances, the rest stays static; a bad time is a
/// clear error and leaves the scene as it was.
#[test]
fn a_kept_motion_poses_the_scene_as_loading_at_that_time_does() {
    let cases = moving_cases();
    for (name, bytes) in &cases {
        let load = |time: f32, keep_motion: bool| {
            let options = LoadOptions { time, keep_motion, animation: AnimationChoice::First, ..Default::default() };
            scene::load_gltf_slice(bytes, None, &options).unwrap()
        };
        let mut moving = load(0.0, true);
        let motion = moving.motion.as_ref().unwrap_or_else(|| panic!("{name}: no motion kept"));
        assert!(motion.moving_placements() + motion.deformed_meshes() > 0, "{name}: nothing moves");
        assert!(!moving.instances.is_empty(), "{name}: the moving meshes are not instances");
        for time in [0.0, 0.3, 1.0, 1.7, 9.0, 0.5] {
            assert!(moving.pose(time).unwrap(), "{name}");
            let (posed, loaded) = (placed_triangles(moving.clone()), placed_triangles(load(time, false)));
            assert_eq!(posed.len(), loaded.len(), "{name} at {time}");
            for (a, b) in posed.iter().zip(&loaded) {
                let close = a.iter().zip(b).all(|(a, b)| (*a - *b).length() < 1e-4);
                assert!(close, "{name} at {time}: posed {a:?}, loaded {b:?}");
            }
        }
        // A time that is not a number: an error, the scene as it was.
        let before = placed_triangles(moving.clone());
        assert!(moving.pose(f32::NAN).unwrap_err().to_string().contains("finite"), "{name}");
        assert_eq!(placed_triangles(moving.clone()), before, "{name}");
    }
    // Without keep_motion nothing is kept; a scene without motion does not move.
    let mut still = scene::load_gltf_slice(&cases[1].1, None, &LoadOptions::default()).unwrap();
    assert!(still.motion.is_none() && still.instances.is_empty());
    assert!(!still.pose(1.0).unwrap());
}

use tracer::scene::AnimationChoice;

/// Scenes that move, each with its name: the generated moving seed with its gpu-instanced node
/// turned too (a skinned, morphed mesh; LINEAR, STEP, CUBICSPLINE), a skin with an animated
/// joint, and a node with slerp plus CUBICSPLINE.
fn moving_cases() -> Vec<(&'static str, Vec<u8>)> {
    let skin_animation = r#"{"channels": [{"sampler": 0, "target": {"node": 2, "path": "translation"}}],
        "samplers": [{"input": 6, "output": 7}]}"#;
    let turn = r#"[{"channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}},
                              {"sampler": 1, "target": {"node": 0, "path": "translation"}}],
        "samplers": [{"input": 2, "output": 3}, {"input": 2, "output": 4, "interpolation": "CUBICSPLINE"}]}]"#;
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let quarter_turn = [0.0, 0.0, 0.0, 1.0, 0.0, h, 0.0, h];
    let turn_accessors: Vec<(&str, &[f32])> = vec![
        ("SCALAR", &[0.0, 2.0]),
        ("VEC4", &quarter_turn),
        ("VEC3", &[0.0, 0.0, 0.0, 0.0, 0.0, -5.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -5.0, 0.0, 0.0, 0.0]),
    ];
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("the moving-scene seed, its instances turning", common::moving_parts_gltf()),
        ("a skin", skinned_json(None, skin_animation).into_bytes()),
        ("a node turning", animated_json(turn, &turn_accessors).into_bytes()),
    ];
    cases
}

/// The scene as `keep_motion` loads it at time 0, with its packed pose.
fn load_moving(bytes: &[u8]) -> (Scene, tracer::pack::Packed) {
    let options = LoadOptions { keep_motion: true, animation: AnimationChoice::First, ..Default::default() };
    let scene = scene::load_gltf_slice(bytes, None, &options).unwrap();
    let settings = tracer::kernel::RenderSettings { width: 16, height: 12, ..Default::default() };
    let (moving, packed) = tracer::pack::MovingScene::new(scene, &settings).unwrap();
    (moving.scene().clone(), packed)
}

/// A bundle of a scene that moves carries its motion section (`tracer/src/bundle/motion.rs`):
/// read back, its moving parts pose to the very meshes and instances (bit for bit) the loaded
/// scene poses to, at several times, and encode again to the same bytes; a static scene's
/// bundle has no such section and is the bytes it always was.
#[test]
fn a_bundle_carries_the_motion_and_poses_as_the_scene_does() {
    use tracer::bundle::{encode_named, encode_scene, Bundle};
    for (name, bytes) in &moving_cases() {
        let (mut scene, packed) = load_moving(bytes);
        let encoded = encode_scene(name, &packed, &scene);
        let bundle = Bundle::decode(&encoded).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(bundle.encode(), encoded, "{name}: re-encoding differs");
        let mut moving = bundle.moving.unwrap_or_else(|| panic!("{name}: no motion section"));
        let (a, b) = (scene.motion.as_ref().unwrap(), moving.motion.as_ref().unwrap());
        assert_eq!((a.name(), a.duration(), a.describe()), (b.name(), b.duration(), b.describe()), "{name}");
        for time in [0.0, 0.3, 1.0, 1.7, 9.0, 0.5] {
            assert!(scene.pose(time).unwrap() && moving.pose(time).unwrap(), "{name}");
            assert_eq!(moving.meshes, scene.meshes, "{name} at {time}: the posed meshes differ");
            assert_eq!(moving.instances, scene.instances, "{name} at {time}: the posed instances differ");
        }
    }
    // A static scene: the same bytes as a bundle without a motion section, and none read back.
    let still = scene::load_gltf_slice(&moving_cases()[1].1, None, &LoadOptions::default()).unwrap();
    let (_, packed) = tracer::pack::build_and_pack(&still, &Default::default()).unwrap();
    let bytes = encode_scene("still", &packed, &still);
    assert_eq!(bytes, encode_named("still", &packed), "a static scene's bundle changed");
    assert!(Bundle::decode(&bytes).unwrap().moving.is_none());
    assert!(tracer::bundle::entries(&bytes).unwrap().iter().all(|(n, _)| !n.starts_with("motion.")));
}

/// The motion section's decoder (`scene::moving_from_streams`) on corrupt streams: every
/// integer replaced by values around it and by huge ones, every truncation, a NaN in place of
/// each float: an error or a motion that poses, never a panic or a huge allocation.
#[test]
fn a_corrupt_motion_section_is_an_error_never_a_panic() {
    for (name, bytes) in &moving_cases() {
        let (scene, packed) = load_moving(bytes);
        let (anim, ints, floats) = scene::motion_streams(&scene).unwrap();
        // What the page does with accepted parts: pose them over the bundle's packed arrays.
        let pose_over_packed = |mut moving: Scene| {
            if let Ok(posing) = tracer::pack::Posing::new(&packed, &moving) {
                for t in [0.0, 0.7, 5.0] {
                    if moving.pose(t).is_ok() {
                        let _ = posing.pack(&moving);
                    }
                }
            }
        };
        assert!(scene::moving_from_streams(&anim, &ints, &floats).is_ok(), "{name}");
        let mut accepted = 0;
        for i in 0..ints.len() {
            for v in [0, 1, ints[i].wrapping_add(1), ints[i].wrapping_sub(1), 1 << 30, u32::MAX] {
                let mut bad = ints.clone();
                bad[i] = v;
                if let Ok(moving) = scene::moving_from_streams(&anim, &bad, &floats) {
                    accepted += 1;
                    pose_over_packed(moving);
                }
            }
        }
        for len in 0..ints.len() {
            assert!(scene::moving_from_streams(&anim, &ints[..len], &floats).is_err(), "{name}: {len} ints");
        }
        for len in 0..floats.len() {
            assert!(scene::moving_from_streams(&anim, &ints, &floats[..len]).is_err(), "{name}: {len} floats");
        }
        for i in 0..floats.len() {
            let mut bad = floats.clone();
            bad[i] = f32::NAN;
            let err = scene::moving_from_streams(&anim, &ints, &bad).unwrap_err();
            assert!(err.contains("not finite"), "{name}: {err}");
            // Huge values (keyframe times out of order, matrices that cannot be inverted).
            for v in [-1e30, 1e30, 0.0] {
                bad[i] = v;
                if let Ok(moving) = scene::moving_from_streams(&anim, &ints, &bad) {
                    pose_over_packed(moving);
                }
            }
        }
        println!(
            "{name}: {} ints, {} floats, {accepted} of {} changed ints accepted",
            ints.len(),
            floats.len(),
            ints.len() * 6
        );
    }
}
