//! The interface between the target-independent lowering (`lower/`) and one shading language
//! (`glsl/`, `wgsl/`, ...).
//!
//! The lowering decides everything that is the same in every language: which functions,
//! structs, consts and resources are emitted and in which order, what becomes a statement and
//! what an expression, which branches specialisation removes, names, the source map, and which
//! divergence helper (`lp_*`) a construct needs. It writes the core that all C-family shading
//! languages share (blocks in braces, `;`-terminated statements, `return`/`break`/`continue`,
//! assignments, calls, field access, indexing, constructors `T(..)`, operators with C
//! precedence) and asks a [`Language`] for everything else: type and declaration syntax,
//! literals, conversions, pointers, control-flow headers, resource declarations and fetches,
//! helper bodies, entry points and the harness shader.
//!
//! A new target is a new module with the same files as `glsl/` and `wgsl/` and an
//! implementation of this trait; the compiler lists what it has to provide. Entry kinds grow
//! the same way: a new kind is a new method here (with a default that refuses it, so a
//! language that cannot express it says so) and a new [`crate::EntryPoint`] shape.

use std::collections::BTreeSet;

use crate::ir::BinOp;
use crate::types::{Scalar, Ty};
use crate::Harness;

/// Semantic helpers: functions that keep the DSL's (Rust's) meaning where a language's
/// built-in differs. The lowering or the language asks for one; the language writes its
/// body ([`Language::helper`]). Emitted once each, in this order (dependencies first).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Helper {
    U32ToF32,
    I32ToF32,
    F32ToU32,
    F32ToI32,
    DivI32,
    RemI32,
    FmodF32,
    IsNan,
    IsInfinite,
    IsFinite,
    Signum,
    Round,
    /// `x - trunc(x)` for the type named `ty` in the target language (helper name suffix
    /// `suffix`).
    Fract {
        ty: String,
        suffix: String,
    },
    LengthSquared {
        ty: String,
        suffix: String,
    },
    /// A left-to-right fold of the `n` components of a vector with `op` (`min`, `max`, `+`
    /// or `*`).
    Reduce {
        op: &'static str,
        ty: String,
        n: u8,
        suffix: String,
        scalar: Scalar,
    },
    FetchVec4(crate::TexelRows),
    FetchUVec4(crate::TexelRows),
    /// WGSL: `bitcast<f32>` of a constant behind a function call (see `float_from_bits`).
    FloatFromBits,
}

/// What a texel fetch reads: unsigned (`Texels<UVec4>`) or float texels, laid out how.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fetch {
    pub unsigned: bool,
    pub rows: crate::TexelRows,
}

/// Helpers a language asks for while writing an expression.
pub(crate) type Helpers = BTreeSet<Helper>;

/// Reinterpretations of a 32-bit value as another type (no conversion of the value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Bitcast {
    F32ToU32,
    U32ToF32,
    I32ToU32,
    U32ToI32,
}

/// An expression's text and its precedence ([`prec`]): the lowering parenthesises an operand
/// whose precedence is below what its context needs.
pub(crate) type Text = (String, u8);

/// Operator precedence, the same in every C-family shading language (WGSL's stricter grammar
/// for bitwise operators and shifts is kept by the lowering's operand rules).
pub(crate) mod prec {
    pub const TERNARY: u8 = 3;
    pub const LOR: u8 = 4;
    pub const LAND: u8 = 5;
    pub const BOR: u8 = 6;
    pub const BXOR: u8 = 7;
    pub const BAND: u8 = 8;
    pub const EQ: u8 = 9;
    pub const REL: u8 = 10;
    pub const SHIFT: u8 = 11;
    pub const ADD: u8 = 12;
    pub const MUL: u8 = 13;
    pub const UNARY: u8 = 14;
    pub const ATOM: u8 = 16;

    /// `s`, parenthesised when its precedence is below `min`.
    pub fn wrap(s: super::Text, min: u8) -> String {
        if s.1 < min {
            format!("({})", s.0)
        } else {
            s.0
        }
    }
}

/// One `#[resources]` struct's fields that the emitted code uses, in declaration order.
pub(crate) struct ResourceBlock {
    /// The Rust struct name (`Scene`).
    pub name: String,
    /// Its global name in generated code (`scene`); a field's global is `{global}_{field}`.
    pub global: String,
    /// `Scene (file:line)`, for the comment above the declarations.
    pub origin: String,
    /// `#[resources(group = N)]`: the bind group of its bindings, where a language has groups.
    pub group: u32,
    /// Its scalars bound as read-only storage rather than a uniform ([`crate::BindingKind::Scalars`]):
    /// group 0 of a module with compute stages.
    pub scalars_in_storage: bool,
    pub fields: Vec<ResourceField>,
}

