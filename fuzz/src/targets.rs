//! The file targets: what the program does with bytes from a file, as far as it goes.

use std::path::Path;
use std::sync::OnceLock;

use glam::Vec3;
use tracer::backend::cpu::CpuRenderer;
use tracer::backend::Renderer;
use tracer::kernel::RenderSettings;
use tracer::pack::build_and_pack;
use tracer::scene::{self, LoadOptions, Scene, SceneError, SkyFormat};

/// Every target, the file ones and the server.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// glTF JSON and the GLB container, through `load_gltf_slice`, then BVH + packing.
    Gltf,
    /// OBJ + MTL (+ the textures the MTL names), through `load_obj_slice`, then packing.
    Obj,
    /// PNG / JPEG (and the formats refused as unsupported: WebP, KTX2...) as a glTF texture.
    Texture,
    /// Radiance HDR and OpenEXR skies through `load_sky_slice`, then packing with the sky.
    Sky,
    /// The bundle decoder; a bundle that decodes is rendered (one sample, 4x3 pixels, CPU).
    Bundle,
    /// HTTP requests to a running `lightport serve` over loopback (see [`crate::http`]).
    Http,
}

impl Target {
    /// Every target, in the order the docs list them.
    pub const ALL: [Target; 6] =
        [Target::Gltf, Target::Obj, Target::Texture, Target::Sky, Target::Bundle, Target::Http];

    /// The targets that run in-process on bytes ([`Target::run`]).
    pub const FILES: [Target; 5] = [Target::Gltf, Target::Obj, Target::Texture, Target::Sky, Target::Bundle];

    /// The name used by `scripts/fuzz.sh`, the binaries and the folders.
    pub fn name(self) -> &'static str {
        match self {
            Target::Gltf => "gltf",
            Target::Obj => "obj",
            Target::Texture => "texture",
            Target::Sky => "sky",
            Target::Bundle => "bundle",
            Target::Http => "http",
        }
    }

    /// The target called `name`.
    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }

    /// The largest input the fuzzers generate for this target (libFuzzer's `-max_len`): big
    /// enough for the seeds that matter, small enough to keep executions fast.
    pub fn max_len(self) -> usize {
        match self {
            Target::Gltf => 64 << 10,
            Target::Obj => 16 << 10,
            Target::Texture => 32 << 10,
            Target::Sky => 48 << 10,
            Target::Bundle => 64 << 10,
            Target::Http => 4 << 10,
        }
    }

    /// Runs a file target on `data`. Every outcome but a panic or a hang is a pass: the point
    /// is that bad input gets an error. (The HTTP target runs through [`crate::http`].)
    pub fn run(self, data: &[u8]) {
        match self {
            Target::Gltf => gltf(data),
            Target::Obj => obj(data),
            Target::Texture => texture(data),
            Target::Sky => sky(data),
            Target::Bundle => bundle(data),
            Target::Http => panic!("the HTTP target needs a server: use lightport_fuzz::http"),
        }
    }
}

/// What the CLI and the page do after loading: build the BVH and pack. Errors are fine.
fn pack(scene: &Scene) {
    let _ = build_and_pack(scene, &RenderSettings::default());
}

/// glTF JSON or GLB from memory (external files are refused: there is no folder).
pub fn gltf(data: &[u8]) {
    if let Ok(scene) = scene::load_gltf_slice(data, None, &LoadOptions::default()) {
        pack(&scene);
    }
}

/// The line that separates an OBJ input from the MTL library served for any `mtllib`.
pub const MTL_SEPARATOR: &[u8] = b"\n#---mtl---\n";

/// An OBJ input: the OBJ text, then (after [`MTL_SEPARATOR`]) the MTL served for every
/// `mtllib`; texture maps named in it are served a tiny PNG (`.png`) or JPEG (other names).
pub fn obj(data: &[u8]) {
    let (obj, mtl) = match find(data, MTL_SEPARATOR) {
        Some(at) => (&data[..at], Some(&data[at + MTL_SEPARATOR.len()..])),
        None => (data, None),
    };
    let read = |path: &Path| -> Result<Vec<u8>, SceneError> {
        let missing = || SceneError::Io { path: path.to_owned(), error: std::io::ErrorKind::NotFound.into() };
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
        match ext.as_str() {
            "mtl" => mtl.map(<[u8]>::to_vec).ok_or_else(missing),
            "png" => Ok(tiny_images().0.clone()),
            "" => Err(missing()),
            _ => Ok(tiny_images().1.clone()),
        }
    };
    if let Ok(scene) = scene::load_obj_slice(obj, "fuzz.obj", &read, &LoadOptions::default()) {
        pack(&scene);
    }
}

/// An image as a glTF texture ([`crate::glb::textured_quad`]).
pub fn texture(data: &[u8]) {
    gltf(&crate::glb::textured_quad(data));
}

/// The magic number of OpenEXR files; anything else is read as Radiance HDR.
pub const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// A sky (EXR when it starts with [`EXR_MAGIC`], else HDR), packed with a small scene.
pub fn sky(data: &[u8]) {
    let format = if data.starts_with(&EXR_MAGIC) { SkyFormat::Exr } else { SkyFormat::Hdr };
    if let Ok(sky) = scene::load_sky_slice(data, format, "fuzz sky", 1.0, 0.5) {
        let mut scene = scene::diffuse_plane(Vec3::splat(0.5));
        scene.sky = Some(sky);
        pack(&scene);
    }
}

/// A bundle; one that decodes is posed (when it moves) and rendered as the page would (whatever its image size says,
/// 4x3 pixels here, one sample), so that values that decode but make no sense cannot hang or
/// crash the kernel. The page first peeks at its features (`bundle::peek_features`, on the
/// same untrusted bytes): that must not fail where decoding succeeds, nor disagree with it.
pub fn bundle(data: &[u8]) {
    let peeked = tracer::bundle::peek_features(data);
    if let Ok(tracer::bundle::Bundle { mut packed, moving, .. }) = tracer::bundle::Bundle::decode(data) {
        assert_eq!(peeked.ok(), Some(packed.features), "peek_features disagrees with decode");
        // A motion section that decodes poses (or is a clear error) at any time.
        if let Some(mut moving) = moving {
            let end = moving.motion.as_ref().map_or(0.0, |m| m.duration());
            for time in [0.0, 0.37, end, end + 1.0] {
                let _ = moving.pose(time);
            }
        }
        packed.scene.width = 4;
        packed.scene.height = 3;
        CpuRenderer::new(packed, 1).render_frame().expect("the CPU renderer does not fail");
    }
}

/// A tiny PNG and a tiny JPEG (4x4), the textures served to OBJ inputs.
pub fn tiny_images() -> &'static (Vec<u8>, Vec<u8>) {
    static IMAGES: OnceLock<(Vec<u8>, Vec<u8>)> = OnceLock::new();
    IMAGES.get_or_init(|| {
        let image = image::RgbImage::from_fn(4, 4, |x, y| image::Rgb([x as u8 * 60, y as u8 * 60, 200]));
        let encode = |format| {
            let mut out = std::io::Cursor::new(Vec::new());
            image::DynamicImage::ImageRgb8(image.clone()).write_to(&mut out, format).expect("encode a 4x4 image");
            out.into_inner()
        };
        (encode(image::ImageFormat::Png), encode(image::ImageFormat::Jpeg))
    })
}

/// Where `needle` first occurs in `haystack`.
pub fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}
