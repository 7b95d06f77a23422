//! Scenes: loading, flattening and validating `.gltf`/`.glb`/`.obj`/`.fbx` files (+ `.hdr`/`.exr` skies)
//! into one renderer-agnostic [`Scene`], plus small generated scenes for tests.
//!
//! # Conventions
//! Everything follows glTF: right-handed coordinates, +Y up, metres, cameras look down their
//! local -Z, counter-clockwise triangles are front faces, colours are **linear** RGB.
//! Texture coordinates follow glTF too: `(0, 0)` is the **top-left** corner of an image
//! (OBJ `vt` coordinates are flipped on load to match).
//!
//! # Units of light
//! Lightport keeps glTF's photometric numbers as they are (no 683 lm/W factor) and treats them
//! as the renderer's radiometric units:
//! * [`Material::emission`] is emitted **radiance** (glTF `emissiveFactor` x
//!   `KHR_materials_emissive_strength`, i.e. nits in glTF, read as W/(sr m²) per RGB channel).
//! * [`PointLight::intensity`] is **radiant intensity** (glTF `color` x `intensity`, candela in
//!   glTF, read as W/sr per channel): the irradiance at distance `d` facing the light is
//!   `intensity / d²`.
//! * [`Sky`] texels are radiance, multiplied by [`Sky::intensity`].
//!
//! The three use the same unit, so a scene keeps its glTF light balance.
//!
//! # What is read
//! * glTF: the default scene (else the first; with no scene at all, every root node), node
//!   matrices and TRS posed by an animation (`gltf_loader/animation.rs`: the first by default, or
//!   [`LoadOptions::animation`], at [`LoadOptions::time`]), skins (`gltf_loader/skin.rs`: each
//!   vertex moved by its weighted joints on the host), morph targets (`gltf_loader/morph.rs`),
//!   `EXT_mesh_gpu_instancing` (each instance's TRS under its node, flattened
//!   like every node), meshes in TRIANGLES / TRIANGLE_STRIP / TRIANGLE_FAN mode (indexed or not,
//!   sparse accessors, `KHR_mesh_quantization`), POSITION, NORMAL (transformed by the inverse
//!   transpose; flat normals when absent), TEXCOORD_0, materials (`baseColorFactor`,
//!   `baseColorTexture`, `emissiveFactor`, `emissiveTexture`, `KHR_materials_emissive_strength`,
//!   `alphaMode` and `alphaCutoff`: see `material_alpha`),
//!   PNG/JPEG images with sampler wrap modes, `KHR_lights_punctual`, and the first perspective
//!   camera in depth-first node order. Primitives without a material get glTF's default
//!   material (white, albedo 1).
//! * `KHR_lights_punctual`: point lights; **spot lights become point lights** (cone ignored,
//!   warned); directional lights are skipped (warned); `range` is ignored (physical falloff).
//! * OBJ/MTL: see the `obj_loader` notes: `Kd`, `map_Kd`, `Ke`, `map_Ke`; a default camera.
//! * FBX (binary and ASCII, 6.1 to 7.7, native builds only: the parser is the ufbx C library):
//!   see the `fbx_loader` notes. Axis systems and units are converted to +Y-up metres; meshes,
//!   normals, the first UV set, base colour and emission (factors and textures, embedded or
//!   external), point lights and the first perspective camera are read; skinning, blend shapes,
//!   animation, NURBS and other light kinds are warned about.
//!
//! # Extensions and warnings
//! A glTF file **requiring** an extension Lightport cannot honour is refused
//! ([`SceneError::UnsupportedRequiredExtension`]), e.g. `EXT_meshopt_compression`,
//! `KHR_texture_basisu`. `KHR_draco_mesh_compression` is decoded (`draco-core`, pure Rust, so
//! natively and in the page alike). Required extensions that only change the
//! look (`KHR_materials_*`, `KHR_texture_transform`) are accepted with a warning. Everything
//! else unsupported (listed extensions, point/line
//! primitives, textures on other UV sets, vertex colours, orthographic
//! cameras...) is reported once in [`Scene::warnings`], naming the feature.
//!
//! # Robustness
//! Loading never panics on any input and never hangs: every size in a file is checked against
//! the data that backs it before anything is allocated, indices are range-checked, non-finite
//! vertex data is refused, node hierarchies must be trees, and totals are capped
//! ([`MAX_TRIANGLES`], [`MAX_TEXTURE_DIMENSION`], [`MAX_IMAGE_TEXELS`], [`MAX_SCENE_TEXELS`],
//! [`MAX_FILE_BYTES`]). Malformed data (truncated or missing buffers, out-of-range indices,
//! NaN/Inf, missing or corrupt images) is an error; files with nothing to render are refused
//! with [`SceneError::NoTriangles`]. Third-party decoders (images, OBJ) run under
//! `catch_unwind` as a last line of defence.

