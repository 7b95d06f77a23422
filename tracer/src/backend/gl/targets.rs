//! What GL passes that draw into images share: the objects a pass owner created (deleted
//! together), RGBA32F images and the framebuffers that render into them, and reading one back.
//! The renderer's accumulation and the denoiser's filter passes are both made of these.

use glam::Vec4;
use glow::HasContext;

use super::{gl_failed, set_nearest, words_as_bytes, words_as_bytes_mut, GlError};

/// Every GL object an owner created, deleted together.
#[derive(Default)]
pub(super) struct Objects {
    pub(super) textures: Vec<glow::Texture>,
    pub(super) framebuffers: Vec<glow::Framebuffer>,
    pub(super) programs: Vec<glow::Program>,
    pub(super) vertex_arrays: Vec<glow::VertexArray>,
}

impl Objects {
    pub(super) fn delete(&mut self, gl: &glow::Context) {
        // SAFETY: each object was created on `gl` and is deleted once (the lists are drained).
        unsafe {
            for t in self.textures.drain(..) {
                gl.delete_texture(t);
            }
            for f in self.framebuffers.drain(..) {
                gl.delete_framebuffer(f);
            }
            for p in self.programs.drain(..) {
                gl.delete_program(p);
            }
            for v in self.vertex_arrays.drain(..) {
                gl.delete_vertex_array(v);
            }
        }
    }
}

/// An RGBA32F texture of `width` x `height` texels filled from `texels` (row-major, one per
/// texel), NEAREST-filtered.
pub(super) fn image_texture(
    gl: &glow::Context,
    width: u32,
    height: u32,
    texels: &[Vec4],
    objects: &mut Objects,
) -> Result<glow::Texture, GlError> {
    debug_assert_eq!(texels.len(), width as usize * height as usize);
    let words: Vec<u32> = texels.iter().flat_map(|t| t.to_array().map(f32::to_bits)).collect();
    // SAFETY: texture creation and upload on the current context; the slice holds width x
    // height RGBA floats.
    unsafe {
        let texture = gl.create_texture().map_err(gl_failed("glCreateTexture (RGBA32F image)"))?;
        objects.textures.push(texture);
        gl.bind_texture(glow::TEXTURE_2D, Some(texture));
        set_nearest(gl);
        gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 4);
        let data = glow::PixelUnpackData::Slice(Some(words_as_bytes(&words)));
        let (w, h) = (width as i32, height as i32);
        gl.tex_image_2d(glow::TEXTURE_2D, 0, glow::RGBA32F as i32, w, h, 0, glow::RGBA, glow::FLOAT, data);
        let error = gl.get_error();
        gl.bind_texture(glow::TEXTURE_2D, None);
        if error != glow::NO_ERROR {
            let detail = format!("{width}x{height} RGBA32F: error {error:#06x}");
            return Err(GlError::Gl { what: "creating an image texture", detail });
        }
        Ok(texture)
    }
}

/// [`image_texture`] and a framebuffer that renders into it.
pub(super) fn render_target(
    gl: &glow::Context,
    width: u32,
    height: u32,
    texels: &[Vec4],
    objects: &mut Objects,
) -> Result<(glow::Texture, glow::Framebuffer), GlError> {
    let texture = image_texture(gl, width, height, texels, objects)?;
    Ok((texture, framebuffer_for(gl, &[texture], width, height, objects)?))
}

/// `attachments` images of `width` x `height` texels, zeroed, and one framebuffer that renders
/// into all of them: image k is colour attachment k, the fragment shader's output at location k.
pub(super) fn render_targets(
    gl: &glow::Context,
    width: u32,
    height: u32,
    attachments: usize,
    objects: &mut Objects,
) -> Result<(Vec<glow::Texture>, glow::Framebuffer), GlError> {
    let zeros = vec![Vec4::ZERO; width as usize * height as usize];
    let textures =
        (0..attachments).map(|_| image_texture(gl, width, height, &zeros, objects)).collect::<Result<Vec<_>, _>>()?;
    let framebuffer = framebuffer_for(gl, &textures, width, height, objects)?;
    Ok((textures, framebuffer))
}

/// A framebuffer drawing into `textures` (colour attachments 0, 1, ...).
fn framebuffer_for(
    gl: &glow::Context,
    textures: &[glow::Texture],
    width: u32,
    height: u32,
    objects: &mut Objects,
) -> Result<glow::Framebuffer, GlError> {
    // SAFETY: framebuffer creation on the current context, attaching its own textures.
    unsafe {
        let max = gl.get_parameter_i32(glow::MAX_DRAW_BUFFERS).max(1) as usize;
        if textures.len() > max {
            return Err(GlError::Unsupported(format!(
                "a pass writes {} images but GL_MAX_DRAW_BUFFERS is {max}",
                textures.len()
            )));
        }
        let framebuffer = gl.create_framebuffer().map_err(gl_failed("glCreateFramebuffer"))?;
        objects.framebuffers.push(framebuffer);
        gl.bind_framebuffer(glow::FRAMEBUFFER, Some(framebuffer));
        let mut buffers = Vec::new();
        for (k, texture) in textures.iter().enumerate() {
            let attachment = glow::COLOR_ATTACHMENT0 + k as u32;
            gl.framebuffer_texture_2d(glow::FRAMEBUFFER, attachment, glow::TEXTURE_2D, Some(*texture), 0);
            buffers.push(attachment);
        }
        gl.draw_buffers(&buffers);
        let status = gl.check_framebuffer_status(glow::FRAMEBUFFER);
        gl.bind_framebuffer(glow::FRAMEBUFFER, None);
        if status != glow::FRAMEBUFFER_COMPLETE {
            return Err(GlError::Unsupported(format!(
                "an RGBA32F {width}x{height} framebuffer with {} attachments is incomplete (status {status:#06x})",
                textures.len()
            )));
        }
        Ok(framebuffer)
    }
}

/// The RGBA32F pixels of `framebuffer`'s colour attachment `attachment`, row-major.
pub(super) fn read_image(
    gl: &glow::Context,
    framebuffer: glow::Framebuffer,
    attachment: u32,
    width: u32,
    height: u32,
) -> Result<Vec<Vec4>, GlError> {
    let mut words = vec![0u32; width as usize * height as usize * 4];
    // SAFETY: the framebuffer belongs to the current context; the slice holds width x height
    // RGBA floats, the size glReadPixels writes with PACK_ALIGNMENT 4.
    let error = unsafe {
        gl.bind_framebuffer(glow::READ_FRAMEBUFFER, Some(framebuffer));
        gl.read_buffer(glow::COLOR_ATTACHMENT0 + attachment);
        gl.pixel_store_i32(glow::PACK_ALIGNMENT, 4);
        let data = glow::PixelPackData::Slice(Some(words_as_bytes_mut(&mut words)));
        gl.read_pixels(0, 0, width as i32, height as i32, glow::RGBA, glow::FLOAT, data);
        gl.bind_framebuffer(glow::READ_FRAMEBUFFER, None);
        gl.get_error()
    };
    if error != glow::NO_ERROR {
        return Err(GlError::Gl { what: "glReadPixels (RGBA, FLOAT)", detail: format!("error {error:#06x}") });
    }
    Ok(words.chunks_exact(4).map(|t| Vec4::from_array([t[0], t[1], t[2], t[3]].map(f32::from_bits))).collect())
}
