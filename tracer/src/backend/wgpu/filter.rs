//! [`WgpuFilter`]: the denoiser's à-trous passes as compute passes. The kernel's
//! `denoise::atrous_pixel`, generated as an image pass (`shaders-generated/denoise_pass.wgsl`),
//! is dispatched once per pass; each pass's output (`lp_output`) is copied over the colour
//! array in the `FilterImage`'s texel buffer for the next pass, so the image stays on the
//! device until the last pass is read back.

use glam::Vec4;
use lightport_codegen::Target;
use wgpu::util::DeviceExt;

use super::{
    compile_pipeline, map_readback, pipeline_bind_groups, place_arrays, reflect, storage_limit, u32_uniform_bytes,
    upload_scene, BufferEntry, ShaderLayout, WgpuDevice, WgpuError, WgpuOptions, TARGET_UNIFORM, WORKGROUP_SIZE,
};
use crate::kernel::denoise::{FilterImage, ATROUS_ITERATIONS};

/// The uniform struct holding the `FilterImage`'s scalars (codegen names it after the struct).
const FILTER_UNIFORM: &str = "filter_image";
/// The read-write storage buffer an image pass stores its pixels in (codegen's entry point).
const OUTPUT_BUFFER: &str = "lp_output";

/// One run's buffers ([`WgpuFilter::upload`]).
struct PassBuffers {
    groups: Vec<wgpu::BindGroup>,
    /// The `FilterImage` uniform, and where its `step` sits in it.
    uniform: wgpu::Buffer,
    step_offset: Option<u64>,
    /// The texel buffer holding the colour (at `color_start` bytes) and the guide.
    texels: wgpu::Buffer,
    color_start: u64,
    output: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Bytes of one image (colour, output and read-back alike).
    bytes: u64,
}

/// The filter pass's pipeline on a device.
pub struct WgpuFilter {
    pipeline: wgpu::ComputePipeline,
    layout: ShaderLayout,
}

impl WgpuFilter {
    /// Compiles the filter pass on `device`, waiting for the compiler's verdict.
    pub async fn new(device: &WgpuDevice) -> Result<Self, WgpuError> {
        let generated = crate::kernel::denoise_pass_shader(Target::Wgsl)?;
        let layout = reflect(&generated, FILTER_UNIFORM, &[OUTPUT_BUFFER, TARGET_UNIFORM])?;
        let pipeline = compile_pipeline(&device.device, &generated, None).await?;
        Ok(WgpuFilter { pipeline, layout })
    }

