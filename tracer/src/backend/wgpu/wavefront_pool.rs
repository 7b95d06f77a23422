//! The wavefront's pool on a wgpu device: the buffers of its own resources structs (`Paths`, the
//! pool's arrays, queues and counters; `Dispatch`, the indirect dispatches' sizes), laid out as
//! codegen bound them, for [`WavefrontRenderer`](super::WavefrontRenderer).

use lightport_codegen::{BindingKind, ResourceBindings};
use wgpu::util::DeviceExt;

use super::{BufferEntry, OwnResource, ShaderLayout, UniformLayout, WgpuError};
use crate::backend::wavefront::array_len;

/// The `#[resources]` structs of the wavefront besides the scene, as codegen names them.
const PATHS: &str = "Paths";
const DISPATCH: &str = "Dispatch";

/// One storage buffer of `Paths` or `Dispatch`: where each of its arrays starts (elements).
pub(super) struct PoolBuffer {
    pub(super) buffer: wgpu::Buffer,
    /// (field, start, length, bytes per element)
    arrays: Vec<(String, u64, u64, u64)>,
}

impl PoolBuffer {
    /// The byte range of array `field` in this buffer.
    pub(super) fn range(&self, field: &str) -> Option<(u64, u64)> {
        self.arrays.iter().find(|a| a.0 == field).map(|(_, start, len, size)| (start * size, len * size))
    }
}

/// The buffers of the wavefront's own resources structs (`Paths`, `Dispatch`).
pub(super) struct PoolResources {
    /// Their bindings (groups 1 and 2).
    pub(super) entries: Vec<BufferEntry>,
    pub(super) buffers: Vec<PoolBuffer>,
    pub(super) paths_uniform: (wgpu::Buffer, UniformLayout),
    /// The `Dispatch` storage buffer, also the indirect dispatches' arguments.
    pub(super) dispatch_args: wgpu::Buffer,
}

/// Creates the pool of `pool` slots for `pixels` pixels and the dispatch sizes' buffer, as
/// `generated` binds them (`Paths::seed` = `seed`, nothing wanted yet).
pub(super) fn pool_resources(
    d: &wgpu::Device,
    generated: &lightport_codegen::Generated,
    layout: &ShaderLayout,
    pool: u32,
    pixels: u32,
    seed: u32,
) -> Result<PoolResources, WgpuError> {
    let values = |field: &str| -> Option<u32> {
        match field {
            "pool" => Some(pool),
            "pixels" => Some(pixels),
            "frames_wanted" => Some(0),
            "seed" => Some(seed),
            _ => None,
        }
    };
    let (mut entries, mut buffers) = (Vec::new(), Vec::new());
    let (mut paths_uniform, mut dispatch_args) = (None, None);
    for resources in generated.bindings.iter().filter(|b| b.resources != "Scene") {
        let (uniform, storage) = pool_buffers(d, layout, resources, pool, pixels, &values)?;
        entries.push(BufferEntry::uniform(&uniform.0, uniform.1.clone()));
        for (resource, b) in storage {
            entries.push(BufferEntry::storage(&resource, b.buffer.clone(), false));
            if resources.resources == DISPATCH {
                dispatch_args = Some(b.buffer.clone());
            }
            buffers.push(b);
        }
        if resources.resources == PATHS {
            if let Some(members) = uniform.0.uniform.clone() {
                paths_uniform = Some((uniform.1, members));
            }
        }
    }
    let (Some(paths_uniform), Some(dispatch_args)) = (paths_uniform, dispatch_args) else {
        return Err(WgpuError::UnboundResource {
            name: format!("{PATHS} / {DISPATCH}"),
            detail: ": the wavefront shader lacks the pool or the dispatch sizes".into(),
        });
    };
    Ok(PoolResources { entries, buffers, paths_uniform, dispatch_args })
}

/// The uniform and storage buffers of one wavefront resources struct (`Paths`, `Dispatch`),
/// laid out as codegen bound them: each array at its start, the uniform's fields from
/// `values` and the starts.
#[allow(clippy::type_complexity)]
pub(super) fn pool_buffers(
    d: &wgpu::Device,
    layout: &ShaderLayout,
    resources: &ResourceBindings,
    pool: u32,
    pixels: u32,
    values: &dyn Fn(&str) -> Option<u32>,
) -> Result<((OwnResource, wgpu::Buffer), Vec<(OwnResource, PoolBuffer)>), WgpuError> {
    let mut storage = Vec::new();
    let mut starts = Vec::new();
    let mut uniform = None;
    for binding in &resources.bindings {
        let own = layout.own(&binding.variable).clone();
        match binding.kind {
            BindingKind::Uniform => uniform = Some(own),
            BindingKind::Storage | BindingKind::Atomics => {
                let mut arrays = Vec::new();
                let mut end = 0u64;
                // The image's sums first, at offset 0: the display pass reads them from there.
                let mut fields: Vec<_> = binding.fields.iter().collect();
                fields.sort_by_key(|f| f.field != "image");
                for f in fields {
                    let size = if f.ty == "Vec4" || f.ty == "UVec4" { 16 } else { 4 };
                    let len = array_len(&f.field, pool, pixels) as u64;
                    arrays.push((f.field.clone(), end, len, size));
                    starts.push((format!("lp_start_{}", f.field), end));
                    end += len;
                }
                let size = end.max(1) * arrays.first().map_or(4, |a| a.3);
                let mut usage =
                    wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
                if resources.resources == DISPATCH {
                    usage |= wgpu::BufferUsages::INDIRECT;
                }
                let buffer = d.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(&binding.variable),
                    size,
                    usage,
                    mapped_at_creation: false,
                });
                storage.push((own, PoolBuffer { buffer, arrays }));
            }
            BindingKind::Texels | BindingKind::Scalars => {
                return Err(WgpuError::UnboundResource {
                    name: binding.variable.clone(),
                    detail: ": the wavefront's pool has no read-only buffers (it is not in group 0)".into(),
                })
            }
        }
    }
    let Some(uniform) = uniform else {
        return Err(WgpuError::UnboundResource {
            name: resources.resources.clone(),
            detail: ": no uniform block".into(),
        });
    };
    let bytes = super::u32_uniform_bytes(&uniform, |member| {
        starts.iter().find(|(n, _)| n == member).map(|(_, s)| *s as u32).or_else(|| values(member))
    })?;
    let buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(&resources.resources),
        contents: &bytes,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    });
    Ok(((uniform, buffer), storage))
}
