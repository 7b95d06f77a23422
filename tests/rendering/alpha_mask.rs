//! Alpha cut-outs (glTF `alphaMode` MASK, `Features::alpha_mask`, `tracer::kernel::alpha_mask::is_hole`)
//! on the CPU: camera rays see through holes pixel by pixel, shadows fall only under opaque
//! texels, bounces pass through holes, emitters emit only where they are opaque, the kernel
//! and data are unchanged for scenes without masks, bundles carry the layout, and loading
//! (MASK, BLEND, OPAQUE, cutoffs out of range).

use crate::common;

use glam::{Vec2, Vec3, Vec4Swizzles};
use tracer::kernel::camera::camera_ray;
use tracer::kernel::integrator::render_sample;
use tracer::kernel::traverse::occluded;
use tracer::kernel::Strategy;
use tracer::pack::Packed;
use tracer::scene::{alpha_checker, Camera, Material, PointLight, Scene, Texture, Triangle, Wrap};

/// The two triangles of quad `q` (counter-clockwise from the front) with texture coordinates
/// q0 (0, 1), q1 (1, 1), q2 (1, 0), q3 (0, 0).
fn quad(q: [Vec3; 4], material: u32) -> Vec<Triangle> {
    let uv = [Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)];
    [[0, 1, 2], [0, 2, 3]]
        .iter()
        .map(|&[a, b, c]| {
            let positions = [q[a], q[b], q[c]];
            let n = (positions[1] - positions[0]).cross(positions[2] - positions[0]).normalize();
            Triangle {
                positions,
                normals: [n; 3],
                uvs: [uv[a], uv[b], uv[c]],
                uvs1: Default::default(),
                tangents: Default::default(),
                material,
            }
        })
        .collect()
}

/// A material cut out by texture 0's alpha at `cutoff` (None: opaque).
fn masked(base: Vec3, cutoff: Option<f32>) -> Material {
    Material { base_color_texture: Some(0), alpha_cutoff: cutoff, ..Material::diffuse("masked", base) }
}

/// A texture of one texel of alpha `a` (white).
fn uniform_alpha(a: u8) -> Texture {
    Texture {
        width: 1,
        height: 1,
        texels: vec![0x00ff_ffff | (a as u32) << 24].into(),
        wrap_s: Wrap::Repeat,
        wrap_t: Wrap::Repeat,
    }
}

fn pack(scene: &Scene, size: u32, strategy: Strategy, max_depth: u32) -> Packed {
    scene.validate().expect("valid scene");
    common::agreement::packed(scene, strategy, size, max_depth)
}

/// Per pixel, the mean of `frames` samples (channel mean), and whether every sample was finite.
fn pixel_means(packed: &Packed, frames: u32) -> Vec<f64> {
    let mut k = packed.scene.clone();
    let mut sums = vec![0.0f64; (k.width * k.height) as usize];
    for f in 0..frames {
        k.frame_seed = f.wrapping_mul(0x9e37_79b9).wrapping_add(7);
        k.frame_index = f;
        for y in 0..k.height {
            for x in 0..k.width {
                let s = render_sample(&k, x, y);
                assert_eq!(s.w, 1.0, "pixel ({x}, {y}): a non-finite sample");
                sums[(y * k.width + x) as usize] += s.xyz().dot(Vec3::splat(1.0 / 3.0)) as f64;
            }
        }
    }
    sums.iter().map(|s| s / frames as f64).collect()
}

/// Where the rays through pixel (x, y)'s four corners meet the plane `axis = value`.
fn corner_points(packed: &Packed, x: u32, y: u32, axis: usize, value: f32) -> [Vec3; 4] {
    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)].map(|(dx, dy)| {
        let ray = camera_ray(&packed.scene, Vec2::new(x as f32 + dx, y as f32 + dy), Vec2::splat(0.5));
        let t = (value - ray.origin[axis]) / ray.dir[axis];
        ray.origin + ray.dir * t
    })
}

/// The checker cell (of `n` per side) of a point of the unit square `uv`, or None on its border.
fn cell(uv: Vec2, n: u32) -> Option<(i32, i32)> {
    let c = uv * n as f32;
    let near_edge = |v: f32| (v - v.round()).abs() < 1e-3;
    (!near_edge(c.x) && !near_edge(c.y)).then(|| (c.x.floor() as i32, c.y.floor() as i32))
}

/// Whether checker cell (cx, cy) of `alpha_checker` is a hole.
fn is_hole_cell((cx, cy): (i32, i32)) -> bool {
    (cx + cy) % 2 != 0
}

// ---------------------------------------------------------------------------------------------
// Camera rays.

/// A 2 x 2 m quad cut by a 4 x 4 alpha checker at z = 0 in front of an emitting wall (radiance
/// 1) at z = -1; the camera at z = 4 sees exactly the quad.
fn screen_before_emitter(cutoff: Option<f32>) -> Scene {
    let mut triangles = quad(
        [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)],
        0,
    );
    let w = 4.0;
    triangles.extend(quad(
        [Vec3::new(-w, -w, -1.0), Vec3::new(w, -w, -1.0), Vec3::new(w, w, -1.0), Vec3::new(-w, w, -1.0)],
        1,
    ));
    Scene {
        triangles,
        materials: vec![masked(Vec3::splat(0.5), cutoff), Material::emissive("wall", Vec3::ZERO, Vec3::ONE)],
        textures: vec![alpha_checker(4)],
        camera: Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y, 2.0 * 0.25f32.atan()),
        ..Scene::default()
    }
}