mod accessor;
// ufbx is C, built with the system C compiler; there is none for wasm32-unknown-unknown, so the
// browser build has no FBX loader (`lightport serve` converts FBX scenes into bundles instead).
#[cfg(not(target_arch = "wasm32"))]
mod fbx_loader;
mod generate;
mod gltf_loader;
mod instance;
mod lighting;
mod material;
mod material_alpha;
mod obj_loader;
mod sky;
pub mod stability;
mod tangents;
pub(crate) mod texture;
pub mod texture_ref;
mod util;

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3, Vec4};

pub use generate::{
    alpha_checker, alpha_masked_screen, checker_floor, cornell_box, diffuse_plane, glass_cornell, instanced_field,
    instanced_masked_leaves, instanced_shapes, metal_rough_spheres, terrain_and_spheres, white_furnace,
};
pub use lighting::WEAK_EMITTERS;
pub use material::Material;

/// The scenes generated in code that the command line names: `cornell` (also `cornell-box`),
/// `metal-rough-spheres`, `glass-cornell`, `instanced-shapes` (8 x 8 placements of one mesh) and
/// `instanced-field` (10,000 placements of a 10,240-triangle sphere: 102 million triangles).
pub const BUILTIN_SCENES: [&str; 5] =
    ["cornell", "metal-rough-spheres", "glass-cornell", "instanced-shapes", "instanced-field"];

/// The scene generated in code called `name` (see [`BUILTIN_SCENES`]).
pub fn builtin(name: &str) -> Option<Scene> {
    match name {
        "cornell" | "cornell-box" => Some(cornell_box()),
        "metal-rough-spheres" => Some(metal_rough_spheres()),
        "glass-cornell" => Some(glass_cornell()),
        "instanced-shapes" => Some(instanced_shapes(8)),
        "instanced-field" => Some(instanced_field(100)),
        _ => None,
    }
}
pub use gltf_loader::{load_gltf_slice, motion_streams, moving_from_streams, AnimationChoice, Motion};
pub use instance::{place_triangle, Instance, InstanceError, Mesh};
pub use obj_loader::load_obj_slice;
pub use sky::{load_sky, load_sky_slice, SkyFormat};
pub use texture::{srgb_to_linear, srgba8_to_linear, EncodedImage, TextureTexels};
pub use texture_ref::UvTransform;

/// Most triangles a loaded scene may have after instancing (each [`Triangle`] is 100 bytes,
/// so this caps a scene's triangle list at about 1.7 GB).
pub const MAX_TRIANGLES: usize = 1 << 24;
/// Largest accepted width or height of a texture or sky image.
pub const MAX_TEXTURE_DIMENSION: u32 = 16384;
/// Most texels one texture or sky image may have (64 Mi: 1 GiB as `Vec4`), checked from the
/// image header before decoding.
pub const MAX_IMAGE_TEXELS: u64 = 1 << 26;
/// Most texels all of a scene's textures may have together (256 Mi: 4 GiB as `Vec4`), so that
/// many images sharing one small, highly compressed file cannot exhaust memory.
pub const MAX_SCENE_TEXELS: u64 = 1 << 28;
/// Largest accepted size of one file read by the loaders (scene, buffer, image or sky).
pub const MAX_FILE_BYTES: u64 = 4 << 30;
/// Largest emitted radiance a loader accepts, per channel (material emission, and sky texels
/// times the sky intensity); larger values are refused as malformed, like NaN and infinity.
/// The sun is about 1.6e9 (cd/m², read as W/(sr m²)), so this leaves 600x headroom, while a
/// sample (radiance x path throughput / pdf, up to about 1e3 x the radiance) squared and summed
/// over a million frames, as the CPU backend's variance does, stays finite in f32.
pub const MAX_RADIANCE: f32 = 1e12;

