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
