//! What every wgpu entry point of the kernel shares: the generated shader's resource layout
//! (read back with naga), a `#[resources]` struct (the path tracer's `Scene`, the denoiser's
//! `FilterImage`) uploaded as a uniform and storage buffers, bind groups, and limit checks
//! (compiling, with errors at the kernel's Rust lines, is `compile.rs`). The renderer
//! ([`super::WgpuRenderer`]), the denoiser's passes ([`super::WgpuFilter`]) and the equivalence
//! harness ([`crate::backend::harness::WgpuHarness`]) are entry points over them.
//!
//! "Scene" below names whichever `#[resources]` struct the shader reads: codegen declares its
//! scalars as the struct named after it (`scene`, `filter_image`; a uniform, or for the
//! wavefront's stages a read-only storage buffer, which lavapipe does not re-specialise the
//! shader for at each pipeline bind: `lightport_codegen::BindingKind::Scalars`) and its texel
//! arrays in `lp_{name}_vec4f` / `lp_{name}_vec4u`. "The scene uniform" is that struct.

use lightport_codegen::Generated;
use wgpu::util::DeviceExt;

use super::compile::{annotate_messages, Message};
use super::{WgpuError, WgpuOptions};
use crate::backend::{exchange_scene, RenderError};
use crate::kernel::Features;
use crate::pack::Packed;
use kernel_dsl::{Resource, Resources};

/// Where each resource of the generated shader is bound, as the shader declares it: the
/// scene's (shared by every kernel entry point) and the entry point's own.
#[derive(Clone, Debug, Default)]
pub(crate) struct ShaderLayout {
    /// The resources struct's global name (`scene`, `filter_image`): its uniform's name.
    pub(crate) global: String,
    /// The `scene` uniform: binding, size, and each member's (name, offset).
    pub(crate) scene_uniform: Option<UniformLayout>,
    /// The storage buffers holding the scene's texel arrays (one per element type).
    pub(crate) texel_buffers: Vec<TexelBuffer>,
    /// The entry point's own resources (e.g. the accumulation buffer), each named by the caller.
    pub(crate) own: Vec<OwnResource>,
}

/// The storage buffer of the scene's texel arrays of one element type, as codegen declares it:
/// every array the shader reads whose texels are `vec4<u32>` (`unsigned`) or `vec4<f32>`, one
/// after another, each starting where the `scene` uniform's `lp_start_{field}` says.
#[derive(Clone, Debug)]
pub(crate) struct TexelBuffer {
    pub(crate) unsigned: bool,
    pub(crate) group: u32,
    pub(crate) binding: u32,
}

/// The prefix of the `scene` uniform's members that hold where each texel array starts.
pub(crate) const START_PREFIX: &str = "lp_start_";

/// The name codegen gives the texel buffer of resources `global` whose texels are `vec4<u32>`
/// (`unsigned`) or `vec4<f32>` (`codegen/src/wgsl/shaders.rs`).
fn texel_buffer_name(global: &str, unsigned: bool) -> String {
    format!("lp_{global}_{}", if unsigned { "vec4u" } else { "vec4f" })
}

/// One texel array the shader reads, placed in its element type's buffer.
pub(crate) struct PlacedArray<'a> {
    pub(crate) field: &'static str,
    pub(crate) unsigned: bool,
    /// Where it starts in its buffer, in texels.
    pub(crate) start: u64,
    pub(crate) bytes: &'a [u8],
}

