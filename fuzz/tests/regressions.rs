//! The fuzzers' findings, each refused with a clear error now (the inputs are in
//! `fuzz/regressions/`, which the smoke run and every fuzzing run also replay).

use std::path::Path;
use std::sync::mpsc;
use std::time::Duration;

use lightport_fuzz::{regressions, seeds, Target};
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::Renderer;
use tracer::scene::{self, LoadOptions, SceneError};

fn regression(target: Target, name: &str) -> Vec<u8> {
    std::fs::read(seeds::regressions_dir(target).join(name)).expect("the committed regression input")
}

/// A committed bundle carries the fingerprint of the kernel it was written by; every kernel
/// change alters it. The input is replayed against this build's kernel by rewriting that field
/// (the rest of the bundle, the finding itself, is unchanged).
fn for_this_kernel(mut bytes: Vec<u8>) -> Vec<u8> {
    if let Err(tracer::bundle::BundleError::OtherKernel { found, expected }) = tracer::bundle::decode(&bytes) {
        if let Some(i) = bytes.windows(4).position(|w| w == found.to_le_bytes()) {
            bytes[i..i + 4].copy_from_slice(&expected.to_le_bytes());
        }
    }
    bytes
}

/// A bundle whose `scene_scale` is NaN decoded, and the kernel then never finished a frame
/// (the CPU renderer hung; the page would have hung the GPU).
#[test]
fn a_bundle_with_a_nan_uniform_is_refused() {
    let input = for_this_kernel(regression(Target::Bundle, "nan-scene-scale-hang.lpb"));
    let err = tracer::bundle::decode(&input).unwrap_err();
    assert!(err.to_string().contains("scene_scale is NaN"), "{err}");
}

/// The committed bundles are the generated ones (`lightport_fuzz::regressions`), up to the
/// kernel fingerprint: a format change, or a change of the scenes they are made from, needs
/// them rewritten (`cargo run -p lightport-fuzz -- regressions`).
#[test]
fn the_committed_regression_bundles_are_the_generated_ones() {
    for (name, bytes) in regressions::generated() {
        let committed = for_this_kernel(regression(Target::Bundle, name));
        assert!(
            committed == bytes,
            "fuzz/regressions/bundle/{name} is stale: rewrite it with `cargo run -p lightport-fuzz -- regressions`"
        );
    }
}

/// Renders `packed` (one sample) on another thread; `None` if the frame takes over 60 s.
fn render_within_a_minute(packed: tracer::pack::Packed) -> Option<tracer::backend::Image> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut renderer = CpuRenderer::new(packed, 1);
        renderer.render_frame().expect("frame");
        let _ = tx.send(renderer.image().expect("image"));
    });
    rx.recv_timeout(Duration::from_secs(60)).ok()
}

/// A leaf's child entry replaced by 0 (the second bundle hang of the long run: one word of
/// the Cornell box's `node_children`). Entry 0 marks an unused slot (it is the root, nobody's
/// child), but this slot kept the leaf's box: every ray through it restarted traversal at the
/// root, for ever. Traversal now never follows entry 0; the bundle is valid and renders.
#[test]
fn a_bundle_with_a_child_entry_of_zero_renders() {
    let input = for_this_kernel(regression(Target::Bundle, "leaf-entry-zero-hang.lpb"));
    let packed = tracer::bundle::decode(&input).expect("entry 0 is an unused slot, whatever its box");
    let image = render_within_a_minute(packed).expect("the frame ended (traversal skipped entry 0)");
    assert!(image.mean().max_element() > 0.0, "the Cornell box is lit");
}

/// A texture starting at texel 2^32 - 16 decoded, and the kernel's texel index overflowed
/// (`texel_word`, a panic in debug builds, a wrapped read on a GPU); now refused at decode.
#[test]
fn a_bundle_texture_beyond_its_texels_is_refused() {
    let input = for_this_kernel(regression(Target::Bundle, "texture-first-texel-overflow.lpb"));
    let err = tracer::bundle::decode(&input).unwrap_err();
    assert!(err.to_string().contains("texture 0: 4 x 4 texels from texel 4294967280, of 32"), "{err}");
}