#[test]
fn camera_rays_see_the_backdrop_exactly_through_the_holes() {
    let size = 48;
    for (cutoff, holes_expected) in [(Some(0.5), true), (None, false)] {
        let packed = pack(&screen_before_emitter(cutoff), size, Strategy::Bsdf, 1);
        assert_eq!(packed.features.alpha_mask, holes_expected);
        let means = pixel_means(&packed, 4);
        let (mut through, mut blocked) = (0, 0);
        for y in 0..size {
            for x in 0..size {
                let corners = corner_points(&packed, x, y, 2, 0.0);
                // u = (X + 1) / 2, v = (1 - Y) / 2 on the quad.
                let cells: Vec<Option<(i32, i32)>> =
                    corners.iter().map(|p| cell(Vec2::new(0.5 * (p.x + 1.0), 0.5 * (1.0 - p.y)), 4)).collect();
                let Some(c) = cells[0] else { continue };
                if cells.iter().any(|&o| o != Some(c)) {
                    continue; // the pixel straddles a cell's edge
                }
                let m = means[(y * size + x) as usize];
                let expected = if holes_expected && is_hole_cell(c) { 1.0 } else { 0.0 };
                assert!((m - expected).abs() < 1e-6, "cutoff {cutoff:?}: pixel ({x}, {y}) in cell {c:?}: {m}");
                if expected > 0.0 {
                    through += 1;
                } else {
                    blocked += 1;
                }
            }
        }
        println!("cutoff {cutoff:?}: {through} pixels see the emitter through holes, {blocked} the quad");
        assert!(blocked > 500 && (through > 500) == holes_expected, "{through} / {blocked}");
    }
}

// ---------------------------------------------------------------------------------------------
// Shadow rays.

/// A white floor at y = 0, a 1 x 1 m occluder cut by a 4 x 4 alpha checker at y = 1.5 and a
/// point light at (0, 3, 0): the occluder's shadow on the floor is the checker scaled by 2.
/// The camera (at y = 1, below the occluder, 90°) sees the floor's [-1, 1]² exactly.
fn occluder_over_floor() -> Scene {
    let f = 3.0;
    let mut triangles =
        quad([Vec3::new(-f, 0.0, f), Vec3::new(f, 0.0, f), Vec3::new(f, 0.0, -f), Vec3::new(-f, 0.0, -f)], 0);
    triangles.extend(quad(
        [Vec3::new(-0.5, 1.5, 0.5), Vec3::new(0.5, 1.5, 0.5), Vec3::new(0.5, 1.5, -0.5), Vec3::new(-0.5, 1.5, -0.5)],
        1,
    ));
    Scene {
        triangles,
        materials: vec![Material::diffuse("floor", Vec3::splat(0.5)), masked(Vec3::splat(0.5), Some(0.5))],
        textures: vec![alpha_checker(4)],
        point_lights: vec![PointLight { position: Vec3::new(0.0, 3.0, 0.0), intensity: Vec3::splat(5.0) }],
        camera: Camera::look_at(Vec3::new(0.0, 1.0, 0.0), Vec3::ZERO, Vec3::NEG_Z, 90f32.to_radians()),
        ..Scene::default()
    }
}

/// The occluder's checker cell above floor point `p` as seen from the light (None: outside
/// the occluder or on a cell's edge), in the occluder quad's uv (u along +X, v along +Z).
fn shadow_cell(p: Vec3) -> Option<Option<(i32, i32)>> {
    let q = p * 0.5; // where the ray to (0, 3, 0) crosses y = 1.5
    if q.x.abs() >= 0.5 || q.z.abs() >= 0.5 {
        let outside = q.x.abs() > 0.5 + 1e-3 || q.z.abs() > 0.5 + 1e-3;
        return outside.then_some(None);
    }
    cell(Vec2::new(q.x + 0.5, q.z + 0.5), 4).map(Some)
}

