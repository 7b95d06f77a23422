//! Scenes that move: a renderer takes a posed scene's geometry (`Renderer::take_geometry`) and
//! renders what a renderer created for that pose renders, on every runtime.

use glam::Vec3;
use tracer::backend::{create, Renderer, RendererKind};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::{pack_textures, pack_with_textures, static_bvh, Packed};
use tracer::scene::{load_gltf_slice, LoadOptions, Scene, Sky};

/// The image after `frames` frames, as its pixels' bits.
fn frames_bits(r: &mut dyn Renderer, frames: u32) -> Vec<u32> {
    for _ in 0..frames {
        r.render_frame().expect("frame");
    }
    r.image().expect("image").pixels.iter().flat_map(|p| p.to_array()).map(f32::to_bits).collect()
}

/// After `take_geometry` a renderer restarts and renders the moved scene bit for bit as a
/// renderer created for it does (same seed), and not as it rendered before: a skinned, morphed
/// mesh made again and placements turned, on the CPU, GL and wgpu; its uniforms stay.
#[test]
fn a_renderer_takes_a_moved_scene_and_renders_it_as_a_new_one() {
    let options = LoadOptions { keep_motion: true, ..Default::default() };
    let mut scene: Scene = load_gltf_slice(&crate::common::moving_parts_gltf(), None, &options).expect("loads");
    scene.sky = Some(Sky::uniform(Vec3::splat(0.8)));
    let settings = RenderSettings { width: 24, height: 24, strategy: Strategy::Mis, max_depth: 3 };
    // What a moving scene reuses from pose to pose: the static level's BVH and the textures.
    let (bvh, textures) = (static_bvh(&scene).expect("BVH"), pack_textures(&scene));
    let pack_at = |scene: &Scene| -> Packed { pack_with_textures(scene, &bvh, &textures, &settings).expect("packs") };
    let at_rest = pack_at(&scene);
    let mut moved = scene.clone();
    assert!(moved.pose(0.8).expect("poses"));
    for kind in RendererKind::ALL {
        let mut r = create(kind, at_rest.clone(), 7).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        r.set_uniforms(&mut |s| s.max_depth = 2).expect("uniforms");
        let before = frames_bits(r.as_mut(), 2);
        r.take_geometry(pack_at(&moved)).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert_eq!((r.frames(), r.packed().scene.max_depth), (0, 2), "{kind:?}: restarted, uniforms kept");
        let after = frames_bits(r.as_mut(), 2);
        let mut fresh = create(kind, pack_at(&moved), 7).expect("renderer");
        fresh.set_uniforms(&mut |s| s.max_depth = 2).expect("uniforms");
        assert!(after == frames_bits(fresh.as_mut(), 2), "{kind:?}: not the moved scene's image");
        assert!(after != before, "{kind:?}: the motion does not show");
    }
}

/// A renderer takes pose after pose (natively GL and wgpu write the moved arrays over what
/// they hold, in place while they fit): each renders bit for bit what a renderer created for
/// that pose renders, including a pose whose arrays outgrow what the first one left room for
/// (wgpu: new buffers) and the pose it started from; a scene another kernel would draw is
/// refused and the renderer keeps rendering its pose.
#[test]
fn a_renderer_takes_pose_after_pose_and_refuses_another_kernel() {
    use kernel_dsl::Texels;
    let options = LoadOptions { keep_motion: true, ..Default::default() };
    let mut scene: Scene = load_gltf_slice(&crate::common::moving_parts_gltf(), None, &options).expect("loads");
    scene.sky = Some(Sky::uniform(Vec3::splat(0.8)));
    let settings = RenderSettings { width: 16, height: 16, strategy: Strategy::Mis, max_depth: 3 };
    let (bvh, textures) = (static_bvh(&scene).expect("BVH"), pack_textures(&scene));
    let pack_at = |time: f32| -> Packed {
        let mut posed = scene.clone();
        posed.pose(time).expect("poses");
        pack_with_textures(&posed, &bvh, &textures, &settings).expect("packs")
    };
    // Texels past the last triangle are read by no ray: the same image from a larger array,
    // which the room left after the first pose does not hold.
    let grown = |mut p: Packed| -> Packed {
        let mut triangles = p.scene.triangles.as_slice().to_vec();
        triangles.resize(triangles.len() + 4096, glam::Vec4::ZERO);
        p.scene.triangles = Texels::new(triangles);
        p
    };
    let poses = [
        ("0.8 s", pack_at(0.8)),
        ("0.3 s, grown", grown(pack_at(0.3))),
        ("1.5 s", pack_at(1.5)),
        ("0 s", pack_at(0.0)),
    ];
    let other_kernel = tracer::pack::build_and_pack(&tracer::scene::cornell_box(), &settings).expect("packs").1;
    for kind in RendererKind::ALL {
        let mut r = create(kind, pack_at(0.0), 7).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        for (what, packed) in &poses {
            r.take_geometry(packed.clone()).unwrap_or_else(|e| panic!("{kind:?} at {what}: {e}"));
            let taken = frames_bits(r.as_mut(), 2);
            let mut fresh = create(kind, packed.clone(), 7).expect("renderer");
            assert!(taken == frames_bits(fresh.as_mut(), 2), "{kind:?} at {what}: not the pose's image");
        }
        r.restart().expect("restart");
        let before = frames_bits(r.as_mut(), 1);
        assert!(r.take_geometry(other_kernel.clone()).is_err(), "{kind:?}: another kernel's scene taken");
        r.restart().expect("restart");
        assert!(frames_bits(r.as_mut(), 1) == before, "{kind:?}: the refused scene changed the image");
    }
}

