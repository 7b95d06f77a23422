//! Code generation: snapshots of every generated file, validation of every output, mapping
//! of validation errors back to the Rust source, determinism, naming, and the divergence
//! rules of DESIGN.md principle 2 as they appear in the emitted code.

// The `#[kernel]` modules here are read as IR and generated, not called as Rust.
#![allow(dead_code)]

use lightport_codegen::{validate, Program, Selection, Target};

#[kernel_dsl::kernel]
pub mod subset {
    //! A kernel module touching every construct of the subset.
    use glam::{UVec4, Vec2, Vec3, Vec4, Vec4Swizzles};
    use kernel_dsl::Texels;

    pub const N: usize = 4;
    pub const SCALE: f32 = 2.0 * 0.25;

    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Inner {
        pub a: f32,
        pub b: u32,
    }

    #[derive(Clone, Copy, Debug, PartialEq)]
    pub struct Outer {
        pub inner: Inner,
        pub v: Vec3,
        pub values: [f32; N],
    }

    #[resources]
    pub struct Data {
        pub texels: Texels<Vec4>,
        pub words: Texels<UVec4>,
        pub gain: f32,
        pub count: u32,
    }

    pub fn bump(state: &mut u32, by: u32) {
        *state = state.wrapping_add(by);
    }

    /// `if` values of struct type: in a `let`, an assignment, a `return` and a tail. WGSL's
    /// `select` takes scalars and vectors only, so these become statements there.
    pub fn pick(a: Inner, b: Inner, first: bool) -> Inner {
        let chosen = if first { a } else { b };
        let mut other = a;
        if chosen.b > 3 {
            other = if chosen.a > 1.0 { b } else { a };
        }
        if other.b > chosen.b {
            return if first { other } else { chosen };
        }
        if first {
            b
        } else {
            a
        }
    }

    pub fn set_field(o: &mut Outer, x: f32) {
        o.inner.a = x;
        o.values[1] = x * 2.0;
    }

    /// Shadowing, reserved names, control flow and every cast.
    pub fn everything(data: &Data, input: f32, sample: i32) -> Vec4 {
        let texture = input * SCALE;
        let texture = texture + 1.0;
        let mut acc = 0.0;
        for i in 0..N {
            acc += i as f32;
        }
        for i in 1..=3u32 {
            acc += (i * 2) as f32;
        }
        let mut k = 0;
        while k < 10 {
            k += 3;
        }
        let mut state = 7u32;
        loop {
            bump(&mut state, 5);
            if state > 20 {
                break;
            }
            if state == 12 {
                continue;
            }
        }
        let kind = match sample {
            0 => 1.0,
            1 | 2 => 2.0,
            _ => 3.0,
        };
        let sign = if input < 0.0 { -1.0 } else { 1.0 };
        let mut o = Outer { inner: Inner { a: 0.0, b: 3 }, v: Vec3::new(1.0, 2.0, 3.0), values: [0.0; N] };
        set_field(&mut o, texture);
        let q = sample / 2 + sample % 3;
        let bits = input.to_bits() ^ (state << 3);
        let t = data.texels.fetch(data.count).xyz() * data.gain;
        let w = data.words.fetch(0).x;
        let u = (input * 1000.0) as u32;
        let iv = input as i32;
        let fu = w as f32 + u as f32;
        let fi = q as f32 + iv as f32;
        let r = input.round() + input.fract() + input.signum() + (input % 1.5);
        let n = Vec2::new(acc, kind).normalize().extend(sign).extend(o.values[1]);
        if input.is_nan() || !input.is_finite() {
            return Vec4::ZERO;
        }
        n + Vec4::new(t.x + fu, fi + r, (bits & 255) as f32 + k as f32, o.inner.a + o.inner.b as f32)
    }
}

fn tracer_program() -> Program {
    Program::link(&tracer::kernel::modules()).expect("the tracer's kernel links")
}