#[test]
fn shadows_fall_only_under_opaque_texels() {
    let scene = occluder_over_floor();
    let size = 48;
    for strategy in [Strategy::Nee, Strategy::Mis] {
        let packed = pack(&scene, size, strategy, 2);
        assert!(packed.features.alpha_mask);
        let means = pixel_means(&packed, 2);
        let (mut lit, mut dark) = (0, 0);
        for y in 0..size {
            for x in 0..size {
                let corners = corner_points(&packed, x, y, 1, 0.0);
                let cells: Vec<_> = corners.iter().map(|&p| shadow_cell(p)).collect();
                let Some(c) = cells[0] else { continue };
                if cells.iter().any(|&o| o != Some(c)) {
                    continue;
                }
                let m = means[(y * size + x) as usize];
                if c.is_none_or(is_hole_cell) {
                    assert!(
                        m > 0.05,
                        "{strategy:?}: pixel ({x}, {y}) under a hole or beside the occluder is dark: {m}"
                    );
                    lit += 1;
                } else {
                    assert_eq!(m, 0.0, "{strategy:?}: pixel ({x}, {y}) under opaque cell {c:?} is lit");
                    dark += 1;
                }
            }
        }
        println!("{strategy:?}: {lit} floor pixels lit, {dark} in shadow");
        assert!(lit > 400 && dark > 300, "{lit} / {dark}");
    }
    // The shadow-ray test itself, at floor points: blocked exactly under opaque texels.
    let packed = pack(&scene, 4, Strategy::Nee, 2);
    let mut r = common::TestRng::new(3);
    let (mut checked, mut blocked) = (0, 0);
    for _ in 0..20_000 {
        let p = Vec3::new(r.range(-1.2, 1.2), 1e-4, r.range(-1.2, 1.2));
        let Some(c) = shadow_cell(p) else { continue };
        let to_light = Vec3::new(0.0, 3.0, 0.0) - p;
        let hit = occluded(&packed.scene, p, to_light.normalize(), to_light.length() * 0.9999);
        assert_eq!(hit, c.is_some_and(|c| !is_hole_cell(c)), "floor point {p}, cell {c:?}");
        checked += 1;
        blocked += hit as u32;
    }
    assert!(blocked > 2000 && checked - blocked > 2000, "{blocked} of {checked}");
}

// ---------------------------------------------------------------------------------------------
// Bounces.

/// A white floor, at y = 1 a 10 x 10 m occluder of texture 0 (one texel of `alpha`, cutoff 0.5;
/// `None`: no occluder) and at y = 2 an emitting ceiling facing down (radiance 1). The camera
/// at y = 0.5 looks down at the floor, lit only through the occluder.
fn floor_under_ceiling(alpha: Option<u8>) -> Scene {
    let f = 5.0;
    let at = |y: f32| [Vec3::new(-f, y, f), Vec3::new(f, y, f), Vec3::new(f, y, -f), Vec3::new(-f, y, -f)];
    let mut triangles = quad(at(0.0), 0);
    let [a, b, c, d] = at(2.0);
    triangles.extend(quad([d, c, b, a], 1));
    if alpha.is_some() {
        triangles.extend(quad(at(1.0), 2));
    }
    Scene {
        triangles,
        materials: vec![
            Material::diffuse("floor", Vec3::splat(0.5)),
            Material::emissive("ceiling", Vec3::ZERO, Vec3::ONE),
            masked(Vec3::splat(0.5), Some(0.5)),
        ],
        textures: vec![uniform_alpha(alpha.unwrap_or(255))],
        camera: Camera::look_at(Vec3::new(0.0, 0.5, 0.0), Vec3::ZERO, Vec3::NEG_Z, 60f32.to_radians()),
        ..Scene::default()
    }
}

#[test]
fn bounces_pass_through_holes() {
    let size = 16;
    let mean = |alpha: Option<u8>, strategy: Strategy| {
        let means = pixel_means(&pack(&floor_under_ceiling(alpha), size, strategy, 2), 64);
        common::mean_variance(means.iter().copied())
    };
    for strategy in [Strategy::Bsdf, Strategy::Mis] {
        let (open, open_var, n) = mean(None, strategy);
        let (holes, holes_var, _) = mean(Some(0), strategy);
        let (opaque, _, _) = mean(Some(255), strategy);
        let sigma = ((open_var + holes_var) / n as f64).sqrt();
        println!("{strategy:?}: no occluder {open:.4}, all holes {holes:.4} (σ {sigma:.1e}), opaque {opaque:.4}");
        // Floor radiance under an infinite-ish emitter: albedo x 1 (less the plane's finite edge).
        assert!(open > 0.3, "{open}");
        assert!((open - holes).abs() < 5.0 * sigma + 1e-9, "{strategy:?}: {open} vs {holes}");
        assert_eq!(opaque, 0.0, "{strategy:?}: an opaque occluder lets light through");
    }
}

// ---------------------------------------------------------------------------------------------
// Masked emitters: light samples in holes emit nothing, as BSDF rays see nothing there.

