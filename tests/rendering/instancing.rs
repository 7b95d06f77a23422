//! Two levels render what one level renders: the same triangles placed by instances (as
//! `tracer::scene::instanced_shapes` places them, mirrored and non-uniformly scaled ones
//! included) and baked into one triangle list give the same image, statistically, with every
//! strategy. (Each GPU runtime against the CPU on the instanced scene: the agreement suite.)

use crate::common::agreement::{assert_runs_agree, packed, run, STRATEGIES};
use tracer::backend::cpu::CpuRenderer;

#[test]
fn instanced_and_flattened_render_the_same_image() {
    let scene = tracer::scene::instanced_shapes(5);
    let mut flat = scene.clone();
    flat.bake_instances().expect("bakes");
    let size = 32;
    for strategy in STRATEGIES {
        let (two, one) = (packed(&scene, strategy, size, 4), packed(&flat, strategy, size, 4));
        assert!(two.features.instances && !one.features.instances);
        let a = run(&mut CpuRenderer::new(two, 1), size, 256);
        let b = run(&mut CpuRenderer::new(one, 2), size, 256);
        let z = assert_runs_agree(&format!("instanced shapes {strategy:?}"), ["two levels", "flattened"], &a, &b);
        eprintln!(
            "instanced shapes {strategy:?}: max z {z:.2}; two levels {:.2} s, flattened {:.2} s",
            a.seconds, b.seconds
        );
    }
}

/// The stress field: 10,000 placements of a 10,240-triangle sphere (over 100 million triangles
/// placed) pack into a few megabytes and render finite, lit samples.
#[test]
fn a_hundred_million_placed_triangles_render() {
    let scene = tracer::scene::instanced_field(100);
    assert!(scene.placed_triangle_count() >= 100_000_000, "{}", scene.placed_triangle_count());
    let p = packed(&scene, tracer::kernel::Strategy::Mis, 16, 4);
    let geometry = ["triangles", "shading", "nodes", "node_children"];
    let arrays = p.arrays(16384).expect("fits in textures");
    let bytes: usize = arrays.iter().filter(|a| geometry.contains(&a.name)).map(|a| a.texels * a.texel_bytes).sum();
    assert!(bytes < 8 << 20, "{bytes} bytes of geometry");
    // Flattened, it would not fit: refused with a clear error, the scene left as it was.
    let mut flat = scene.clone();
    let e = flat.bake_instances().unwrap_err();
    assert!(e.to_string().contains("keep its instances"), "{e}");
    assert_eq!(flat.instances.len(), scene.instances.len());
    let r = run(&mut CpuRenderer::new(p, 1), 16, 2);
    assert_eq!(r.rejected, 0);
    let mean = r.per_frame.iter().flatten().map(|m| m.y).sum::<f64>();
    assert!(mean > 0.0, "a black image");
}