/// The committed `shaders-generated/` is the one stored copy of each generated file (its git
/// diff is the review a snapshot tool would give): it must be what the kernel generates now.
#[test]
fn every_generated_file_matches_the_committed_file() {
    let files = tracer::kernel::generated_shaders().expect("generation and validation succeed");
    assert!(files.len() >= 16, "one GLSL and one WGSL file per kernel module");
    for f in &files {
        let committed =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/shaders-generated/").to_string() + &f.name)
                .unwrap_or_default();
        assert!(committed == f.source, "shaders-generated/{} is stale: run `cargo run -- shaders`", f.name);
    }
    // And nothing else: a file no kernel module generates any more is stale too (CI's only
    // freshness check, as `lightport shaders --check` is; this one shares the test build).
    let dir = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/shaders-generated")).expect("shaders-generated/");
    for entry in dir {
        let name = entry.expect("directory entry").file_name().to_string_lossy().into_owned();
        let shader = name.ends_with(".glsl") || name.ends_with(".wgsl");
        assert!(
            !shader || files.iter().any(|f| f.name == name),
            "shaders-generated/{name}: no kernel module generates it any more: run `cargo run -- shaders`"
        );
    }
}

/// The generated kernels divide no integers by a variable except once per texture wrap (issue
/// 31): SIMD drivers (llvmpipe, SwiftShader) have no vector integer division, so each one is a
/// division per lane, and SwiftShader's JIT compiles each slowly. Signed division and
/// remainder (GLSL's `lp_div_i32`, `lp_rem_i32`: an unsigned division and sign fixes each) are
/// absent, the wrap's remainder (`textures::euclid_remainder`) divides once, the wrap
/// (`wrap_pair`) not at all beside it (one remainder per mode: a SIMD driver runs both modes'
/// branches), a bilinear lookup (`textures::footprint`) wraps once per axis for both its texels, and the GLSL
/// data-texture fetch, which every node, triangle and material read goes through, finds its row
/// without shifting (scene arrays have power-of-two widths: a product by 1/width) and, in the
/// denoiser's image pass (arrays as wide as the image), with an f32 division only.
#[test]
fn the_kernels_divide_integers_only_where_a_texture_wraps() {
    let files = tracer::kernel::generated_shaders().expect("generation and validation succeed");
    let body = |source: &str, signature: &str| -> String {
        let start = source.find(signature).unwrap_or_else(|| panic!("{signature} generated"));
        let end = source[start..].find("\n}\n").expect("function end") + start;
        source[start..end].to_string()
    };
    // A function's code without its comment lines.
    let code_of =
        |function: &str| -> String { function.lines().filter(|l| !l.trim_start().starts_with("//")).collect() };
    for name in ["path_tracer.frag.glsl", "path_tracer.wgsl", "path_tracer_wavefront.wgsl"] {
        let source = &files.iter().find(|f| f.name == name).unwrap_or_else(|| panic!("{name} generated")).source;
        for helper in ["lp_div_i32", "lp_rem_i32"] {
            assert!(!source.contains(helper), "{name} divides signed integers ({helper})");
        }
        let glsl = name.ends_with(".glsl");
        let remainder = body(source, if glsl { "int euclid_remainder(" } else { "fn euclid_remainder(" });
        assert_eq!(remainder.matches(['%', '/']).count(), 1, "{name}: one division per wrap:\n{remainder}");
        let wrap = body(source, if glsl { "ivec2 wrap_pair(" } else { "fn wrap_pair(" });
        assert!(!wrap.contains('%'), "{name}: the wrap divides beside its remainder:\n{wrap}");
        // A bilinear lookup (colour or alpha alone) wraps each axis once for both its texels.
        let footprint = body(source, if glsl { "Footprint footprint(" } else { "fn footprint(" });
        assert_eq!(footprint.matches("wrap_pair(").count(), 2, "{name}: one wrap per axis:\n{footprint}");
        for lookup in ["bilinear(", "bilinear_alpha("] {
            let signature = match (glsl, lookup) {
                (true, "bilinear(") => "vec4 bilinear(".to_string(),
                (true, _) => format!("float {lookup}"),
                (false, _) => format!("fn {lookup}"),
            };
            let lookup = body(source, &signature);
            assert!(
                lookup.contains("footprint(") && !lookup.contains("wrap_"),
                "{name}: wraps beside its footprint:\n{lookup}"
            );
        }
        if glsl {
            for fetch in ["vec4 lp_fetch_vec4(", "uvec4 lp_fetch_uvec4("] {
                let fetch = body(source, fetch);
                let code = code_of(&fetch);
                assert!(!code.contains(['%', '/']), "{name}: the data fetch divides:\n{fetch}");
                assert!(!code.contains("if ("), "{name}: the data fetch branches:\n{fetch}");
                // SwiftShader runs each vector shift lane by lane (four extracts, shifts and inserts).
                assert!(!code.contains(">>") && !code.contains("<<"), "{name}: the data fetch shifts:\n{fetch}");
                assert!(
                    code.contains("int(i) & (w - 1)") && code.contains("* inverse_width"),
                    "{name}: the data fetch's column is a mask and its row a product:\n{fetch}"
                );
            }
        }
    }
    // The denoiser's image pass reads image-wide arrays (any width): an f32 quotient.
    let pass = &files.iter().find(|f| f.name == "denoise_pass.frag.glsl").expect("the filter pass").source;
    let fetch = body(pass, "vec4 lp_fetch_vec4(");
    let code = code_of(&fetch);
    assert!(!code.contains('%'), "the filter pass's data fetch divides integers:\n{fetch}");
    assert_eq!(code.matches('/').count(), 1, "the filter pass's data fetch's one division:\n{fetch}");
    assert!(code.contains("float(i) / float(w)"), "the filter pass's division in f32:\n{fetch}");
}

