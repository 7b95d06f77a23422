//! The WGSL file around the kernel functions: resource bindings, the compute entry point and
//! the harness shader.

use std::fmt::Write as _;

use std::collections::BTreeMap;

use crate::language::{HarnessShader, ResourceBlock, ResourceKind, SampleFields, StorageElement};
use crate::names;
use crate::{BindingKind, BoundField, PixelOutput, ResourceBinding, ResourceBindings};

/// The storage buffer holding every texel array of resource struct global `global` whose
/// element is `vec4<u32>` (`unsigned`) or `vec4<f32>`, one array after another.
pub(super) fn texel_buffer(global: &str, unsigned: bool) -> String {
    format!("lp_{global}_{}", if unsigned { "vec4u" } else { "vec4f" })
}

/// The uniform member holding where texel array `field` starts in its buffer (in texels).
pub(super) fn start_member(field: &str) -> String {
    format!("lp_start_{field}")
}

/// The storage buffer holding every `Storage<T>` array of resource struct global `global` with
/// element `element`, one array after another.
pub(super) fn storage_buffer(global: &str, element: StorageElement) -> String {
    let suffix = match element {
        StorageElement::Vec4 => "vec4f",
        StorageElement::UVec4 => "vec4u",
        StorageElement::U32 => "u32",
        StorageElement::F32 => "f32",
    };
    format!("lp_{global}_storage_{suffix}")
}

/// The storage buffer of `atomic<u32>` holding every `Atomics` array of resource struct global
/// `global`, one array after another.
pub(super) fn atomics_buffer(global: &str) -> String {
    format!("lp_{global}_atomics")
}

fn wgsl_element(element: StorageElement) -> &'static str {
    match element {
        StorageElement::Vec4 => "vec4<f32>",
        StorageElement::UVec4 => "vec4<u32>",
        StorageElement::U32 => "u32",
        StorageElement::F32 => "f32",
    }
}

/// Each resources struct's bindings, in the order [`resources`] declares them.
///
/// A struct's bindings live in bind group `#[resources(group = N)]` (default 0), numbered from
/// 0 within each group in the order the structs are declared (link order). For each struct, in
/// this order:
///
/// 1. its struct `{Struct}Uniforms` (a uniform; in group 0 of a compute module a read-only
///    storage buffer: [`BindingKind::Scalars`]): the scalar and vector fields in declaration order,
///    then `lp_start_{field}` (u32) for each texel array in declaration order, then for each
///    storage array, then for each `Atomics` array: where the array starts in its buffer (in
///    elements);
/// 2. the texel arrays (`Texels<..>`), concatenated into one read-only storage buffer per element
///    type: `vec4<f32>`, then `vec4<u32>`. Two storage buffers however many arrays the kernel
///    reads: WebGPU guarantees 8 per shader stage, and the all-features kernel reads 11 arrays;
/// 3. (compute modules) the `Storage<T>` arrays, concatenated into one `var<storage,
///    read_write>` buffer per element type, in the order `vec4<f32>`, `vec4<u32>`, `u32`, `f32`;
/// 4. (compute modules) every `Atomics` array, concatenated into one `var<storage, read_write>`
///    buffer of `atomic<u32>`.
///
/// Only buffers holding an array the code uses are declared (and numbered).
pub(super) fn layout(blocks: &[ResourceBlock]) -> Vec<ResourceBindings> {
    let mut next: BTreeMap<u32, u32> = BTreeMap::new();
    let mut out = Vec::new();
    for block in blocks {
        let base = &block.global;
        let mut members = Vec::new();
        let mut starts = Vec::new();
        let mut storage_starts = Vec::new();
        let mut atomic_starts = Vec::new();
        let mut texels: [Vec<BoundField>; 2] = [Vec::new(), Vec::new()];
        let mut storage: BTreeMap<StorageElement, Vec<BoundField>> = BTreeMap::new();
        let mut atomics = Vec::new();
        for f in &block.fields {
            let start =
                |ty: &str| BoundField { field: f.name.clone(), ty: ty.into(), member: Some(start_member(&f.name)) };
            let element = |ty: &str| BoundField { field: f.name.clone(), ty: ty.into(), member: None };
            match &f.kind {
                ResourceKind::Uniform { .. } => members.push(BoundField {
                    field: f.name.clone(),
                    ty: f.dsl_type.clone(),
                    member: Some(names::safe(&f.name)),
                }),
                ResourceKind::Texels { unsigned } => {
                    starts.push(start("u32"));
                    texels[*unsigned as usize].push(element(if *unsigned { "UVec4" } else { "Vec4" }));
                }
                ResourceKind::Storage { element: e } => {
                    storage_starts.push(start("u32"));
                    storage.entry(*e).or_default().push(element(e.dsl_type()));
                }
                ResourceKind::Atomics => {
                    atomic_starts.push(start("u32"));
                    atomics.push(element("u32"));
                }
            }
        }
        let group = block.group;
        let counter = next.entry(group).or_insert(0);
        let mut take = || {
            let b = *counter;
            *counter += 1;
            b
        };
        let mut bindings = Vec::new();
        members.extend(starts);
        members.extend(storage_starts);
        members.extend(atomic_starts);
        let kind = if block.scalars_in_storage { BindingKind::Scalars } else { BindingKind::Uniform };
        bindings.push(ResourceBinding { binding: take(), variable: base.clone(), kind, fields: members });
        for (unsigned, fields) in [false, true].into_iter().zip(texels) {
            if !fields.is_empty() {
                let variable = texel_buffer(base, unsigned);
                bindings.push(ResourceBinding { binding: take(), variable, kind: BindingKind::Texels, fields });
            }
        }
        for (element, fields) in storage {
            let variable = storage_buffer(base, element);
            bindings.push(ResourceBinding { binding: take(), variable, kind: BindingKind::Storage, fields });
        }
        if !atomics.is_empty() {
            let variable = atomics_buffer(base);
            bindings.push(ResourceBinding { binding: take(), variable, kind: BindingKind::Atomics, fields: atomics });
        }
        out.push(ResourceBindings { resources: block.name.clone(), group, bindings });
    }
    out
}

