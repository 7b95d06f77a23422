//! Compute kernels (`#[kernel(compute)]`): `Storage` and `Atomics` resources, their WGSL
//! layout (bind groups, bindings, the data hosts read it from), compute entry points, and
//! GLSL ES 3.00's refusal, at the Rust function.

// The `#[kernel]` modules here are read as IR and generated (the CPU runs of compute modules
// are kernel-dsl's `tests/ui/pass/compute_queue.rs`).
#![allow(dead_code)]

use std::collections::BTreeMap;

use lightport_codegen::{
    dispatch_grid, validate, BindingKind, BoundField, Program, ResourceBinding, Selection, Target,
    COMPUTE_WORKGROUP_SIZE,
};

#[kernel_dsl::kernel(compute)]
pub mod wavefront {
    use glam::{UVec4, Vec4};
    use kernel_dsl::{Atomics, Storage, Texels};

    pub const HEAD: u32 = 0;

    #[resources]
    pub struct Pool {
        pub weights: Storage<f32>,
        pub colours: Storage<Vec4>,
        pub items: Storage<u32>,
        pub sky: Texels<Vec4>,
        pub keys: Storage<UVec4>,
        pub counters: Atomics,
        pub count: u32,
        pub totals: Atomics,
        pub gain: f32,
    }

    /// Where the second stage's queue lives: another bind group (a stage's indirect-dispatch
    /// arguments must not be bound by the stage that is dispatched with them).
    #[resources(group = 1)]
    pub struct Queue {
        pub entries: Storage<u32>,
        pub head: Atomics,
    }

    pub fn enqueue_even(pool: &Pool, queue: &Queue, invocation: u32) {
        if invocation >= pool.count {
            return;
        }
        let item = pool.items.load(invocation);
        pool.counters.atomic_add(1, 1);
        if (item & 1) == 0 {
            let slot = queue.head.atomic_add(HEAD, 1);
            queue.entries.store(slot, item);
        }
        let old = pool.totals.atomic_exchange(0, item);
        pool.totals.atomic_max(1, old);
        pool.totals.atomic_min(2, item);
        pool.totals.atomic_sub(3, 1);
        if pool.totals.atomic_load(4) == 0 {
            pool.totals.atomic_store(4, item + 1);
        }
    }

    pub fn shade(pool: &Pool, queue: &Queue, invocation: u32) {
        if invocation >= queue.head.atomic_load(HEAD) {
            return;
        }
        let item = queue.entries.load(invocation);
        let w = pool.weights.load(item) * pool.gain;
        pool.weights.store(item, w);
        let c = pool.colours.load(item) + pool.sky.fetch(item);
        pool.colours.store(item, c * w);
        pool.keys.store(item, UVec4::new(item, 0, 0, 1));
    }

    /// Not a stage: it returns a value.
    pub fn count_of(pool: &Pool, invocation: u32) -> u32 {
        pool.count + invocation
    }

    /// `store` has no value: it cannot be bound.
    #[allow(clippy::let_unit_value, clippy::let_and_return)]
    pub fn store_as_value(pool: &Pool, invocation: u32) {
        let nothing = pool.items.store(invocation, 1);
        nothing
    }
}

/// A kernel function named as a stage's entry point (`main_{stage}`).
#[kernel_dsl::kernel(compute)]
pub mod clash {
    use kernel_dsl::Atomics;

    #[resources]
    pub struct Ticks {
        pub count: Atomics,
    }

    pub fn tick(ticks: &Ticks, invocation: u32) {
        ticks.count.atomic_add(0, main_tick(invocation));
    }

    pub fn main_tick(invocation: u32) -> u32 {
        invocation & 1
    }

    pub fn tock(ticks: &Ticks, invocation: u32) {
        ticks.count.atomic_sub(0, invocation & 1);
    }
}

/// A plain module beside the compute one: it still generates for GLSL.
#[kernel_dsl::kernel]
pub mod plain {
    pub fn twice(x: f32) -> f32 {
        x * 2.0
    }
}

