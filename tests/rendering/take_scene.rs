//! A renderer compiled before its scene is known: created from `Packed::placeholder` (the
//! features only, as `bundle::peek_features` reads them from a bundle's header) and drawn once,
//! it takes the scene (`Renderer::take_scene`) and renders it bit for bit as a renderer created
//! for it does, on every runtime and schedule. The page's viewer compiles so while it decodes.

use tracer::backend::{create_scheduled, Renderer, RendererKind, Schedule};
use tracer::kernel::{RenderSettings, Strategy};
use tracer::pack::{build_and_pack, Packed};
use tracer::scene::{self, Scene};

/// The image after `frames` frames, as its pixels' bits.
fn frames_bits(r: &mut dyn Renderer, frames: u32) -> Vec<u32> {
    for _ in 0..frames {
        r.render_frame().expect("frame");
    }
    r.image().expect("image").pixels.iter().flat_map(|p| p.to_array()).map(f32::to_bits).collect()
}

fn packed(scene: &Scene, size: u32) -> Packed {
    let settings = RenderSettings { width: size, height: size, strategy: Strategy::Mis, max_depth: 4 };
    build_and_pack(scene, &settings).expect("packs").1
}

/// Scenes of different kernel variants: lights, textures and a sky, instances, alpha masks,
/// metal and roughness; and every runtime and schedule that runs each.
fn cases() -> Vec<(&'static str, Packed)> {
    let mut textured = scene::load(&crate::common::test_data("scenes/khronos/BoxTextured/glTF/BoxTextured.gltf"))
        .expect("BoxTextured");
    textured.sky = Some(scene::Sky::uniform(glam::Vec3::ONE));
    vec![
        ("Cornell box", packed(&scene::cornell_box(), 16)),
        ("BoxTextured under a sky", packed(&textured, 16)),
        ("instanced shapes", packed(&scene::instanced_shapes(2), 16)),
        ("alpha-masked screen", packed(&scene::alpha_masked_screen(), 16)),
        ("metal-rough spheres", packed(&scene::metal_rough_spheres(), 16)),
    ]
}

const RUNS: [(RendererKind, Schedule); 5] = [
    (RendererKind::Cpu, Schedule::Megakernel),
    (RendererKind::Cpu, Schedule::Wavefront),
    (RendererKind::Gl, Schedule::Megakernel),
    (RendererKind::Wgpu, Schedule::Megakernel),
    (RendererKind::Wgpu, Schedule::Wavefront),
];

/// The placeholder of each scene's features renders (a black image: nothing to hit, nothing
/// to emit); after `take_scene` the same renderer restarts and renders the scene exactly as a
/// renderer created for it, with the same seed.
#[test]
fn a_renderer_compiled_for_a_placeholder_takes_the_scene_and_renders_it_as_a_new_one() {
    for (name, scene) in cases() {
        let (width, height) = (scene.scene.width, scene.scene.height);
        for (kind, schedule) in RUNS {
            let what = format!("{name} on {kind:?}, {schedule:?}");
            let placeholder = Packed::placeholder(scene.features, width, height);
            let mut r = create_scheduled(kind, schedule, placeholder, 7).unwrap_or_else(|e| panic!("{what}: {e}"));
            let warm = frames_bits(r.as_mut(), 1);
            assert!(warm.iter().all(|&b| f32::from_bits(b) == 0.0), "{what}: the placeholder drew something");
            r.take_scene(scene.clone()).unwrap_or_else(|e| panic!("{what}: {e}"));
            assert_eq!(r.frames(), 0, "{what}: not restarted");
            let taken = frames_bits(r.as_mut(), 2);
            let mut fresh = create_scheduled(kind, schedule, scene.clone(), 7).expect("renderer");
            assert!(taken == frames_bits(fresh.as_mut(), 2), "{what}: not the scene's image");
            assert!(taken.iter().any(|&b| f32::from_bits(b) > 0.0), "{what}: a black image proves nothing");
        }
    }
}

/// A scene of another kernel variant or image size is refused, and the renderer goes on
/// rendering the scene it had, as it did.
#[test]
fn a_scene_of_another_kernel_or_size_is_refused_and_changes_nothing() {
    let cornell = packed(&scene::cornell_box(), 16);
    let other_kernel = packed(&scene::metal_rough_spheres(), 16);
    let other_size = packed(&scene::cornell_box(), 12);
    for (kind, schedule) in RUNS {
        let what = format!("{kind:?}, {schedule:?}");
        let mut r = create_scheduled(kind, schedule, cornell.clone(), 7).unwrap_or_else(|e| panic!("{what}: {e}"));
        let before = frames_bits(r.as_mut(), 1);
        let kernel = r.take_scene(other_kernel.clone()).expect_err("another kernel's scene taken").to_string();
        assert!(kernel.contains("kernel"), "{what}: {kernel}");
        let size = r.take_scene(other_size.clone()).expect_err("another size taken").to_string();
        assert!(size.contains("16x16") && size.contains("12x12"), "{what}: {size}");
        r.restart().expect("restart");
        assert!(frames_bits(r.as_mut(), 1) == before, "{what}: a refused scene changed the image");
    }
}

/// GL's warm-up (the page's WebGL2 draws it before the decode: a 1x1 preview handed to the
/// driver without an error query) leaves nothing behind: the renderer then takes the scene and
/// renders it as a new one, its preview included.
#[test]
fn gl_warmed_up_on_a_placeholder_renders_the_scene_taken_as_a_new_one() {
    use tracer::backend::gl::GlRenderer;
    let scene = packed(&scene::cornell_box(), 16);
    let placeholder = Packed::placeholder(scene.features, 16, 16);
    let mut warmed = GlRenderer::headless(placeholder, 7).expect("GL renderer");
    warmed.warm_up().expect("warm-up");
    warmed.take_scene(scene.clone()).expect("takes the scene");
    let mut fresh = GlRenderer::headless(scene, 7).expect("GL renderer");
    warmed.render_preview(4, 4).expect("preview");
    fresh.render_preview(4, 4).expect("preview");
    let bits = |r: &GlRenderer| -> Vec<u32> {
        r.read_preview().expect("preview").iter().flat_map(|p| p.to_array()).map(f32::to_bits).collect()
    };
    assert!(bits(&warmed) == bits(&fresh), "not the scene's preview");
    assert!(frames_bits(&mut warmed, 2) == frames_bits(&mut fresh, 2), "not the scene's image");
}