/// The moving-parts glTF (a skinned, morphed mesh and three placements turning) inside a larger
/// scene: `instanced_shapes(3)`'s static floor and light, its sphere placed 9 times (a static
/// level of many nodes, kept levels of shared meshes, a top level of 13 placements whose size
/// changes from pose to pose), and its sky or none.
fn moving_in_a_larger_scene(sky: bool) -> Scene {
    let options = LoadOptions { keep_motion: true, ..Default::default() };
    let mut scene: Scene = load_gltf_slice(&crate::common::moving_parts_gltf(), None, &options).expect("loads");
    let more = tracer::scene::instanced_shapes(3);
    let (materials, meshes) = (scene.materials.len() as u32, scene.meshes.len() as u32);
    scene
        .triangles
        .extend(more.triangles.iter().map(|t| tracer::scene::Triangle { material: t.material + materials, ..*t }));
    scene.meshes.extend(more.meshes.iter().map(|m| tracer::scene::Mesh {
        triangles:
            m.triangles.iter().map(|t| tracer::scene::Triangle { material: t.material + materials, ..*t }).collect(),
    }));
    scene.instances.extend(more.instances.iter().map(|i| tracer::scene::Instance { mesh: i.mesh + meshes, ..*i }));
    scene.materials.extend(more.materials);
    scene.sky = if sky { more.sky } else { None };
    scene
}

/// A served moving scene poses from what its bundle carries (`tracer::pack::Posing`: the
/// packed first pose and the motion section's moving parts) to the same packed arrays, bit for
/// bit (compared as encoded bundles), as the loaded scene's `MovingScene` at several times; and
/// both are what packing the posed scene whole gives, except the light list, which stays the
/// first pose's (with a sky, only the sky's share of the light samples could differ). With
/// and without a sky; a bundle whose moving parts do not match its arrays is refused.
#[test]
fn a_bundle_poses_as_the_loaded_scene_and_as_packing_it_whole() {
    use tracer::bundle::{encode, encode_scene, Bundle};
    use tracer::pack::MovingScene;
    let settings = RenderSettings { width: 20, height: 16, strategy: Strategy::Mis, max_depth: 3 };
    for sky in [false, true] {
        let scene = moving_in_a_larger_scene(sky);
        let (bvh, textures) = (static_bvh(&scene).expect("BVH"), pack_textures(&scene));
        let (mut loaded, first) = MovingScene::new(scene.clone(), &settings).expect("packs");
        let bytes = encode_scene("moving", &first, loaded.scene());
        let bundle = Bundle::decode(&bytes).expect("decodes");
        let parts = bundle.moving.expect("a motion section");
        let mut served = MovingScene::from_bundle(&bundle.packed, parts).expect("poses from the bundle");
        let mut whole = scene.clone();
        let mut top_sizes = std::collections::BTreeSet::new();
        for time in [0.0, 0.3, 0.8, 1.7, 0.05, 9.0] {
            assert!(loaded.pose(time).expect("poses") && served.pose(time).expect("poses"));
            whole.pose(time).expect("poses");
            let (a, b) = (loaded.pack().expect("packs"), served.pack().expect("packs"));
            assert!(encode(&a) == encode(&b), "sky {sky}, {time} s: the bundle's pose differs from the loaded scene's");
            let mut reference = pack_with_textures(&whole, &bvh, &textures, &settings).expect("packs");
            assert_eq!(reference.features, a.features, "sky {sky}, {time} s");
            if !sky {
                assert!(reference.scene.lights == a.scene.lights, "{time} s: without a sky the lights never change");
            }
            reference.scene.lights = first.scene.lights.clone();
            assert!(encode(&reference) == encode(&a), "sky {sky}, {time} s: the pose differs from packing it whole");
            top_sizes.insert(a.scene.instance_first);
        }
        assert!(top_sizes.len() > 1, "sky {sky}: the node arrays never changed size: {top_sizes:?}");
    }
    // Moving parts that are not the packed scene's: refused with a reason, not a panic.
    let (_, other) = MovingScene::new(moving_in_a_larger_scene(false), &settings).expect("packs");
    let small = load_gltf_slice(
        &crate::common::moving_parts_gltf(),
        None,
        &LoadOptions { keep_motion: true, ..Default::default() },
    )
    .expect("loads");
    let err = Bundle::decode(&encode_scene("mixed", &other, &small)).expect_err("mismatched parts");
    assert!(err.to_string().contains("do not match"), "{err}");
}