fn program() -> Program {
    Program::link(&[wavefront::kernel_ir(), plain::kernel_ir()]).expect("links")
}

fn stages() -> Selection {
    Selection::compute(&["enqueue_even", "shade"], BTreeMap::new())
}

#[test]
fn compute_stages_generate_valid_wgsl_with_one_entry_point_each() {
    let g = program().emit(Target::Wgsl, &stages()).expect("emits");
    validate::validate(&g).unwrap_or_else(|e| panic!("{e}\n{}", g.source));
    insta::assert_snapshot!("wavefront.wgsl", g.source);
    for stage in ["enqueue_even", "shade"] {
        let entry = format!(
            "@compute @workgroup_size(64)\nfn main_{stage}(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {{\n    {stage}(id.x + id.y * groups.x * 64u);\n}}"
        );
        assert!(g.source.contains(&entry), "{stage}'s entry point:\n{}", g.source);
    }
    assert_eq!(g.source.matches("@compute").count(), 2, "one entry point per stage, one set of resources");
    for access in [
        "lp_pool_storage_u32[pool.lp_start_items + invocation]",
        "lp_queue_storage_u32[queue.lp_start_entries + slot] = item;",
        "atomicAdd(&lp_pool_atomics[pool.lp_start_counters + 1u], 1u)",
        "atomicAdd(&lp_queue_atomics[queue.lp_start_head + HEAD], 1u)",
        "atomicExchange(&lp_pool_atomics[pool.lp_start_totals + 0u], item)",
        "atomicMax(&lp_pool_atomics[pool.lp_start_totals + 1u], old)",
        "atomicMin(&lp_pool_atomics[pool.lp_start_totals + 2u], item)",
        "atomicSub(&lp_pool_atomics[pool.lp_start_totals + 3u], 1u)",
        "atomicLoad(&lp_pool_atomics[pool.lp_start_totals + 4u])",
        "atomicStore(&lp_pool_atomics[pool.lp_start_totals + 4u], item + 1u);",
        "lp_pool_storage_vec4u[pool.lp_start_keys + item] = vec4<u32>(item, 0u, 0u, 1u);",
    ] {
        assert!(g.source.contains(access), "`{access}` in:\n{}", g.source);
    }
}