/// The texel arrays the shader reads (the `scene` uniform's `lp_start_*` members, in their
/// order), each placed after the previous array of its element type; the arrays a moved scene
/// replaces ([`Packed::GEOMETRY_ARRAYS`]) last, so that taking a pose rewrites only the tail of
/// each buffer ([`take_scene_geometry`]).
pub(crate) fn place_arrays<'a>(
    uniform: Option<&UniformLayout>,
    global: &str,
    scene: &'a dyn Resources,
) -> Result<Vec<PlacedArray<'a>>, WgpuError> {
    let bindings = scene.fields();
    let mut ends = [0u64; 2];
    let mut placed = Vec::new();
    let members: Vec<&str> = uniform.map_or(Vec::new(), |u| u.members.iter().map(|(m, _)| m.as_str()).collect());
    let (moving, steady): (Vec<&str>, Vec<&str>) =
        members.iter().filter_map(|m| m.strip_prefix(START_PREFIX)).partition(|f| is_moving(f));
    for field in steady.into_iter().chain(moving) {
        let (name, bytes, unsigned): (&'static str, &[u8], bool) = match bindings.iter().find(|(n, _)| *n == field) {
            Some((n, Resource::Vec4s(t))) => (n, bytemuck::cast_slice(t.as_slice()), false),
            Some((n, Resource::UVec4s(t))) => (n, bytemuck::cast_slice(t.as_slice()), true),
            other => {
                return Err(WgpuError::UnboundResource {
                    name: format!("{global}.{START_PREFIX}{field}"),
                    detail: other.map_or(String::new(), |(_, b)| {
                        format!(" as a texel array's start (the field is {})", b.dsl_type())
                    }),
                })
            }
        };
        let end = &mut ends[unsigned as usize];
        placed.push(PlacedArray { field: name, unsigned, start: *end, bytes });
        *end += bytes.len() as u64 / 16;
    }
    Ok(placed)
}

/// Whether a moved scene replaces texel array `field` ([`Packed::GEOMETRY_ARRAYS`]).
fn is_moving(field: &str) -> bool {
    Packed::GEOMETRY_ARRAYS.contains(&field)
}

/// The bytes of the texel buffer of one element type: its arrays one after another (one zero
/// texel when there are none: a binding cannot be empty).
fn texel_buffer_bytes(placed: &[PlacedArray], unsigned: bool) -> u64 {
    placed.iter().filter(|a| a.unsigned == unsigned).map(|a| a.bytes.len() as u64).sum::<u64>().max(16)
}

/// "lp_scene_vec4f (triangles + shading + ...)": a texel buffer and the arrays in it.
fn describe_texel_buffer(global: &str, placed: &[PlacedArray], unsigned: bool) -> String {
    let fields: Vec<&str> = placed.iter().filter(|a| a.unsigned == unsigned).map(|a| a.field).collect();
    format!("{} ({})", texel_buffer_name(global, unsigned), fields.join(" + "))
}

/// A resource of the entry point rather than of the scene.
#[derive(Clone, Debug)]
pub(crate) struct OwnResource {
    pub(crate) name: String,
    pub(crate) group: u32,
    pub(crate) binding: u32,
    /// The struct layout of a uniform; `None` for a storage buffer.
    pub(crate) uniform: Option<UniformLayout>,
}

impl ShaderLayout {
    /// The entry point's resource `name` (checked present by [`reflect`]).
    pub(crate) fn own(&self, name: &str) -> &OwnResource {
        self.own.iter().find(|r| r.name == name).expect("reflect checks that every own resource is declared")
    }
}

#[derive(Clone, Debug)]
pub(crate) struct UniformLayout {
    pub(crate) group: u32,
    pub(crate) binding: u32,
    pub(crate) size: u32,
    pub(crate) members: Vec<(String, u32)>,
    /// Declared `var<storage, read>` (the scene's scalars) rather than `var<uniform>`.
    pub(crate) storage: bool,
}

impl UniformLayout {
    /// How the buffer holding it is bound.
    pub(crate) fn binding_type(&self) -> wgpu::BufferBindingType {
        if self.storage {
            wgpu::BufferBindingType::Storage { read_only: true }
        } else {
            wgpu::BufferBindingType::Uniform
        }
    }

    /// What the buffer holding it is created for (written again by the host: the camera).
    pub(crate) fn usage(&self) -> wgpu::BufferUsages {
        let bound = if self.storage { wgpu::BufferUsages::STORAGE } else { wgpu::BufferUsages::UNIFORM };
        bound | wgpu::BufferUsages::COPY_DST
    }
}