/// Every index the kernel follows is checked at decode: one bad index of each kind, in a
/// bundle that otherwise decodes, is refused with what it is.
#[test]
fn every_index_the_kernel_follows_is_checked_at_decode() {
    use glam::Vec4;
    use kernel_dsl::Texels;
    let cornell = tracer::bundle::decode(&regressions::cornell()).expect("the Cornell box decodes");
    type Edit = fn(&mut tracer::pack::Packed);
    let edits: [(&str, Edit, &str); 8] = [
        (
            "a child pointing back at its parent",
            |p| {
                let mut c = p.scene.node_children.as_slice().to_vec();
                let last = c.len() - 1;
                c[last].x = (last as u32) << 8;
                p.scene.node_children = Texels::new(c);
            },
            "children come after their parent",
        ),
        (
            "a node with two parents",
            |p| {
                let mut c = p.scene.node_children.as_slice().to_vec();
                let child =
                    (0..4).map(|s| c[0][s]).find(|e| e & 255 == 0 && *e != 0).expect("the root has a child node");
                let slot = (0..4).find(|&s| c[0][s] != child).unwrap();
                c[0][slot] = child;
                p.scene.node_children = Texels::new(c);
            },
            "is the child of two nodes",
        ),
        (
            "a leaf beyond the triangles",
            |p| {
                let mut c = p.scene.node_children.as_slice().to_vec();
                let n = p.triangle_count as u32;
                let (node, slot) =
                    (0..c.len()).flat_map(|i| (0..4).map(move |s| (i, s))).find(|&(i, s)| c[i][s] & 255 > 0).unwrap();
                c[node][slot] = (n << 8) | 1;
                p.scene.node_children = Texels::new(c);
            },
            "a leaf of triangles",
        ),
        (
            "overlapping leaves",
            |p| {
                let mut c = p.scene.node_children.as_slice().to_vec();
                let leaves: Vec<(usize, usize)> = (0..c.len())
                    .flat_map(|i| (0..4).map(move |s| (i, s)))
                    .filter(|&(i, s)| c[i][s] & 255 > 0)
                    .collect();
                let (a, b) = (leaves[0], leaves[1]);
                c[b.0][b.1] = c[a.0][a.1];
                p.scene.node_children = Texels::new(c);
            },
            "overlap",
        ),
        (
            "a triangle's material out of range",
            |p| {
                let mut t = p.scene.triangles.as_slice().to_vec();
                t[0].w = 3.0e9;
                p.scene.triangles = Texels::new(t);
            },
            "triangle 0: material 3000000000",
        ),
        (
            "a triangle's light out of range",
            |p| {
                let mut t = p.scene.triangles.as_slice().to_vec();
                t[1].w = p.light_count as f32;
                p.scene.triangles = Texels::new(t);
            },
            "triangle 0: light",
        ),
        (
            "a light's alias out of range",
            |p| {
                let mut l = p.scene.lights.as_slice().to_vec();
                l[0].y = -1.0;
                p.scene.lights = Texels::new(l);
            },
            "light 0: alias -1",
        ),
        (
            "a material texture that does not exist",
            |p| {
                let mut m: Vec<Vec4> = p.scene.materials.as_slice().to_vec();
                m[0].w = 0.0;
                p.scene.materials = Texels::new(m);
            },
            "material 0: texture 0 / -1 of 0",
        ),
    ];
    for (what, edit, expected) in edits {
        let mut p = cornell.clone();
        edit(&mut p);
        let err = tracer::bundle::decode(&tracer::bundle::encode(&p)).map(drop).unwrap_err();
        assert!(err.to_string().contains(expected), "{what}: {err}");
    }
}

/// A relative OBJ index reaching before the first normal (`f 1//-5` with one `vn`) wrapped
/// to a huge index in tobj, which then overflowed multiplying it (a panic in debug builds,
/// caught as "the OBJ parser failed unexpectedly"); now refused before tobj runs, naming the
/// line. (So is a positive index tobj would overflow on.)
#[test]
fn obj_face_indices_tobj_would_overflow_on_are_refused() {
    let input = regression(Target::Obj, "relative-normal-index-overflow.obj");
    let read = |p: &Path| -> Result<Vec<u8>, SceneError> {
        Err(SceneError::Io { path: p.to_owned(), error: std::io::ErrorKind::NotFound.into() })
    };
    let err = scene::load_obj_slice(&input, "n.obj", &read, &LoadOptions::default()).unwrap_err();
    assert!(
        err.to_string().contains("line 5: relative normal index -5 reaches before the first `vn` (1 so far)"),
        "{err}"
    );
    let positive = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//6148914691236517206\n";
    let err = scene::load_obj_slice(positive, "p.obj", &read, &LoadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("line 5: normal index 6148914691236517206 is above"), "{err}");
}

/// A 69-byte HDR declaring 8192 x 8192 texels: the decoder allocated the image (1.5 GiB with
/// the conversions, seconds) before finding the data missing. Now refused from the header.
#[test]
fn a_sky_declaring_more_than_its_bytes_can_hold_is_refused() {
    let input = regression(Target::Sky, "unbacked-8192x8192.hdr");
    let err = scene::load_sky_slice(&input, scene::SkyFormat::Hdr, "sky", 1.0, 0.0).unwrap_err();
    assert!(
        err.to_string().contains(&format!("declares 8192 x 8192 texels, more than its {} bytes", input.len())),
        "{err}"
    );
}

