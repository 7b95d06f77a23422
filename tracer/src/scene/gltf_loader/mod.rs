//! glTF 2.0 (`.gltf` + external/data-URI buffers, and `.glb`) loading.
//!
//! The `gltf` crate parses and validates the JSON; everything after that (GLB container,
//! buffers, accessors, images, the node graph) is read here from the JSON structures with
//! checked lookups only, so that no file can make the loader panic, hang or over-allocate.

use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;

use glam::{Mat3, Mat4, Quat, Vec2, Vec3, Vec4};
use gltf::json::camera::Type as CameraType;
use gltf::json::extensions::scene::khr_lights_punctual::Type as LightType;
use gltf::json::mesh::{Mode, Semantic};
use gltf::json::texture::WrappingMode;
use gltf::json::validation::Checked;
use gltf::json::Root;
use serde_json::{Map, Value};

mod animation;
mod draco;
mod materials;
mod morph;
mod motion;
mod motion_data;
mod nodes;
mod placement;
mod skin;

pub use animation::AnimationChoice;
pub use motion::Motion;
pub use motion_data::{motion_streams, moving_from_streams};

use super::accessor::Buffers;
use super::texture::{
    decode_textures_forgiving, is_texture_problem, material_label, probe_srgb, ImageHeader, ImageProblems,
    PendingTexture, Probed,
};
use super::texture_ref::{self, UvTransform};
use super::util::{read_file, read_uri};
use super::{
    flat_normal, Camera, FoundCamera, LoadOptions, Material, PointLight, Scene, SceneError, Triangle, Warnings, Wrap,
    MAX_SCENE_TEXELS, MAX_TRIANGLES,
};
use animation::NodePose;
use draco::PrimitiveData;
use materials::ImageSource;
use nodes::{semantic_name, to_vec2, LocalPrimitive};

/// Extensions Lightport implements.
const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_volume",
    "KHR_mesh_quantization",
    "KHR_draco_mesh_compression",
    "EXT_mesh_gpu_instancing",
    "EXT_texture_webp",
    "KHR_texture_transform",
];

/// Extensions whose absence only changes the look, so a file requiring them is still rendered
/// (with a warning): material models, texture transforms, variants, animation.
fn is_approximable(ext: &str) -> bool {
    ext.starts_with("KHR_materials_") || ext == "KHR_animation_pointer" || ext == "KHR_xmp_json_ld"
}

/// What Lightport does about an extension it does not implement, for the warning text.
fn extension_note(ext: &str) -> &'static str {
    match ext {
        "KHR_materials_diffuse_transmission" => "transmissive surfaces are rendered as opaque diffuse",
        "EXT_meshopt_compression" | "KHR_meshopt_compression" => {
            "compressed primitives are read from their uncompressed fallback, or skipped"
        }
        "KHR_materials_variants" => "the default materials are used",
        "KHR_texture_basisu" | "EXT_texture_avif" | "MSFT_texture_dds" => {
            "the fallback PNG/JPEG image is used when there is one"
        }
        "KHR_node_visibility" => "every node is rendered visible",
        "KHR_animation_pointer" => "animations are ignored",
        e if e.starts_with("KHR_materials_") => "that part of the material is ignored (diffuse model)",
        _ => "ignored",
    }
}

fn malformed(m: String) -> SceneError {
    SceneError::Malformed(m)
}

/// Loads a `.gltf` or `.glb` file. External files are resolved next to it.
pub(crate) fn load_gltf(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    let bytes = read_file(path)?;
    let base = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    load_gltf_slice(&bytes, Some(base), options)
}

/// Loads glTF (JSON or GLB, recognised by content) from memory. Relative URIs are resolved
/// against `base_dir`; with `None`, only embedded data (GLB chunk, data URIs) can be used.
pub fn load_gltf_slice(bytes: &[u8], base_dir: Option<&Path>, options: &LoadOptions) -> Result<Scene, SceneError> {
    let (json, bin) = split_container(bytes)?;
    let (mut root, animations) = parse_json(json)?;
    let mut warnings = Warnings::default();
    check_extensions(&mut root, &mut warnings)?;
    precheck(&root)?;
    validate(&root)?;
    let root = &root;
    let loader = Loader {
        root,
        buffers: Buffers::new(root, base_dir, bin),
        base_dir,
        warnings,
        triangles: Vec::new(),
        materials: Vec::new(),
        material_map: HashMap::new(),
        textures: Vec::new(),
        texture_map: HashMap::new(),
        images: HashMap::new(),
        probed: Vec::new(),
        meshes: HashMap::new(),
        point_lights: Vec::new(),
        camera: None,
        saw_orthographic: false,
        strict: options.strict,
        problems: ImageProblems::default(),
        texture_problems: HashMap::new(),
        without_texcoord1: HashMap::new(),
        image_problems: HashMap::new(),
        material_label: String::new(),
        mesh_instances: 0,
        pose: HashMap::new(),
        time: 0.0,
        pending: Vec::new(),
        instanced_meshes: Vec::new(),
        instances: Vec::new(),
        motion: None,
        moving_meshes: HashMap::new(),
    };
    loader.run(&animations, options)
}