/// A flattened, validated scene: everything in world space, ready to be packed.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// World-space triangles (node transforms applied, winding fixed for mirroring transforms):
    /// the static part of the scene, every light-emitting triangle included.
    pub triangles: Vec<Triangle>,
    /// Meshes placed by [`Scene::instances`], each stored once in its own space.
    pub meshes: Vec<Mesh>,
    /// Placements of [`Scene::meshes`] (a two-level scene, `Features::instances`; none in a
    /// scene whose every mesh is static and used once).
    pub instances: Vec<Instance>,
    /// Materials referenced by [`Triangle::material`].
    pub materials: Vec<Material>,
    /// Decoded textures referenced by materials.
    pub textures: Vec<Texture>,
    /// Point lights (glTF `KHR_lights_punctual` point lights, and spot lights treated as points).
    pub point_lights: Vec<PointLight>,
    /// The camera: the scene's first perspective camera, or one framing the scene's bounds.
    pub camera: Camera,
    /// An environment map. Loaders never set it (a sky comes from [`load_sky`]).
    pub sky: Option<Sky>,
    /// Unsupported features met while loading, each reported once and named.
    pub warnings: Vec<String>,
    /// The animation that moves this scene's instances and deformed meshes, kept by a loader
    /// asked to ([`LoadOptions::keep_motion`]); [`Scene::pose`] poses the scene with it.
    pub motion: Option<Motion>,
}

/// One triangle in world space. Vertex order is counter-clockwise seen from the front face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// World-space vertex positions (metres).
    pub positions: [Vec3; 3],
    /// World-space unit shading normals (generated flat normals when the file had none).
    pub normals: [Vec3; 3],
    /// Texture coordinates (glTF `TEXCOORD_0`; `(0,0)` = top-left of an image), zero when absent.
    pub uvs: [Vec2; 3],
    /// The second texture coordinate set (glTF `TEXCOORD_1`), zero when absent; only packed
    /// when some texture reads it ([`UvTransform::texcoord`], `Features::texcoord1`).
    pub uvs1: [Vec2; 3],
    /// World-space tangents for normal mapping: xyz along +u, w the handedness (±1) of the
    /// bitangent `w * cross(normal, tangent)` (glTF `TANGENT`, else MikkTSpace). Zero when the
    /// triangle's material has no normal map (only such materials need them).
    pub tangents: [Vec4; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// Texture coordinate wrapping, as glTF samplers define it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// Tile the image (glTF's default).
    #[default]
    Repeat,
    /// Clamp to the border texels.
    ClampToEdge,
    /// Tile, mirroring every other copy.
    MirroredRepeat,
}

/// A decoded texture. Texel `(x, y)` is `texels[y * width + x]`; row 0 is the top of the image,
/// which is texture coordinate v = 0 (glTF convention).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// Width in texels (> 0).
    pub width: u32,
    /// Height in texels (> 0).
    pub height: u32,
    /// `width * height` texels, one `u32` each: 8-bit RGBA as stored in the image file (colour
    /// **sRGB-encoded**, alpha linear), red in the low byte (`r | g << 8 | b << 16 | a << 24`).
    /// This is the packed layout every backend reads; the kernel decodes sRGB to linear when it
    /// samples, [`Texture::linear`] does the same on the CPU side. Loaded scenes' textures share
    /// one atlas, which packing shares too (see [`TextureTexels`]); `Vec::into` makes one.
    pub texels: TextureTexels,
    /// Wrapping along u.
    pub wrap_s: Wrap,
    /// Wrapping along v.
    pub wrap_t: Wrap,
}

