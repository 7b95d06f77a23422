//! Packing: a loaded scene and its BVH become the texel arrays and uniforms the kernel reads
//! (`kernel::scene_data::Scene`), plus the [`Features`] the scene uses. The same packed data
//! feeds every backend: the CPU reads the arrays directly, GPUs upload them as textures.
//!
//! Nothing is packed that the scene does not use: no sky means no sky arrays, no textures
//! means no texture atlas (and no per-vertex UVs), flat geometry means no shading normals.
//!
//! One module per concept: [`geometry`] (the BVH checks, triangles, shading data and nodes),
//! [`materials`], [`textures`] (the atlas, made once per scene) and [`texture_refs`],
//! [`lights`] (the light list and its alias table), [`sky`] (the environment map and its
//! sampling CDFs) and [`camera`]; this file decides the [`Features`] and assembles the result.

use crate::bvh::Bvh;
use crate::kernel::scene_data::Scene as KernelScene;
use crate::kernel::{Features, RenderSettings};
use crate::scene::{Scene, SkyFile};

mod alpha_mask;
mod camera;
mod geometry;
mod instances;
pub use instances::top_level;
mod lights;
mod materials;
mod moving;
pub use moving::{MovingScene, PoseError};
mod posing;
pub use posing::{Posing, REFIT_BOUND, REFIT_MIN_TRIANGLES};
pub(crate) mod sky;
#[cfg(test)]
mod tests;
mod texture_refs;
mod textures;

pub use texture_refs::TextureRefs;
pub use textures::{pack_textures, AtlasImage, PackedTextures};

/// The packed scene.
#[derive(Clone, Debug)]
pub struct Packed {
    pub scene: KernelScene,
    pub features: Features,
    pub triangle_count: usize,
    pub light_count: usize,
    /// The textures of `scene.texture_texels`, in order, as images: what a bundle ships instead
    /// of the texels (empty when the scene has no textures).
    pub texture_images: Vec<AtlasImage>,
    /// The sky's source file, which a bundle ships instead of `scene.sky` and `scene.sky_rows`
    /// (`None` without a sky, or for a sky made in code).
    pub sky_file: Option<SkyFile>,
}

/// Why a scene cannot be packed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PackError {
    #[error(
        "the scene has {0} triangles; the packed layout stores indices as exact floats, so at most 16,777,216 fit"
    )]
    TooManyTriangles(usize),
    #[error("the BVH references triangle {0}, which the scene does not have")]
    BadBvh(u32),
    #[error("{what} needs {texels} texels, more than a {max}x{max} texture holds")]
    TooLarge { what: &'static str, texels: usize, max: u32 },
    #[error("the BVH needs a traversal stack of {needed} entries; the kernel's holds {max}")]
    BvhTooDeep { needed: u32, max: u32 },
    #[error(transparent)]
    Bvh(crate::bvh::BvhError),
    #[error("the image size {width}x{height} is invalid (each side 1..=16384)")]
    BadSize { width: u32, height: u32 },
    #[error("a BVH leaf holds {triangles} triangles; the kernel's traversal takes at most {max}")]
    LeafTooLarge { triangles: u32, max: u32 },
    #[error(transparent)]
    Instance(crate::scene::InstanceError),
    #[error("the packed textures were made from another scene (they do not match this scene's textures)")]
    TexturesMismatch,
    /// [`Posing`]: the moving parts (a bundle's motion section) do not match the packed scene.
    #[error("the moving parts do not match the packed scene: {0}")]
    NotThisPose(String),
    /// [`Packed::take_geometry`] of a pose that needs another kernel variant (a deeper
    /// traversal stack, say), or [`Packed::exchange_scene`] with a scene of other features:
    /// the renderer must be created again for it.
    #[error("the scene taken needs another kernel variant ({now:?}, was {was:?}): create the renderer again")]
    KernelChanged { was: Box<Features>, now: Box<Features> },
}

/// An optional index as the packed layout stores it: the index as an exact float, or -1.
fn index_value(i: Option<u32>) -> f32 {
    i.map_or(-1.0, |i| i as f32)
}

/// Builds the BVH and packs `scene` for `settings`, packing the textures in parallel with the
/// BVH build (neither needs the other).
pub fn build_and_pack(scene: &Scene, settings: &RenderSettings) -> Result<(Bvh, Packed), BuildAndPackError> {
    let (bvh, textures) = rayon::join(|| static_bvh(scene), || pack_textures(scene));
    let bvh = bvh?;
    let packed = pack_with_textures(scene, &bvh, &textures, settings)?;
    Ok((bvh, packed))
}