#[test]
fn the_layout_is_exposed_in_binding_order_per_group() {
    let g = program().emit(Target::Wgsl, &stages()).expect("emits");
    let field = |f: &str, ty: &str| BoundField { field: f.into(), ty: ty.into(), member: None };
    let member = |f: &str, ty: &str, m: &str| BoundField { field: f.into(), ty: ty.into(), member: Some(m.into()) };
    let binding =
        |binding, variable: &str, kind, fields| ResourceBinding { binding, variable: variable.into(), kind, fields };
    assert_eq!(g.bindings.len(), 2);
    let (pool, queue) = (&g.bindings[0], &g.bindings[1]);
    assert_eq!((pool.resources.as_str(), pool.group, queue.resources.as_str(), queue.group), ("Pool", 0, "Queue", 1));
    assert_eq!(
        pool.bindings,
        vec![
            // Group 0's scalars: read-only storage, not a uniform (`BindingKind::Scalars`).
            binding(
                0,
                "pool",
                BindingKind::Scalars,
                vec![
                    member("count", "u32", "count"),
                    member("gain", "f32", "gain"),
                    member("sky", "u32", "lp_start_sky"),
                    member("weights", "u32", "lp_start_weights"),
                    member("colours", "u32", "lp_start_colours"),
                    member("items", "u32", "lp_start_items"),
                    member("keys", "u32", "lp_start_keys"),
                    member("counters", "u32", "lp_start_counters"),
                    member("totals", "u32", "lp_start_totals"),
                ]
            ),
            binding(1, "lp_pool_vec4f", BindingKind::Texels, vec![field("sky", "Vec4")]),
            // Storage buffers in the fixed order vec4<f32>, vec4<u32>, u32, f32, whatever the
            // declaration order.
            binding(2, "lp_pool_storage_vec4f", BindingKind::Storage, vec![field("colours", "Vec4")]),
            binding(3, "lp_pool_storage_vec4u", BindingKind::Storage, vec![field("keys", "UVec4")]),
            binding(4, "lp_pool_storage_u32", BindingKind::Storage, vec![field("items", "u32")]),
            binding(5, "lp_pool_storage_f32", BindingKind::Storage, vec![field("weights", "f32")]),
            binding(6, "lp_pool_atomics", BindingKind::Atomics, vec![field("counters", "u32"), field("totals", "u32")]),
        ]
    );
    // Group 1 numbers its bindings from 0.
    assert_eq!(
        queue.bindings,
        vec![
            binding(
                0,
                "queue",
                BindingKind::Uniform,
                vec![member("entries", "u32", "lp_start_entries"), member("head", "u32", "lp_start_head")]
            ),
            binding(1, "lp_queue_storage_u32", BindingKind::Storage, vec![field("entries", "u32")]),
            binding(2, "lp_queue_atomics", BindingKind::Atomics, vec![field("head", "u32")]),
        ]
    );
    // The declarations say the same.
    for (decl, b) in [
        ("@group(0) @binding(6) var<storage, read_write> lp_pool_atomics: array<atomic<u32>>;", 6),
        ("@group(1) @binding(1) var<storage, read_write> lp_queue_storage_u32: array<u32>;", 1),
        ("@group(0) @binding(5) var<storage, read_write> lp_pool_storage_f32: array<f32>;", 5),
    ] {
        assert!(g.source.contains(decl), "binding {b}: `{decl}` in:\n{}", g.source);
    }
}

#[test]
fn glsl_refuses_compute_kernels_at_the_function() {
    let program = program();
    let err = program.emit(Target::GlslEs300, &stages()).expect_err("GLSL ES 3.00 has no compute");
    let text = err.to_string();
    assert!(
        text.contains("compute.rs:")
            && text.contains("in kernel fn `wavefront::enqueue_even`")
            && text.contains("GLSL ES 3.00 has neither; it is generated for WGSL and the CPU only"),
        "{text}"
    );
    assert_eq!(err.span, program_span("enqueue_even"));
    // Any function of a compute module, entry point or not.
    let module = Selection::module(&program, "wavefront");
    let err = program.emit(Target::GlslEs300, &module).expect_err("compute module in GLSL");
    assert!(err.to_string().contains("is a compute kernel (storage, atomics)"), "{err}");
    let only = Selection { roots: vec!["count_of".into()], ..Selection::default() };
    let err = program.emit(Target::GlslEs300, &only).expect_err("compute module in GLSL");
    assert_eq!(err.function.as_deref(), Some("wavefront::count_of"));
    // A plain module of the same program still generates for GLSL.
    let plain = Selection::module(&program, "plain");
    let g = program.emit(Target::GlslEs300, &plain).expect("plain module in GLSL");
    validate::validate(&g).unwrap_or_else(|e| panic!("{e}\n{}", g.source));
}

fn program_span(function: &str) -> lightport_codegen::ir::Span {
    let ir = wavefront::kernel_ir();
    ir.items
        .iter()
        .find_map(|i| match i {
            kernel_dsl::ir::Item::Fn(f) if f.name == function => Some(f.span),
            _ => None,
        })
        .expect("function")
}

#[test]
fn a_stage_needs_the_stage_signature() {
    let program = program();
    let err = program
        .emit(Target::Wgsl, &Selection::compute(&["count_of"], BTreeMap::new()))
        .expect_err("a stage returns nothing");
    assert!(err.to_string().contains("a compute stage is `fn count_of(<&resources..>, invocation: u32)`"), "{err}");
    assert_eq!(err.span, program_span("count_of"));
    let err = program.emit(Target::Wgsl, &Selection::compute(&["twice"], BTreeMap::new())).expect_err("no invocation");
    assert!(err.to_string().contains("a compute stage is"), "{err}");
}