pub(crate) struct ResourceField {
    /// The Rust field name.
    pub name: String,
    /// The field's type as the kernel source spells it (`f32`, `Vec3`, `Texels<Vec4>`).
    pub dsl_type: String,
    pub kind: ResourceKind,
}

pub(crate) enum ResourceKind {
    /// `Texels<Vec4>` (`unsigned: false`) or `Texels<UVec4>`: an array of 4-component texels.
    Texels { unsigned: bool },
    /// A scalar or vector set once per dispatch, with the language's type name.
    Uniform { type_name: String },
    /// `Storage<T>` (compute modules): a read-write array of `element`.
    Storage { element: StorageElement },
    /// `Atomics` (compute modules): `u32` counters updated atomically.
    Atomics,
}

/// The element of a `Storage<T>` resource field, in the order its buffers are bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum StorageElement {
    Vec4,
    UVec4,
    U32,
    F32,
}

impl StorageElement {
    pub fn of(t: &Ty) -> Option<StorageElement> {
        Some(match t {
            Ty::Vector(Scalar::F32, 4) => StorageElement::Vec4,
            Ty::Vector(Scalar::U32, 4) => StorageElement::UVec4,
            Ty::Scalar(Scalar::U32) => StorageElement::U32,
            Ty::Scalar(Scalar::F32) => StorageElement::F32,
            _ => return None,
        })
    }

    /// The type as the kernel source spells it.
    pub fn dsl_type(self) -> &'static str {
        match self {
            StorageElement::Vec4 => "Vec4",
            StorageElement::UVec4 => "UVec4",
            StorageElement::U32 => "u32",
            StorageElement::F32 => "f32",
        }
    }
}

/// An atomic operation on a counter of an `Atomics` resource field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum AtomicOp {
    Add,
    Sub,
    Min,
    Max,
    Exchange,
    Load,
    Store,
}

impl AtomicOp {
    /// The op of a DSL method (`atomic_add`).
    pub fn of_method(method: &str) -> Option<AtomicOp> {
        Some(match method {
            "atomic_add" => AtomicOp::Add,
            "atomic_sub" => AtomicOp::Sub,
            "atomic_min" => AtomicOp::Min,
            "atomic_max" => AtomicOp::Max,
            "atomic_exchange" => AtomicOp::Exchange,
            "atomic_load" => AtomicOp::Load,
            "atomic_store" => AtomicOp::Store,
            _ => return None,
        })
    }
}

/// One argument of the kernel function a harness calls: its value decoded from input words.
pub(crate) struct HarnessArg {
    /// The local that holds it (`lp_arg0`).
    pub name: String,
    pub type_name: String,
    /// An expression building the value from the input words.
    pub value: String,
    /// `&mut` parameter: passed by reference, its final value is an output.
    pub by_ref: bool,
}

/// What a language needs to write an equivalence-test harness shader (see [`Harness`]).
pub(crate) struct HarnessShader<'h> {
    pub layout: &'h Harness,
    /// The kernel function's name in generated code.
    pub function: String,
    pub args: Vec<HarnessArg>,
    /// The return type's name, or `None` for a function without a value.
    pub result_type: Option<String>,
    /// `lp_w[k] = word;` statements storing every output word (return value first, then each
    /// `&mut` argument's final value); they read the result from `lp_result`.
    pub stores: Vec<String>,
}

/// Everything that is one shading language's own. See the module documentation for what
/// stays in the lowering.
pub(crate) trait Language {
    // ------------------------------------------------------------ names and types