#[test]
fn a_masked_emitter_emits_only_where_opaque() {
    // The emitting wall of the camera test, masked itself (cutoff 0.5 on the 4 x 4 checker),
    // lighting a floor: NEE, BSDF sampling and MIS must agree, at half the unmasked light.
    let mut r = Vec::new();
    for masked_light in [true, false] {
        let f = 2.0;
        let mut triangles =
            quad([Vec3::new(-f, 0.0, f), Vec3::new(f, 0.0, f), Vec3::new(f, 0.0, -f), Vec3::new(-f, 0.0, -f)], 0);
        let l = 0.5;
        triangles.extend(quad(
            [Vec3::new(-l, 1.0, -l), Vec3::new(l, 1.0, -l), Vec3::new(l, 1.0, l), Vec3::new(-l, 1.0, l)],
            1,
        ));
        let light = Material {
            base_color_texture: Some(0),
            alpha_cutoff: masked_light.then_some(0.5),
            ..Material::emissive("light", Vec3::ZERO, Vec3::splat(4.0))
        };
        let scene = Scene {
            triangles,
            materials: vec![Material::diffuse("floor", Vec3::splat(0.5)), light],
            textures: vec![alpha_checker(4)],
            camera: Camera::look_at(Vec3::new(0.0, 0.9, 0.0), Vec3::ZERO, Vec3::NEG_Z, 60f32.to_radians()),
            ..Scene::default()
        };
        for strategy in Strategy::ALL {
            let means = pixel_means(&pack(&scene, 16, strategy, 2), 128);
            let (m, var, n) = common::mean_variance(means.iter().copied());
            println!("masked light {masked_light}, {strategy:?}: {m:.4} ± {:.4}", (var / n as f64).sqrt());
            r.push((m, var / n as f64));
        }
    }
    for i in 0..3 {
        for j in 0..3 {
            let ((a, va), (b, vb)) = (r[i], r[j]);
            assert!((a - b).abs() < 5.0 * (va + vb).sqrt(), "masked light: strategies {i} and {j}: {a} vs {b}");
        }
    }
    // Half the light's area is holes: about half the light (not exactly: the checker's cells
    // are not seen alike from every floor point).
    let ratio = r[2].0 / r[5].0;
    assert!(ratio > 0.35 && ratio < 0.65, "masked / unmasked light: {ratio}");
}

// ---------------------------------------------------------------------------------------------
// Specialisation and data.

#[test]
fn only_masked_scenes_carry_the_alpha_test() {
    use lightport_codegen::Target;
    let masked_scene = screen_before_emitter(Some(0.5));
    // The same scene opaque, and masked with a factor that always passes and no texture: no test.
    let opaque = screen_before_emitter(None);
    let mut passing = screen_before_emitter(Some(0.5));
    passing.materials[0].base_color_texture = None;
    passing.materials[0].alpha = 0.75;
    let mut failing = passing.clone();
    failing.materials[0].alpha = 0.25;
    let mut storage_buffers = Vec::new();
    for (name, scene, on) in [
        ("masked", &masked_scene, true),
        ("opaque", &opaque, false),
        ("passing factor", &passing, false),
        ("failing factor", &failing, true),
    ] {
        let packed = pack(scene, 4, Strategy::Mis, 4);
        assert_eq!(packed.features.alpha_mask, on, "{name}");
        let k = &packed.scene;
        assert_eq!(k.materials.len(), scene.materials.len() * if on { 3 } else { 2 }, "{name}");
        let flags: Vec<f32> = k.triangles.as_slice().chunks(3).map(|t| t[2].w).collect();
        assert_eq!(flags.iter().filter(|&&f| f == 1.0).count(), if on { 2 } else { 0 }, "{name}: {flags:?}");
        assert!(flags.iter().all(|&f| f == 0.0 || f == 1.0));
        for target in [Target::GlslEs300, Target::Wgsl] {
            let source = tracer::kernel::path_tracer_shader(&packed.features, target).unwrap().source;
            for name in ["is_hole", "alpha_mask_first"] {
                assert_eq!(source.contains(name), on, "{target:?}: {name} present: {on}");
            }
            if target == Target::Wgsl {
                storage_buffers.push(source.matches("var<storage").count());
            }
        }
    }
    // A factor below the cutoff without a texture: the whole quad is a hole.
    let packed = pack(&failing, 8, Strategy::Bsdf, 1);
    assert!(pixel_means(&packed, 1).iter().all(|&m| m == 1.0), "the quad must vanish");
    // WebGPU's default is 8 storage buffers per stage: alpha masks add none (the masked and
    // the opaque textured scene; the untextured ones have no texture arrays).
    println!("WGSL storage buffers (masked, opaque, passing factor, failing factor): {storage_buffers:?}");
    assert_eq!(storage_buffers[0], storage_buffers[1]);
}

/// The functions of a generated shader (GLSL or WGSL): name and body, from a header line at
/// column 0 ending in `{` to the `}` that closes it at column 0.
fn shader_functions(source: &str) -> Vec<(String, String)> {
    let mut functions = Vec::new();
    let mut current: Option<(String, String)> = None;
    for line in source.lines() {
        if let Some((name, body)) = current.as_mut() {
            if line == "}" {
                functions.push((std::mem::take(name), std::mem::take(body)));
                current = None;
            } else {
                body.push_str(line);
                body.push('\n');
            }
        } else if !line.starts_with([' ', '/', '#']) && line.ends_with('{') && line.contains('(') {
            let head = &line[..line.find('(').unwrap()];
            let name = head.rsplit(' ').next().unwrap_or(head).to_string();
            current = Some((name, String::new()));
        }
    }
    functions
}

/// Call sites of function `name` in `body` (not those of functions whose names end in it).
fn call_sites(body: &str, name: &str) -> usize {
    let call = format!("{name}(");
    body.match_indices(&call).filter(|(i, _)| !body[..*i].ends_with(|c: char| c.is_alphanumeric() || c == '_')).count()
}

