//! The denoised image on the canvas, through the kernel's display transform: the runtimes' own
//! display passes (`GlDisplay` on WebGL2, `DisplayPass` on WebGPU), fed the denoised linear
//! image (a mean, so `inverse_frames` is 1) instead of the accumulation. Tone curve, exposure and
//! sRGB encoding are therefore the raw image's, and the CLI's PNG output's.

use glam::Vec3;
use glow::HasContext;
use tracer::backend::gl::GlDisplay;
use tracer::backend::wgpu::DisplayPass;
use tracer::backend::Image;
use tracer::output::Display;
use wgpu::util::DeviceExt;

/// The image's pixels as RGBA32F bytes (alpha 1, so a row of texels is a row of the image).
fn rgba_bytes(pixels: &[Vec3]) -> Vec<u8> {
    pixels.iter().flat_map(|p| p.extend(1.0).to_array()).flat_map(f32::to_le_bytes).collect()
}

/// The denoised image as a WebGL2 texture, drawn by the runtime's own display pass
/// ([`GlDisplay::draw_texture`]; row y = image row y from the top, as the accumulation texture).
pub struct GlImageDisplay {
    texture: glow::Texture,
    /// Which image the texture holds (see [`draw`](Self::draw)).
    uploaded: Option<u64>,
}

impl GlImageDisplay {
    pub fn new(gl: &glow::Context) -> Result<Self, String> {
        // SAFETY: object creation on the current context.
        let texture = unsafe { gl.create_texture() }
            .map_err(|e| format!("creating the denoised image's GL texture failed: {e}"))?;
        Ok(GlImageDisplay { texture, uploaded: None })
    }

    /// Draws `image` (known to the caller as `id`: uploaded again only when it changes) through
    /// `pass` and `display` to the canvas.
    pub fn draw(&mut self, gl: &glow::Context, pass: &GlDisplay, image: &Image, id: u64, display: &Display) {
        let (w, h) = (image.width as i32, image.height as i32);
        // SAFETY: a texture of this context, RGBA32F of the image's size, filled from a buffer
        // of exactly width x height x 16 bytes; the binding is reset afterwards.
        unsafe {
            if self.uploaded != Some(id) {
                gl.active_texture(glow::TEXTURE0);
                gl.bind_texture(glow::TEXTURE_2D, Some(self.texture));
                gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 4);
                gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_MIN_FILTER, glow::NEAREST as i32);
                gl.tex_parameter_i32(glow::TEXTURE_2D, glow::TEXTURE_MAG_FILTER, glow::NEAREST as i32);
                let bytes = rgba_bytes(&image.pixels);
                gl.tex_image_2d(
                    glow::TEXTURE_2D,
                    0,
                    glow::RGBA32F as i32,
                    w,
                    h,
                    0,
                    glow::RGBA,
                    glow::FLOAT,
                    glow::PixelUnpackData::Slice(Some(&bytes)),
                );
                gl.bind_texture(glow::TEXTURE_2D, None);
                self.uploaded = Some(id);
            }
            gl.disable(glow::BLEND);
            gl.disable(glow::SCISSOR_TEST);
        }
        pass.draw_texture(gl, self.texture, None, [w, h], 1.0, display);
    }

    /// Deletes the texture; `gl` must be the context it was created on.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: created on `gl`, deleted once (self is consumed).
        unsafe { gl.delete_texture(self.texture) };
    }
}

/// The denoised image as a WebGPU storage buffer, drawn by the runtime's own display pass
/// ([`DisplayPass::draw_buffer`]; row 0 at the top, as the accumulation buffer).
#[derive(Default)]
pub struct GpuImageDisplay {
    /// The image's pixels and which image they are.
    pixels: Option<(wgpu::Buffer, u64)>,
}

impl GpuImageDisplay {
    /// Draws `image` (known to the caller as `id`: uploaded again only when it changes) through
    /// `pass` and `display` into `target`.
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pass: &DisplayPass,
        target: &wgpu::TextureView,
        image: &Image,
        id: u64,
        display: &Display,
    ) {
        if self.pixels.as_ref().is_none_or(|(_, uploaded)| *uploaded != id) {
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("lightport denoised image"),
                contents: &rgba_bytes(&image.pixels),
                usage: wgpu::BufferUsages::STORAGE,
            });
            self.pixels = Some((buffer, id));
        }
        if let Some((pixels, _)) = &self.pixels {
            pass.draw_buffer(device, queue, target, pixels, image.width, 1.0, display);
        }
    }
}