/// The scene arrays' fetch (`lp_fetch_*` at `TexelRows::PowerOfTwoWidth`) finds texel i at
/// column `i & (w - 1)`, row `(i - column) as f32 * (1 / w)` with 1/w made from the f32 bits of
/// the width (`0x7f000000 - bits(w)`), in f32 as the shader computes it: exact for every
/// power-of-two width and row a texture can have (16384 x 16384 natively), and every texture
/// shape the GL backend makes has a power-of-two width.
#[test]
fn scene_arrays_have_power_of_two_widths_and_the_fetch_row_is_exact() {
    let fetch_model = |i: u32, w: u32| -> (i32, i32) {
        let w = w as i32;
        let column = (i as i32) & (w - 1);
        let inverse_width = f32::from_bits(0x7f00_0000 - (w as f32).to_bits());
        (column, (((i as i32) - column) as f32 * inverse_width) as i32)
    };
    for k in 0..=14u32 {
        let w = 1u32 << k;
        assert_eq!(f32::from_bits(0x7f00_0000 - (w as f32).to_bits()), 1.0 / w as f32, "1/{w}");
        for row in (0..16384u32).step_by(7).chain([16383]) {
            for i in [row * w, row * w + w / 2, row * w + w - 1] {
                assert_eq!(fetch_model(i, w), ((i % w) as i32, (i / w) as i32), "texel {i} of width {w}");
            }
        }
    }
    for texels in [0usize, 1, 2, 3, 5, 1000, 65_537, 1 << 20, (1 << 28) - 3] {
        let (w, h) = tracer::backend::gl::texture_shape(texels, 16384).expect("fits");
        assert!(w.is_power_of_two(), "{texels} texels: width {w}");
        assert!(w as usize * h as usize >= texels.max(1), "{texels} texels: {w}x{h}");
    }
}

/// A model of the GLSL data fetch's row and column at any width (`lp_fetch_*` at
/// `TexelRows::AnyWidth`, the denoiser's image pass: an f32 quotient, corrected once), in f32
/// as the shader computes it, with the conversion and the division each off by up
/// to 3 ULP (GLSL ES 3.00 allows 2.5 for division; llvmpipe rounds correctly, so the corrections
/// never run there): exact for every texel row of the image-wide denoiser arrays, and of
/// power-of-two widths up to 2^28 texels too (as a model, though scene arrays use the product), first
/// and last columns.
#[test]
fn the_data_fetch_row_estimate_is_corrected_to_the_exact_row() {
    let nudge =
        |x: f32, ulps: i32| if x == 0.0 && ulps < 0 { x } else { f32::from_bits((x.to_bits() as i32 + ulps) as u32) };
    let widths: Vec<u32> = (0..=15).map(|k| 1u32 << k).chain([3, 320, 640, 1000, 1920, 4095, 16383]).collect();
    for w in widths {
        let rows = ((1u64 << 28) / w as u64).min(32768) as u32;
        let mut sample: Vec<u32> = (0..rows.min(64)).chain((0..rows).step_by(97)).collect();
        sample.extend([rows - 1, rows / 2, rows / 3]);
        for row in sample {
            for i in [row * w, row * w + w / 2, row * w + w - 1] {
                for (a, b) in [(0, 0), (1, 3), (-1, -3), (3, 3), (-3, -3), (1, -2), (-2, 1)] {
                    let mut r = (nudge(nudge(i as f32, a) / w as f32, b)) as u32;
                    let mut column = i.wrapping_sub(r.wrapping_mul(w));
                    if (column as i32) < 0 {
                        r -= 1;
                        column = column.wrapping_add(w);
                    } else if column >= w {
                        r += 1;
                        column -= w;
                    }
                    assert_eq!((r, column), (i / w, i % w), "texel {i} of width {w}, nudged {a} / {b} ULP");
                }
            }
        }
    }
}