/// How many copies of `callee` a shader compiler that inlines every call (as GPU drivers do)
/// makes inside `root`: its call sites, each multiplied by the copies of its caller.
fn inlined_copies(functions: &[(String, String)], root: &str, callee: &str) -> usize {
    let body = &functions.iter().find(|(n, _)| n == root).unwrap_or_else(|| panic!("no function {root}")).1;
    functions
        .iter()
        .filter(|(n, _)| n != root)
        .map(|(n, _)| match call_sites(body, n) {
            0 => 0,
            sites if n == callee => sites,
            sites => sites * inlined_copies(functions, n, callee),
        })
        .sum()
}

/// The loops of a shader function's body: the text of each, from its head (`while`, `for`,
/// `loop`) to its closing brace, nested loops included.
fn loops_of(body: &str) -> Vec<String> {
    let lines: Vec<&str> = body.lines().collect();
    let mut loops = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let head = line.trim_start();
        if !(head.starts_with("while")
            || head.starts_with("for ")
            || head.starts_with("for(")
            || head.starts_with("loop"))
            || !head.ends_with('{')
        {
            continue;
        }
        let mut depth = 0i32;
        let mut text = String::new();
        for l in &lines[i..] {
            text.push_str(l);
            text.push('\n');
            depth += l.matches('{').count() as i32 - l.matches('}').count() as i32;
            if depth <= 0 {
                break;
            }
        }
        loops.push(text);
    }
    loops
}

/// Whether `text` calls `callee`, directly or through the functions it calls.
fn reaches(functions: &[(String, String)], text: &str, callee: &str) -> bool {
    functions.iter().any(|(n, body)| call_sites(text, n) > 0 && (n == callee || reaches(functions, body, callee)))
}

/// Issue 31: alpha masks cost 1.3-2.6x per sample on the GPU runtimes. Three causes, each held
/// off here in the generated GLSL and WGSL of a masked scene's megakernel:
/// - the hole test (texel fetches) inside a traversal loop: SIMD drivers (llvmpipe,
///   SwiftShader) run it under a lane mask for every node or triangle, masked or not (2.4x
///   per sample on GL with no triangle flagged). No loop that runs the node tests may reach
///   `is_hole`;
/// - shadow rays traversing twice (unmasked triangles, then masked ones): `occluded` holds one
///   traversal loop (`intersect_node` and `intersect_triangle` once each), and the function
///   that runs its hole test is the one that runs the node tests: traversal resumes behind a
///   hole instead of starting again;
/// - for closest hits, a hole test and a loop of its own around traversal on every ray's path
///   (`visible_hit`, or `closest_visible_*`'s one traversal, which cost as much: the code's
///   presence costs llvmpipe, 1.18x per sample with nearly no ray meeting a mask). The path
///   loop (`trace_path`) tests the candidate itself (`in_hole`) and searches again behind a
///   hole in its next iteration: `closest_candidate`, its traversal, does not reach `is_hole`.
///
/// Both in one-level scenes and in two-level ones (`Features::instances`, whose traversal loop
/// walks both levels: the search again behind each hole lasted there longer).
#[test]
fn the_hole_test_stays_out_of_the_traversal_loop_and_traversal_runs_once() {
    use lightport_codegen::Target;
    let packed = pack(&screen_before_emitter(Some(0.5)), 4, Strategy::Mis, 4);
    assert!(packed.features.alpha_mask && !packed.features.instances);
    let two_level = tracer::kernel::Features { instances: true, ..packed.features };
    for (target, features) in
        [Target::GlslEs300, Target::Wgsl].into_iter().flat_map(|t| [(t, packed.features), (t, two_level)])
    {
        let target_features = format!("{target:?}, instances {}", features.instances);
        let source = tracer::kernel::path_tracer_shader(&features, target).unwrap().source;
        let functions = shader_functions(&source);
        let body_of = |name: &str| &functions.iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("no {name}")).1;
        // Closest hits: the path loop passes through holes; its traversal has no hole test.
        let path = body_of("trace_path");
        assert_eq!(call_sites(path, "in_hole"), 1, "{target_features}: the path loop tests its candidate");
        assert_eq!(call_sites(path, "trace_closest"), 0, "{target_features}: no hole test around traversal");
        assert_eq!(inlined_copies(&functions, "closest_candidate", "intersect_node"), 1, "{target_features}");
        assert!(
            !reaches(&functions, body_of("closest_candidate"), "is_hole"),
            "{target_features}: the closest hit's traversal tests holes"
        );
        // Shadow rays: one traversal, which tests the masked candidates it finds.
        {
            let ray = "occluded";
            for callee in ["is_hole", "intersect_node", "intersect_triangle"] {
                assert_eq!(inlined_copies(&functions, ray, callee), 1, "{target_features}: {ray}: copies of {callee}");
            }
            // The function of this ray that calls `is_hole` itself: it calls `intersect_node`
            // itself too, in a loop that does not reach `is_hole`.
            let mut owners = functions
                .iter()
                .filter(|(n, b)| call_sites(b, "is_hole") > 0 && (n == ray || inlined_copies(&functions, ray, n) > 0));
            let (owner, body) = owners.next().unwrap_or_else(|| panic!("{target_features}: {ray}: no hole test"));
            assert!(owners.next().is_none(), "{target_features}: {ray}: one function tests holes");
            assert_eq!(call_sites(body, "intersect_node"), 1, "{target_features}: {ray}: {owner} must traverse itself");
            // Both levels, in two-level scenes: the same function enters placements.
            let enters = call_sites(body, "instance_ray");
            assert_eq!(enters, features.instances as usize, "{target_features}: {ray}: {owner} enters placements");
            let traversal_loops: Vec<String> =
                loops_of(body).into_iter().filter(|l| call_sites(l, "intersect_node") > 0).collect();
            let innermost = traversal_loops.iter().min_by_key(|l| l.len()).expect("a traversal loop");
            assert!(
                !reaches(&functions, innermost, "is_hole"),
                "{target_features}: {ray}: the hole test in {owner}'s traversal loop"
            );
        }
    }
}