    /// Keywords, reserved words and built-ins a kernel name must not take (it gets a `_`).
    fn reserved_words(&self) -> &'static [&'static str];
    /// Prefixes the language reserves for itself (`gl_`).
    fn reserved_prefixes(&self) -> &'static [&'static str] {
        &[]
    }
    fn scalar_type(&self, s: Scalar) -> &'static str;
    fn vector_type(&self, s: Scalar, n: u8) -> String;
    /// The name of a type as a value (parameter type, constructor, return type). Structs are
    /// named by [`crate::names::safe`].
    fn type_name(&self, t: &Ty) -> String {
        match t {
            Ty::Scalar(s) => self.scalar_type(*s).to_string(),
            Ty::IntVar(_) => self.scalar_type(Scalar::I32).to_string(),
            Ty::Vector(s, n) => self.vector_type(*s, *n),
            Ty::Struct(name) => crate::names::safe(name),
            Ty::Array(elem, n) => self.array_type(&self.type_name(elem), *n),
            Ty::RefMut(inner) => self.type_name(inner),
            Ty::Unit | Ty::Never => "void".into(),
            Ty::Texels(_) | Ty::Storage(_) | Ty::Atomics | Ty::Resource(_) => "<resource>".into(),
        }
    }
    fn array_type(&self, elem: &str, n: u32) -> String;
    /// A typed name: a struct field, a parameter, the part of a local declaration after its
    /// keyword.
    fn decl(&self, t: &Ty, name: &str) -> String;
    /// A local binding without its initialiser: `T name` / `var name: T` / `let name: T`.
    fn local(&self, t: &Ty, name: &str, mutable: bool) -> String;
    fn struct_decl(&self, name: &str, field_decls: &[String]) -> String;
    fn const_decl(&self, decl: &str, value: &str) -> String;

    // ------------------------------------------------------------ functions

    /// The function's first line, ending in `{`.
    fn function_head(&self, name: &str, params: &[String], ret: &Ty) -> String;
    /// A `&mut T` parameter.
    fn ref_param(&self, t: &Ty, name: &str) -> String;
    /// Whether a by-value parameter must be copied into a local to be assigned or indexed
    /// (the lowering then declares the parameter under another name and copies it).
    fn param_needs_copy(&self, t: &Ty, mutable: bool) -> bool;

    // ------------------------------------------------------------ statements

    /// `if (c) {` / `if c {` (an `else if` is `} else ` followed by this).
    fn if_head(&self, cond: &str) -> String;
    fn while_head(&self, cond: &str) -> String;
    fn loop_head(&self) -> String;
    /// `for` over `start..end` (`cmp` is `<` or `<=`) with the loop variable `var` of type
    /// `type_name`.
    fn for_range_head(&self, var: &str, type_name: &str, start: &str, cmp: &str, end: &str) -> String;
    /// A statement evaluating `value` for its effects; `used` when it is neither a call nor of
    /// unit type (some languages reject an unused value).
    fn discard(&self, value: &str, used: bool) -> String;
    /// Whether locals start zeroed (a `[0; N]` initialiser then needs no code).
    fn locals_start_zeroed(&self) -> bool;
    /// A statement setting each of the `len` elements of `array` to `value`, with `index` as
    /// the loop variable.
    fn fill_array(&self, array: &str, len: u32, index: &str, value: &str) -> String;

    // ------------------------------------------------------------ expressions

    /// An integer literal of a signed (`unsigned: false`) or unsigned 32-bit type.
    fn int_literal(&self, digits: &str, unsigned: bool) -> String;
    /// The amount of a shift by a literal (`rhs_ty` its type in Rust).
    fn shift_amount(&self, amount: Text, rhs_ty: &Ty) -> Text;
    fn bitcast(&self, b: Bitcast) -> &'static str;
    /// NaN or an infinity from its bits, as an expression (no language has a literal for them).
    fn float_from_bits(&self, bits: u32, _helpers: &mut Helpers) -> String {
        format!("{}({bits:#010x}u)", self.bitcast(Bitcast::U32ToF32))
    }
    /// `*p` of a `&mut` parameter.
    fn deref(&self, pointer: Text) -> Text;
    /// `&mut place` passed to a `&mut` parameter.
    fn address_of(&self, place: Text) -> Text;
    /// A `&mut` value used as its target (fields, indexing, method receivers).
    fn auto_deref(&self, pointer: Text) -> Text;
    /// `if c { a } else { b }` as an expression.
    fn select(&self, cond: Text, then: Text, otherwise: Text) -> Text;
    /// A constructor of the all-zero value of `type_name`, if the language has one.
    fn zero_value(&self, type_name: &str) -> Option<String>;
    /// A language spelling for a binary operation, or `Ok(None)` for the C operator; `Err`
    /// for one the language cannot express (the message says what to write instead).
    fn binary(
        &self,
        op: BinOp,
        l: &Text,
        lt: &Ty,
        r: &Text,
        rt: &Ty,
        helpers: &mut Helpers,
    ) -> Result<Option<Text>, String>;
    /// The name of a built-in function where it differs from the common one (`atan2`).
    fn builtin(&self, name: &'static str) -> &'static str {
        name
    }
    /// The scalar or vector field `field` of resource struct global `global`.
    fn resource_field(&self, global: &str, field: &str) -> String;
    /// Texel `index` of the texel array `field` of resource struct global `global`.
    fn fetch(&self, global: &str, field: &str, index: Text, fetch: Fetch, helpers: &mut Helpers) -> String;

    // ------------------------------------------------------------ compute (storage, atomics)

    /// Whether the language has storage buffers and atomics (compute modules and compute
    /// entry points). A language without them refuses compute modules at the function before
    /// anything below is asked for; should one be asked for anyway, its default is an error
    /// (`Err`: the message), never a panic.
    fn supports_compute(&self) -> bool {
        false
    }
    /// Element `index` of the storage array `field` of resource struct global `global`, as a
    /// place (read, or assigned by a statement).
    fn storage_element(
        &self,
        _global: &str,
        _field: &str,
        _element: StorageElement,
        _index: Text,
    ) -> Result<String, String> {
        Err(no_compute("`Storage` arrays"))
    }
    /// An atomic operation on counter `index` of the `Atomics` field `field` (`value`: its
    /// operand, none for a load).
    fn atomic(
        &self,
        _global: &str,
        _field: &str,
        _op: AtomicOp,
        _index: Text,
        _value: Option<Text>,
    ) -> Result<String, String> {
        Err(no_compute("atomics"))
    }
    /// The compute entry points, one per stage function `fn(.., invocation: u32)` (names in
    /// generated code).
    fn compute_entries(&self, _stages: &[String]) -> Result<String, String> {
        Err(no_compute("compute entry points"))
    }

    // ------------------------------------------------------------ the file around the functions

    /// The first lines: version, the `header` comment, precision and the like.
    fn preamble(&self, header: &str) -> String;
    fn resources(&self, blocks: &[ResourceBlock]) -> String;
    /// The bind groups and bindings [`Language::resources`] declares, for hosts; empty where the
    /// language binds resources by name (GLSL's uniforms and samplers).
    fn bindings(&self, _blocks: &[ResourceBlock]) -> Vec<crate::ResourceBindings> {
        Vec::new()
    }
    fn helper(&self, h: &Helper) -> String;
    /// The entry point around `fn(&Resources, x: u32, y: u32) -> Vec4` named `function`, doing
    /// `output` with its value (see [`crate::EntryPoint`]).
    /// The entry point around `function`; `fields`: when it returns a struct of Vec4s, that
    /// struct, each field accumulated into its own target (None: it returns one Vec4).
    fn pixel_entry(&self, function: &str, output: crate::PixelOutput, fields: Option<&SampleFields>) -> String;

    // ------------------------------------------------------------ the equivalence harness

    /// Input word `k` of the current invocation.
    fn harness_word(&self, k: u32) -> String;
    /// A scalar of type `s` from the input word `word`.
    fn decode_word(&self, s: Scalar, word: &str) -> String {
        match s {
            Scalar::F32 => format!("{}({word})", self.bitcast(Bitcast::U32ToF32)),
            Scalar::I32 => format!("{}({word})", self.bitcast(Bitcast::U32ToI32)),
            Scalar::Bool => format!("({word} != 0u)"),
            Scalar::U32 | Scalar::USize => word.to_string(),
        }
    }
    /// The output word of a scalar `value` of type `s`.
    fn encode_word(&self, s: Scalar, value: &str) -> String;
    fn harness_shader(&self, h: &HarnessShader) -> String;
}