#[test]
fn the_subset_module_generates_valid_glsl_and_wgsl() {
    let program = Program::link(&[subset::kernel_ir()]).expect("links");
    for target in [Target::GlslEs300, Target::Wgsl] {
        let g = program.emit(target, &Selection::default()).expect("emits");
        validate::validate(&g).unwrap_or_else(|e| panic!("{e}\n{}", g.source));
        insta::assert_snapshot!(format!("subset.{}", target.extension()), g.source);
    }
}

#[test]
fn the_header_says_how_to_regenerate_only_when_the_caller_says_so() {
    let program = Program::link(&[subset::kernel_ir()]).unwrap();
    for target in [Target::GlslEs300, Target::Wgsl] {
        let plain = program.emit(target, &Selection::default()).unwrap().source;
        let header = plain.lines().find(|l| l.starts_with("// Generated")).expect("a header line");
        assert!(header.ends_with("(modules: subset). Do not edit."), "{header}");
        assert!(!plain.contains("cargo run"), "a user's shader names no command of this repository");
        let selection = Selection { regenerate: Some("run `make shaders`".into()), ..Selection::default() };
        let noted = program.emit(target, &selection).unwrap().source;
        assert!(noted.contains("(modules: subset). Do not edit: run `make shaders`.\n"), "{noted}");
    }
}

#[test]
fn the_subset_module_runs_on_the_cpu() {
    let data = subset::Data {
        texels: kernel_dsl::Texels::new(vec![glam::Vec4::ONE; 4]),
        words: kernel_dsl::Texels::new(vec![glam::UVec4::splat(9)]),
        gain: 2.0,
        count: 3,
    };
    let v = subset::everything(&data, 0.75, 2);
    assert!(v.is_finite());
    assert_eq!(subset::everything(&data, f32::NAN, 0), glam::Vec4::ZERO);
}

#[test]
fn output_is_deterministic() {
    for target in [Target::GlslEs300, Target::Wgsl] {
        // GLSL ES 3.00: every function but the compute modules' (which it refuses).
        let program = tracer_program();
        let selection = match target {
            Target::GlslEs300 => Selection { roots: plain_functions(), ..Selection::default() },
            Target::Wgsl => Selection::default(),
        };
        let a = program.emit(target, &selection).unwrap().source;
        let b = tracer_program().emit(target, &selection).unwrap().source;
        assert_eq!(a, b);
    }
}

