//! The bodies of the divergence helpers in WGSL.

use crate::language::{Helper, Language as _};

use super::Wgsl;

pub(super) fn text(h: &Helper) -> String {
    match h {
        Helper::U32ToF32 => "// u32 as f32, rounded to nearest even like Rust: both halves convert exactly, the sum rounds once.\nfn lp_u32_to_f32(x: u32) -> f32 {\n    return f32(x >> 16u) * 65536.0 + f32(x & 65535u);\n}\n".into(),
        Helper::I32ToF32 => "// i32 as f32 (magnitude through lp_u32_to_f32, so i32::MIN works).\nfn lp_i32_to_f32(x: i32) -> f32 {\n    if x < 0 {\n        return -lp_u32_to_f32(0u - bitcast<u32>(x));\n    }\n    return lp_u32_to_f32(bitcast<u32>(x));\n}\n".into(),
        Helper::F32ToU32 => "// f32 as u32 saturates like Rust: NaN and negatives give 0, too large gives u32::MAX.\nfn lp_f32_to_u32(x: f32) -> u32 {\n    if x >= 4294967296.0 {\n        return 4294967295u;\n    }\n    if x > 0.0 {\n        return u32(x);\n    }\n    return 0u;\n}\n".into(),
        Helper::F32ToI32 => "// f32 as i32 saturates like Rust: NaN gives 0, out of range gives i32::MIN/MAX.\nfn lp_f32_to_i32(x: f32) -> i32 {\n    if x >= 2147483648.0 {\n        return 2147483647i;\n    }\n    if x >= -2147483648.0 {\n        return i32(x);\n    }\n    if x < 0.0 {\n        return -2147483647i - 1i;\n    }\n    return 0i;\n}\n".into(),
        // WGSL's integer `/` and `%` and float `%` already truncate like Rust: the lowering
        // never asks for these.
        Helper::DivI32 | Helper::RemI32 | Helper::FmodF32 | Helper::FetchVec4(_) | Helper::FetchUVec4(_) => {
            unreachable!("WGSL never asks for {h:?}")
        }
        Helper::FloatFromBits => "// NaN and infinities at run time: a WGSL constant expression may not produce them.\nfn lp_f32_from_bits(bits: u32) -> f32 {\n    return bitcast<f32>(bits);\n}\n".into(),
        Helper::IsNan => "// From the bits: drivers may fold NaN checks away under fast-math.\nfn lp_is_nan(x: f32) -> bool {\n    return (bitcast<u32>(x) & 0x7fffffffu) > 0x7f800000u;\n}\n".into(),
        Helper::IsInfinite => "fn lp_is_infinite(x: f32) -> bool {\n    return (bitcast<u32>(x) & 0x7fffffffu) == 0x7f800000u;\n}\n".into(),
        Helper::IsFinite => "fn lp_is_finite(x: f32) -> bool {\n    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;\n}\n".into(),
        Helper::Signum => "// Rust's signum: 1.0 for +0.0, -1.0 for -0.0, NaN stays NaN (WGSL's sign(0.0) is 0.0).\nfn lp_signum(x: f32) -> f32 {\n    if lp_is_nan(x) {\n        return x;\n    }\n    return select(1.0, -1.0, (bitcast<u32>(x) & 0x80000000u) != 0u);\n}\n".into(),
        Helper::Round => "// Rust's round: halves away from zero (WGSL's round() goes to even).\nfn lp_round(x: f32) -> f32 {\n    var t: f32 = trunc(x);\n    if abs(x - t) >= 0.5 {\n        t += sign(x);\n    }\n    return t;\n}\n".into(),
        Helper::Fract { ty: t, suffix: s } => format!("// Rust's fract: x - trunc(x) (WGSL's fract() is x - floor(x)).\nfn lp_fract_{s}(x: {t}) -> {t} {{\n    return x - trunc(x);\n}}\n"),
        Helper::LengthSquared { ty: t, suffix: s } => format!("fn lp_length_squared_{s}(v: {t}) -> f32 {{\n    return dot(v, v);\n}}\n"),
        Helper::Reduce { op, ty, n, suffix, scalar } => {
            let (name, expr) = crate::lower::reduce_parts(op, *n);
            let scalar = Wgsl.scalar_type(*scalar);
            format!("fn lp_{name}_{suffix}(v: {ty}) -> {scalar} {{\n    return {expr};\n}}\n")
        }
    }
}