/// A point light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// World-space position (metres).
    pub position: Vec3,
    /// Radiant intensity per linear RGB channel (glTF `color x intensity`; see the module docs
    /// for units): irradiance at distance `d` is `intensity / d²`.
    pub intensity: Vec3,
}

/// A thin-lens (or pinhole) perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position in world space.
    pub position: Vec3,
    /// A point the camera looks at (the view direction is `target - position`).
    pub target: Vec3,
    /// World-space up hint (not necessarily orthogonal to the view direction).
    pub up: Vec3,
    /// Vertical field of view in radians (glTF `yfov`). The horizontal one follows the image.
    pub yfov: f32,
    /// Lens radius in metres; 0 is a pinhole camera (no depth of field).
    pub aperture_radius: f32,
    /// Distance from `position` to the plane in focus, in metres (> 0).
    pub focus_distance: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Self::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, DEFAULT_YFOV)
    }
}

/// A loader's first perspective camera, before its focus distance is known.
pub(crate) struct FoundCamera {
    pub position: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit up hint.
    pub up: Vec3,
    pub yfov: f32,
}

impl FoundCamera {
    /// The camera, focused where its view axis passes the centre of `bounds` (the scene's).
    pub(crate) fn finish(self, bounds: &Aabb) -> Camera {
        let radius = 0.5 * bounds.diagonal().length();
        let along = (bounds.center() - self.position).dot(self.forward);
        let focus = if along.is_finite() && along > 1e-3 * radius.max(1e-6) { along } else { radius.max(1.0) };
        Camera {
            position: self.position,
            target: self.position + self.forward * focus,
            up: self.up,
            yfov: self.yfov,
            aperture_radius: 0.0,
            focus_distance: focus,
        }
    }
}

/// Vertical field of view of generated cameras (45°).
pub const DEFAULT_YFOV: f32 = std::f32::consts::FRAC_PI_4;

impl Camera {
    /// A pinhole camera at `position` looking at `target`, focused on the target.
    pub fn look_at(position: Vec3, target: Vec3, up: Vec3, yfov: f32) -> Self {
        let distance = (target - position).length();
        Self {
            position,
            target,
            up,
            yfov,
            aperture_radius: 0.0,
            focus_distance: if distance > 0.0 && distance.is_finite() { distance } else { 1.0 },
        }
    }

    /// A camera on the +Z side of `bounds` looking at its centre (-Z), far enough back for the
    /// bounding sphere to fit in a 45° vertical field of view. Used when a file has no camera.
    pub fn framing(bounds: &Aabb) -> Self {
        if bounds.is_empty() {
            return Self::default();
        }
        let center = bounds.center();
        let radius = (0.5 * bounds.diagonal().length()).max(1e-3);
        let distance = radius / (0.5 * DEFAULT_YFOV).sin() * 1.05;
        Self::look_at(center + Vec3::new(0.0, 0.0, distance), center, Vec3::Y, DEFAULT_YFOV)
    }

    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        (self.target - self.position).normalize_or(Vec3::NEG_Z)
    }
}

/// An equirectangular environment map.
///
/// Direction `d` (unit, world space) maps to `u = 0.5 + atan2(d.x, -d.z) / 2π` (after rotating
/// `d` by `-rotation` about +Y) and `v = acos(d.y) / π`: row 0 is straight up (+Y), the image
/// centre is seen looking down -Z, u grows towards +X. Texel `(x, y)` is
/// `texels[y * width + x]` and covers `u in [x/width, (x+1)/width)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Sky {
    /// Width in texels (> 0).
    pub width: u32,
    /// Height in texels (> 0).
    pub height: u32,
    /// Linear radiance, finite and non-negative, row 0 = top.
    pub texels: Vec<Vec3>,
    /// Multiplier applied to every texel.
    pub intensity: f32,
    /// Rotation of the map about +Y, radians (counter-clockwise seen from above).
    pub rotation: f32,
    /// The file the texels were decoded from (`None` for a sky made in code): what a bundle
    /// ships instead of the texels.
    pub file: Option<SkyFile>,
}