/// Bundles carry the feature and its layout, and refuse offsets and flags that do not match.
#[test]
fn bundles_carry_alpha_masks_and_refuse_a_wrong_layout() {
    let packed = pack(&tracer::scene::alpha_masked_screen(), 8, Strategy::Mis, 4);
    let decoded = tracer::bundle::decode(&tracer::bundle::encode(&packed)).expect("round trip");
    assert!(decoded.features.alpha_mask);
    assert_eq!(decoded.scene.has_alpha_mask, 1);
    assert_eq!(decoded.scene.alpha_mask_first, packed.scene.alpha_mask_first);
    assert_eq!(pixel_means(&decoded, 1), pixel_means(&packed, 1), "the same image from the bundle");
    for (what, change) in [
        ("alpha_mask_first", (|p: &mut Packed| p.scene.alpha_mask_first += 1) as fn(&mut Packed)),
        ("has_alpha_mask", |p: &mut Packed| p.scene.has_alpha_mask = 0),
        ("alpha-mask texture", |p: &mut Packed| {
            let first = p.scene.alpha_mask_first as usize;
            let mut texels = p.scene.materials.as_slice().to_vec();
            texels[first + 1].x = 99.0;
            p.scene.materials = texels.into();
        }),
        ("triangle flag", |p: &mut Packed| {
            let mut texels = p.scene.triangles.as_slice().to_vec();
            texels[2].w = 2.0;
            p.scene.triangles = texels.into();
        }),
    ] {
        let mut bad = packed.clone();
        change(&mut bad);
        let err = tracer::bundle::decode(&tracer::bundle::encode(&bad)).expect_err(what);
        assert!(err.to_string().contains("alpha"), "{what}: {err}");
    }
}

#[test]
fn the_generated_scene_is_finite_and_its_holes_show() {
    let scene = tracer::scene::alpha_masked_screen();
    let packed = pack(&scene, 24, Strategy::Mis, 4);
    assert!(packed.features.alpha_mask && packed.features.emissive_triangles);
    let with = pixel_means(&packed, 4);
    let mut opaque = scene.clone();
    opaque.materials.iter_mut().for_each(|m| m.alpha_cutoff = None);
    let without = pixel_means(&pack(&opaque, 24, Strategy::Mis, 4), 4);
    let differ = with.iter().zip(&without).filter(|(a, b)| (*a - *b).abs() > 0.05 * b.max(0.05)).count();
    println!("alpha_masked_screen: {differ} of {} pixels change with the masks", with.len());
    assert!(differ * 5 > with.len(), "{differ} pixels");
}

// ---------------------------------------------------------------------------------------------
// Loading.