/// Reads the resource layout of the generated shader with naga (the WGSL front end wgpu uses).
/// `global` names the resources struct the shader reads (`scene`, `filter_image`); `own` the
/// entry point's resources: each must be declared, and anything that is neither one of them
/// nor the struct's data is an error.
pub(crate) fn reflect(generated: &Generated, global: &str, own: &[&str]) -> Result<ShaderLayout, WgpuError> {
    let module = naga::front::wgsl::parse_str(&generated.source).map_err(|e| WgpuError::Compile {
        log: annotate_messages(
            &[Message {
                text: e.emit_to_string(&generated.source),
                line: e.location(&generated.source).map(|l| l.line_number),
            }],
            generated,
        ),
    })?;
    let mut layout = ShaderLayout { global: global.to_string(), ..ShaderLayout::default() };
    let texel_buffers = [false, true].map(|unsigned| (texel_buffer_name(global, unsigned), unsigned));
    for (_, variable) in module.global_variables.iter() {
        let (Some(name), Some(binding)) = (&variable.name, &variable.binding) else { continue };
        let uniform = |storage| match &module.types[variable.ty].inner {
            naga::TypeInner::Struct { members, span } => Some(UniformLayout {
                group: binding.group,
                binding: binding.binding,
                size: *span,
                members: members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect(),
                storage,
            }),
            _ => None,
        };
        match (name.as_str(), variable.space) {
            (n, naga::AddressSpace::Uniform) if n == global => layout.scene_uniform = uniform(false),
            (n, naga::AddressSpace::Storage { access })
                if n == global && !access.contains(naga::StorageAccess::STORE) =>
            {
                layout.scene_uniform = uniform(true)
            }
            (n, space) if own.contains(&n) => layout.own.push(OwnResource {
                name: n.to_string(),
                group: binding.group,
                binding: binding.binding,
                uniform: if space == naga::AddressSpace::Uniform { uniform(false) } else { None },
            }),
            (n, naga::AddressSpace::Storage { access }) if texel_buffers.iter().any(|(b, _)| b == n) => {
                if access.contains(naga::StorageAccess::STORE) {
                    return Err(WgpuError::UnboundResource {
                        name: n.to_string(),
                        detail: " as a writable buffer (scene data is read-only)".into(),
                    });
                }
                let unsigned = texel_buffers.iter().any(|(b, u)| b == n && *u);
                layout.texel_buffers.push(TexelBuffer { unsigned, group: binding.group, binding: binding.binding });
            }
            (n, space) => {
                return Err(WgpuError::UnboundResource { name: n.to_string(), detail: format!(" (in {space:?})") })
            }
        }
    }
    if let Some(missing) = own.iter().find(|n| !layout.own.iter().any(|r| r.name == **n)) {
        return Err(WgpuError::UnboundResource {
            name: missing.to_string(),
            detail: ": the generated entry point lacks it".into(),
        });
    }
    Ok(layout)
}

/// The bytes of the `scene` uniform struct (resources `global`): each member's value at its WGSL offset.
pub(crate) fn scene_uniform_bytes(
    layout: &UniformLayout,
    global: &str,
    scene: &dyn Resources,
) -> Result<Vec<u8>, WgpuError> {
    let bindings = scene.fields();
    let placed = place_arrays(Some(layout), global, scene)?;
    let mut bytes = vec![0u8; layout.size as usize];
    for (member, offset) in &layout.members {
        // Members carry the field's name as generated code spells it (`step` is `step_`).
        let value = bindings.iter().find(|(n, _)| lightport_codegen::identifier(n) == *member).map(|(_, b)| b);
        let start = member.strip_prefix(START_PREFIX).and_then(|f| placed.iter().find(|a| a.field == f));
        let words: Vec<u32> = match value {
            _ if start.is_some() => {
                let a = start.expect("checked");
                // Indices are u32 in the shader: a start beyond them cannot be reached.
                let start = u32::try_from(a.start).map_err(|_| WgpuError::SceneTooLarge {
                    array: describe_texel_buffer(global, &placed, a.unsigned),
                    bytes: texel_buffer_bytes(&placed, a.unsigned),
                    limit: "u32 texel indices",
                    max: (u32::MAX as u64 + 1) * 16,
                })?;
                vec![start]
            }
            Some(Resource::F32(x)) => vec![x.to_bits()],
            Some(Resource::U32(x)) => vec![**x],
            Some(Resource::Vec3(v)) => v.to_array().map(f32::to_bits).to_vec(),
            Some(other) => {
                return Err(WgpuError::UnboundResource {
                    name: format!("{global}.{member}"),
                    detail: format!(" as a uniform member (the field is {})", other.dsl_type()),
                })
            }
            None => {
                return Err(WgpuError::UnboundResource { name: format!("{global}.{member}"), detail: String::new() })
            }
        };
        let start = *offset as usize;
        for (i, w) in words.iter().enumerate() {
            bytes[start + 4 * i..start + 4 * i + 4].copy_from_slice(&w.to_le_bytes());
        }
    }
    Ok(bytes)
}

