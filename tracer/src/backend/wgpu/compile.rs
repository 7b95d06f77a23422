//! Compiling the generated WGSL into a compute pipeline, with the compiler's messages mapped
//! back to the kernel's Rust lines.

use std::borrow::Cow;

use lightport_codegen::Generated;

use super::{WgpuError, ENTRY_POINT};

/// One message of the shader compiler, at a generated line when it names one.
pub(crate) struct Message {
    pub(crate) text: String,
    pub(crate) line: Option<u32>,
}

/// The messages with, under each that names a generated line, that line and the Rust location
/// it was generated from.
pub(crate) fn annotate_messages(messages: &[Message], generated: &Generated) -> String {
    let mut out = String::new();
    for m in messages {
        out.push_str(m.text.trim_end());
        out.push('\n');
        let Some(n) = m.line else { continue };
        if let Some(text) = generated.source.lines().nth((n as usize).saturating_sub(1)) {
            out.push_str(&format!("    generated line {n}: {}\n", text.trim()));
        }
        if let Some(at) = generated.rust_location(n) {
            out.push_str(&format!("    from {}:{}:{} (in {})\n", at.file, at.span.line, at.span.column, at.function));
        }
    }
    out
}

/// The outcome of compiling a pipeline, known only once the device answers: WebGPU reports
/// shader errors asynchronously (a promise in the browser).
pub type PipelineCheck = std::pin::Pin<Box<dyn std::future::Future<Output = Result<(), WgpuError>>>>;

/// Compiles the generated WGSL into a compute pipeline on `device` with `layout`. Errors carry
/// wgpu's messages (naga's front end and validator, then the driver's pipeline creation), each
/// with its generated line mapped back to the kernel's Rust source.
pub async fn compile_pipeline(
    device: &wgpu::Device,
    generated: &Generated,
    layout: Option<&wgpu::PipelineLayout>,
) -> Result<wgpu::ComputePipeline, WgpuError> {
    let (pipeline, check) = start_pipeline(device, generated, layout);
    check.await?;
    Ok(pipeline)
}

/// [`compile_pipeline`] without waiting: the pipeline at once (usable as soon as the device has
/// compiled it: commands are queued behind that), and the check that reports whether it
/// compiled. The browser's viewer creates renderers from synchronous calls and awaits the check
/// separately.
pub fn start_pipeline(
    device: &wgpu::Device,
    generated: &Generated,
    layout: Option<&wgpu::PipelineLayout>,
) -> (wgpu::ComputePipeline, PipelineCheck) {
    let (mut pipelines, check) = start_pipelines(device, generated, &[(ENTRY_POINT, layout)]);
    (pipelines.remove(0), check)
}

/// [`start_pipeline`] for several entry points of one shader module (a compute module's
/// stages), each with its pipeline layout: the pipelines in order, and one check for all.
pub fn start_pipelines(
    device: &wgpu::Device,
    generated: &Generated,
    entries: &[(&str, Option<&wgpu::PipelineLayout>)],
) -> (Vec<wgpu::ComputePipeline>, PipelineCheck) {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("lightport path tracer"),
        source: wgpu::ShaderSource::Wgsl(Cow::Borrowed(&generated.source)),
    });
    let pipelines = entries
        .iter()
        .map(|(entry, layout)| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: *layout,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        })
        .collect();
    let names: Vec<String> = entries.iter().map(|(e, _)| e.to_string()).collect();
    let scope = scope.pop();
    let info = module.get_compilation_info();
    let generated = generated.clone();
    let check = async move {
        let info = info.await;
        let scope = scope.await;
        let errors: Vec<Message> = info
            .messages
            .iter()
            .filter(|m| m.message_type == wgpu::CompilationMessageType::Error)
            .map(|m| Message { text: m.message.clone(), line: m.location.map(|l| l.line_number) })
            .collect();
        if !errors.is_empty() {
            return Err(WgpuError::Compile { log: annotate_messages(&errors, &generated) });
        }
        if let Some(e) = scope {
            return Err(WgpuError::Compile {
                log: format!("creating the compute pipeline (entry point `{}`): {e}", names.join("`, `")),
            });
        }
        Ok(())
    };
    (pipelines, Box::pin(check))
}