/// The BVH of `scene`'s static triangles, which [`pack`] takes (the placed meshes' own are
/// built there). A scene of placed meshes only has no static level: an empty BVH stands for it.
pub fn static_bvh(scene: &Scene) -> Result<Bvh, crate::bvh::BvhError> {
    if scene.triangles.is_empty() && !scene.instances.is_empty() {
        Ok(Bvh::default())
    } else {
        crate::bvh::build(&scene.triangles)
    }
}

/// Why [`build_and_pack`] failed.
#[derive(Debug, thiserror::Error)]
pub enum BuildAndPackError {
    #[error(transparent)]
    Bvh(#[from] crate::bvh::BvhError),
    #[error(transparent)]
    Pack(#[from] PackError),
}

/// Packs `scene` (with its BVH) for rendering with `settings`: [`pack_textures`], then
/// [`pack_with_textures`].
pub fn pack(scene: &Scene, bvh: &Bvh, settings: &RenderSettings) -> Result<Packed, PackError> {
    pack_with_textures(scene, bvh, &pack_textures(scene), settings)
}

/// Packs `scene` (with its BVH) for rendering with `settings`, taking its textures already
/// packed by [`pack_textures`] (shared, not copied).
pub fn pack_with_textures(
    scene: &Scene,
    bvh: &Bvh,
    textures: &PackedTextures,
    settings: &RenderSettings,
) -> Result<Packed, PackError> {
    let matches = textures.emissive_mean_luminance.len() == scene.textures.len()
        && if textures.used { texture_refs::matches(scene, textures) } else { textures.info.is_empty() };
    if !matches {
        return Err(PackError::TexturesMismatch);
    }
    let (width, height) = (settings.width, settings.height);
    if !(1..=16384).contains(&width) || !(1..=16384).contains(&height) {
        return Err(PackError::BadSize { width, height });
    }
    let ordered = geometry::Ordered::new(scene, bvh)?;
    let emissive = lights::Emissive::new(scene, bvh);
    // Which materials are alpha-masked ([`crate::scene::Material::is_masked`]), and which of
    // their triangles can have a hole (in BVH order): only those are alpha-tested.
    let masked_material: Vec<bool> = scene.materials.iter().map(|m| m.is_masked(textures.used)).collect();
    let alpha_tested =
        alpha_mask::needs_alpha_test(&ordered.triangles, &scene.materials, &scene.textures, &masked_material);
    let features = scene_features(scene, textures, &ordered, &emissive, &alpha_tested);

    let bounds = scene.bounds();
    let sky = sky::pack_sky(scene.sky.as_ref());
    let lights = lights::pack_lights(scene, &ordered.triangles, &emissive, textures, bounds, sky.mean_radiance);
    let geometry = geometry::pack_geometry(&ordered, &features, &emissive, &alpha_tested);
    let materials = materials::pack_materials(scene, textures, &features);
    let camera = camera::PackedCamera::new(&scene.camera, width, height);
    let scene_scale = bounds.min.abs().max(bounds.max.abs()).max_element();
    let parts = Parts { geometry, materials, lights, sky, camera, scene_scale };
    let light_count = parts.lights.count;
    let kernel_scene = kernel_scene(parts, scene, textures, &features, settings, ordered.leaf_stack_limit);
    let texture_images = if features.textures { textures.images.clone() } else { Vec::new() };
    let sky_file = scene.sky.as_ref().and_then(|s| s.file.clone());
    let triangle_count = ordered.triangles.len();
    Ok(Packed { scene: kernel_scene, features, triangle_count, light_count, texture_images, sky_file })
}

/// What `scene` uses, once its triangles are in BVH order and its emitters and alpha-tested
/// triangles known.
fn scene_features(
    scene: &Scene,
    textures: &PackedTextures,
    ordered: &geometry::Ordered,
    emissive: &lights::Emissive,
    alpha_tested: &[bool],
) -> Features {
    let textures_used = textures.used;
    Features {
        sky: scene.sky.is_some(),
        textures: textures_used,
        shading: textures_used || ordered.smooth(),
        point_lights: !scene.point_lights.is_empty(),
        emissive_triangles: !emissive.triangles.is_empty(),
        metal_rough: scene.materials.iter().any(|m| m.uses_metal_rough()),
        transmission: scene.materials.iter().any(|m| m.transmits()),
        volume: scene.materials.iter().any(|m| m.absorption().max_element() > 0.0),
        normal_map: textures_used && scene.materials.iter().any(|m| m.normal_texture.is_some()),
        alpha_mask: alpha_tested.contains(&true),
        texture_transform: textures_used && textures.refs.as_ref().is_some_and(|r| r.transform),
        texcoord1: textures_used && textures.refs.as_ref().is_some_and(|r| r.texcoord1),
        instances: ordered.two_level(),
        traversal_stack: ordered.traversal_stack,
        denoise_guide: false,
    }
}

/// The packed arrays of each concept, before they become the kernel's `Scene`.
struct Parts {
    geometry: geometry::PackedGeometry,
    materials: materials::PackedMaterials,
    lights: lights::PackedLights,
    sky: sky::PackedSky,
    camera: camera::PackedCamera,
    scene_scale: f32,
}

/// The kernel's `Scene`: every array and uniform.
fn kernel_scene(
    parts: Parts,
    scene: &Scene,
    textures: &PackedTextures,
    features: &Features,
    settings: &RenderSettings,
    leaf_stack_limit: u32,
) -> KernelScene {
    let Parts { geometry, materials, lights, sky, camera, scene_scale } = parts;
    let scene_sky = scene.sky.as_ref();
    let mut kernel_scene = KernelScene {
        triangles: geometry.triangles,
        shading: geometry.shading,
        nodes: geometry.nodes,
        node_children: geometry.node_children,
        materials: materials.materials,
        lights: lights.lights,
        texture_texels: textures.texels.clone(),
        texture_info: textures.info.clone(),
        sky: sky.texels,
        sky_rows: sky.rows,
        metal_rough: materials.metal_rough,
        tangent_first: geometry.tangent_first,
        normal_map_first: materials.normal_map_first,
        alpha_mask_first: materials.alpha_mask_first,
        texture_ref_first: textures.refs.as_ref().filter(|_| features.textures).map_or(0, |r| r.refs.len() as u32),
        texcoord1_first: geometry.texcoord1_first,
        transmission_first: materials.transmission_first,
        instance_first: geometry.instance_first,
        camera_position: camera.position,
        camera_right: camera.right,
        camera_up: camera.up,
        camera_forward: camera.forward,
        lens_radius: camera.lens_radius,
        focus_distance: camera.focus_distance,
        width: settings.width,
        height: settings.height,
        frame_seed: 0,
        max_depth: settings.max_depth.max(1),
        strategy: settings.strategy.uniform_value(),
        light_count: lights.count as u32,
        sky_width: scene_sky.map_or(0, |s| s.width),
        sky_height: scene_sky.map_or(0, |s| s.height),
        sky_intensity: scene_sky.map_or(0.0, |s| s.intensity),
        sky_rotation: scene_sky.map_or(0.0, |s| s.rotation),
        scene_scale: if scene_scale.is_finite() { scene_scale } else { 1.0 },
        leaf_stack_limit,
        ..KernelScene::default()
    };
    features.set_kernel_flags(&mut kernel_scene);
    kernel_scene
}

impl Packed {
    /// The texel arrays [`take_geometry`](Self::take_geometry) replaces: a renderer uploads
    /// these again for a moved scene and keeps the others (textures, materials, sky).
    pub const GEOMETRY_ARRAYS: [&'static str; 5] = ["triangles", "shading", "nodes", "node_children", "lights"];

    /// Takes the geometry of `moved` (this scene posed at another time by `Scene::pose`, packed
    /// with the same textures and settings) in place of this one's: the triangles, their
    /// shading data, the nodes and placements, the lights and what depends on them. Uniforms
    /// set since packing (camera, strategy, depth, the denoiser's guide) stay. A pose that
    /// needs another kernel variant is [`PackError::KernelChanged`], and nothing changes; a
    /// kernel with a larger traversal stack than the pose needs draws it (the pose's
    /// `leaf_stack_limit` keeps its pushes within its own need).
    pub fn take_geometry(&mut self, mut moved: Packed) -> Result<(), PackError> {
        self.exchange_geometry(&mut moved)
    }

    /// [`take_geometry`](Self::take_geometry) that hands back what it replaced: `moved` then
    /// holds this scene's former geometry, and exchanging again restores it exactly (a renderer
    /// that cannot upload the moved arrays undoes the take, without copying the scene first).
    pub fn exchange_geometry(&mut self, moved: &mut Packed) -> Result<(), PackError> {
        let stack = self.features.traversal_stack;
        let now = Features { denoise_guide: self.features.denoise_guide, ..moved.features };
        let fits = now.traversal_stack <= stack || stack == 0;
        if (Features { traversal_stack: stack, ..now }) != self.features || !fits {
            return Err(PackError::KernelChanged { was: Box::new(self.features), now: Box::new(now) });
        }
        let (s, m) = (&mut self.scene, &mut moved.scene);
        std::mem::swap(&mut s.triangles, &mut m.triangles);
        std::mem::swap(&mut s.shading, &mut m.shading);
        std::mem::swap(&mut s.nodes, &mut m.nodes);
        std::mem::swap(&mut s.node_children, &mut m.node_children);
        std::mem::swap(&mut s.lights, &mut m.lights);
        std::mem::swap(&mut s.tangent_first, &mut m.tangent_first);
        std::mem::swap(&mut s.texcoord1_first, &mut m.texcoord1_first);
        std::mem::swap(&mut s.instance_first, &mut m.instance_first);
        std::mem::swap(&mut s.light_count, &mut m.light_count);
        std::mem::swap(&mut s.scene_scale, &mut m.scene_scale);
        std::mem::swap(&mut s.leaf_stack_limit, &mut m.leaf_stack_limit);
        std::mem::swap(&mut self.triangle_count, &mut moved.triangle_count);
        std::mem::swap(&mut self.light_count, &mut moved.light_count);
        Ok(())
    }

    /// A scene of nothing that needs the kernel variant of `features`, at `width` x `height`
    /// (at least 1x1): no arrays (a runtime binds each as one zero texel, and reads beyond an
    /// array are zero on every runtime: node 0 has no children, every ray misses), the camera
    /// at the origin looking down -z. A renderer created from it compiles the very kernel a
    /// scene with these features needs, and drawing it once warms that kernel up, while the
    /// scene itself is still being decoded (`bundle::peek_features`); the renderer then takes
    /// the scene ([`Renderer::take_scene`](crate::backend::Renderer::take_scene)).
    pub fn placeholder(features: Features, width: u32, height: u32) -> Packed {
        let (width, height) = (width.max(1), height.max(1));
        let mut scene = KernelScene {
            camera_right: glam::Vec3::X * (width as f32 / height as f32),
            camera_up: glam::Vec3::Y,
            camera_forward: glam::Vec3::NEG_Z,
            focus_distance: 1.0,
            width,
            height,
            max_depth: 1,
            scene_scale: 1.0,
            ..Default::default()
        };
        features.set_kernel_flags(&mut scene);
        Packed { scene, features, triangle_count: 0, light_count: 0, texture_images: Vec::new(), sky_file: None }
    }

    /// Exchanges the whole scene (every array and uniform) with `other`, which must need the
    /// same kernel variant (equal [`Features`]; else [`PackError::KernelChanged`], and nothing
    /// changes): what a renderer created for one scene needs to draw another without compiling
    /// again (`Renderer::take_scene`). Exchanging again restores both exactly.
    pub fn exchange_scene(&mut self, other: &mut Packed) -> Result<(), PackError> {
        if self.features != other.features {
            return Err(PackError::KernelChanged { was: Box::new(self.features), now: Box::new(other.features) });
        }
        std::mem::swap(self, other);
        Ok(())
    }

    /// FNV-1a over the texture atlas's texels: the page reports it, so a test can tell that the
    /// browser decoded a bundle's images to the very texels the native loader made.
    pub fn texture_checksum(&self) -> u32 {
        let words: &[u32] = bytemuck::cast_slice(self.scene.texture_texels.as_slice());
        words.iter().flat_map(|w| w.to_le_bytes()).fold(0x811c_9dc5, |h, b| (h ^ b as u32).wrapping_mul(0x0100_0193))
    }

    /// Placements of a two-level scene (`Features::instances`, the static triangles' one
    /// included); 0 for a one-level scene.
    pub fn placement_count(&self) -> usize {
        match self.features.instances {
            true => {
                self.scene.nodes.len().saturating_sub(self.scene.instance_first as usize)
                    / crate::kernel::instances::INSTANCE_TEXELS as usize
            }
            false => 0,
        }
    }

    /// Asks for the denoiser's guide (`Features::denoise_guide`) or not: a renderer created
    /// from this accumulates it besides the image (`Renderer::guide`). No repacking: a flag
    /// and its uniform.
    pub fn set_denoise_guide(&mut self, on: bool) {
        self.features.denoise_guide = on;
        self.scene.has_denoise_guide = on as u32;
    }

    /// Sets the render settings that are uniforms (no repacking needed).
    pub fn apply(&mut self, settings: &RenderSettings) {
        let s = &mut self.scene;
        s.max_depth = settings.max_depth.max(1);
        s.strategy = settings.strategy.uniform_value();
        if settings.width != s.width || settings.height != s.height {
            let aspect_old = s.width as f32 / s.height as f32;
            let aspect_new = settings.width as f32 / settings.height as f32;
            s.camera_right *= aspect_new / aspect_old;
            s.width = settings.width;
            s.height = settings.height;
        }
    }
}