/// The storage-buffer binding size the renderer works under.
pub(crate) fn storage_limit(limits: &wgpu::Limits, options: &WgpuOptions) -> u64 {
    let device = limits.max_storage_buffer_binding_size;
    options.max_storage_buffer_binding_size.map_or(device, |m| m.min(device))
}

/// The storage buffers per shader stage the renderer works under.
pub(crate) fn storage_buffers_limit(limits: &wgpu::Limits, options: &WgpuOptions) -> u32 {
    let device = limits.max_storage_buffers_per_shader_stage;
    options.max_storage_buffers_per_shader_stage.map_or(device, |m| m.min(device))
}

/// Checks the scene's arrays and the shader's resources against the device's limits.
/// `storage_buffers` and `groups` count every storage buffer and bind group the shader uses.
pub(crate) fn check_scene_limits(
    limits: &wgpu::Limits,
    options: &WgpuOptions,
    scene: &dyn Resources,
    layout: &ShaderLayout,
) -> Result<(), WgpuError> {
    let binding_max = storage_limit(limits, options);
    let buffer_max = limits.max_buffer_size;
    let placed = place_arrays(layout.scene_uniform.as_ref(), &layout.global, scene)?;
    for buffer in &layout.texel_buffers {
        let bytes = texel_buffer_bytes(&placed, buffer.unsigned);
        for (limit, max) in [("max_storage_buffer_binding_size", binding_max), ("max_buffer_size", buffer_max)] {
            if bytes > max {
                return Err(WgpuError::SceneTooLarge {
                    array: describe_texel_buffer(&layout.global, &placed, buffer.unsigned),
                    bytes,
                    limit,
                    max,
                });
            }
        }
    }
    let own_storage = layout.own.iter().filter(|r| r.uniform.is_none()).count();
    let scene_storage = layout.scene_uniform.as_ref().is_some_and(|u| u.storage) as usize;
    let storage_buffers = (layout.texel_buffers.len() + own_storage + scene_storage) as u64;
    let groups =
        1 + layout.texel_buffers.iter().map(|b| b.group).chain(layout.own.iter().map(|r| r.group)).max().unwrap_or(0)
            as u64;
    let uniform_size = layout.scene_uniform.as_ref().filter(|u| !u.storage).map_or(0, |u| u.size) as u64;
    for (limit, needed, max) in [
        ("max_storage_buffers_per_shader_stage", storage_buffers, storage_buffers_limit(limits, options) as u64),
        ("max_bind_groups", groups, limits.max_bind_groups as u64),
        ("max_uniform_buffer_binding_size", uniform_size, limits.max_uniform_buffer_binding_size),
    ] {
        if needed > max {
            return Err(WgpuError::Unsupported { limit, needed, max });
        }
    }
    Ok(())
}

/// A buffer and where the shader binds it.
#[derive(Clone)]
pub(crate) struct BufferEntry {
    pub(crate) group: u32,
    pub(crate) binding: u32,
    pub(crate) buffer: wgpu::Buffer,
    pub(crate) ty: wgpu::BufferBindingType,
}

impl BufferEntry {
    pub(crate) fn uniform(resource: &OwnResource, buffer: wgpu::Buffer) -> BufferEntry {
        let ty = wgpu::BufferBindingType::Uniform;
        BufferEntry { group: resource.group, binding: resource.binding, buffer, ty }
    }