/// A sky's source file: its format and bytes, which decode to the sky's texels.
#[derive(Clone, Debug, PartialEq)]
pub struct SkyFile {
    pub format: SkyFormat,
    pub bytes: EncodedImage,
}

impl Sky {
    /// A sky of constant radiance (a 1x1 map), for analytic tests.
    pub fn uniform(radiance: Vec3) -> Self {
        Self { width: 1, height: 1, texels: vec![radiance], intensity: 1.0, rotation: 0.0, file: None }
    }

    /// The sky a scene that nothing lights gets ([`Scene::light_if_unlit`]): uniform radiance
    /// 1, the "white sky" of the web path tracers' benchmarks, so a material's albedo reads
    /// as its brightness at exposure 0.
    pub fn default_white() -> Self {
        Self::uniform(Vec3::ONE)
    }

    /// Texture coordinates of world direction `dir` (see the type docs).
    pub fn direction_to_uv(&self, dir: Vec3) -> Vec2 {
        let d = glam::Quat::from_rotation_y(-self.rotation) * dir.normalize_or(Vec3::Y);
        let u = 0.5 + d.x.atan2(-d.z) / std::f32::consts::TAU;
        let v = d.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
        Vec2::new(u, v)
    }

    /// Radiance seen along `dir` (nearest texel, times `intensity`): a reference lookup.
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        let uv = self.direction_to_uv(dir);
        let x = ((uv.x - uv.x.floor()) * self.width as f32) as usize;
        let y = (uv.y * self.height as f32) as usize;
        let x = x.min(self.width.saturating_sub(1) as usize);
        let y = y.min(self.height.saturating_sub(1) as usize);
        self.texels.get(y * self.width as usize + x).copied().unwrap_or(Vec3::ZERO) * self.intensity
    }
}

/// An axis-aligned box. The empty box has `min = +inf`, `max = -inf`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// How far from the origin (scene units, each coordinate) a scene's geometry, camera and
/// lights may lie. Past about this the renderer's f32 arithmetic on world coordinates
/// overflows (a triangle's edge cross products against a ray's offset, the squared diagonal
/// that frames the camera), and a scene there would render as NaN or fail as "an invalid
/// camera". A scene beyond it is refused by [`Scene::validate`]; a pose that carries a
/// placement or a skinned or morphed mesh beyond it drops that, as one that is not finite.
pub const WORLD_LIMIT: f32 = 1e12;

/// How far from the origin the camera may stand: back from the world, as the framing of a scene
/// at [`WORLD_LIMIT`] puts it up to ~6 limits out (and the kernel's products stay finite to ~10).
pub const CAMERA_LIMIT: f32 = 10.0 * WORLD_LIMIT;

/// Whether `p` is finite and within [`WORLD_LIMIT`] of the origin on every axis.
pub fn in_world(p: Vec3) -> bool {
    p.is_finite() && p.abs().max_element() <= WORLD_LIMIT
}

impl Aabb {
    /// Whether the box is empty or lies within [`WORLD_LIMIT`] ([`in_world`]).
    pub fn in_world(&self) -> bool {
        self.is_empty() || (in_world(self.min) && in_world(self.max))
    }

    /// The empty box.
    pub const EMPTY: Self = Self { min: Vec3::INFINITY, max: Vec3::NEG_INFINITY };

