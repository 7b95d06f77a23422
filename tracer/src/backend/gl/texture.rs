//! The data textures: the shape a packed array takes as a 2D texture (a power-of-two width, so
//! that the shader's `lp_fetch_*` finds texel i's row by a shift and its column by a mask:
//! `lightport_codegen::TexelRows::PowerOfTwoWidth`), the scene's arrays laid out in it, and
//! their upload.

use glow::HasContext;

use kernel_dsl::Resource;

use super::{gl_failed, GlError};
use crate::pack::{PackError, Packed};

/// Lays out `texels` as a 2D texture of power-of-two width no larger than `max_size`:
/// the narrowest power of two that keeps the height within `max_size` and near-square.
pub fn texture_shape(texels: usize, max_size: u32) -> Option<(u32, u32)> {
    let texels = texels.max(1);
    let mut width = 1u32;
    while (width as usize) * (width as usize) < texels && width < max_size {
        width *= 2;
    }
    let height = texels.div_ceil(width as usize);
    (height <= max_size as usize).then_some((width, height as u32))
}

/// Used and allocated texels of one packed array once laid out as a 2D texture.
#[derive(Clone, Debug, PartialEq)]
pub struct ArrayStats {
    pub name: &'static str,
    pub texels: usize,
    pub width: u32,
    pub height: u32,
    /// Bytes per texel (16 for RGBA32F / RGBA32UI).
    pub texel_bytes: usize,
}

impl ArrayStats {
    pub fn allocated(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

impl Packed {
    /// Every packed array with its texture layout for `max_texture_size`; arrays the scene
    /// does not use are absent.
    pub fn arrays(&self, max_texture_size: u32) -> Result<Vec<ArrayStats>, PackError> {
        let s = &self.scene;
        let list: [(&'static str, usize); 11] = [
            ("triangles", s.triangles.len()),
            ("shading", s.shading.len()),
            ("nodes", s.nodes.len()),
            ("node_children", s.node_children.len()),
            ("materials", s.materials.len()),
            ("lights", s.lights.len()),
            ("texture_texels", s.texture_texels.len()),
            ("texture_info", s.texture_info.len()),
            ("sky", s.sky.len()),
            ("sky_rows", s.sky_rows.len()),
            ("metal_rough", s.metal_rough.len()),
        ];
        let mut out = Vec::new();
        for (name, texels) in list {
            if texels == 0 {
                continue;
            }
            let (width, height) = texture_shape(texels, max_texture_size).ok_or(PackError::TooLarge {
                what: name,
                texels,
                max: max_texture_size,
            })?;
            out.push(ArrayStats { name, texels, width, height, texel_bytes: 16 });
        }
        Ok(out)
    }
}

/// The bytes of 32-bit words. Pixel data stays in `u32` buffers because WebGL views it in
/// place as a `Float32Array`/`Uint32Array`, which must be 4-byte aligned.
pub(crate) fn words_as_bytes(words: &[u32]) -> &[u8] {
    // SAFETY: u8 has no alignment or validity requirements; the length covers the same bytes.
    unsafe { std::slice::from_raw_parts(words.as_ptr().cast::<u8>(), std::mem::size_of_val(words)) }
}

pub(crate) fn words_as_bytes_mut(words: &mut [u32]) -> &mut [u8] {
    // SAFETY: as above; every byte pattern is a valid u32, so writes through the view are sound.
    unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), std::mem::size_of_val(words)) }
}

/// NEAREST filtering and edge clamping for the bound 2D texture (float textures are not
/// filterable in OpenGL ES 3.0; the default mipmapped filter would leave them incomplete).
pub(crate) unsafe fn set_nearest(gl: &glow::Context) {
    gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_MIN_FILTER, glow::NEAREST as i32);
    gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_MAG_FILTER, glow::NEAREST as i32);
    gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_WRAP_S, glow::CLAMP_TO_EDGE as i32);
    gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_WRAP_T, glow::CLAMP_TO_EDGE as i32);
}

/// Uploads a packed array as a row-major 2D texture of the shape [`texture_shape`] gives
/// (an empty array the shader still declares becomes one zero texel).
pub(crate) unsafe fn upload_texels(
    gl: &glow::Context,
    binding: &Resource<'_>,
    max_texture_size: u32,
    name: &'static str,
) -> Result<glow::Texture, GlError> {
    let texels = binding.texels().unwrap_or(0);
    let (w, h) = texture_shape(texels, max_texture_size).ok_or(GlError::SceneTooLarge {
        max_texture_size,
        reason: PackError::TooLarge { what: name, texels, max: max_texture_size },
    })?;
    let mut words = Vec::with_capacity(w as usize * h as usize * 4);
    let (internal, format, ty) = match binding {
        Resource::UVec4s(t) => {
            words.extend(t.as_slice().iter().flat_map(|texel| texel.to_array()));
            (glow::RGBA32UI, glow::RGBA_INTEGER, glow::UNSIGNED_INT)
        }
        Resource::Vec4s(t) => {
            words.extend(t.as_slice().iter().flat_map(|texel| texel.to_array().map(f32::to_bits)));
            (glow::RGBA32F, glow::RGBA, glow::FLOAT)
        }
        _ => unreachable!("only texel arrays are uploaded"),
    };
    words.resize(w as usize * h as usize * 4, 0);
    let texture = gl.create_texture().map_err(gl_failed("glCreateTexture (scene data)"))?;
    gl.bind_texture(glow::TEXTURE_2D, Some(texture));
    set_nearest(gl);
    gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 4);
    gl.tex_image_2d(
        glow::TEXTURE_2D,
        0,
        internal as i32,
        w as i32,
        h as i32,
        0,
        format,
        ty,
        glow::PixelUnpackData::Slice(Some(words_as_bytes(&words))),
    );
    let error = gl.get_error();
    gl.bind_texture(glow::TEXTURE_2D, None);
    if error != glow::NO_ERROR {
        gl.delete_texture(texture);
        return Err(GlError::Gl {
            what: "uploading a scene texture",
            detail: format!("scene_{name} ({w}x{h}, {texels} texels): error {error:#06x}"),
        });
    }
    Ok(texture)
}