    pub(crate) fn storage(resource: &OwnResource, buffer: wgpu::Buffer, read_only: bool) -> BufferEntry {
        let ty = wgpu::BufferBindingType::Storage { read_only };
        BufferEntry { group: resource.group, binding: resource.binding, buffer, ty }
    }
}

/// The `scene` uniform's buffer and layout, kept for updates (the camera, the frame seed).
pub(crate) type SceneUniform = (wgpu::Buffer, UniformLayout);

/// Uploads the scene data the shader reads: the `scene` uniform (returned with its layout,
/// for later updates) and the texel buffers, each array copied straight into its place.
pub(crate) fn upload_scene(
    d: &wgpu::Device,
    layout: &ShaderLayout,
    scene: &dyn Resources,
) -> Result<(Vec<BufferEntry>, Option<SceneUniform>), WgpuError> {
    upload_scene_with_room(d, layout, scene, None)
}

/// [`upload_scene`] with `room`: each texel buffer then has an eighth of its moving tail's size
/// to spare (up to `room` bytes in all), so that the next poses, whose top level and remade
/// meshes may need a few more nodes, are written in place.
pub(crate) fn upload_scene_with_room(
    d: &wgpu::Device,
    layout: &ShaderLayout,
    scene: &dyn Resources,
    room: Option<u64>,
) -> Result<(Vec<BufferEntry>, Option<SceneUniform>), WgpuError> {
    let mut entries = Vec::new();
    let mut scene_uniform = None;
    if let Some(u) = &layout.scene_uniform {
        let buffer = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("scene uniforms"),
            contents: &scene_uniform_bytes(u, &layout.global, scene)?,
            usage: u.usage(),
        });
        let ty = u.binding_type();
        entries.push(BufferEntry { group: u.group, binding: u.binding, buffer: buffer.clone(), ty });
        scene_uniform = Some((buffer, u.clone()));
    }
    let placed = place_arrays(layout.scene_uniform.as_ref(), &layout.global, scene)?;
    for texels in &layout.texel_buffers {
        let bytes = texel_buffer_bytes(&placed, texels.unsigned);
        let tail: u64 = placed
            .iter()
            .filter(|a| a.unsigned == texels.unsigned && is_moving(a.field))
            .map(|a| a.bytes.len() as u64)
            .sum();
        let size = room.map_or(bytes, |max| (bytes + tail / 8).next_multiple_of(16).min(max).max(bytes));
        let buffer = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some(&texel_buffer_name(&layout.global, texels.unsigned)),
            size,
            // COPY_DST: an image pass's output becomes the next pass's input in place, and a
            // moved scene's geometry is written over the tail.
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: true,
        });
        {
            let mut view = buffer
                .slice(..)
                .get_mapped_range_mut()
                .map_err(|e| WgpuError::Wgpu { what: "writing the scene's texel buffer", detail: e.to_string() })?;
            for a in placed.iter().filter(|a| a.unsigned == texels.unsigned) {
                let start = a.start as usize * 16;
                view.slice(start..start + a.bytes.len()).copy_from_slice(a.bytes);
            }
        }
        buffer.unmap();
        let ty = wgpu::BufferBindingType::Storage { read_only: true };
        entries.push(BufferEntry { group: texels.group, binding: texels.binding, buffer, ty });
    }
    Ok((entries, scene_uniform))
}

/// The room a renderer's scene buffers get ([`upload_scene_with_room`]): the most bytes a
/// buffer may have, for a two-level scene (`Features::instances`, the only kind that moves);
/// `None` (exact sizes) for a one-level one.
pub(crate) fn scene_room(limits: &wgpu::Limits, options: &WgpuOptions, features: &Features) -> Option<u64> {
    features.instances.then(|| most_buffer_bytes(limits, options))
}

/// The most bytes one storage buffer the shader binds whole may have.
pub(crate) fn most_buffer_bytes(limits: &wgpu::Limits, options: &WgpuOptions) -> u64 {
    storage_limit(limits, options).min(limits.max_buffer_size)
}