    /// Grows the box to contain `p`.
    pub fn extend(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// Whether the box contains nothing.
    pub fn is_empty(&self) -> bool {
        !(self.min.cmple(self.max).all())
    }

    /// Centre (meaningless when empty).
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// `max - min` (zero when empty).
    pub fn diagonal(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }
}

/// Why a scene or sky could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A file could not be read.
    // The OS error is in the message and not a `source()`: anyhow's `{:#}` (the CLI) prints a
    // source after the message, and it was written twice.
    #[error("cannot read {path}: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        error: std::io::Error,
    },
    /// The file extension names no format Lightport reads.
    #[error("unsupported file type {0:?}: expected .gltf, .glb, .obj or .fbx (scenes), .hdr or .exr (skies)")]
    UnsupportedFileType(String),
    /// The file is not valid glTF (bad container, JSON or schema).
    #[error("invalid glTF: {0}")]
    InvalidGltf(String),
    /// The glTF file lists an extension in `extensionsRequired` that Lightport cannot honour.
    #[error("the glTF file requires extension {0}, which Lightport does not support")]
    UnsupportedRequiredExtension(String),
    /// The file's data is inconsistent (out-of-range indices, truncated buffers, NaN, ...).
    #[error("malformed scene: {0}")]
    Malformed(String),
    /// Something is bigger than Lightport accepts.
    #[error("too large: {0}")]
    TooLarge(String),
    /// Nothing renderable was found.
    #[error("the scene has no triangles to render{0}")]
    NoTriangles(String),
    /// An image could not be decoded.
    #[error("image {name}: {message}")]
    Image {
        /// Which image (file name or glTF image index).
        name: String,
        /// What went wrong.
        message: String,
    },
    /// The OBJ or MTL parser refused the file.
    #[error("OBJ {path}: {message}")]
    Obj {
        /// The OBJ or MTL file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The FBX parser (ufbx) refused the file, or this build has no FBX loader (wasm32).
    #[error("FBX {path}: {message}")]
    Fbx {
        /// The FBX file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A parameter passed to a loader is out of range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
}

/// Loader settings.
///
/// By default loading is forgiving, as other glTF viewers are: a texture whose image file is
/// missing or unreadable, or whose data does not decode, is dropped with a warning naming the
/// image and the materials using it, and those materials render with their factors. A
/// malformed scene file (truncated buffers, out-of-range indices, ...) is an error either way.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Refuse the scene, with the image's own error, when a texture cannot be used, instead
    /// of warning (`lightport render --strict` also refuses scenes with any other warning).
    pub strict: bool,
    /// The glTF animation that poses the scene (by default the first, as viewers play it).
    pub animation: AnimationChoice,
    /// The time in seconds at which the animation poses the scene (clamped to its keyframes).
    pub time: f32,
    /// Place every mesh into the static triangles, even those that glTF nodes share (by
    /// default shared meshes are stored once and placed by instances: a two-level scene).
    pub flatten: bool,
    /// Keep the chosen animation in the scene ([`Scene::motion`]) so that [`Scene::pose`]
    /// moves it to any time: the meshes it moves become instances (two levels) and skinned or
    /// morphed meshes are made again at each pose, instead of being flattened at `time`.
    pub keep_motion: bool,
}

/// Loads a scene with default [`LoadOptions`], choosing the format from the file extension:
/// `.gltf`/`.glb` (glTF 2.0), `.obj` (Wavefront, with its MTL libraries) or `.fbx` (Autodesk
/// FBX, binary or ASCII; not in wasm32 builds).
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with(path, &LoadOptions::default())
}

/// Loads a scene (see [`load`]) with the given options.
pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).unwrap_or_default();
    match ext.as_str() {
        "gltf" | "glb" => gltf_loader::load_gltf(path, options),
        "obj" => obj_loader::load_obj(path, options),
        #[cfg(not(target_arch = "wasm32"))]
        "fbx" => fbx_loader::load_fbx(path, options),
        #[cfg(target_arch = "wasm32")]
        "fbx" => Err(SceneError::Fbx {
            path: path.to_owned(),
            message: "the browser build cannot read FBX: convert it on the server side (`lightport serve scene.fbx`)"
                .into(),
        }),
        _ => Err(SceneError::UnsupportedFileType(
            path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default(),
        )),
    }
}

