//! WGSL, as WebGPU and wgpu take it.
//!
//! - `mod.rs`: types, declarations, statements and expressions.
//! - `helpers.rs`: the bodies of the `lp_*` divergence helpers.
//! - `shaders.rs`: the preamble, resource bindings, the entry point, the harness shader.
//! - `reserved.rs`: the names a kernel identifier must not take.
//!
//! WGSL has pointers (`&mut` parameters are `ptr<function, T>`), immutable parameters, typed
//! integer literals (`1i`, `1u`), `u32` shift amounts, `select` instead of `?:`, no implicit
//! use of a value as a statement, and resources as bind-group bindings (uniform blocks and
//! storage buffers) read by indexing.

mod helpers;
mod reserved;
mod shaders;

use crate::ir::BinOp;
use crate::language::{prec, AtomicOp, Bitcast, Fetch, Helper, Helpers, Language, SampleFields, StorageElement, Text};
use crate::types::{Scalar, Ty, U32};

/// The WGSL language.
pub(crate) struct Wgsl;

impl Language for Wgsl {
    fn reserved_words(&self) -> &'static [&'static str] {
        reserved::RESERVED
    }

    fn scalar_type(&self, s: Scalar) -> &'static str {
        match s {
            Scalar::F32 => "f32",
            Scalar::I32 => "i32",
            Scalar::U32 | Scalar::USize => "u32",
            Scalar::Bool => "bool",
        }
    }

    fn vector_type(&self, s: Scalar, n: u8) -> String {
        format!("vec{n}<{}>", self.scalar_type(s))
    }

    fn array_type(&self, elem: &str, n: u32) -> String {
        format!("array<{elem}, {n}>")
    }

    fn decl(&self, t: &Ty, name: &str) -> String {
        format!("{name}: {}", self.type_name(t))
    }

    fn local(&self, t: &Ty, name: &str, mutable: bool) -> String {
        let kw = if mutable { "var" } else { "let" };
        format!("{kw} {}", self.decl(t, name))
    }

    fn struct_decl(&self, name: &str, field_decls: &[String]) -> String {
        let mut out = format!("struct {name} {{\n");
        for d in field_decls {
            out.push_str(&format!("    {d},\n"));
        }
        out.push_str("}\n\n");
        out
    }

    fn const_decl(&self, decl: &str, value: &str) -> String {
        format!("const {decl} = {value};")
    }

    fn function_head(&self, name: &str, params: &[String], ret: &Ty) -> String {
        if *ret == Ty::Unit {
            format!("fn {name}({}) {{", params.join(", "))
        } else {
            format!("fn {name}({}) -> {} {{", params.join(", "), self.type_name(ret))
        }
    }

    fn ref_param(&self, t: &Ty, name: &str) -> String {
        format!("{name}: ptr<function, {}>", self.type_name(t))
    }

    /// WGSL parameters are immutable, and arrays are only indexable dynamically in a `var`.
    fn param_needs_copy(&self, t: &Ty, mutable: bool) -> bool {
        mutable || matches!(t, Ty::Array(..))
    }

    fn if_head(&self, cond: &str) -> String {
        format!("if {cond} {{")
    }

    fn while_head(&self, cond: &str) -> String {
        format!("while {cond} {{")
    }

    fn loop_head(&self) -> String {
        "loop {".into()
    }

    fn for_range_head(&self, var: &str, type_name: &str, start: &str, cmp: &str, end: &str) -> String {
        format!("for (var {var}: {type_name} = {start}; {var} {cmp} {end}; {var}++) {{")
    }

    /// A value that is neither a call nor `()` must be assigned to the phony `_`.
    fn discard(&self, value: &str, used: bool) -> String {
        if used {
            format!("_ = {value};")
        } else {
            format!("{value};")
        }
    }

    fn locals_start_zeroed(&self) -> bool {
        true
    }

    fn fill_array(&self, array: &str, len: u32, index: &str, value: &str) -> String {
        format!("for (var {index}: u32 = 0u; {index} < {len}u; {index}++) {{ {array}[{index}] = {value}; }}")
    }

    fn int_literal(&self, digits: &str, unsigned: bool) -> String {
        let suffix = if unsigned { "u" } else { "i" };
        format!("{digits}{suffix}")
    }

    /// Shift amounts are `u32` in WGSL.
    fn shift_amount(&self, amount: Text, rhs_ty: &Ty) -> Text {
        if rhs_ty.strip_ref() == &U32 {
            return amount;
        }
        let digits = amount.0.trim_end_matches('i');
        (format!("{digits}u"), prec::ATOM)
    }

    fn bitcast(&self, b: Bitcast) -> &'static str {
        match b {
            Bitcast::F32ToU32 | Bitcast::I32ToU32 => "bitcast<u32>",
            Bitcast::U32ToF32 => "bitcast<f32>",
            Bitcast::U32ToI32 => "bitcast<i32>",
        }
    }

    /// Through a function: a WGSL const-expression may not produce NaN or an infinity
    /// (Chromium's Tint rejects `bitcast<f32>(0x7fc00000u)`; naga accepts it), a call of a
    /// user function is never one.
    fn float_from_bits(&self, bits: u32, helpers: &mut Helpers) -> String {
        helpers.insert(Helper::FloatFromBits);
        format!("lp_f32_from_bits({bits:#010x}u)")
    }

    fn deref(&self, pointer: Text) -> Text {
        (format!("*{}", prec::wrap(pointer, prec::ATOM)), prec::UNARY)
    }

    fn address_of(&self, place: Text) -> Text {
        (format!("&{}", prec::wrap(place, prec::ATOM)), prec::UNARY)
    }

    fn auto_deref(&self, pointer: Text) -> Text {
        (format!("(*{})", pointer.0), prec::ATOM)
    }

    /// `select(false_value, true_value, condition)`.
    fn select(&self, cond: Text, then: Text, otherwise: Text) -> Text {
        (format!("select({}, {}, {})", otherwise.0, then.0, cond.0), prec::ATOM)
    }

    fn zero_value(&self, type_name: &str) -> Option<String> {
        Some(format!("{type_name}()"))
    }

    /// `==` and `!=` on vectors are component-wise in WGSL: reduce them as Rust does.
    fn binary(
        &self,
        op: BinOp,
        l: &Text,
        lt: &Ty,
        r: &Text,
        _rt: &Ty,
        _helpers: &mut Helpers,
    ) -> Result<Option<Text>, String> {
        Ok(match op {
            BinOp::Eq | BinOp::Ne if matches!(lt, Ty::Vector(..)) => {
                let f = if op == BinOp::Eq { "all" } else { "any" };
                Some((format!("{f}({} {} {})", l.0, op.symbol(), r.0), prec::ATOM))
            }
            _ => None,
        })
    }

    /// Scalars and vectors are fields of the struct's uniform block (`{global}.{field}`).
    fn resource_field(&self, global: &str, field: &str) -> String {
        format!("{global}.{}", crate::names::safe(field))
    }

    /// Texel arrays share one storage buffer per element type ([`shaders::texel_buffer`]); each
    /// starts at `{global}.lp_start_{field}`.
    fn fetch(&self, global: &str, field: &str, index: Text, fetch: Fetch, _helpers: &mut Helpers) -> String {
        let buffer = shaders::texel_buffer(global, fetch.unsigned);
        format!("{buffer}[{global}.{} + {}]", shaders::start_member(field), prec::wrap(index, prec::MUL))
    }

    fn preamble(&self, header: &str) -> String {
        format!("{header}\n")
    }

    fn resources(&self, blocks: &[crate::language::ResourceBlock]) -> String {
        shaders::resources(blocks)
    }

    fn bindings(&self, blocks: &[crate::language::ResourceBlock]) -> Vec<crate::ResourceBindings> {
        shaders::layout(blocks)
    }

    fn supports_compute(&self) -> bool {
        true
    }

    /// Storage arrays of one element type share a buffer ([`shaders::storage_buffer`]); each
    /// starts at `{global}.lp_start_{field}`.
    fn storage_element(
        &self,
        global: &str,
        field: &str,
        element: StorageElement,
        index: Text,
    ) -> Result<String, String> {
        let buffer = shaders::storage_buffer(global, element);
        Ok(format!("{buffer}[{global}.{} + {}]", shaders::start_member(field), prec::wrap(index, prec::MUL)))
    }

    fn atomic(
        &self,
        global: &str,
        field: &str,
        op: AtomicOp,
        index: Text,
        value: Option<Text>,
    ) -> Result<String, String> {
        let buffer = shaders::atomics_buffer(global);
        let place = format!("&{buffer}[{global}.{} + {}]", shaders::start_member(field), prec::wrap(index, prec::MUL));
        let f = match op {
            AtomicOp::Add => "atomicAdd",
            AtomicOp::Sub => "atomicSub",
            AtomicOp::Min => "atomicMin",
            AtomicOp::Max => "atomicMax",
            AtomicOp::Exchange => "atomicExchange",
            AtomicOp::Load => "atomicLoad",
            AtomicOp::Store => "atomicStore",
        };
        Ok(match value {
            Some(v) => format!("{f}({place}, {})", v.0),
            None => format!("{f}({place})"),
        })
    }

    fn compute_entries(&self, stages: &[String]) -> Result<String, String> {
        Ok(shaders::compute_entries(stages))
    }

    fn helper(&self, h: &Helper) -> String {
        helpers::text(h)
    }

    fn pixel_entry(&self, function: &str, output: crate::PixelOutput, fields: Option<&SampleFields>) -> String {
        shaders::pixel_entry(function, output, fields)
    }

    fn harness_word(&self, k: u32) -> String {
        format!("lp_args[base + {k}u]")
    }

    fn encode_word(&self, s: Scalar, value: &str) -> String {
        match s {
            Scalar::F32 | Scalar::I32 => format!("bitcast<u32>({value})"),
            Scalar::Bool => format!("select(0u, 1u, {value})"),
            Scalar::U32 | Scalar::USize => value.to_string(),
        }
    }

    fn harness_shader(&self, h: &crate::language::HarnessShader) -> String {
        shaders::harness(h)
    }
}