/// Takes `scene`, the scene `entries` and `uniform` were uploaded for with another pose's
/// geometry (only [`Packed::GEOMETRY_ARRAYS`] differ, placed last): its geometry is written
/// over each texel buffer's tail and its uniform (the arrays' starts) rewritten, in place,
/// when every buffer has room; otherwise the scene is uploaded again with room to spare, at
/// most `max_bytes` a buffer, into new buffers. Returns whether the buffers are new (bind
/// groups must be made again). Limits are the caller's to check first (`check_scene_limits`).
fn take_scene_geometry(
    d: &wgpu::Device,
    queue: &wgpu::Queue,
    layout: &ShaderLayout,
    scene: &dyn Resources,
    max_bytes: u64,
    entries: &mut Vec<BufferEntry>,
    uniform: &mut Option<SceneUniform>,
) -> Result<bool, WgpuError> {
    let placed = place_arrays(layout.scene_uniform.as_ref(), &layout.global, scene)?;
    let buffer_of = |t: &TexelBuffer| {
        entries.iter().find(|e| (e.group, e.binding) == (t.group, t.binding)).map(|e| e.buffer.clone())
    };
    let buffers: Option<Vec<(bool, wgpu::Buffer)>> =
        layout.texel_buffers.iter().map(|t| buffer_of(t).map(|b| (t.unsigned, b))).collect();
    let fits = buffers
        .as_ref()
        .is_some_and(|buffers| buffers.iter().all(|(unsigned, b)| b.size() >= texel_buffer_bytes(&placed, *unsigned)));
    match (buffers, fits) {
        (Some(buffers), true) => {
            for a in placed.iter().filter(|a| is_moving(a.field) && !a.bytes.is_empty()) {
                if let Some((_, buffer)) = buffers.iter().find(|(unsigned, _)| *unsigned == a.unsigned) {
                    queue.write_buffer(buffer, a.start * 16, a.bytes);
                }
            }
            if let Some((buffer, u)) = uniform.as_ref() {
                queue.write_buffer(buffer, 0, &scene_uniform_bytes(u, &layout.global, scene)?);
            }
            Ok(false)
        }
        _ => {
            (*entries, *uniform) = upload_scene_with_room(d, layout, scene, Some(max_bytes))?;
            Ok(true)
        }
    }
}

/// What a renderer's shader is bound to: the scene's uniform and texel buffers (a moved scene's
/// geometry is written over them, or they are replaced), the renderer's own buffers, and the
/// bind groups over both. The megakernel and the wavefront keep one each.
pub(crate) struct Bindings {
    pub(crate) layout: ShaderLayout,
    pub(crate) group_layouts: Vec<wgpu::BindGroupLayout>,
    pub(crate) scene: Vec<BufferEntry>,
    pub(crate) scene_uniform: Option<SceneUniform>,
    pub(crate) own: Vec<BufferEntry>,
    pub(crate) groups: Vec<wgpu::BindGroup>,
}

impl Bindings {
    /// Binds `entries` (the scene's first, then `own_count` of the renderer's own) with
    /// `group_layouts`.
    pub(crate) fn new(
        d: &wgpu::Device,
        layout: ShaderLayout,
        group_layouts: Vec<wgpu::BindGroupLayout>,
        mut entries: Vec<BufferEntry>,
        own_count: usize,
        scene_uniform: Option<SceneUniform>,
    ) -> Bindings {
        let groups = bind_groups(d, &group_layouts, &entries);
        let own = entries.split_off(entries.len() - own_count);
        Bindings { layout, group_layouts, scene: entries, scene_uniform, own, groups }
    }

    /// Takes `scene`, the scene bound here with another pose's geometry: checked against the
    /// device's limits, then written in place or uploaded again (see [`take_scene_geometry`]),
    /// and bound again if its buffers are new.
    pub(crate) fn take_geometry(
        &mut self,
        device: &super::WgpuDevice,
        options: &WgpuOptions,
        scene: &dyn Resources,
    ) -> Result<(), WgpuError> {
        let (d, max_bytes) = (&device.device, self.room_for(device, options, scene)?);
        let (entries, uniform) = (&mut self.scene, &mut self.scene_uniform);
        if take_scene_geometry(d, &device.queue, &self.layout, scene, max_bytes, entries, uniform)? {
            self.bind_again(d);
        }
        Ok(())
    }