impl Scene {
    /// Bounds of all triangles, placed ones included (point lights and camera excluded).
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for t in &self.triangles {
            for p in t.positions {
                b.extend(p);
            }
        }
        for w in self.placement_boxes().iter().filter(|w| w.min.cmple(w.max).all()) {
            b.extend(w.min);
            b.extend(w.max);
        }
        b
    }

    /// Fills in MikkTSpace tangents ([`Triangle::tangents`]) for the triangles whose material
    /// has a normal map and that have none (all zero), as for a glTF without `TANGENT`: for
    /// scenes made in code. Loaders do this themselves.
    pub fn generate_tangents(&mut self) {
        let needs = |t: &Triangle| {
            t.tangents == [Vec4::ZERO; 3]
                && self.materials.get(t.material as usize).is_some_and(|m| m.normal_texture.is_some())
        };
        let which: Vec<usize> = (0..self.triangles.len()).filter(|&i| needs(&self.triangles[i])).collect();
        let corners: Vec<&Triangle> = which.iter().map(|&i| &self.triangles[i]).collect();
        if let Some(tangents) = tangents::corner_tangents(&corners) {
            for (i, t) in which.into_iter().zip(tangents) {
                self.triangles[i].tangents = t;
            }
        }
    }

    /// Checks the scene's invariants: indices in range, finite data, unit-ish normals,
    /// texture sizes. Loaders and generators always produce valid scenes; this is for scenes
    /// built by hand.
    pub fn validate(&self) -> Result<(), SceneError> {
        let bad = |m: String| Err(SceneError::Malformed(m));
        let texture_ok = |t: Option<u32>| t.is_none_or(|t| (t as usize) < self.textures.len());
        self.check_instances().map_err(|e| SceneError::Malformed(e.to_string()))?;
        let placed = self.meshes.iter().flat_map(|m| &m.triangles);
        for (i, t) in self.triangles.iter().chain(placed).enumerate() {
            if t.material as usize >= self.materials.len() {
                return bad(format!("triangle {i} uses missing material {}", t.material));
            }
            let finite = t.positions.iter().all(|p| p.is_finite())
                && t.normals.iter().all(|n| n.is_finite())
                && t.uvs.iter().all(|uv| uv.is_finite())
                && t.uvs1.iter().all(|uv| uv.is_finite())
                && t.tangents.iter().all(|t| t.is_finite());
            if !finite {
                return bad(format!("triangle {i} has non-finite vertex data"));
            }
            if let Some(p) = t.positions.iter().find(|p| !in_world(**p)) {
                return bad(format!(
                    "triangle {i} has a vertex at {p}, beyond {WORLD_LIMIT:e} units of the origin (where the renderer's \
                     arithmetic overflows)"
                ));
            }
        }
        for (i, m) in self.materials.iter().enumerate() {
            if !m.texture_slots().into_iter().all(texture_ok) {
                return bad(format!("material {i} uses a missing texture"));
            }
            if !m.base_color.is_finite()
                || !m.emission.is_finite()
                || m.emission.min_element() < 0.0
                || !m.normal_scale.is_finite()
            {
                return bad(format!("material {i} has invalid colours"));
            }
            if !(0.0..=1.0).contains(&m.alpha) || m.alpha_cutoff.is_some_and(|c| !c.is_finite() || c < 0.0) {
                return bad(format!(
                    "material {i} has an alpha outside [0, 1] or an alpha cutoff that is not finite and >= 0"
                ));
            }
            let read = m.texture_slots().into_iter().zip(m.texture_uvs).filter(|(t, _)| t.is_some()).map(|(_, uv)| uv);
            if let Some(t) = read.into_iter().find(|t| !t.is_finite() || t.texcoord >= texture_ref::TEXCOORD_SETS) {
                return bad(format!("material {i} reads a texture with {t:?} (not finite, or no such TEXCOORD set)"));
            }
        }
        for (i, t) in self.textures.iter().enumerate() {
            if t.width == 0 || t.height == 0 || t.texels.len() != t.width as usize * t.height as usize {
                return bad(format!("texture {i} has inconsistent size"));
            }
        }
        for (i, l) in self.point_lights.iter().enumerate() {
            if !l.position.is_finite() || !l.intensity.is_finite() {
                return bad(format!("point light {i} is not finite"));
            }
            if !in_world(l.position) {
                return bad(format!("point light {i} lies beyond {WORLD_LIMIT:e} units of the origin"));
            }
        }
        if let Some(sky) = &self.sky {
            if sky.width == 0 || sky.height == 0 || sky.texels.len() != sky.width as usize * sky.height as usize {
                return bad("sky has inconsistent size".into());
            }
        }
        let c = &self.camera;
        let finite = c.position.is_finite() && c.target.is_finite() && c.up.is_finite();
        let fov_ok = c.yfov > 0.0 && c.yfov < std::f32::consts::PI;
        if !finite || !fov_ok || c.position == c.target {
            return bad("invalid camera".into());
        }
        if [c.position, c.target].iter().any(|p| p.abs().max_element() > CAMERA_LIMIT) {
            return bad(format!("the camera lies (or looks at a point) beyond {CAMERA_LIMIT:e} units of the origin"));
        }
        Ok(())
    }
}

