//! GLSL ES 3.00 (`#version 300 es`): WebGL2, OpenGL ES 3.0+, desktop GL with ES compatibility.
//!
//! - `mod.rs`: types, declarations, statements and expressions.
//! - `helpers.rs`: the bodies of the `lp_*` divergence helpers.
//! - `shaders.rs`: the preamble, resource declarations, the entry point, the harness shader.
//! - `reserved.rs`: the names a kernel identifier must not take.
//!
//! GLSL ES 3.00 has no pointers (`&mut` parameters are `inout`), no integer division or `%`
//! defined for negative operands, a flooring `mod()`, no NaN/Inf literals, and resources as
//! uniforms and samplers (data textures read with `texelFetch`).

mod helpers;
mod reserved;
mod shaders;

use crate::ir::BinOp;
use crate::language::{prec, Bitcast, Fetch, Helper, Helpers, Language, SampleFields, Text};
use crate::types::{Scalar, Ty, I32};

pub(crate) use shaders::fullscreen_vertex_shader;

/// The GLSL ES 3.00 language.
pub(crate) struct Glsl;

impl Language for Glsl {
    fn reserved_words(&self) -> &'static [&'static str] {
        reserved::RESERVED
    }

    fn reserved_prefixes(&self) -> &'static [&'static str] {
        &["gl_"]
    }

    fn scalar_type(&self, s: Scalar) -> &'static str {
        match s {
            Scalar::F32 => "float",
            Scalar::I32 => "int",
            Scalar::U32 | Scalar::USize => "uint",
            Scalar::Bool => "bool",
        }
    }

    fn vector_type(&self, s: Scalar, n: u8) -> String {
        let p = match s {
            Scalar::F32 => "",
            Scalar::I32 => "i",
            Scalar::U32 | Scalar::USize => "u",
            Scalar::Bool => "b",
        };
        format!("{p}vec{n}")
    }

    fn array_type(&self, elem: &str, n: u32) -> String {
        format!("{elem}[{n}]")
    }

    /// `T name`; arrays `T name[N]`.
    fn decl(&self, t: &Ty, name: &str) -> String {
        match t {
            Ty::Array(elem, n) => format!("{} {name}[{n}]", self.type_name(elem)),
            _ => format!("{} {name}", self.type_name(t)),
        }
    }

    fn local(&self, t: &Ty, name: &str, _mutable: bool) -> String {
        self.decl(t, name)
    }

    fn struct_decl(&self, name: &str, field_decls: &[String]) -> String {
        let mut out = format!("struct {name} {{\n");
        for d in field_decls {
            out.push_str(&format!("    {d};\n"));
        }
        out.push_str("};\n\n");
        out
    }

    fn const_decl(&self, decl: &str, value: &str) -> String {
        format!("const {decl} = {value};")
    }

    fn function_head(&self, name: &str, params: &[String], ret: &Ty) -> String {
        format!("{} {name}({}) {{", self.type_name(ret), params.join(", "))
    }

    fn ref_param(&self, t: &Ty, name: &str) -> String {
        format!("inout {}", self.decl(t, name))
    }

    fn param_needs_copy(&self, _t: &Ty, _mutable: bool) -> bool {
        false
    }

    fn if_head(&self, cond: &str) -> String {
        format!("if ({cond}) {{")
    }

    fn while_head(&self, cond: &str) -> String {
        format!("while ({cond}) {{")
    }

    fn loop_head(&self) -> String {
        "while (true) {".into()
    }

    fn for_range_head(&self, var: &str, type_name: &str, start: &str, cmp: &str, end: &str) -> String {
        format!("for ({type_name} {var} = {start}; {var} {cmp} {end}; ++{var}) {{")
    }

    fn discard(&self, value: &str, _used: bool) -> String {
        format!("{value};")
    }

    /// GLSL leaves locals undefined.
    fn locals_start_zeroed(&self) -> bool {
        false
    }

    fn fill_array(&self, array: &str, len: u32, index: &str, value: &str) -> String {
        format!("for (int {index} = 0; {index} < {len}; ++{index}) {{ {array}[{index}] = {value}; }}")
    }

    fn int_literal(&self, digits: &str, unsigned: bool) -> String {
        if unsigned {
            format!("{digits}u")
        } else {
            digits.to_string()
        }
    }

    fn shift_amount(&self, amount: Text, _rhs_ty: &Ty) -> Text {
        amount
    }

    fn bitcast(&self, b: Bitcast) -> &'static str {
        match b {
            Bitcast::F32ToU32 => "floatBitsToUint",
            Bitcast::U32ToF32 => "uintBitsToFloat",
            Bitcast::I32ToU32 => "uint",
            Bitcast::U32ToI32 => "int",
        }
    }

    /// `inout` parameters are values: no pointer syntax.
    fn deref(&self, pointer: Text) -> Text {
        pointer
    }

    fn address_of(&self, place: Text) -> Text {
        place
    }

    fn auto_deref(&self, pointer: Text) -> Text {
        pointer
    }

    fn select(&self, cond: Text, then: Text, otherwise: Text) -> Text {
        let w = |t: Text, min: u8| prec::wrap(t, min);
        (
            format!(
                "{} ? {} : {}",
                w(cond, prec::TERNARY + 1),
                w(then, prec::TERNARY + 1),
                w(otherwise, prec::TERNARY)
            ),
            prec::TERNARY,
        )
    }

    fn zero_value(&self, _type_name: &str) -> Option<String> {
        None
    }

    /// GLSL ES leaves integer `/` and `%` undefined for negative operands, and its float `mod()`
    /// floors where Rust's `%` truncates.
    fn binary(
        &self,
        op: BinOp,
        l: &Text,
        lt: &Ty,
        r: &Text,
        rt: &Ty,
        helpers: &mut Helpers,
    ) -> Result<Option<Text>, String> {
        Ok(match op {
            BinOp::Div if *lt == I32 => {
                helpers.insert(Helper::DivI32);
                Some((format!("lp_div_i32({}, {})", l.0, r.0), prec::ATOM))
            }
            BinOp::Rem if *lt == I32 => {
                helpers.insert(Helper::DivI32);
                helpers.insert(Helper::RemI32);
                Some((format!("lp_rem_i32({}, {})", l.0, r.0), prec::ATOM))
            }
            BinOp::Rem if lt.scalar() == Some(Scalar::F32) => {
                if matches!(lt, Ty::Vector(..)) || matches!(rt, Ty::Vector(..)) {
                    return Err("`%` on float vectors is not supported: apply it per component".into());
                }
                helpers.insert(Helper::FmodF32);
                Some((format!("lp_fmod_f32({}, {})", l.0, r.0), prec::ATOM))
            }
            _ => None,
        })
    }

    fn builtin(&self, name: &'static str) -> &'static str {
        match name {
            "atan2" => "atan",
            other => other,
        }
    }

    /// Every resource field is its own uniform: `{global}_{field}`.
    fn resource_field(&self, global: &str, field: &str) -> String {
        format!("{global}_{field}")
    }

    /// Every texel array is its own data texture, `{global}_{field}`.
    fn fetch(&self, global: &str, field: &str, index: Text, fetch: Fetch, helpers: &mut Helpers) -> String {
        let (h, name) = if fetch.unsigned {
            (Helper::FetchUVec4(fetch.rows), "lp_fetch_uvec4")
        } else {
            (Helper::FetchVec4(fetch.rows), "lp_fetch_vec4")
        };
        helpers.insert(h);
        format!("{name}({global}_{field}, {})", index.0)
    }

    fn preamble(&self, header: &str) -> String {
        shaders::preamble(header)
    }

    fn resources(&self, blocks: &[crate::language::ResourceBlock]) -> String {
        shaders::resources(blocks)
    }

    fn helper(&self, h: &Helper) -> String {
        helpers::text(h)
    }

    fn pixel_entry(&self, function: &str, output: crate::PixelOutput, fields: Option<&SampleFields>) -> String {
        shaders::pixel_entry(function, output, fields)
    }

    fn harness_word(&self, k: u32) -> String {
        format!("lp_word(base, {k}u)")
    }

    fn encode_word(&self, s: Scalar, value: &str) -> String {
        match s {
            Scalar::F32 => format!("floatBitsToUint({value})"),
            Scalar::I32 | Scalar::Bool => format!("uint({value})"),
            Scalar::U32 | Scalar::USize => value.to_string(),
        }
    }

    fn harness_shader(&self, h: &crate::language::HarnessShader) -> String {
        shaders::harness(h)
    }
}