/// A glTF grid of `n` x `n` quads (2n² triangles) facing +Z, whose one morph target slides
/// strips of it apart, its weight animated from 0 at 0 s to 1 at 1 s (LINEAR).
fn morphed_grid_gltf(n: usize) -> Vec<u8> {
    use base64::Engine;
    let mut positions = Vec::new();
    let mut bulge = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f32 / n as f32 * 2.0 - 1.0, j as f32 / n as f32 * 2.0 - 1.0);
            positions.extend([x, y, 0.0]);
            // Strips of columns slid apart along Y: at weight 0.1 a refit stays close to a
            // build, at 1 it is far worse (examples/bench_refit.rs's torn grid).
            let strip = (i * 16 / (n + 1)) as f32;
            bulge.extend([0.0, if strip % 2.0 == 0.0 { strip / 8.0 } else { -strip / 8.0 }, 0.0]);
        }
    }
    let mut indices: Vec<u32> = Vec::new();
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let at = |i: u32, j: u32| j * (n as u32 + 1) + i;
            indices.extend([at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    let floats = |v: &[f32]| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let mut bytes = floats(&positions);
    let offsets = [0, bytes.len()];
    bytes.extend(floats(&bulge));
    let index_at = bytes.len();
    bytes.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let keys_at = bytes.len();
    bytes.extend(floats(&[0.0, 1.0, 0.0, 1.0]));
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bytes));
    let vertices = (n + 1) * (n + 1);
    let json = serde_json::json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "weights": [0.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "targets": [{"POSITION": 1}]}]}],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
                        "samplers": [{"input": 3, "output": 4}]}],
        "buffers": [{"byteLength": bytes.len(), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": offsets[0], "byteLength": vertices * 12},
            {"buffer": 0, "byteOffset": offsets[1], "byteLength": vertices * 12},
            {"buffer": 0, "byteOffset": index_at, "byteLength": indices.len() * 4},
            {"buffer": 0, "byteOffset": keys_at, "byteLength": 16}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": vertices, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": vertices, "type": "VEC3", "min": [0, -2, 0], "max": [0, 2, 0]},
            {"bufferView": 2, "componentType": 5125, "count": indices.len(), "type": "SCALAR"},
            {"bufferView": 3, "byteOffset": 0, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]},
            {"bufferView": 3, "byteOffset": 8, "componentType": 5126, "count": 2, "type": "SCALAR"}
        ]
    });
    serde_json::to_vec(&json).unwrap()
}

/// A deformed mesh of `pack::REFIT_MIN_TRIANGLES` or more (a 48 x 48 morphed grid, 4,608
/// triangles) is posed with its first pose's bottom level refitted, not built again: its node
/// arrays differ from packing the posed scene whole, yet the CPU renders the two bit for bit
/// alike (the closest hit does not depend on the hierarchy); where the refit degrades past
/// `REFIT_BOUND` (strips torn apart at 1 s) the pose builds it again, as packing whole does. Below the threshold (the
/// moving-parts scene above) poses stay bit for bit what packing whole gives.
#[test]
fn a_large_deformed_mesh_is_refitted_and_renders_as_packing_it_whole() {
    use tracer::pack::MovingScene;
    let options = LoadOptions { keep_motion: true, ..Default::default() };
    let mut scene: Scene = load_gltf_slice(&morphed_grid_gltf(48), None, &options).expect("loads");
    scene.sky = Some(Sky::uniform(Vec3::splat(0.8)));
    assert!(scene.meshes.iter().any(|m| m.triangles.len() >= tracer::pack::REFIT_MIN_TRIANGLES));
    let settings = RenderSettings { width: 24, height: 24, strategy: Strategy::Mis, max_depth: 3 };
    let (bvh, textures) = (static_bvh(&scene).expect("BVH"), pack_textures(&scene));
    let (mut moving, _) = MovingScene::new(scene.clone(), &settings).expect("packs");
    let mut whole = scene.clone();
    let mut refitted = Vec::new();
    for time in [0.1, 0.05, 1.0] {
        assert!(moving.pose(time).expect("poses"));
        whole.pose(time).expect("poses");
        let posed = moving.pack().expect("packs");
        let reference = pack_with_textures(&whole, &bvh, &textures, &settings).expect("packs");
        refitted.push(posed.scene.nodes != reference.scene.nodes);
        let image = |packed: Packed| frames_bits(create(RendererKind::Cpu, packed, 3).expect("renderer").as_mut(), 2);
        assert!(image(posed) == image(reference), "{time} s: the refitted pose renders differently");
    }
    assert_eq!(refitted, [true, true, false], "refitted at 0.1 and 0.05 s, torn past the bound at 1 s: built again");
}