/// The refusal of a compute construct by a language without compute.
fn no_compute(what: &str) -> String {
    format!("this target has no {what} (no storage buffers, atomics or compute shaders): compute kernels are generated for WGSL and the CPU only")
}

/// The struct an accumulating entry point's function returns: its type's name and its Vec4
/// fields, in order (output 0 is the first field).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SampleFields {
    pub type_name: String,
    pub fields: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::{prec, AtomicOp, StorageElement};
    use crate::Target;

    /// A language without compute answers a compute construct with an error, not a panic, if
    /// the lowering's refusal at the function (`lower::refuse_compute`) is ever bypassed.
    #[test]
    fn a_language_without_compute_refuses_it_with_errors() {
        let glsl = Target::GlslEs300.language();
        assert!(!glsl.supports_compute());
        let index = || ("i".to_string(), prec::ATOM);
        let storage = glsl.storage_element("pool", "items", StorageElement::U32, index());
        let atomic = glsl.atomic("pool", "counters", AtomicOp::Add, index(), Some(("1u".into(), prec::ATOM)));
        let entries = glsl.compute_entries(&["shade".to_string()]);
        for (what, result) in [("storage", storage), ("atomic", atomic), ("entries", entries)] {
            let message = result.expect_err(what);
            assert!(message.contains("compute kernels are generated for WGSL and the CPU only"), "{what}: {message}");
        }
        assert!(Target::Wgsl.language().compute_entries(&["shade".to_string()]).is_ok());
    }
}
