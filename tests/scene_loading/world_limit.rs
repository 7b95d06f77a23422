//! Geometry beyond `scene::WORLD_LIMIT` (1e12 units): finite, but where the renderer's f32
//! arithmetic overflows. A static scene there is refused, naming the limit, whether flattened
//! or instanced; within it, it loads. (Poses that carry a part there drop it: the CLI's
//! `a_placement_a_pose_cannot_place_is_dropped_with_one_warning`.)

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
