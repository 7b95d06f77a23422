//! The bodies of the divergence helpers in GLSL ES 3.00.

use crate::language::{Helper, Language as _};
use crate::TexelRows;

use super::Glsl;

pub(super) fn text(h: &Helper) -> String {
    match h {
        Helper::U32ToF32 => "// u32 as f32, rounded to nearest even like Rust: both halves convert exactly, the sum rounds once.\nfloat lp_u32_to_f32(uint x) {\n    return float(x >> 16u) * 65536.0 + float(x & 65535u);\n}\n".into(),
        Helper::I32ToF32 => "// i32 as f32 (magnitude through lp_u32_to_f32, so i32::MIN works).\nfloat lp_i32_to_f32(int x) {\n    if (x < 0) {\n        return -lp_u32_to_f32(0u - uint(x));\n    }\n    return lp_u32_to_f32(uint(x));\n}\n".into(),
        Helper::F32ToU32 => "// f32 as u32 saturates like Rust: NaN and negatives give 0, too large gives u32::MAX.\nuint lp_f32_to_u32(float x) {\n    if (x >= 4294967296.0) {\n        return 4294967295u;\n    }\n    if (x > 0.0) {\n        return uint(x);\n    }\n    return 0u;\n}\n".into(),
        Helper::F32ToI32 => "// f32 as i32 saturates like Rust: NaN gives 0, out of range gives i32::MIN/MAX.\nint lp_f32_to_i32(float x) {\n    if (x >= 2147483648.0) {\n        return 2147483647;\n    }\n    if (x >= -2147483648.0) {\n        return int(x);\n    }\n    if (x < 0.0) {\n        return -2147483647 - 1;\n    }\n    return 0;\n}\n".into(),
        Helper::DivI32 => "// i32 division truncating toward zero like Rust (GLSL ES leaves negative operands undefined).\nint lp_div_i32(int a, int b) {\n    uint ua = a < 0 ? 0u - uint(a) : uint(a);\n    uint ub = b < 0 ? 0u - uint(b) : uint(b);\n    uint q = ua / ub;\n    return (a < 0) != (b < 0) ? int(0u - q) : int(q);\n}\n".into(),
        Helper::RemI32 => "// i32 remainder with the sign of the dividend, like Rust.\nint lp_rem_i32(int a, int b) {\n    return a - lp_div_i32(a, b) * b;\n}\n".into(),
        Helper::FmodF32 => "// f32 % like WGSL and (up to rounding) Rust: truncated, sign of the dividend; GLSL's mod() floors.\nfloat lp_fmod_f32(float a, float b) {\n    return a - b * trunc(a / b);\n}\n".into(),
        Helper::IsNan => "// From the bits: drivers may fold isnan() away under fast-math.\nbool lp_is_nan(float x) {\n    return (floatBitsToUint(x) & 0x7fffffffu) > 0x7f800000u;\n}\n".into(),
        Helper::IsInfinite => "bool lp_is_infinite(float x) {\n    return (floatBitsToUint(x) & 0x7fffffffu) == 0x7f800000u;\n}\n".into(),
        Helper::IsFinite => "bool lp_is_finite(float x) {\n    return (floatBitsToUint(x) & 0x7f800000u) != 0x7f800000u;\n}\n".into(),
        Helper::Signum => "// Rust's signum: 1.0 for +0.0, -1.0 for -0.0, NaN stays NaN (GLSL's sign(0.0) is 0.0).\nfloat lp_signum(float x) {\n    if (lp_is_nan(x)) {\n        return x;\n    }\n    return (floatBitsToUint(x) & 0x80000000u) != 0u ? -1.0 : 1.0;\n}\n".into(),
        Helper::Round => "// Rust's round: halves away from zero (GLSL's round() may pick either).\nfloat lp_round(float x) {\n    float t = trunc(x);\n    if (abs(x - t) >= 0.5) {\n        t += sign(x);\n    }\n    return t;\n}\n".into(),
        Helper::Fract { ty: t, suffix: s } => format!("// Rust's fract: x - trunc(x) (GLSL's fract() is x - floor(x)).\n{t} lp_fract_{s}({t} x) {{\n    return x - trunc(x);\n}}\n"),
        Helper::LengthSquared { ty: t, suffix: s } => format!("float lp_length_squared_{s}({t} v) {{\n    return dot(v, v);\n}}\n"),
        Helper::Reduce { op, ty, n, suffix, scalar } => {
            let (name, expr) = crate::lower::reduce_parts(op, *n);
            let scalar = Glsl.scalar_type(*scalar);
            format!("{scalar} lp_{name}_{suffix}({ty} v) {{\n    return {expr};\n}}\n")
        }
        Helper::FetchVec4(rows) => fetch("vec4", "sampler2D", "RGBA32F", *rows),
        // GLSL builds NaN and infinities with uintBitsToFloat in place.
        Helper::FloatFromBits => unreachable!("GLSL never asks for {h:?}"),
        Helper::FetchUVec4(rows) => fetch("uvec4", "usampler2D", "RGBA32UI", *rows),
    }
}

/// `lp_fetch_{ty}`: texel `i` of a row-major data texture of `format` texels, its row and column
/// without integer division (SIMD drivers divide lane by lane) and, at a power-of-two width,
/// without shifts: SwiftShader (WebGL2 in a browser without a GPU) runs every vector shift lane
/// by lane, four extracts, shifts and inserts for one `>>`. There the column is `i & (w - 1)` and
/// the row `(i - column) * (1 / w)` in f32, exact: `i - column` is `row * w`, at most 14
/// significant bits times a power of two (textures have at most 2^14 rows), and the reciprocal of
/// a power of two is one, made from the width's f32 bits by one subtraction. An index past the
/// texture reads outside it, as before (a negative row from `int(i)` past 2^31). At any width the f32 quotient is
/// within one of the row for every texture a backend makes (`tests/kernel/codegen.rs` models
/// both), and the column from it, wrapped below zero or at least the width, says which way to
/// correct.
fn fetch(ty: &str, sampler: &str, format: &str, rows: TexelRows) -> String {
    match rows {
        TexelRows::PowerOfTwoWidth => format!(
            "// Texel `i` of a row-major {format} data texture whose width is a power of two: its column\n\
             // a mask, its row the texels before that row times 1/width (exact in f32; no shifts, which\n\
             // SwiftShader runs lane by lane).\n\
             {ty} lp_fetch_{ty}(highp {sampler} t, uint i) {{\n    int w = textureSize(t, 0).x;\n    \
             int column = int(i) & (w - 1);\n    \
             float inverse_width = uintBitsToFloat(0x7f000000u - floatBitsToUint(float(w)));\n    \
             int row = int(float(int(i) - column) * inverse_width);\n    \
             return texelFetch(t, ivec2(column, row), 0);\n}}\n"
        ),
        TexelRows::AnyWidth => format!(
            "// Texel `i` of a row-major {format} data texture, its row and column without integer division\n\
             // (SIMD drivers divide lane by lane): an f32 quotient within one of the row, corrected once.\n\
             {ty} lp_fetch_{ty}(highp {sampler} t, uint i) {{\n    uint w = uint(textureSize(t, 0).x);\n    uint row = uint(float(i) / float(w));\n    uint column = i - row * w;\n    \
             if (int(column) < 0) {{\n        row -= 1u;\n        column += w;\n    }} else if (column >= w) {{\n        \
             row += 1u;\n        column -= w;\n    }}\n    return texelFetch(t, ivec2(int(column), int(row)), 0);\n}}\n"
        ),
    }
}