/// Collects warnings, each key reported once.
#[derive(Default)]
pub(crate) struct Warnings {
    seen: std::collections::HashSet<String>,
    list: Vec<String>,
    /// Zero-area triangles the loader dropped ([`Warnings::keep_triangle`]), reported as one
    /// warning with their count.
    degenerate: usize,
}

impl Warnings {
    /// Whether a loader keeps a triangle with these world-space corners: not when its area is
    /// exactly zero (collinear or coincident corners), since no ray can hit it (the kernel's
    /// intersection test refuses a zero determinant) and many of them at one place made the
    /// BVH build quadratic. Dropped ones are counted for one warning.
    pub(crate) fn keep_triangle(&mut self, positions: &[Vec3; 3]) -> bool {
        let keep = (positions[1] - positions[0]).cross(positions[2] - positions[0]) != Vec3::ZERO;
        if !keep {
            self.degenerate += 1;
        }
        keep
    }

    /// Why a loader found no triangles: `otherwise`, unless it dropped every one as degenerate.
    pub(crate) fn why_no_triangles(&self, otherwise: &str) -> String {
        match self.degenerate {
            0 => otherwise.to_owned(),
            n => format!(" (all {n} of its triangles have zero area)"),
        }
    }

    /// Turns the count of dropped triangles into its warning (once, when the loader is done).
    fn report_degenerate(&mut self) {
        let n = std::mem::take(&mut self.degenerate);
        if n > 0 {
            self.once("degenerate triangles", || {
                format!(
                    "{n} triangle(s) of zero area (collinear or coincident corners) were dropped: no ray can hit them"
                )
            });
        }
    }

    /// Reports `message` unless something was already reported under `key`.
    pub(crate) fn once(&mut self, key: &str, message: impl FnOnce() -> String) {
        if self.seen.insert(key.to_owned()) {
            let m = message();
            log::warn!("{m}");
            self.list.push(m);
        }
    }

    pub(crate) fn list_is_empty(&mut self) -> bool {
        self.report_degenerate();
        self.list.is_empty()
    }

    pub(crate) fn joined(&mut self) -> String {
        self.report_degenerate();
        self.list.join("; ")
    }

    pub(crate) fn into_vec(mut self) -> Vec<String> {
        self.report_degenerate();
        self.list
    }
}

/// Flat unit normal of a triangle (counter-clockwise front), +Y for degenerate triangles.
pub(crate) fn flat_normal(p: &[Vec3; 3]) -> Vec3 {
    (p[1] - p[0]).cross(p[2] - p[0]).normalize_or(Vec3::Y)
}