    /// [`Renderer::take_scene`](crate::backend::Renderer::take_scene) for the renderer whose
    /// scene, `packed`, is bound here: `scene` exchanged with it (refused for another kernel
    /// variant or image size), checked against the device's limits, every array uploaded into
    /// new buffers and bound again with the renderer's own. A failed upload exchanges back:
    /// nothing changes.
    pub(crate) fn take_scene(
        &mut self,
        device: &super::WgpuDevice,
        options: &WgpuOptions,
        packed: &mut Packed,
        mut scene: Packed,
    ) -> Result<(), RenderError> {
        exchange_scene(packed, &mut scene)?;
        let uploaded = self
            .room_for(device, options, &packed.scene)
            .and_then(|max_bytes| upload_scene_with_room(&device.device, &self.layout, &packed.scene, Some(max_bytes)));
        match uploaded {
            Ok((entries, uniform)) => {
                (self.scene, self.scene_uniform) = (entries, uniform);
                self.bind_again(&device.device);
                Ok(())
            }
            Err(e) => {
                // Back to the scene the buffers hold (the exchange was just checked).
                let _ = packed.exchange_scene(&mut scene);
                Err(e.into())
            }
        }
    }

    /// The most bytes one of `scene`'s buffers may take on `device`, once the scene is checked
    /// against the device's limits (what taking a scene or a pose checks first).
    fn room_for(
        &self,
        device: &super::WgpuDevice,
        options: &WgpuOptions,
        scene: &dyn Resources,
    ) -> Result<u64, WgpuError> {
        check_scene_limits(&device.limits, options, scene, &self.layout)?;
        Ok(most_buffer_bytes(&device.limits, options))
    }

    /// New bind groups over the scene's buffers (new ones) and the renderer's own.
    fn bind_again(&mut self, d: &wgpu::Device) {
        let entries: Vec<BufferEntry> = self.scene.iter().chain(&self.own).cloned().collect();
        self.groups = bind_groups(d, &self.group_layouts, &entries);
    }
}

/// The bind group layouts of `entries` (groups 0, 1, ... as the shader numbers them) and the
/// pipeline layout they imply.
pub(crate) fn bind_group_layouts(
    d: &wgpu::Device,
    entries: &[BufferEntry],
) -> (Vec<wgpu::BindGroupLayout>, wgpu::PipelineLayout) {
    let group_count = entries.iter().map(|e| e.group).max().map_or(0, |g| g + 1);
    let group_layouts: Vec<wgpu::BindGroupLayout> = (0..group_count)
        .map(|group| {
            let layout_entries: Vec<wgpu::BindGroupLayoutEntry> = entries
                .iter()
                .filter(|e| e.group == group)
                .map(|e| wgpu::BindGroupLayoutEntry {
                    binding: e.binding,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer { ty: e.ty, has_dynamic_offset: false, min_binding_size: None },
                    count: None,
                })
                .collect();
            d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("lightport"),
                entries: &layout_entries,
            })
        })
        .collect();
    let layout_refs: Vec<Option<&wgpu::BindGroupLayout>> = group_layouts.iter().map(Some).collect();
    let pipeline_layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("lightport"),
        bind_group_layouts: &layout_refs,
        immediate_size: 0,
    });
    (group_layouts, pipeline_layout)
}

/// The bind groups of `entries` on `layouts` ([`bind_group_layouts`] of entries like them).
fn bind_groups(d: &wgpu::Device, layouts: &[wgpu::BindGroupLayout], entries: &[BufferEntry]) -> Vec<wgpu::BindGroup> {
    (0..layouts.len() as u32)
        .map(|group| {
            let group_entries: Vec<wgpu::BindGroupEntry> = entries
                .iter()
                .filter(|e| e.group == group)
                .map(|e| wgpu::BindGroupEntry { binding: e.binding, resource: e.buffer.as_entire_binding() })
                .collect();
            d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("lightport"),
                layout: &layouts[group as usize],
                entries: &group_entries,
            })
        })
        .collect()
}