/// Splits a GLB container into its JSON and BIN chunks; other input is returned as JSON.
fn split_container(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), SceneError> {
    let invalid = |m: String| SceneError::InvalidGltf(m);
    if bytes.is_empty() {
        return Err(invalid("the file is empty".into()));
    }
    if !bytes.starts_with(b"glTF") {
        return Ok((bytes, None));
    }
    let u32_at = |at: usize| bytes.get(at..at + 4).and_then(|b| b.try_into().ok()).map(u32::from_le_bytes);
    let version = u32_at(4).ok_or_else(|| invalid("GLB header is truncated".into()))?;
    if version != 2 {
        return Err(invalid(format!("GLB version {version}, expected 2")));
    }
    let length = u32_at(8).ok_or_else(|| invalid("GLB header is truncated".into()))? as usize;
    if length > bytes.len() {
        return Err(invalid(format!("GLB is truncated: its header says {length} bytes, the file has {}", bytes.len())));
    }
    let data =
        bytes.get(12..length).ok_or_else(|| invalid(format!("GLB length {length} is smaller than its header")))?;
    let mut json = None;
    let mut bin = None;
    let mut pos = 0usize;
    let mut chunk = 0;
    while pos < data.len() {
        let header = data.get(pos..pos + 8).ok_or_else(|| invalid(format!("GLB chunk {chunk} header is truncated")))?;
        let len = u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize;
        let kind = &header[4..8];
        let start = pos + 8;
        let content = start.checked_add(len).and_then(|end| data.get(start..end)).ok_or_else(|| {
            invalid(format!("GLB chunk {chunk} is truncated: {len} bytes declared, {} left", data.len() - start))
        })?;
        match (chunk, kind) {
            (0, b"JSON") => json = Some(content),
            (0, _) => return Err(invalid("the first GLB chunk is not JSON".into())),
            (_, b"BIN\0") if bin.is_none() => bin = Some(content),
            (_, b"JSON") => return Err(invalid("GLB has more than one JSON chunk".into())),
            (_, b"BIN\0") => return Err(invalid("GLB has more than one BIN chunk".into())),
            _ => {} // unknown chunks are skipped, as the spec asks
        }
        pos = start + len;
        chunk += 1;
    }
    let json = json.ok_or_else(|| invalid("GLB has no JSON chunk".into()))?;
    Ok((json, bin))
}

/// Applies the extension policy: required extensions Lightport cannot honour refuse the file;
/// approximable ones are accepted with a warning; unsupported used ones are warned about.
fn check_extensions(root: &mut Root, warnings: &mut Warnings) -> Result<(), SceneError> {
    for ext in &root.extensions_required {
        if SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            continue;
        }
        if !is_approximable(ext) {
            return Err(SceneError::UnsupportedRequiredExtension(ext.clone()));
        }
    }
    // The gltf crate's validation refuses required extensions it does not know; this loader
    // has decided about each of them above.
    root.extensions_required.clear();
    let used: Vec<String> = root.extensions_used.clone();
    for ext in used {
        warn_extension(warnings, &ext);
    }
    Ok(())
}

fn warn_extension(warnings: &mut Warnings, ext: &str) {
    if SUPPORTED_EXTENSIONS.contains(&ext) {
        return;
    }
    warnings.once(ext, || format!("{ext} is not supported: {}", extension_note(ext)));
}

fn warn_extensions(warnings: &mut Warnings, map: Option<&Map<String, Value>>) {
    for key in map.into_iter().flat_map(|m| m.keys()) {
        warn_extension(warnings, key);
    }
}

/// Checks the few things the `gltf` crate's validation would index without checking.
fn precheck(root: &Root) -> Result<(), SceneError> {
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, accessor) in &prim.attributes {
                if accessor.value() >= root.accessors.len() {
                    return Err(malformed(format!(
                        "mesh {m} primitive {p}: attribute {} uses accessor {}, which does not exist",
                        semantic_name(semantic),
                        accessor.value()
                    )));
                }
            }
        }
    }
    Ok(())
}