/// The functions of the tracer's kernel modules that are not compute modules.
fn plain_functions() -> Vec<String> {
    let modules = tracer::kernel::modules();
    let plain = modules.iter().filter(|m| !m.compute);
    plain
        .flat_map(|m| m.items.iter())
        .filter_map(|i| match i {
            kernel_dsl::ir::Item::Fn(f) => Some(f.name.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn each_function_names_its_rust_source() {
    let g = tracer_program()
        .emit(Target::GlslEs300, &Selection { roots: vec!["wang_hash".into()], ..Default::default() })
        .unwrap();
    assert!(g.source.contains("// rng::wang_hash (lightport-tracer/src/kernel/rng.rs:9)"), "{}", g.source);
    // Only what the root needs is emitted.
    assert!(!g.source.contains("random_float"));
}

#[test]
fn generated_identifiers_avoid_reserved_words_and_double_underscores() {
    let program = Program::link(&[subset::kernel_ir()]).unwrap();
    let g = program.emit(Target::GlslEs300, &Selection::default()).unwrap();
    assert!(g.source.contains("float texture_ = input_ * SCALE;"), "{}", g.source);
    assert!(!g.source.contains("__"), "{}", g.source);
    assert!(g.source.contains("sample_"));
}

#[test]
fn divergent_semantics_use_the_helpers() {
    let program = Program::link(&[subset::kernel_ir()]).unwrap();
    let glsl = program.emit(Target::GlslEs300, &Selection::default()).unwrap().source;
    let wgsl = program.emit(Target::Wgsl, &Selection::default()).unwrap().source;
    for helper in [
        "lp_f32_to_u32(",
        "lp_f32_to_i32(",
        "lp_u32_to_f32(",
        "lp_i32_to_f32(",
        "lp_round(",
        "lp_signum(",
        "lp_is_nan(",
    ] {
        assert!(glsl.contains(helper), "GLSL lacks {helper}");
        assert!(wgsl.contains(helper), "WGSL lacks {helper}");
    }
    // GLSL ES leaves negative integer division undefined and floors `mod`; WGSL matches Rust.
    assert!(glsl.contains("lp_div_i32(") && glsl.contains("lp_rem_i32(") && glsl.contains("lp_fmod_f32("));
    assert!(!wgsl.contains("lp_div_i32"));
    // Shift amounts: WGSL needs u32; `x << 3` stays a shift.
    assert!(wgsl.contains("<< 3u"));
}

#[test]
fn wgsl_validation_errors_point_at_the_rust_function() {
    let program = tracer_program();
    let mut g =
        program.emit(Target::Wgsl, &Selection { roots: vec!["pixel_seed".into()], ..Default::default() }).unwrap();
    // Break the body of `pixel_seed` the way a codegen bug would: a type error.
    g.source = g.source.replace("    let s: u32 = wang_hash(", "    let bad: u32 = 1.5;\n    let s: u32 = wang_hash(");
    assert!(g.source.contains("let bad"), "the corruption must apply:\n{}", g.source);
    let err = validate::validate(&g).expect_err("naga must reject a f32 returned as u32");
    let text = err.to_string();
    assert!(text.contains("lightport-tracer/src/kernel/rng.rs:") && text.contains("rng::pixel_seed"), "{text}");
}

#[test]
fn glsl_parse_errors_point_at_the_rust_function() {
    let program = tracer_program();
    let mut g =
        program.emit(Target::GlslEs300, &Selection { roots: vec!["random_u32".into()], ..Default::default() }).unwrap();
    g.source = g.source.replace("state ^= state << 13;", "state ^= state << ;");
    let err = validate::validate(&g).expect_err("glsl-lang must reject a syntax error");
    assert!(err.to_string().contains("rng::random_u32"), "{err}");
}

#[test]
fn link_errors_name_the_rust_location() {
    let m = subset::kernel_ir();
    let err = Program::link(&[m.clone(), m]).expect_err("duplicate names are refused");
    let text = err.to_string();
    assert!(text.contains("tests/kernel/codegen.rs:") && text.contains("also defined"), "{text}");
}

#[test]
fn every_supported_method_is_implemented_for_some_type() {
    use lightport_codegen::types::{method_result, Ty, F32, I32, U32};
    let vec3 = Ty::builtin("Vec3").unwrap();
    let vec4 = Ty::builtin("Vec4").unwrap();
    let texels = Ty::Texels(Box::new(vec4.clone()));
    let storage = Ty::Storage(Box::new(U32));
    for m in kernel_dsl::ir::SUPPORTED_METHODS {
        let found =
            [F32, I32, U32, vec3.clone(), vec4.clone(), texels.clone(), storage.clone(), Ty::Atomics].iter().any(|t| {
                (0..3).any(|arity| method_result(t, m, &vec![t.clone(); arity]).is_some())
                    || method_result(t, m, &[U32]).is_some()
                    || method_result(t, m, &[U32, U32]).is_some()
                    || method_result(t, m, &[F32]).is_some()
                    || method_result(t, m, &[vec3.clone(), F32]).is_some()
            });
        assert!(found, "`{m}` is accepted by the macro but no type implements it in codegen");
    }
}

#[test]
fn specialisation_removes_unused_features_code_and_data() {
    use tracer::kernel::Features;
    let all = tracer::kernel::path_tracer_shader(&Features::all(), Target::GlslEs300).unwrap().source;
    let cornell = Features { emissive_triangles: true, ..Default::default() };
    let small = tracer::kernel::path_tracer_shader(&cornell, Target::GlslEs300).unwrap().source;
    assert!(small.len() < all.len() * 9 / 10, "{} vs {} bytes", small.len(), all.len());
    for gone in
        ["scene_sky", "sky_texel_radiance", "sample_texture", "scene_texture_texels", "scene_shading", "LIGHT_POINT"]
    {
        assert!(all.contains(gone), "the full kernel has {gone}");
        assert!(!small.contains(gone), "a scene without it must not carry {gone}");
    }
    assert!(small.contains("void main()") && small.contains("render_sample(pixel.x, pixel.y)"));
}

/// The denoiser's guide costs nothing unless asked for: without `Features::denoise_guide` the
/// kernel has one output and none of the guide's code (the first hit's albedo is never looked
/// up, the `has_denoise_guide` branches are folded away); with it, the entry point accumulates
/// the four fields of `GuidedSample` into four targets, in GLSL and WGSL.
#[test]
fn the_denoisers_guide_is_in_the_kernel_only_when_asked_for() {
    use tracer::kernel::Features;
    let plain = Features { emissive_triangles: true, ..Default::default() };
    let guided = Features { denoise_guide: true, ..plain };
    for target in [Target::GlslEs300, Target::Wgsl] {
        let without = tracer::kernel::path_tracer_shader(&plain, target).unwrap().source;
        let with = tracer::kernel::path_tracer_shader(&guided, target).unwrap().source;
        for extra in
            ["lp_accumulation1", "lp_accumulation3", "render_guided_sample", ".albedo = base_color_at", "GuidedSample"]
        {
            assert!(with.contains(extra), "{target:?}: the guided kernel has {extra}");
            assert!(!without.contains(extra), "{target:?}: a kernel without the guide must not carry {extra}");
        }
        assert!(!without.contains("has_denoise_guide") && !with.contains("has_denoise_guide"), "{target:?}: folded");
        assert!(!with.contains("lp_accumulation4"), "{target:?}: exactly four outputs");
    }
}

/// Two levels cost a one-level scene nothing: without `Features::instances` the kernel has no
/// instance code (the one-level traversal loop as it was), with it the loop enters placements
/// and hits are brought back to world space, in GLSL and WGSL.
#[test]
fn two_level_traversal_is_in_the_kernel_only_for_scenes_with_instances() {
    use tracer::kernel::Features;
    let plain = Features { emissive_triangles: true, ..Default::default() };
    let two_level = Features { instances: true, ..plain };
    for target in [Target::GlslEs300, Target::Wgsl] {
        let without = tracer::kernel::path_tracer_shader(&plain, target).unwrap().source;
        let with = tracer::kernel::path_tracer_shader(&two_level, target).unwrap().source;
        for extra in
            ["instance_ray", "instance_texel", "instance_handedness", "affine_point", "instance_sp", "two_level"]
        {
            assert!(with.contains(extra), "{target:?}: the two-level kernel has {extra}");
            assert!(!without.contains(extra), "{target:?}: a one-level kernel must not carry {extra}");
        }
        assert!(!without.contains("has_instances") && !with.contains("has_instances"), "{target:?}: folded");
    }
}

#[test]
fn every_kernel_function_has_a_valid_equivalence_harness() {
    let program = tracer_program();
    let mut checked = 0;
    let mut wide = Vec::new();
    let mut refused_harnesses = 0;
    for module in tracer::kernel::modules() {
        for item in &module.items {
            let kernel_dsl::ir::Item::Fn(f) = item else { continue };
            for target in [Target::GlslEs300, Target::Wgsl] {
                if module.compute {
                    // A compute module's functions (the wavefront's stages) read the pool, in
                    // bind groups 1 and 2, where a harness binds its own arguments: they are
                    // tested through the wavefront renderers, and the steps they call through
                    // `tests/equivalence/path_segment.rs`. GLSL refuses them at the function
                    // as compute; WGSL refuses their harness, naming the function and the group.
                    let e = program.emit(target, &Selection::harness(&f.name)).expect_err("no harness in groups 1, 2");
                    if target == Target::GlslEs300 {
                        // At the first compute function it reaches (a callee, maybe).
                        assert!(e.message.contains("GLSL ES 3.00") && e.function.is_some(), "{e}");
                    } else {
                        let function = format!("{}::{}", module.name, f.name);
                        assert_eq!(e.function.as_deref(), Some(function.as_str()), "{e}");
                        let groups =
                            ["`Paths`, a `#[resources(group = 1)]`", "`Dispatch`, a `#[resources(group = 2)]`"];
                        assert!(
                            e.message.contains(&format!("no equivalence harness around `{}`", f.name))
                                && groups.iter().any(|g| e.message.contains(g)),
                            "{e}"
                        );
                        refused_harnesses += 1;
                    }
                    continue;
                }
                let g = program.emit(target, &Selection::harness(&f.name)).expect("harness emits");
                validate::validate(&g).unwrap_or_else(|e| panic!("harness of {}: {e}\n{}", f.name, g.source));
                let h = g.harness.expect("layout");
                if h.output_words > 16 && target == Target::GlslEs300 {
                    wide.push(f.name.clone());
                }
            }
            checked += 1;
        }
    }
    assert!(checked > 30, "{checked} functions");
    // The wavefront's stages and their helpers: plan_generate, generate, plan_extend, extend,
    // shade, plan_connect, connect, accumulate, write_grid, load_path, store_path.
    assert!(refused_harnesses >= 11, "{refused_harnesses} compute functions refused a WGSL harness");
    // GLSL ES 3.00 guarantees 4 colour attachments: 16 words per invocation. One function is
    // wider: a path segment's shading (the path, the shadow ray and the denoiser's first hit,
    // 36 words), checked against the CPU on wgpu and WebGPU (`tests/equivalence/path_segment.rs`:
    // the wavefront's languages) and through images on GL. Any other function must fit.
    assert_eq!(wide, ["shade_hit"], "functions whose GLSL harness needs more than 4 RGBA32UI attachments");
    // The layout of a known function: intersect_triangle(origin, dir, v0, v1, v2) -> TriangleHit.
    let g = program.emit(Target::GlslEs300, &Selection::harness("intersect_triangle")).unwrap();
    let h = g.harness.unwrap();
    assert_eq!((h.input_words, h.output_words), (15, 3));
    // random_float(&mut u32) -> f32: one word in, the result and the new state out.
    let g = program.emit(Target::Wgsl, &Selection::harness("random_float")).unwrap();
    let h = g.harness.unwrap();
    assert_eq!((h.input_words, h.output_words), (1, 2));
}

/// A user's kernel that imports one of the tracer's, as a crate depending on `lightport-tracer` would.
#[kernel_dsl::kernel]
pub mod user_noise {
    use tracer::kernel::rng::random_float;

    /// A uniform value in [-1, 1).
    pub fn signed_noise(state: &mut u32) -> f32 {
        random_float(state) * 2.0 - 1.0
    }
}

#[test]
fn source_tags_name_the_package_not_the_machine() {
    // Every tag is `<package>/<path in the package>`, whatever directory the crate was built in.
    let program = Program::link(&[user_noise::kernel_ir(), tracer::kernel::rng::kernel_ir()]).unwrap();
    let source = program.emit(Target::Wgsl, &Selection::module(&program, "user_noise")).unwrap().source;
    assert!(source.contains("// user_noise::signed_noise (lightport/tests/kernel/codegen.rs:"), "{source}");
    assert!(source.contains("// rng::random_float (lightport-tracer/src/kernel/rng.rs:"), "{source}");
    for module in tracer::kernel::modules() {
        assert!(module.file.starts_with("lightport-tracer/src/kernel/"), "{}", module.file);
    }
    // The header names no repository command.
    assert!(!source.contains("cargo run"), "{source}");
}

mod build_script {
    use super::*;
    use lightport_codegen::build::{self, BuildError, Shaders};

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("lightport-build-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    #[test]
    fn write_shaders_writes_each_module_in_each_language_validated() {
        let dir = temp_dir("modules");
        let modules = [user_noise::kernel_ir(), tracer::kernel::rng::kernel_ir()];
        let written = build::write_shaders(&modules, &dir).expect("generates, validates and writes");
        let names: Vec<String> =
            written.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
        assert_eq!(names, ["user_noise.glsl", "user_noise.wgsl", "rng.glsl", "rng.wgsl"]);
        let program = Program::link(&modules).unwrap();
        let wgsl = std::fs::read_to_string(dir.join("user_noise.wgsl")).unwrap();
        let expected = Selection { regenerate: None, ..Selection::module(&program, "user_noise") };
        let plain = program.emit(Target::Wgsl, &expected).unwrap().source;
        // The same code as `emit`; only the header says how the file is regenerated.
        assert_eq!(wgsl.lines().skip(1).collect::<Vec<_>>(), plain.lines().skip(1).collect::<Vec<_>>());
        assert!(wgsl.lines().next().unwrap().contains("regenerated by the build script"), "{wgsl}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_unchanged_file_is_not_rewritten_and_a_stale_one_is() {
        let dir = temp_dir("fresh");
        let shaders = Shaders::new(&[user_noise::kernel_ir(), tracer::kernel::rng::kernel_ir()])
            .module("user_noise")
            .targets(&[Target::Wgsl]);
        let written = shaders.clone().write(&dir).unwrap();
        assert_eq!(written, [dir.join("user_noise.wgsl")], "only the file asked for");
        let path = &written[0];
        let old = std::time::SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1_000_000_000);
        std::fs::File::options().write(true).open(path).unwrap().set_modified(old).unwrap();
        shaders.clone().write(&dir).unwrap();
        assert_eq!(std::fs::metadata(path).unwrap().modified().unwrap(), old, "an unchanged file keeps its time");
        std::fs::write(path, "stale").unwrap();
        shaders.write(&dir).unwrap();
        assert!(std::fs::read_to_string(path).unwrap().contains("fn signed_noise("), "a stale file is rewritten");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn an_entry_point_selection_writes_a_fragment_shader_and_a_compute_shader() {
        let shaders = Shaders::new(&tracer::kernel::modules())
            .selection("cornell", Selection::entry("render_sample", Default::default()));
        let names: Vec<String> = shaders.generate().unwrap().into_iter().map(|(name, _)| name).collect();
        assert_eq!(names, ["cornell.frag.glsl", "cornell.wgsl"]);
    }

    #[test]
    fn errors_name_the_kernel_source_and_nothing_is_written() {
        let dir = temp_dir("errors");
        // The same module twice: its items are defined twice, a link error at the Rust source.
        let twice = [user_noise::kernel_ir(), user_noise::kernel_ir()];
        let err = build::write_shaders(&twice, &dir).unwrap_err();
        assert!(matches!(err, BuildError::Codegen(_)), "{err}");
        // A build script's `main` prints the error's Debug: the located message, not a struct.
        assert!(format!("{err:?}").starts_with("lightport/tests/kernel/codegen.rs:"), "{err:?}");
        assert!(!dir.exists(), "nothing is written when anything fails");

        let modules = [user_noise::kernel_ir(), tracer::kernel::rng::kernel_ir()];
        let err = Shaders::new(&modules).module("blur").write(&dir).unwrap_err();
        assert_eq!(err.to_string(), "no kernel module `blur` among those linked (user_noise, rng)");
        assert!(!dir.exists());
    }
}

#[test]
fn the_scene_decides_the_traversal_stack_on_every_gpu_target() {
    use tracer::kernel::{Features, RenderSettings};
    use tracer::pack::pack;
    let cornell = tracer::scene::cornell_box();
    let bvh = tracer::bvh::build(&cornell.triangles).unwrap();
    let packed = pack(&cornell, &bvh, &RenderSettings::default()).unwrap();
    let stack = packed.features.traversal_stack;
    assert!((1..16).contains(&stack), "the Cornell box needs a few entries: {stack}");
    for target in [Target::GlslEs300, Target::Wgsl] {
        let sized = tracer::kernel::path_tracer_shader(&packed.features, target).unwrap().source;
        let full = tracer::kernel::path_tracer_shader(&Features { traversal_stack: 0, ..packed.features }, target)
            .unwrap()
            .source;
        let (decl_sized, decl_full) = match target {
            Target::GlslEs300 => (format!("const uint STACK_SIZE = {stack}u;"), "const uint STACK_SIZE = 64u;".into()),
            Target::Wgsl => (format!("const STACK_SIZE: u32 = {stack}u;"), "const STACK_SIZE: u32 = 64u;".to_string()),
        };
        assert!(sized.contains(&decl_sized) && full.contains(&decl_full), "{target:?}:\n{sized}");
        // The arrays themselves are sized to it, not only the bound checks.
        let array = match target {
            Target::GlslEs300 => format!("uint stack[{stack}]"),
            Target::Wgsl => format!("var stack: array<u32, {stack}>;"),
        };
        assert!(sized.contains(&array) && !full.contains(&array), "{target:?}: {array}\n{sized}");
        // The committed Cornell variant is this scene's kernel.
        let name = match target {
            Target::GlslEs300 => "path_tracer_cornell.frag.glsl",
            Target::Wgsl => "path_tracer_cornell.wgsl",
        };
        let committed =
            std::fs::read_to_string(format!("{}/shaders-generated/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap();
        // Everything but the header, which says how the committed file is regenerated.
        let body =
            |s: &str| s.lines().filter(|l| !l.starts_with("// Generated by")).map(str::to_string).collect::<Vec<_>>();
        assert_eq!(body(&committed), body(&sized), "shaders-generated/{name} is not the packed Cornell box's kernel");
    }
}