/// The bind groups of `entries` (groups 0, 1, ...) on the layouts `pipeline` derived from its
/// shader (a pipeline created without an explicit layout).
pub(crate) fn pipeline_bind_groups(
    d: &wgpu::Device,
    pipeline: &wgpu::ComputePipeline,
    entries: &[&BufferEntry],
    label: &str,
) -> Vec<wgpu::BindGroup> {
    let count = entries.iter().map(|e| e.group).max().map_or(0, |g| g + 1);
    (0..count)
        .map(|group| {
            let members: Vec<wgpu::BindGroupEntry> = entries
                .iter()
                .filter(|e| e.group == group)
                .map(|e| wgpu::BindGroupEntry { binding: e.binding, resource: e.buffer.as_entire_binding() })
                .collect();
            d.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &pipeline.get_bind_group_layout(group),
                entries: &members,
            })
        })
        .collect()
}

/// The bytes of a uniform struct whose members are all `u32`, from `value` per member name.
pub(crate) fn u32_uniform_bytes(
    uniform: &OwnResource,
    value: impl Fn(&str) -> Option<u32>,
) -> Result<Vec<u8>, WgpuError> {
    let layout = uniform.uniform.as_ref().ok_or_else(|| WgpuError::UnboundResource {
        name: uniform.name.clone(),
        detail: ": expected a uniform struct".into(),
    })?;
    let mut bytes = vec![0u8; layout.size as usize];
    for (member, offset) in &layout.members {
        let value = value(member).ok_or_else(|| WgpuError::UnboundResource {
            name: format!("{}.{member}", uniform.name),
            detail: String::new(),
        })?;
        bytes[*offset as usize..*offset as usize + 4].copy_from_slice(&value.to_le_bytes());
    }
    Ok(bytes)
}

/// The contents of `readback` (texels, words) once the device has mapped it for reading (the
/// copy into it must be submitted already); the buffer is unmapped again. Resolves when the
/// device is polled (natively) or by the browser.
pub(crate) fn map_readback<T: bytemuck::Pod>(
    readback: wgpu::Buffer,
) -> impl std::future::Future<Output = Result<Vec<T>, WgpuError>> + 'static {
    let (sender, receiver) = super::oneshot::channel();
    readback.slice(..).map_async(wgpu::MapMode::Read, move |result| sender.send(result));
    let failed = |detail: String| WgpuError::Wgpu { what: "mapping a read-back buffer", detail };
    async move {
        receiver
            .await
            .ok_or_else(|| failed("the device dropped the request".into()))?
            .map_err(|e| failed(e.to_string()))?;
        let contents: Vec<T> = {
            let view = readback
                .slice(..)
                .get_mapped_range()
                .map_err(|e| WgpuError::Wgpu { what: "reading a read-back buffer", detail: e.to_string() })?;
            bytemuck::pod_collect_to_vec(&view)
        };
        readback.unmap();
        Ok(contents)
    }
}

/// The first error wgpu reported outside an error scope on a device, since [`watch`](Self::watch).
#[derive(Clone, Debug, Default)]
pub(crate) struct UncapturedErrors(std::sync::Arc<std::sync::Mutex<Option<String>>>);

impl UncapturedErrors {
    /// Keeps the first error `device` reports from now on (replacing its previous handler).
    pub(crate) fn watch(device: &wgpu::Device) -> UncapturedErrors {
        let errors = UncapturedErrors::default();
        let sink = errors.0.clone();
        device.on_uncaptured_error(std::sync::Arc::new(move |e: wgpu::Error| {
            let mut slot = sink.lock().unwrap_or_else(|p| p.into_inner());
            slot.get_or_insert_with(|| e.to_string());
        }));
        errors
    }

    /// That error, if there was one.
    pub(crate) fn check(&self) -> Result<(), WgpuError> {
        let slot = self.0.lock().unwrap_or_else(|p| p.into_inner());
        match &*slot {
            Some(detail) => Err(WgpuError::Wgpu { what: "the device", detail: detail.clone() }),
            None => Ok(()),
        }
    }
}