/// A glTF of one quad per material of `materials` (JSON objects), side by side along x, with a
/// 2 x 1 base colour texture (texture 0) whose left texel is opaque and right texel a hole.
fn gltf_with_materials(materials: &[&str]) -> Scene {
    let dir = std::env::temp_dir().join(format!("lightport-alpha-{}-{}", std::process::id(), materials.len()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut png = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &[255, 255, 255, 255, 255, 255, 255, 0],
        2,
        1,
        image::ExtendedColorType::Rgba8,
    )
    .unwrap();
    std::fs::write(dir.join("a.png"), png).unwrap();
    let positions: [[f32; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let uvs: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin = Vec::new();
    positions.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    uvs.iter().flatten().for_each(|f| bin.extend(f.to_le_bytes()));
    indices.iter().for_each(|i| bin.extend(i.to_le_bytes()));
    std::fs::write(dir.join("quad.bin"), &bin).unwrap();
    let nodes: Vec<String> =
        (0..materials.len()).map(|i| format!(r#"{{"mesh": {i}, "translation": [{}, 0, 0]}}"#, 2 * i)).collect();
    let meshes: Vec<String> = (0..materials.len())
        .map(|i| format!(r#"{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "indices": 2, "material": {i}}}]}}"#))
        .collect();
    let gltf = format!(
        r#"{{
      "asset": {{"version": "2.0"}},
      "scene": 0, "scenes": [{{"nodes": [{}]}}], "nodes": [{}],
      "meshes": [{}],
      "materials": [{}],
      "textures": [{{"source": 0}}],
      "images": [{{"uri": "a.png"}}],
      "buffers": [{{"uri": "quad.bin", "byteLength": 92}}],
      "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
                      {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
                      {{"buffer": 0, "byteOffset": 80, "byteLength": 12}}],
      "accessors": [
        {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
        {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
        {{"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}}]
    }}"#,
        (0..materials.len()).map(|i| i.to_string()).collect::<Vec<_>>().join(", "),
        nodes.join(", "),
        meshes.join(", "),
        materials.join(", ")
    );
    std::fs::write(dir.join("quads.gltf"), gltf).unwrap();
    let scene = tracer::scene::load(&dir.join("quads.gltf")).expect("the quads load");
    std::fs::remove_dir_all(&dir).ok();
    scene
}

#[test]
fn alpha_modes_and_cutoffs_load() {
    let texture = r#""pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "baseColorFactor": [1, 1, 1, 0.8]}"#;
    let scene = gltf_with_materials(&[
        &format!(r#"{{"name": "opaque", {texture}}}"#),
        &format!(r#"{{"name": "explicit opaque", "alphaMode": "OPAQUE", "alphaCutoff": 0.9, {texture}}}"#),
        &format!(r#"{{"name": "mask", "alphaMode": "MASK", {texture}}}"#),
        &format!(r#"{{"name": "mask 0.3", "alphaMode": "MASK", "alphaCutoff": 0.3, {texture}}}"#),
        &format!(r#"{{"name": "blend", "alphaMode": "BLEND", {texture}}}"#),
    ]);
    let cutoffs: Vec<(String, Option<f32>, f32)> =
        scene.materials.iter().map(|m| (m.name.clone(), m.alpha_cutoff, m.alpha)).collect();
    assert_eq!(
        cutoffs,
        vec![
            ("opaque".into(), None, 0.8),
            ("explicit opaque".into(), None, 0.8),
            ("mask".into(), Some(0.5), 0.8),
            ("mask 0.3".into(), Some(0.3), 0.8),
            ("blend".into(), Some(0.5), 0.8),
        ]
    );
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(scene.warnings[0].contains("BLEND") && scene.warnings[0].contains("MASK"), "{:?}", scene.warnings);
    // Packed: the texture's alpha at the hit decides, times the factor 0.8 (left texel 0.8,
    // right texel 0): holes in the right half for every masked material, none for the opaque.
    let mut lit = scene.clone();
    lit.sky = Some(tracer::scene::Sky::uniform(Vec3::ONE));
    let packed = pack(&lit, 4, Strategy::Mis, 4);
    assert!(packed.features.alpha_mask);
    let k = &packed.scene;
    for i in 0..packed.triangle_count as u32 {
        let tri = tracer::kernel::scene_data::fetch_triangle(k, i);
        // Points whose uv is well inside the left (u = 0.25, its centre) or the right (u = 0.75) texel.
        let mut holes = [false; 2];
        for (j, target_u) in [0.25f32, 0.75].into_iter().enumerate() {
            let (u, v) = find_barycentrics(k, i, target_u);
            holes[j] = tri.masked && tracer::kernel::alpha_mask::is_hole(k, i, tri.material, u, v);
        }
        let masked = scene.materials[tri.material as usize].alpha_cutoff.is_some();
        assert_eq!(holes, [false, masked], "triangle {i} of material {}", scene.materials[tri.material as usize].name);
    }
}

/// Barycentrics (u, v) of a point of triangle `i` whose texture u is `target_u` and v 0.5-ish.
fn find_barycentrics(k: &tracer::kernel::scene_data::Scene, i: u32, target_u: f32) -> (f32, f32) {
    let mut best = (0.0, 0.0, f32::INFINITY);
    for a in 0..=40 {
        for b in 0..=(40 - a) {
            let (u, v) = (a as f32 / 40.0, b as f32 / 40.0);
            let uv = tracer::kernel::scene_data::texcoord(k, i, u, v);
            let d = (uv.x - target_u).abs() + (uv.y - 0.5).abs() * 0.1;
            if d < best.2 && u + v < 0.98 && u > 0.02 && v > 0.02 {
                best = (u, v, d);
            }
        }
    }
    assert!(best.2 < 0.1, "triangle {i}: no point near u = {target_u}");
    (best.0, best.1)
}

#[test]
fn cutoffs_out_of_range_warn_and_never_panic() {
    let texture = r#""pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}"#;
    let scene = gltf_with_materials(&[
        &format!(r#"{{"name": "negative", "alphaMode": "MASK", "alphaCutoff": -0.5, {texture}}}"#),
        &format!(r#"{{"name": "huge", "alphaMode": "MASK", "alphaCutoff": 1e39, {texture}}}"#),
        &format!(r#"{{"name": "above one", "alphaMode": "MASK", "alphaCutoff": 2, {texture}}}"#),
    ]);
    let cutoffs: Vec<Option<f32>> = scene.materials.iter().map(|m| m.alpha_cutoff).collect();
    assert_eq!(cutoffs, vec![Some(0.0), Some(0.5), Some(2.0)]);
    assert_eq!(scene.warnings.len(), 3, "{:?}", scene.warnings);
    for (w, needle) in scene.warnings.iter().zip(["below 0", "not a finite", "above 1"]) {
        assert!(w.contains("alphaCutoff") && w.contains(needle), "{w}");
    }
    // Hand-built scenes with a NaN or negative cutoff, or an alpha outside [0, 1], are refused.
    for bad in [
        Material { alpha_cutoff: Some(f32::NAN), ..Material::diffuse("m", Vec3::ONE) },
        Material { alpha_cutoff: Some(-1.0), ..Material::diffuse("m", Vec3::ONE) },
        Material { alpha: f32::NAN, ..Material::diffuse("m", Vec3::ONE) },
        Material { alpha: 1.5, ..Material::diffuse("m", Vec3::ONE) },
    ] {
        let mut s = screen_before_emitter(None);
        s.materials[0] = bad;
        let err = s.validate().expect_err("invalid alpha");
        assert!(err.to_string().contains("alpha"), "{err}");
    }
}

/// Each of `triangles` split into four at its edges' midpoints (positions, normals and texture
/// coordinates interpolated), `times` times over.
fn subdivide(triangles: Vec<Triangle>, times: u32) -> Vec<Triangle> {
    (0..times).fold(triangles, |triangles, _| {
        triangles
            .iter()
            .flat_map(|t| {
                let mid = |a: usize, b: usize| Triangle {
                    positions: [(t.positions[a] + t.positions[b]) * 0.5; 3],
                    normals: [(t.normals[a] + t.normals[b]).normalize(); 3],
                    uvs: [(t.uvs[a] + t.uvs[b]) * 0.5; 3],
                    ..*t
                };
                let (m01, m12, m20) = (mid(0, 1), mid(1, 2), mid(2, 0));
                let corner = |v: usize, a: &Triangle, b: &Triangle| Triangle {
                    positions: [t.positions[v], a.positions[0], b.positions[0]],
                    normals: [t.normals[v], a.normals[0], b.normals[0]],
                    uvs: [t.uvs[v], a.uvs[0], b.uvs[0]],
                    ..*t
                };
                let centre = Triangle {
                    positions: [m01.positions[0], m12.positions[0], m20.positions[0]],
                    normals: [m01.normals[0], m12.normals[0], m20.normals[0]],
                    uvs: [m01.uvs[0], m12.uvs[0], m20.uvs[0]],
                    ..*t
                };
                [corner(0, &m01, &m20), corner(1, &m12, &m01), corner(2, &m20, &m12), centre]
            })
            .collect()
    })
}

/// Masks cost only where they are (issue #31): a masked triangle whose texels are opaque
/// throughout is not alpha-tested (its flag is left clear at pack time), one over holes is, and
/// the image is the same bit for bit as when every masked triangle is tested. The screen of
/// `alpha_masked_screen`, subdivided into 128 triangles, over a texture opaque on its left half
/// and a checker of holes on its right half.
#[test]
fn only_triangles_that_can_have_holes_are_alpha_tested() {
    let mut scene = tracer::scene::alpha_masked_screen();
    let n = 16u32;
    let texels: Vec<u32> = (0..n * n)
        .map(|i| if i % n < n / 2 || (i % n + i / n).is_multiple_of(2) { 0xffff_ffff } else { 0x00ff_ffff })
        .collect();
    scene.textures[0] =
        Texture { width: n, height: n, texels: texels.into(), wrap_s: Wrap::ClampToEdge, wrap_t: Wrap::ClampToEdge };
    let (screen, rest): (Vec<Triangle>, Vec<Triangle>) = scene.triangles.iter().partition(|t| t.material == 1);
    scene.triangles = rest.into_iter().chain(subdivide(screen, 3)).collect();
    let p = common::agreement::packed(&scene, Strategy::Mis, 32, 4);
    assert!(p.features.alpha_mask);
    // Per triangle texel 0's w is its material, texel 2's w its mask flag.
    let triangles = p.scene.triangles.as_slice();
    let flags: Vec<(u32, f32)> = triangles.chunks(3).map(|t| (t[0].w as u32, t[2].w)).collect();
    let screen_flags: Vec<f32> = flags.iter().filter(|(m, _)| *m == 1).map(|(_, f)| *f).collect();
    let tested = screen_flags.iter().filter(|f| **f == 1.0).count();
    eprintln!("{tested} of {} screen triangles are alpha-tested", screen_flags.len());
    assert_eq!(screen_flags.len(), 128);
    assert!((64..112).contains(&tested), "{tested} of 128 tested: the opaque half should mostly be left untested");
    // The same scene with every triangle of a masked material tested renders the same image.
    let mut all_tested = p.clone();
    let mut data = all_tested.scene.triangles.as_slice().to_vec();
    for t in data.chunks_mut(3) {
        if matches!(t[0].w as u32, 1 | 2) {
            t[2].w = 1.0;
        }
    }
    all_tested.scene.triangles = kernel_dsl::Texels::new(data);
    let render = |p: &Packed| {
        let mut r = tracer::backend::cpu::CpuRenderer::new(p.clone(), 3);
        for _ in 0..4 {
            tracer::backend::Renderer::render_frame(&mut r).expect("frame");
        }
        tracer::backend::Renderer::accumulation(&r).expect("accumulation")
    };
    let bits = |v: Vec<glam::Vec4>| v.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    assert_eq!(bits(render(&p)), bits(render(&all_tested)), "skipping the test changed the image");
}
