//! The WGSL file around the kernel functions: resource bindings, the compute entry point and
//! the harness shader.

use std::fmt::Write as _;

use crate::language::{HarnessShader, ResourceBlock, ResourceKind};
use crate::names;

/// Resources live in bind group 0: each struct's scalars and vectors in one uniform block
/// (`{Struct}Uniforms`, bound first), then one read-only storage buffer per texel array,
/// numbered on across structs.
pub(super) fn resources(blocks: &[ResourceBlock]) -> String {
    let mut out = String::new();
    let mut binding = 0;
    for block in blocks {
        let _ = writeln!(out, "// resources: {}", block.origin);
        let (res, base) = (&block.name, &block.global);
        let scalars: Vec<(&str, &str)> = block
            .fields
            .iter()
            .filter_map(|f| match &f.kind {
                ResourceKind::Uniform { type_name } => Some((f.name.as_str(), type_name.as_str())),
                ResourceKind::Texels { .. } => None,
            })
            .collect();
        if !scalars.is_empty() {
            let _ = writeln!(out, "struct {res}Uniforms {{");
            for (name, tn) in &scalars {
                let _ = writeln!(out, "    {}: {tn},", names::safe(name));
            }
            out.push_str("}\n");
            let _ = writeln!(out, "@group(0) @binding({binding}) var<uniform> {base}: {res}Uniforms;");
            binding += 1;
        }
        for f in &block.fields {
            if let ResourceKind::Texels { unsigned } = f.kind {
                let e = if unsigned { "vec4<u32>" } else { "vec4<f32>" };
                let _ =
                    writeln!(out, "@group(0) @binding({binding}) var<storage, read> {base}_{}: array<{e}>;", f.name);
                binding += 1;
            }
        }
        out.push('\n');
    }
    out
}

/// A compute shader (8 x 8 workgroups) adding one sample per pixel to the storage buffer
/// `lp_accumulation` (row-major, `lp_target.width` wide).
pub(super) fn pixel_entry(function: &str) -> String {
    format!(
        "// Entry point: one sample per pixel added to the running sum in lp_accumulation.\nstruct LpTarget {{\n    width: u32,\n    height: u32,\n}}\n@group(1) @binding(0) var<storage, read_write> lp_accumulation: array<vec4<f32>>;\n@group(1) @binding(1) var<uniform> lp_target: LpTarget;\n\n@compute @workgroup_size(8, 8)\nfn main(@builtin(global_invocation_id) id: vec3<u32>) {{\n    if id.x >= lp_target.width || id.y >= lp_target.height {{\n        return;\n    }}\n    let i = id.y * lp_target.width + id.x;\n    lp_accumulation[i] = lp_accumulation[i] + {function}(id.x, id.y);\n}}\n"
    )
}

/// A compute shader (64 invocations per workgroup along x): invocation `i` reads its words
/// from `lp_args` and writes its results to `lp_results`, for `i < lp_count.n`.
pub(super) fn harness(h: &HarnessShader) -> String {
    let words = h.layout.output_words.max(1);
    let mut text = String::from(
        "struct LpCount {
    n: u32,
}
@group(1) @binding(0) var<storage, read> lp_args: array<u32>;
@group(1) @binding(1) var<storage, read_write> lp_results: array<u32>;
@group(1) @binding(2) var<uniform> lp_count: LpCount;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= lp_count.n {
        return;
    }
",
    );
    let _ = writeln!(text, "    let base: u32 = id.x * {}u;", h.layout.input_words.max(1));
    let mut args = Vec::new();
    for a in &h.args {
        let kw = if a.by_ref { "var" } else { "let" };
        let _ = writeln!(text, "    {kw} {}: {} = {};", a.name, a.type_name, a.value);
        args.push(if a.by_ref { format!("&{}", a.name) } else { a.name.clone() });
    }
    let _ = writeln!(text, "    var lp_w: array<u32, {words}>;");
    let call = format!("{}({})", h.function, args.join(", "));
    match &h.result_type {
        Some(t) => {
            let _ = writeln!(text, "    let lp_result: {t} = {call};");
        }
        None => {
            let _ = writeln!(text, "    {call};");
        }
    }
    for l in &h.stores {
        let _ = writeln!(text, "    {l}");
    }
    let _ = writeln!(
        text,
        "    for (var k: u32 = 0u; k < {words}u; k++) {{
        lp_results[id.x * {words}u + k] = lp_w[k];
    }}"
    );
    text.push_str("}\n");
    text
}