/// Parses the JSON chunk into the `gltf` crate's schema types, first smoothing over two places
/// where they are stricter than glTF: numbers written as integral floats (`1.0` for a count) are
/// accepted, and `animations` (which Lightport does not use, and whose channel targets the crate
/// requires to name a node) are taken out and returned as JSON (`animation.rs` reads them).
fn parse_json(json: &[u8]) -> Result<(Root, Vec<Value>), SceneError> {
    let invalid = |e: serde_json::Error| SceneError::InvalidGltf(format!("JSON: {e}"));
    let mut value: Value = serde_json::from_slice(json).map_err(invalid)?;
    let mut animations = match value.as_object_mut().and_then(|o| o.remove("animations")) {
        Some(Value::Array(a)) => a,
        _ => Vec::new(),
    };
    animations.iter_mut().for_each(integral_floats_to_integers);
    integral_floats_to_integers(&mut value);
    // Round-trip through text: some schema types (raw JSON values) only deserialize from text.
    let text = serde_json::to_vec(&value).map_err(invalid)?;
    let root: Root = serde_json::from_slice(&text).map_err(invalid)?;
    Ok((root, animations))
}

fn integral_floats_to_integers(v: &mut Value) {
    match v {
        Value::Number(n) => {
            if let Some(f) = n.as_f64().filter(|_| n.is_f64()) {
                if f.fract() == 0.0 && f.abs() < 9.0e15 {
                    *n = serde_json::Number::from(f as i64);
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(integral_floats_to_integers),
        Value::Object(o) => o.values_mut().for_each(integral_floats_to_integers),
        _ => {}
    }
}

/// Runs the `gltf` crate's schema validation, ignoring the checks where it is stricter than
/// glTF 2.0 and which this loader handles itself: accessors without a bufferView (zeros),
/// primitives without POSITION (skipped), textures whose image comes from an extension.
fn validate(root: &Root) -> Result<(), SceneError> {
    use gltf::json::validation::{Error, Validate};
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, err| {
        let path = path().to_string();
        let tolerated = matches!(err, Error::Missing)
            && ((path.starts_with("accessors[") && path.ends_with("].bufferView"))
                || (path.starts_with("textures[") && path.ends_with("].source"))
                || (path.starts_with("meshes[") && path.ends_with(".attributes[\"POSITION\"]")));
        if !tolerated {
            errors.push(format!("{path}: {err}"));
        }
    });
    if errors.is_empty() {
        return Ok(());
    }
    let more = errors.len().saturating_sub(4);
    let tail = if more > 0 { format!(" (and {more} more)") } else { String::new() };
    errors.truncate(4);
    Err(SceneError::InvalidGltf(format!("{}{tail}", errors.join("; "))))
}

struct Loader<'a> {
    root: &'a Root,
    buffers: Buffers<'a>,
    base_dir: Option<&'a Path>,
    warnings: Warnings,
    triangles: Vec<Triangle>,
    materials: Vec<Material>,
    material_map: HashMap<Option<usize>, u32>,
    /// The scene's textures, decoded at the end of loading ([`decode_textures`]).
    textures: Vec<PendingTexture>,
    texture_map: HashMap<usize, Option<u32>>,
    /// glTF image -> the first texture showing it (`None`: unsupported or missing).
    images: HashMap<usize, Option<u32>>,
    /// The images probed, in the order [`PendingTexture::image`] refers to.
    probed: Vec<(ImageSource, ImageHeader)>,
    meshes: HashMap<usize, Rc<Vec<LocalPrimitive>>>,
    point_lights: Vec<PointLight>,
    camera: Option<FoundCamera>,
    saw_orthographic: bool,
    /// [`LoadOptions::strict`].
    strict: bool,
    /// Texture images that cannot be used (warned about at the end).
    problems: ImageProblems,
    /// glTF texture / image -> its entry in `problems`.
    texture_problems: HashMap<usize, usize>,
    /// Material -> its copy without the textures read on `TEXCOORD_1`.
    without_texcoord1: HashMap<u32, u32>,
    image_problems: HashMap<usize, usize>,
    /// The material being converted, as warnings name it.
    material_label: String,
    mesh_instances: usize,
    /// The node transforms of the chosen animation at the chosen time.
    pose: HashMap<usize, NodePose>,
    /// The time `pose` is at, in seconds.
    time: f32,
    /// Placements of meshes met while walking the nodes (`placement.rs`).
    pending: Vec<placement::Pending>,
    /// The meshes placed by `instances`, in mesh space.
    instanced_meshes: Vec<crate::scene::Mesh>,
    instances: Vec<crate::scene::Instance>,
    /// The chosen animation, kept when [`LoadOptions::keep_motion`] asks (`motion.rs`).
    motion: Option<Motion>,
    /// glTF mesh -> its slot in `instanced_meshes` as moving nodes place it (`motion.rs`).
    moving_meshes: HashMap<usize, usize>,
}

impl Loader<'_> {
    fn run(mut self, animations: &[Value], options: &LoadOptions) -> Result<Scene, SceneError> {
        let root = self.root;
        warn_extensions(&mut self.warnings, root.extensions.as_ref().map(|e| &e.others));
        if !options.time.is_finite() {
            return Err(malformed(format!("the animation time {} is not a finite number of seconds", options.time)));
        }
        let (channels, name) = self.channels(animations, &options.animation)?;
        self.pose = animation::pose_at(&channels, options.time);
        self.time = options.time;
        if options.keep_motion && !channels.is_empty() {
            self.motion = Some(Motion::new(self.root, &self.parents()?, channels, name));
        }
        let roots = self.scene_roots()?;
        self.visit(&roots)?;
        self.place_pending(options.flatten)?;

        if self.triangles.is_empty() && self.instances.is_empty() {
            let degenerate = self.warnings.why_no_triangles("");
            let why = if self.mesh_instances == 0 {
                " (no node of the scene has a mesh)".to_owned()
            } else if !degenerate.is_empty() {
                degenerate
            } else if self.warnings.list_is_empty() {
                " (its meshes have no triangles)".to_owned()
            } else {
                format!(" (every primitive was skipped; {})", self.warnings.joined())
            };
            return Err(SceneError::NoTriangles(why));
        }
        self.drop_unused_texcoord1_textures();
        let textures = self.decode_textures()?;
        std::mem::take(&mut self.problems).warn(&mut self.warnings);
        let mut scene = Scene {
            triangles: self.triangles,
            meshes: self.instanced_meshes,
            instances: self.instances,
            materials: self.materials,
            textures,
            point_lights: self.point_lights,
            camera: Camera::default(),
            sky: None,
            warnings: Vec::new(),
            motion: None,
        };
        // The moving parts are posed by the kept motion, as `Scene::pose` will pose them.
        if let Some(motion) = self.motion.take() {
            motion.apply(&mut scene, options.time)?;
            scene.motion = Some(motion);
        }
        let bounds = scene.bounds();
        scene.camera = match self.camera {
            Some(c) => c.finish(&bounds),
            None => {
                if self.saw_orthographic {
                    self.warnings.once("orthographic camera", || {
                        "orthographic cameras are not supported: a perspective camera framing the scene is used".into()
                    });
                }
                Camera::framing(&bounds)
            }
        };
        // The pose's own (a placement it drops) after the loader's.
        let posed = std::mem::replace(&mut scene.warnings, self.warnings.into_vec());
        scene.warnings.extend(posed);
        scene.validate()?;
        Ok(scene)
    }

    /// The root nodes of the scene to render: the default scene, else the first, else (no
    /// scenes at all) every node that is nobody's child.
    fn scene_roots(&mut self) -> Result<Vec<usize>, SceneError> {
        let root = self.root;
        let index = root.scene.map(|s| s.value()).or(if root.scenes.is_empty() { None } else { Some(0) });
        if let Some(i) = index {
            let scene = root.scenes.get(i).ok_or_else(|| malformed(format!("scene {i} does not exist")))?;
            warn_extensions(&mut self.warnings, scene.extensions.as_ref().map(|e| &e.others));
            return Ok(scene.nodes.iter().map(|n| n.value()).collect());
        }
        if root.nodes.is_empty() {
            return Ok(Vec::new());
        }
        self.warnings.once("no scene", || "the file defines no scene: all root nodes are rendered".into());
        let mut is_child = vec![false; root.nodes.len()];
        for node in &root.nodes {
            for c in node.children.iter().flatten() {
                if let Some(flag) = is_child.get_mut(c.value()) {
                    *flag = true;
                }
            }
        }
        Ok((0..root.nodes.len()).filter(|&n| !is_child[n]).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glb_container_errors() {
        assert!(split_container(b"").is_err());
        assert!(split_container(b"glTF").is_err());
        assert!(split_container(b"glTF\x02\0\0\0\x04\0\0\0").is_err());
        assert!(split_container(b"glTF\x02\0\0\0\xff\0\0\0").is_err());
        let mut glb = b"glTF\x02\0\0\0\x1c\0\0\0".to_vec();
        glb.extend_from_slice(&4u32.to_le_bytes());
        glb.extend_from_slice(b"JSON{}  ");
        glb[8] = glb.len() as u8;
        let (json, bin) = split_container(&glb).unwrap();
        assert_eq!(json, b"{}  ");
        assert!(bin.is_none());
    }
}
