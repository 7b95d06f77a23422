//! The kernel's `Scene` fields as the GL backend binds them: data textures and uniforms, and
//! the check that the shader declares nothing else.

use glam::{UVec4, Vec3, Vec4};
use glow::HasContext;
use kernel_dsl::Texels;

use super::{GlError, ACCUMULATION_UNIFORM, SCENE_UNIFORM_PREFIX};
use crate::kernel::scene_data::Scene;

/// One field of the kernel's `Scene` as the GL backend binds it.
#[derive(Clone, Copy, Debug)]
pub enum Binding<'a> {
    /// An RGBA32F data texture (`sampler2D`).
    Vec4s(&'a Texels<Vec4>),
    /// An RGBA32UI data texture (`usampler2D`).
    UVec4s(&'a Texels<UVec4>),
    F32(&'a f32),
    U32(&'a u32),
    Vec3(&'a Vec3),
}

impl Binding<'_> {
    /// The GL type of the uniform the shader declares for this binding (`glGetActiveUniform`).
    pub fn gl_type(&self) -> u32 {
        match self {
            Binding::Vec4s(_) => glow::SAMPLER_2D,
            Binding::UVec4s(_) => glow::UNSIGNED_INT_SAMPLER_2D,
            Binding::F32(_) => glow::FLOAT,
            Binding::U32(_) => glow::UNSIGNED_INT,
            Binding::Vec3(_) => glow::FLOAT_VEC3,
        }
    }

    /// The kernel DSL type of the field (as the IR spells it).
    pub fn dsl_type(&self) -> &'static str {
        match self {
            Binding::Vec4s(_) => "Texels<Vec4>",
            Binding::UVec4s(_) => "Texels<UVec4>",
            Binding::F32(_) => "f32",
            Binding::U32(_) => "u32",
            Binding::Vec3(_) => "Vec3",
        }
    }

    /// Texel count of a data texture; `None` for a uniform.
    pub fn texels(&self) -> Option<usize> {
        match self {
            Binding::Vec4s(t) => Some(t.len()),
            Binding::UVec4s(t) => Some(t.len()),
            _ => None,
        }
    }
}

/// Lists every field of `Scene` with its binding kind. The struct pattern names each field
/// (no `..`) and the kind must match the field's type: a new `Scene` field is a compile error
/// here until it is listed, and the name is the field's own (`stringify!`).
macro_rules! bind_scene_fields {
    ($scene:expr; $($field:ident: $kind:ident),* $(,)?) => {{
        let Scene { $($field),* } = $scene;
        vec![$((stringify!($field), Binding::$kind($field))),*]
    }};
}

/// Every field of the kernel's `Scene`, named as in Rust (the GLSL uniform is `scene_<name>`).
pub fn scene_bindings(scene: &Scene) -> Vec<(&'static str, Binding<'_>)> {
    bind_scene_fields!(scene;
        triangles: Vec4s,
        shading: Vec4s,
        nodes: Vec4s,
        node_children: UVec4s,
        materials: Vec4s,
        lights: Vec4s,
        texture_texels: UVec4s,
        texture_info: UVec4s,
        sky: Vec4s,
        sky_rows: Vec4s,
        metal_rough: Vec4s,
        tangent_first: U32,
        normal_map_first: U32,
        alpha_mask_first: U32,
        texture_ref_first: U32,
        texcoord1_first: U32,
        transmission_first: U32,
        camera_position: Vec3,
        camera_right: Vec3,
        camera_up: Vec3,
        camera_forward: Vec3,
        lens_radius: F32,
        focus_distance: F32,
        width: U32,
        height: U32,
        frame_seed: U32,
        max_depth: U32,
        strategy: U32,
        light_count: U32,
        sky_width: U32,
        sky_height: U32,
        sky_intensity: F32,
        sky_rotation: F32,
        scene_scale: F32,
        leaf_stack_limit: U32,
        has_sky: U32,
        has_textures: U32,
        has_shading: U32,
        has_lights: U32,
        has_triangle_lights: U32,
        has_point_lights: U32,
        has_metal_rough: U32,
        has_normal_map: U32,
        has_alpha_mask: U32,
        has_texture_transform: U32,
        has_texcoord1: U32,
        has_transmission: U32,
        has_volume: U32,
    )
}

/// Every active uniform of `program` must be one the renderer binds, with the GL type of its
/// field: a uniform the codegen adds and this backend does not set is an error, not a zero.
pub(super) fn check_active_uniforms(
    gl: &glow::Context,
    program: glow::Program,
    bindings: &[(&'static str, Binding<'_>)],
) -> Result<(), GlError> {
    // SAFETY: queries on a linked program of the current context.
    let active: Vec<glow::ActiveUniform> =
        unsafe { (0..gl.get_active_uniforms(program)).filter_map(|i| gl.get_active_uniform(program, i)).collect() };
    for u in active {
        if u.name == ACCUMULATION_UNIFORM && u.utype == glow::SAMPLER_2D {
            continue;
        }
        let field = u.name.strip_prefix(SCENE_UNIFORM_PREFIX);
        let binding = field.and_then(|f| bindings.iter().find(|(n, _)| *n == f)).map(|(_, b)| b);
        match binding {
            Some(b) if b.gl_type() == u.utype => {}
            Some(b) => {
                return Err(GlError::UnboundUniform {
                    name: u.name,
                    gl_type: u.utype,
                    expected: format!(
                        " as that type (the Scene field is {}, GL type {:#06x})",
                        b.dsl_type(),
                        b.gl_type()
                    ),
                })
            }
            None => return Err(GlError::UnboundUniform { name: u.name, gl_type: u.utype, expected: String::new() }),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use kernel_dsl::ir::{Item, Type};

    fn type_name(t: &Type) -> String {
        match t {
            Type::Named { name, args } if args.is_empty() => name.clone(),
            Type::Named { name, args } => {
                format!("{name}<{}>", args.iter().map(type_name).collect::<Vec<_>>().join(", "))
            }
            other => format!("{other:?}"),
        }
    }

    /// Every field of every `#[resources]` struct of the kernel is bound, under its own name
    /// and with the right kind; nothing else is.
    #[test]
    fn every_resource_field_is_bound() {
        let scene = Scene::default();
        let bindings = scene_bindings(&scene);
        let mut resources = 0;
        for module in crate::kernel::modules() {
            for item in &module.items {
                let Item::Struct(s) = item else { continue };
                if !s.resources {
                    continue;
                }
                resources += 1;
                let names: Vec<&str> = s.fields.iter().map(|f| f.name.as_str()).collect();
                let bound: Vec<&str> = bindings.iter().map(|(n, _)| *n).collect();
                assert_eq!(bound, names, "the GL backend's bindings must list the fields of {}", s.name);
                for (field, (_, binding)) in s.fields.iter().zip(&bindings) {
                    assert_eq!(type_name(&field.ty), binding.dsl_type(), "field {}", field.name);
                }
            }
        }
        assert_eq!(resources, 1, "one #[resources] struct");
    }
}
