//! `&mut` arguments: a kernel function's pointer argument is the address of a whole variable.
//! `f(&mut path.rng)` or `f(&mut a[i])` is valid Rust but not WGSL (a pointer argument must be
//! "the same memory view as its root identifier" without the `unrestricted_pointer_parameters`
//! extension: Chromium's Tint rejects it, naga's SPIR-V writer panics on it, gfx-rs/wgpu #4540
//! and #6875), so it is a codegen error at the argument on every target, saying what to write.

// The `#[kernel]` modules here are read as IR and generated.
#![allow(dead_code)]

use lightport_codegen::{validate, Program, Selection, Target};

/// What is allowed: a local, a `&mut` parameter passed on (or re-borrowed), and a field or
/// element copied into a local and written back.
#[kernel_dsl::kernel]
pub mod whole {
    pub struct Path {
        pub rng: u32,
        pub depth: u32,
    }

    pub fn step(state: &mut u32) -> u32 {
        *state = state.wrapping_mul(747796405).wrapping_add(2891336453);
        *state
    }

    pub fn pass_on(state: &mut u32) -> u32 {
        step(state).wrapping_add(step(&mut *state))
    }

    pub fn copied(path: &mut Path, streams: [u32; 4], i: u32) -> u32 {
        let mut rng = path.rng;
        let a = step(&mut rng);
        path.rng = rng;
        let mut local = streams;
        let mut element = local[i as usize];
        let b = step(&mut element);
        local[i as usize] = element;
        let mut whole = 7u32;
        let c = step(&mut whole).wrapping_add(pass_on(&mut whole));
        a.wrapping_add(b).wrapping_add(c).wrapping_add(local[0])
    }
}

/// A field of a `&mut` parameter.
#[kernel_dsl::kernel]
pub mod field_of_param {
    use super::whole::{step, Path};

    pub fn advance(path: &mut Path) -> u32 {
        path.depth += 1;
        step(&mut path.rng)
    }
}

/// A field of a local struct, in parentheses.
#[kernel_dsl::kernel]
pub mod field_of_local {
    use super::whole::{step, Path};

    pub fn fresh(seed: u32) -> u32 {
        let mut path = Path { rng: seed, depth: 0 };
        step(&mut (path.rng)).wrapping_add(path.depth)
    }
}

/// An element of a local array.
#[kernel_dsl::kernel]
pub mod element {
    use super::whole::step;

    #[allow(clippy::needless_range_loop)]
    pub fn each(seed: u32) -> u32 {
        let mut streams = [seed; 4];
        let mut sum = 0u32;
        for i in 0..4 {
            sum = sum.wrapping_add(step(&mut streams[i]));
        }
        sum
    }
}

/// Where `needle` first starts in this file outside comments, as spans count: (1-based line,
/// 0-based column).
fn span_of(needle: &str) -> (u32, u32) {
    let source = include_str!("pointer_arguments.rs");
    let (line, text) = source
        .lines()
        .enumerate()
        .find(|(_, l)| l.contains(needle) && !l.trim_start().starts_with("//"))
        .unwrap_or_else(|| panic!("`{needle}` in this file"));
    (line as u32 + 1, text.find(needle).expect("on its line") as u32)
}

#[test]
fn whole_variables_generate_for_every_target() {
    let program = Program::link(&[whole::kernel_ir()]).expect("links");
    let selection = Selection::module(&program, "whole");
    for target in Target::ALL {
        let g = program.emit(target, &selection).expect("emits");
        validate::validate(&g).unwrap_or_else(|e| panic!("{target:?}: {e}\n{}", g.source));
    }
    // And they run as Rust.
    let mut path = whole::Path { rng: 1, depth: 0 };
    let _ = whole::copied(&mut path, [1, 2, 3, 4], 2);
    assert_ne!(path.rng, 1, "the copy is written back");
}

#[test]
fn a_field_or_element_is_refused_at_the_argument() {
    for (module, needle, function, message) in [
        (
            field_of_param::kernel_ir(),
            "&mut path.rng",
            "field_of_param::advance",
            "`&mut path.rng` passes a pointer to a field: WGSL takes only the address of a whole variable as a function's pointer argument. Copy it into a local, pass `&mut local`, and write it back: `let mut rng = path.rng; f(.., &mut rng, ..); path.rng = rng;`",
        ),
        (
            field_of_local::kernel_ir(),
            "&mut (path.rng)",
            "field_of_local::fresh",
            "`&mut (path.rng)` passes a pointer to a field",
        ),
        (
            element::kernel_ir(),
            "&mut streams[i]",
            "element::each",
            "`&mut streams[i]` passes a pointer to an array element: WGSL takes only the address of a whole variable as a function's pointer argument. Copy it into a local, pass `&mut local`, and write it back: `let mut element = streams[i]; f(.., &mut element, ..); streams[i] = element;`",
        ),
    ] {
        // Refused when the program is linked: before any target is chosen.
        let err = Program::link(&[whole::kernel_ir(), module]).expect_err(needle);
        let text = err.to_string();
        assert!(text.contains(message), "{needle}: {text}");
        assert!(text.contains("pointer_arguments.rs:"), "{needle}: {text}");
        assert_eq!(err.function.as_deref(), Some(function), "{needle}: {text}");
        assert_eq!((err.span.line, err.span.column), span_of(needle), "{needle}: {text}");
    }
}
