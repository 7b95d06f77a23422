//! The WGSL file around the kernel functions: resource bindings, the compute entry point and
//! the harness shader.

use std::fmt::Write as _;

use crate::language::{HarnessShader, ResourceBlock, ResourceKind, SampleFields};
use crate::names;
use crate::PixelOutput;

/// The storage buffer holding every texel array of resource struct global `global` whose
/// element is `vec4<u32>` (`unsigned`) or `vec4<f32>`, one array after another.
pub(super) fn texel_buffer(global: &str, unsigned: bool) -> String {
    format!("lp_{global}_{}", if unsigned { "vec4u" } else { "vec4f" })
}

/// The uniform member holding where texel array `field` starts in its buffer (in texels).
pub(super) fn start_member(field: &str) -> String {
    format!("lp_start_{field}")
}

/// Resources live in bind group 0: each struct's scalars and vectors in one uniform block
/// (`{Struct}Uniforms`, bound first), followed by where each texel array starts; then the
/// texel arrays, concatenated into one read-only storage buffer per element type, numbered on
/// across structs. Two storage buffers however many arrays the kernel reads: WebGPU guarantees
/// 8 per shader stage, and the all-features kernel reads 11 arrays.
pub(super) fn resources(blocks: &[ResourceBlock]) -> String {
    let mut out = String::new();
    let mut binding = 0;
    for block in blocks {
        let _ = writeln!(out, "// resources: {}", block.origin);
        let (res, base) = (&block.name, &block.global);
        let mut members = Vec::new();
        let mut starts = Vec::new();
        let mut elements = [false; 2];
        for f in &block.fields {
            match &f.kind {
                ResourceKind::Uniform { type_name } => members.push(format!("{}: {type_name}", names::safe(&f.name))),
                ResourceKind::Texels { unsigned } => {
                    starts.push(format!("{}: u32", start_member(&f.name)));
                    elements[*unsigned as usize] = true;
                }
            }
        }
        let _ = writeln!(out, "struct {res}Uniforms {{");
        for m in &members {
            let _ = writeln!(out, "    {m},");
        }
        if !starts.is_empty() {
            let names: Vec<String> =
                [false, true].iter().filter(|u| elements[**u as usize]).map(|u| texel_buffer(base, *u)).collect();
            let _ = writeln!(out, "    // Where each texel array starts in {} (in texels).", names.join(" / "));
        }
        for m in &starts {
            let _ = writeln!(out, "    {m},");
        }
        out.push_str("}\n");
        let _ = writeln!(out, "@group(0) @binding({binding}) var<uniform> {base}: {res}Uniforms;");
        binding += 1;
        for (unsigned, e) in [(false, "vec4<f32>"), (true, "vec4<u32>")] {
            if elements[unsigned as usize] {
                let name = texel_buffer(base, unsigned);
                let _ = writeln!(out, "@group(0) @binding({binding}) var<storage, read> {name}: array<{e}>;");
                binding += 1;
            }
        }
        out.push('\n');
    }
    out
}

/// A compute shader (8 x 8 workgroups) adding one sample per pixel of a band of rows,
/// `lp_target.first_row` up to (not including) `lp_target.end_row`, to the storage buffer
/// `lp_accumulation` (row-major, `lp_target.width` wide): a whole frame is one band, a slow
/// device's frame several (`tracer::backend::frame_split`). Or, for an image pass, storing each
/// pixel's value in `lp_output`. A function returning a struct of Vec4s (`fields`) accumulates
/// field k into its own buffer: `lp_accumulation` (binding 0) for the first, `lp_accumulation{k}`
/// (binding k + 1) for the others.
pub(super) fn pixel_entry(function: &str, output: PixelOutput, fields: Option<&SampleFields>) -> String {
    let (comment, buffer, store) = match output {
        PixelOutput::Accumulate => (
            "one sample per pixel of the band of rows [first_row, end_row) added to the running sum in lp_accumulation",
            "lp_accumulation",
            format!("lp_accumulation[i] = lp_accumulation[i] + {function}(id.x, y);"),
        ),
        PixelOutput::Write => (
            "each pixel of the band of rows [first_row, end_row) of an image pass, stored in lp_output",
            "lp_output",
            format!("lp_output[i] = {function}(id.x, y);"),
        ),
    };
    let (comment, store, extra) = match fields {
        Some(sample) if output == PixelOutput::Accumulate => {
            let mut store = format!("let s = {function}(id.x, y);");
            let mut extra = String::new();
            for (k, field) in sample.fields.iter().enumerate() {
                let name = if k == 0 { buffer.to_string() } else { format!("{buffer}{k}") };
                let _ = write!(store, "\n    {name}[i] = {name}[i] + s.{field};");
                if k > 0 {
                    let _ = writeln!(
                        extra,
                        "@group(1) @binding({}) var<storage, read_write> {name}: array<vec4<f32>>;",
                        k + 1
                    );
                }
            }
            ("one sample per pixel of the band of rows [first_row, end_row), each of its fields added to its own running sum (lp_accumulation, lp_accumulation1, ...)", store, extra)
        }
        _ => (comment, store, String::new()),
    };
    format!(
        "// Entry point: {comment}.
struct LpTarget {{
    width: u32,
    first_row: u32,
    end_row: u32,
}}
@group(1) @binding(0) var<storage, read_write> {buffer}: array<vec4<f32>>;
@group(1) @binding(1) var<uniform> lp_target: LpTarget;
{extra}
@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {{
    let y = lp_target.first_row + id.y;
    if id.x >= lp_target.width || y >= lp_target.end_row {{
        return;
    }}
    let i = y * lp_target.width + id.x;
    {store}
}}
"
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
