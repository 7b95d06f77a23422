//! The GLSL ES 3.00 file around the kernel functions: preamble, resource uniforms, the
//! fragment-shader entry point, the harness shader, and the full-screen vertex shader.

use std::fmt::Write as _;

use crate::language::{HarnessShader, ResourceBlock, ResourceKind, SampleFields};
use crate::PixelOutput;

pub(super) fn preamble(header: &str) -> String {
    format!("#version 300 es\n{header}\nprecision highp float;\nprecision highp int;\nprecision highp sampler2D;\nprecision highp usampler2D;\n")
}

/// Each resource field is a uniform: texel arrays are data textures (`sampler2D` for RGBA32F,
/// `usampler2D` for RGBA32UI), scalars and vectors plain uniforms.
pub(super) fn resources(blocks: &[ResourceBlock]) -> String {
    let mut out = String::new();
    for block in blocks {
        let _ = writeln!(out, "// resources: {}", block.origin);
        for f in &block.fields {
            match &f.kind {
                ResourceKind::Texels { unsigned } => {
                    let s = if *unsigned { "usampler2D" } else { "sampler2D" };
                    let _ = writeln!(out, "uniform highp {s} {}_{};", block.global, f.name);
                }
                ResourceKind::Uniform { type_name } => {
                    let _ = writeln!(out, "uniform {type_name} {}_{};", block.global, f.name);
                }
                // Not reached: only a `#[kernel(compute)]` module may read storage or atomics
                // (the macro refuses their methods elsewhere), and the lowering refuses every
                // function of such a module for GLSL ES 3.00 before resources are declared.
                ResourceKind::Storage { .. } | ResourceKind::Atomics => {}
            }
        }
        out.push('\n');
    }
    out
}

/// A fragment shader: pixel = `gl_FragCoord.xy`, output = accumulation texel + one sample, or
/// the pixel's value. A function returning a struct of Vec4s (`fields`) accumulates field k
/// into colour attachment k: `lp_out`/`lp_accumulation` for the first, `lp_out{k}` and
/// `lp_accumulation{k}` for the others.
pub(super) fn pixel_entry(function: &str, output: PixelOutput, fields: Option<&SampleFields>) -> String {
    match (output, fields) {
        (PixelOutput::Accumulate, None) => format!(
            "// Entry point: one sample of pixel gl_FragCoord.xy added to the running sum.\nuniform highp sampler2D lp_accumulation;\nout vec4 lp_out;\n\nvoid main() {{\n    uvec2 pixel = uvec2(gl_FragCoord.xy);\n    lp_out = texelFetch(lp_accumulation, ivec2(pixel), 0) + {function}(pixel.x, pixel.y);\n}}\n"
        ),
        (PixelOutput::Accumulate, Some(sample)) => {
            let mut out = String::from(
                "// Entry point: one sample of pixel gl_FragCoord.xy, each of its fields added to its own running sum.\n",
            );
            let mut body = format!("    uvec2 pixel = uvec2(gl_FragCoord.xy);\n    {} s = {function}(pixel.x, pixel.y);\n", sample.type_name);
            for (k, field) in sample.fields.iter().enumerate() {
                let suffix = if k == 0 { String::new() } else { k.to_string() };
                let _ = writeln!(out, "uniform highp sampler2D lp_accumulation{suffix};");
                let _ = writeln!(out, "layout(location = {k}) out vec4 lp_out{suffix};");
                let _ = writeln!(
                    body,
                    "    lp_out{suffix} = texelFetch(lp_accumulation{suffix}, ivec2(pixel), 0) + s.{field};"
                );
            }
            format!("{out}\nvoid main() {{\n{body}}}\n")
        }
        (PixelOutput::Write, _) => format!(
            "// Entry point: pixel gl_FragCoord.xy of an image pass.\nout vec4 lp_out;\n\nvoid main() {{\n    uvec2 pixel = uvec2(gl_FragCoord.xy);\n    lp_out = {function}(pixel.x, pixel.y);\n}}\n"
        ),
    }
}

/// A fragment shader: invocation (x, y) reads its words from the RGBA32UI texture `lp_args`
/// and writes its results to RGBA32UI colour attachments.
pub(super) fn harness(h: &HarnessShader) -> String {
    let texels = h.layout.input_texels();
    let attachments = h.layout.output_attachments();
    let mut text = String::from("uniform highp usampler2D lp_args;\n");
    for j in 0..attachments {
        let _ = writeln!(text, "layout(location = {j}) out uvec4 lp_out{j};");
    }
    text.push_str(
        "
uint lp_word(ivec2 base, uint k) {
    uvec4 t = texelFetch(lp_args, ivec2(base.x + int(k / 4u), base.y), 0);
    return t[int(k % 4u)];
}

void main() {
",
    );
    let _ = writeln!(
        text,
        "    ivec2 cell = ivec2(gl_FragCoord.xy);
    ivec2 base = ivec2(cell.x * {texels}, cell.y);"
    );
    for a in &h.args {
        let _ = writeln!(text, "    {} {} = {};", a.type_name, a.name, a.value);
    }
    let _ = writeln!(text, "    uint lp_w[{}];", attachments * 4);
    let _ = writeln!(text, "    for (int i = 0; i < {}; ++i) {{ lp_w[i] = 0u; }}", attachments * 4);
    let args: Vec<&str> = h.args.iter().map(|a| a.name.as_str()).collect();
    let call = format!("{}({})", h.function, args.join(", "));
    match &h.result_type {
        Some(t) => {
            let _ = writeln!(text, "    {t} lp_result = {call};");
        }
        None => {
            let _ = writeln!(text, "    {call};");
        }
    }
    for l in &h.stores {
        let _ = writeln!(text, "    {l}");
    }
    for j in 0..attachments {
        let k = j * 4;
        let _ = writeln!(text, "    lp_out{j} = uvec4(lp_w[{k}], lp_w[{}], lp_w[{}], lp_w[{}]);", k + 1, k + 2, k + 3);
    }
    text.push_str("}\n");
    text
}

/// The GLSL ES 3.00 vertex shader that pairs with a fragment entry point: one triangle
/// covering the viewport, no vertex buffers.
pub(crate) fn fullscreen_vertex_shader() -> &'static str {
    "#version 300 es\n// Generated by lightport-codegen: a full-screen triangle.\nvoid main() {\n    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);\n    gl_Position = vec4(p, 0.0, 1.0);\n}\n"
}