#[test]
fn store_is_a_statement() {
    let err = program()
        .emit(Target::Wgsl, &Selection { roots: vec!["store_as_value".into()], ..Selection::default() })
        .expect_err("store's value");
    assert!(err.to_string().contains("`store` is a statement"), "{err}");
}

#[test]
fn the_dispatch_grid_covers_every_invocation_within_the_dimension_limit() {
    assert_eq!(COMPUTE_WORKGROUP_SIZE, 64);
    assert_eq!(dispatch_grid(0), [0, 1, 1]);
    assert_eq!(dispatch_grid(1), [1, 1, 1]);
    assert_eq!(dispatch_grid(64), [1, 1, 1]);
    assert_eq!(dispatch_grid(65), [2, 1, 1]);
    assert_eq!(dispatch_grid(65_535 * 64), [65_535, 1, 1]);
    assert_eq!(dispatch_grid(65_535 * 64 + 1), [65_535, 2, 1]);
    for n in [1u32, 1000, 4_194_241, 10_000_000, u32::MAX] {
        let [x, y, z] = dispatch_grid(n);
        assert!(x <= 65_535 && y <= 65_535 && z == 1, "{n}: {x} {y}");
        assert!(x as u64 * y as u64 * 64 >= n as u64, "{n}: {x} x {y} workgroups cover it");
        assert!((x as u64 * (y as u64 - 1)) * 64 < n as u64, "{n}: no whole row of workgroups is idle");
    }
}

#[test]
fn a_function_named_as_an_entry_point_is_an_error_naming_both() {
    let program = Program::link(&[clash::kernel_ir()]).expect("links");
    let err = program
        .emit(Target::Wgsl, &Selection::compute(&["tock", "tick"], BTreeMap::new()))
        .expect_err("`main_tick` is taken");
    let text = err.to_string();
    assert!(
        text.contains("kernel fn `clash::main_tick` has the name of the entry point of compute stage `clash::tick` (`main_tick`, generated for each stage): rename one of them"),
        "{text}"
    );
    assert_eq!(err.function.as_deref(), Some("clash::main_tick"));
    let main_tick = clash::kernel_ir()
        .items
        .iter()
        .find_map(|i| match i {
            kernel_dsl::ir::Item::Fn(f) if f.name == "main_tick" => Some(f.span),
            _ => None,
        })
        .expect("main_tick");
    assert_eq!(err.span, main_tick);
    // A stage whose entry point's name is free generates.
    let g = program.emit(Target::Wgsl, &Selection::compute(&["tock"], BTreeMap::new())).expect("`main_tock` is free");
    validate::validate(&g).unwrap_or_else(|e| panic!("{e}\n{}", g.source));
}

/// A harness binds its arguments and results in bind group 1: a function that reads a
/// resources struct of group 1 or above is refused at the function, naming the struct and its
/// group, instead of emitting a shader whose bindings collide. One that reads group 0 only
/// still gets its harness.
#[test]
fn a_harness_refuses_functions_that_read_resources_beyond_group_0() {
    let program = program();
    let err = program.emit(Target::Wgsl, &Selection::harness("shade")).expect_err("Queue is group 1");
    let text = err.to_string();
    assert!(
        text.contains("in kernel fn `wavefront::shade`")
            && text.contains(
                "no equivalence harness around `shade`: it reads `Queue`, a `#[resources(group = 1)]` struct"
            )
            && text.contains("a harness binds its own arguments and results in bind group 1"),
        "{text}"
    );
    assert_eq!(err.span, program_span("shade"));
    let g = program.emit(Target::Wgsl, &Selection::harness("count_of")).expect("Pool is group 0");
    validate::validate(&g).unwrap_or_else(|e| panic!("{e}\n{}", g.source));
    assert_eq!(g.harness.expect("layout").input_words, 1);
}