/// The declarations of [`layout`]: each struct's uniform block, then its buffers.
pub(super) fn resources(blocks: &[ResourceBlock]) -> String {
    let mut out = String::new();
    for (block, layout) in blocks.iter().zip(layout(blocks)) {
        let _ = writeln!(out, "// resources: {}", block.origin);
        let (res, group) = (&block.name, layout.group);
        let buffers = |kind: BindingKind| -> Vec<&str> {
            layout.bindings.iter().filter(|b| b.kind == kind).map(|b| b.variable.as_str()).collect()
        };
        let _ = writeln!(out, "struct {res}Uniforms {{");
        let mut comment = None;
        for f in &layout.bindings[0].fields {
            let Some(member) = &f.member else { continue };
            let kind = block.fields.iter().find(|b| b.name == f.field).map(|b| &b.kind);
            let (now, type_name) = match kind {
                Some(ResourceKind::Uniform { type_name }) => (None, type_name.as_str()),
                Some(ResourceKind::Texels { .. }) => (Some(BindingKind::Texels), "u32"),
                Some(ResourceKind::Storage { .. }) => (Some(BindingKind::Storage), "u32"),
                Some(ResourceKind::Atomics) | None => (Some(BindingKind::Atomics), "u32"),
            };
            if now.is_some() && now != comment {
                comment = now;
                let (what, unit) = match now {
                    Some(BindingKind::Texels) => ("texel array", "texels"),
                    Some(BindingKind::Storage) => ("storage array", "elements"),
                    _ => ("counter array", "counters"),
                };
                let names = buffers(now.unwrap_or(BindingKind::Atomics));
                let _ = writeln!(out, "    // Where each {what} starts in {} (in {unit}).", names.join(" / "));
            }
            let _ = writeln!(out, "    {member}: {type_name},");
        }
        out.push_str("}\n");
        for b in &layout.bindings {
            let (binding, name) = (b.binding, &b.variable);
            let _ = match b.kind {
                BindingKind::Uniform => {
                    writeln!(out, "@group({group}) @binding({binding}) var<uniform> {name}: {res}Uniforms;")
                }
                BindingKind::Scalars => {
                    writeln!(out, "@group({group}) @binding({binding}) var<storage, read> {name}: {res}Uniforms;")
                }
                BindingKind::Texels => {
                    let e = if b.fields[0].ty == "UVec4" { "vec4<u32>" } else { "vec4<f32>" };
                    writeln!(out, "@group({group}) @binding({binding}) var<storage, read> {name}: array<{e}>;")
                }
                BindingKind::Storage => {
                    let e = block
                        .fields
                        .iter()
                        .find_map(|f| match &f.kind {
                            ResourceKind::Storage { element } if f.name == b.fields[0].field => Some(*element),
                            _ => None,
                        })
                        .map_or("u32", wgsl_element);
                    writeln!(out, "@group({group}) @binding({binding}) var<storage, read_write> {name}: array<{e}>;")
                }
                BindingKind::Atomics => writeln!(
                    out,
                    "@group({group}) @binding({binding}) var<storage, read_write> {name}: array<atomic<u32>>;"
                ),
            };
        }
        out.push('\n');
    }
    out
}

/// The compute entry points: `main_{stage}` calls `stage(invocation)` for each invocation of a
/// 2-D grid of 64-invocation workgroups, `invocation = id.x + id.y * groups.x * 64` (x is at
/// most 65,535 workgroups: [`crate::dispatch_grid`]). Each stage checks its own bound.
pub(super) fn compute_entries(stages: &[String]) -> String {
    let mut out = String::new();
    let size = crate::COMPUTE_WORKGROUP_SIZE;
    for stage in stages {
        let _ = write!(
            out,
            "// Compute entry point: {stage}(invocation) for each invocation of the grid.
@compute @workgroup_size({size})
fn main_{stage}(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {{
    {stage}(id.x + id.y * groups.x * {size}u);
}}

"
        );
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