    /// Queues `ATROUS_ITERATIONS` passes over `image` at steps 1, 2, 4, ... and returns the
    /// future of the last pass's output (natively someone must poll the device).
    pub fn run(
        &self,
        device: &WgpuDevice,
        image: &FilterImage,
    ) -> Result<impl std::future::Future<Output = Result<Vec<Vec4>, WgpuError>> + 'static, WgpuError> {
        let (width, height) = (image.width, image.height);
        let pixels = width as u64 * height as u64;
        if image.color.len() as u64 != pixels || image.guide.len() as u64 != pixels || pixels == 0 {
            return Err(WgpuError::ImageTooLarge {
                width,
                height,
                what: "the filter image (its colour and guide arrays do not match it)",
                needed: image.color.len().max(image.guide.len()) as u64,
                limit: "width x height",
                max: pixels,
            });
        }
        let workgroups = check_limits(&device.limits, width, height)?;
        let buffers = self.upload(device, image)?;
        self.dispatch(device, &buffers, workgroups);
        Ok(map_readback(buffers.readback))
    }

    /// The image's buffers and bind groups: the `FilterImage` uniform and texel buffer, the
    /// pass's output, `lp_target` and the read-back buffer.
    fn upload(&self, device: &WgpuDevice, image: &FilterImage) -> Result<PassBuffers, WgpuError> {
        let (width, height) = (image.width, image.height);
        let d = &device.device;
        let mut image = image.clone();
        image.step = 1;
        let (mut entries, uniform) = upload_scene(d, &self.layout, &image)?;
        let lacks = |name: &str| WgpuError::UnboundResource {
            name: name.to_string(),
            detail: ": the generated filter pass lacks it".into(),
        };
        let (uniform, uniform_layout) = uniform.ok_or_else(|| lacks(FILTER_UNIFORM))?;
        let step = lightport_codegen::identifier("step");
        let step_offset = uniform_layout.members.iter().find(|(n, _)| *n == step).map(|(_, o)| *o as u64);
        let color_start = place_arrays(Some(&uniform_layout), FILTER_UNIFORM, &image)?
            .iter()
            .find(|a| a.field == "color")
            .map(|a| a.start * 16)
            .ok_or_else(|| lacks("filter_image.color"))?;
        let texels = self.layout.texel_buffers.iter().find(|b| !b.unsigned).and_then(|b| {
            entries.iter().find(|e| e.group == b.group && e.binding == b.binding).map(|e| e.buffer.clone())
        });
        let texels = texels.ok_or_else(|| lacks("lp_filter_image_vec4f"))?;
        let bytes = width as u64 * height as u64 * 16;
        let buffer = |label, usage| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        };
        let output = buffer(OUTPUT_BUFFER, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
        let readback = buffer("filter readback", wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        entries.push(BufferEntry::storage(self.layout.own(OUTPUT_BUFFER), output.clone(), false));
        let target = self.layout.own(TARGET_UNIFORM);
        let target_bytes = u32_uniform_bytes(target, |member| match member {
            "width" => Some(width),
            "first_row" => Some(0),
            "end_row" => Some(height),
            _ => None,
        })?;
        let target_buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(TARGET_UNIFORM),
            contents: &target_bytes,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        entries.push(BufferEntry::uniform(target, target_buffer));
        let groups = pipeline_bind_groups(d, &self.pipeline, &entries.iter().collect::<Vec<_>>(), "lightport filter");
        Ok(PassBuffers { groups, uniform, step_offset, texels, color_start, output, readback, bytes })
    }

    /// Queues the passes, one submission each (each step write lands before the pass submitted
    /// after it); the last copies its output into the read-back buffer.
    fn dispatch(&self, device: &WgpuDevice, b: &PassBuffers, workgroups: [u32; 2]) {
        for pass in 0..ATROUS_ITERATIONS {
            if let Some(offset) = b.step_offset {
                device.queue.write_buffer(&b.uniform, offset, &(1u32 << pass).to_le_bytes());
            }
            let mut encoder = device.device.create_command_encoder(&Default::default());
            {
                let mut compute = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("lightport filter pass"),
                    timestamp_writes: None,
                });
                compute.set_pipeline(&self.pipeline);
                for (i, group) in b.groups.iter().enumerate() {
                    compute.set_bind_group(i as u32, group, &[]);
                }
                compute.dispatch_workgroups(workgroups[0], workgroups[1], 1);
            }
            if pass + 1 < ATROUS_ITERATIONS {
                encoder.copy_buffer_to_buffer(&b.output, 0, &b.texels, b.color_start, b.bytes);
            } else {
                encoder.copy_buffer_to_buffer(&b.output, 0, &b.readback, 0, b.bytes);
            }
            device.queue.submit([encoder.finish()]);
        }
    }
}

/// Checks the image against the device's limits (the colour and guide share one storage
/// binding); returns the dispatch size of one pass.
fn check_limits(limits: &wgpu::Limits, width: u32, height: u32) -> Result<[u32; 2], WgpuError> {
    let texel_bytes = width as u64 * height as u64 * 16 * 2;
    let binding_max = storage_limit(limits, &WgpuOptions::default());
    for (limit, max) in [("max_storage_buffer_binding_size", binding_max), ("max_buffer_size", limits.max_buffer_size)]
    {
        if texel_bytes > max {
            let what = "the filter's colour and guide buffer";
            return Err(WgpuError::ImageTooLarge { width, height, what, needed: texel_bytes, limit, max });
        }
    }
    let workgroups = [width.div_ceil(WORKGROUP_SIZE[0]), height.div_ceil(WORKGROUP_SIZE[1])];
    let max = limits.max_compute_workgroups_per_dimension;
    if workgroups[0] > max || workgroups[1] > max {
        let needed = workgroups[0].max(workgroups[1]) as u64;
        let limit = "max_compute_workgroups_per_dimension";
        return Err(WgpuError::ImageTooLarge {
            width,
            height,
            what: "the filter's dispatch",
            needed,
            limit,
            max: max as u64,
        });
    }
    Ok(workgroups)
}