/// JSON without the structure the glTF mutations look for (an empty root array, scalars, an
/// empty object) is mutated without panicking. `[]` made "duplicate an array element" index the
/// empty root array: a panic in the driver, outside any input, which the driver's panic hook
/// silenced; the gltf run ended without a report (the "silent end" of the first long run).
#[test]
fn gltf_mutations_of_degenerate_json_do_not_panic() {
    let mut rng = lightport_fuzz::rng::Rng::new(3);
    for json in [&b"[]"[..], b"{}", b"0", b"\"x\"", b"[[]]", b"null"] {
        for _ in 0..300 {
            let out = lightport_fuzz::mutate::gltf(json, &mut rng).expect("JSON in, JSON out");
            assert!(serde_json::from_slice::<serde_json::Value>(&out).is_ok(), "still JSON");
        }
    }
}

/// A 727-byte tiled EXR (8 x 4 texels) declaring tiles of 16777024 x 64 texels: the decoder
/// allocated a tile (1.9 GiB, 3.7 s; the second campaign's sky finding). Refused from the header.
#[test]
fn a_sky_with_tiles_larger_than_its_bytes_can_hold_is_refused() {
    let input = regression(Target::Sky, "tiled-exr-huge-tiles.exr");
    let err = scene::load_sky_slice(&input, scene::SkyFormat::Exr, "sky", 1.0, 0.0).unwrap_err();
    assert!(err.to_string().contains("declares tiles of 16777024 x 64 texels"), "{err}");
}

/// `Kd 0.5 0` in an MTL made tobj panic (caught, but reported as "the OBJ parser failed
/// unexpectedly"); now the line is named.
#[test]
fn an_mtl_colour_with_two_values_is_refused_with_its_line() {
    let input = regression(Target::Obj, "kd-two-values-panic.obj");
    let text = String::from_utf8(input).unwrap();
    let (obj, mtl) = text.split_once("#---mtl---\n").unwrap();
    let read = |p: &Path| -> Result<Vec<u8>, SceneError> {
        match p.to_str() {
            Some("a.mtl") => Ok(mtl.as_bytes().to_vec()),
            _ => Err(SceneError::Io { path: p.to_owned(), error: std::io::ErrorKind::NotFound.into() }),
        }
    };
    let err = scene::load_obj_slice(obj.as_bytes(), "kd.obj", &read, &LoadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("line 2: Kd needs three values (r g b), found 2"), "{err}");
}

/// Loads `input` as glTF on another thread; `None` if that takes over a minute.
fn load_gltf_within_a_minute(input: Vec<u8>) -> Option<Result<usize, SceneError>> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let loaded = scene::load_gltf_slice(&input, None, &LoadOptions::default()).map(|s| s.triangles.len());
        let _ = tx.send(loaded);
    });
    rx.recv_timeout(Duration::from_secs(60)).ok()
}

/// The fuzz campaign's hang (issue 31): accessors without a buffer view are zero-filled, as the
/// specification says, so 65,535 (or 3,000,000) positions all sit at the origin: 21,845
/// triangles of zero area, on which the BVH build was quadratic (5.6 s; the 3,000,000 variant
/// ran for over 300 s). Zero-area triangles are dropped now, and a scene of nothing else is
/// refused, saying so.
#[test]
fn a_gltf_of_zero_filled_accessors_is_refused_at_once() {
    for (name, triangles) in
        [("zero-filled-accessors-hang.gltf", 21_845), ("zero-filled-accessors-3m-hang.gltf", 1_000_000)]
    {
        let loaded = load_gltf_within_a_minute(regression(Target::Gltf, name)).expect("loading ended");
        let err = loaded.expect_err("no triangle can be hit");
        assert!(err.to_string().contains(&format!("all {triangles} of its triangles have zero area")), "{name}: {err}");
    }
}

/// Zero-area faces among real ones are dropped with one warning that counts them.
#[test]
fn zero_area_triangles_are_dropped_with_one_warning() {
    let mut obj = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\n");
    for _ in 0..10_000 {
        obj.push_str("f 1 2 4\nf 1 1 1\n"); // collinear, then coincident
    }
    let read = |p: &Path| -> Result<Vec<u8>, SceneError> {
        Err(SceneError::Io { path: p.to_owned(), error: std::io::ErrorKind::NotFound.into() })
    };
    let scene = scene::load_obj_slice(obj.as_bytes(), "z.obj", &read, &LoadOptions::default()).expect("one face");
    assert_eq!(scene.triangles.len(), 1);
    let about: Vec<_> = scene.warnings.iter().filter(|w| w.contains("zero area")).collect();
    assert_eq!(about.len(), 1, "{:?}", scene.warnings);
    assert!(about[0].starts_with("20000 triangle(s) of zero area"), "{}", about[0]);
    let only_degenerate = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n";
    let err = scene::load_obj_slice(only_degenerate.as_bytes(), "z.obj", &read, &LoadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("all 1 of its triangles have zero area"), "{err}");
}
