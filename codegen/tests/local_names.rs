//! A local binding named like something the whole program declares (a kernel function, a
//! struct, the global a `#[resources]` struct or one of its fields becomes) is renamed in the
//! generated code, where it would otherwise hide that declaration: Rust still resolves the
//! struct literal and the resource fields after such a local, the shader would not.
//! Program-wide names are asked of the program, not copied into each function's set of names
//! (`names::unique_local`).

// The `#[kernel]` module here is read as IR and generated.
#![allow(dead_code, non_snake_case, clippy::let_and_return)]

use lightport_codegen::{validate, Program, Selection, Target};

#[kernel_dsl::kernel]
pub mod clashing {
    use glam::Vec4;
    use kernel_dsl::Texels;

    pub const LIMIT: f32 = 4.0;

    #[resources]
    pub struct Res {
        pub table: Texels<Vec4>,
        pub gain: f32,
    }

    pub struct Pair {
        pub a: f32,
        pub b: f32,
    }

    pub fn twice(x: f32) -> f32 {
        x * 2.0
    }

    pub fn locals(res: &Res, x: f32) -> f32 {
        let twice = twice(x);
        let Pair = twice + LIMIT;
        let scaled = Pair * res.gain;
        let res_gain = scaled + res.table.fetch(0).x;
        let res_table = res_gain + twice;
        let pair = Pair { a: res_table, b: LIMIT };
        pair.a + pair.b
    }
}

#[test]
fn locals_named_like_program_wide_declarations_are_renamed_on_every_target() {
    let program = Program::link(&[clashing::kernel_ir()]).expect("links");
    let selection = Selection { roots: vec!["locals".into()], ..Selection::default() };
    for target in [Target::Wgsl, Target::GlslEs300] {
        let generated = program.emit(target, &selection).expect("generates");
        validate::validate(&generated).unwrap_or_else(|e| panic!("{target:?}: {e}\n{}", generated.source));
        let source = &generated.source;
        for renamed in ["twice_1", "Pair_1", "res_gain_1", "res_table_1"] {
            assert!(source.contains(renamed), "{target:?}: no local `{renamed}` in\n{source}");
        }
        // The declarations themselves keep their names.
        for kept in ["twice(x)", "LIMIT"] {
            assert!(source.contains(kept), "{target:?}: `{kept}` missing from\n{source}");
        }
    }
}
