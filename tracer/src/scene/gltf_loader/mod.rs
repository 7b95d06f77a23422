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

mod materials;

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
use materials::ImageSource;

/// Extensions Lightport implements.
const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_mesh_quantization",
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
        "KHR_materials_transmission" | "KHR_materials_volume" | "KHR_materials_diffuse_transmission" => {
            "transmissive surfaces are rendered as opaque diffuse"
        }
        "KHR_draco_mesh_compression" | "EXT_meshopt_compression" | "KHR_meshopt_compression" => {
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
    if animations > 0 {
        warnings.once("animations", || "animations are not supported: the scene is rendered in its rest pose".into());
    }
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
    };
    loader.run()
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
/// requires to name a node) are dropped. Returns the root and the number of animations.
fn parse_json(json: &[u8]) -> Result<(Root, usize), SceneError> {
    let invalid = |e: serde_json::Error| SceneError::InvalidGltf(format!("JSON: {e}"));
    let mut value: Value = serde_json::from_slice(json).map_err(invalid)?;
    let animations = match value.as_object_mut().and_then(|o| o.remove("animations")) {
        Some(Value::Array(a)) => a.len(),
        _ => 0,
    };
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

/// One primitive's triangles in mesh space, decoded once per mesh and instanced per node.
struct LocalPrimitive {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    /// `TEXCOORD_1`, read only when the primitive's material samples a texture on it.
    uvs1: Option<Vec<Vec2>>,
    triangles: Vec<[u32; 3]>,
    /// Per corner of `triangles`: the file's `TANGENT`s, else MikkTSpace's; only for a
    /// material with a normal map.
    tangents: Option<Vec<[Vec4; 3]>>,
    material: u32,
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
}

impl Loader<'_> {
    fn run(mut self) -> Result<Scene, SceneError> {
        let root = self.root;
        warn_extensions(&mut self.warnings, root.extensions.as_ref().map(|e| &e.others));
        let roots = self.scene_roots()?;
        self.visit(&roots)?;

        if self.triangles.is_empty() {
            let why = if self.mesh_instances == 0 {
                " (no node of the scene has a mesh)".to_owned()
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
            materials: self.materials,
            textures,
            point_lights: self.point_lights,
            camera: Camera::default(),
            sky: None,
            warnings: Vec::new(),
        };
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
        scene.warnings = self.warnings.into_vec();
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

    /// Walks the node hierarchy depth-first (pre-order, children in file order).
    fn visit(&mut self, roots: &[usize]) -> Result<(), SceneError> {
        let root = self.root;
        let mut visited = vec![false; root.nodes.len()];
        let mut stack: Vec<(usize, Mat4)> = roots.iter().rev().map(|&n| (n, Mat4::IDENTITY)).collect();
        while let Some((n, parent)) = stack.pop() {
            let node = root.nodes.get(n).ok_or_else(|| malformed(format!("node {n} does not exist")))?;
            let seen = visited.get_mut(n).ok_or_else(|| malformed(format!("node {n} does not exist")))?;
            if *seen {
                return Err(malformed(format!(
                    "node {n} is reached twice: the node hierarchy must be a tree (no cycles, no shared children)"
                )));
            }
            *seen = true;
            let world = parent * node_matrix(node, n)?;
            if !world.is_finite() {
                return Err(malformed(format!("node {n} has a non-finite world transform")));
            }
            if node.skin.is_some() {
                self.warnings
                    .once("skinning", || "skinning is not supported: skinned meshes are rendered unskinned".into());
            }
            if let Some(ext) = &node.extensions {
                warn_extensions(&mut self.warnings, Some(&ext.others));
                if let Some(l) = &ext.khr_lights_punctual {
                    self.light(l.light.value(), n, &world)?;
                }
            }
            if let Some(c) = node.camera {
                self.camera(c.value(), &world)?;
            }
            if let Some(m) = node.mesh {
                self.mesh_instances += 1;
                self.instantiate(m.value(), &world)?;
            }
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), world));
            }
        }
        Ok(())
    }

    fn camera(&mut self, index: usize, world: &Mat4) -> Result<(), SceneError> {
        if self.camera.is_some() {
            return Ok(());
        }
        let cam = self.root.cameras.get(index).ok_or_else(|| malformed(format!("camera {index} does not exist")))?;
        let perspective = match (cam.type_, &cam.perspective) {
            (Checked::Valid(CameraType::Perspective), Some(p)) => p,
            _ => {
                self.saw_orthographic = true;
                return Ok(());
            }
        };
        let yfov = perspective.yfov;
        if !(yfov > 0.0 && yfov < std::f32::consts::PI) {
            return Err(malformed(format!("camera {index}: yfov {yfov} is not in (0, π)")));
        }
        let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let up = world.transform_vector3(Vec3::Y).normalize_or_zero();
        if forward == Vec3::ZERO || up == Vec3::ZERO {
            self.warnings
                .once("degenerate camera", || "a camera node has a degenerate transform: it is ignored".into());
            return Ok(());
        }
        self.camera = Some(FoundCamera { position: world.transform_point3(Vec3::ZERO), forward, up, yfov });
        Ok(())
    }

    fn light(&mut self, index: usize, node: usize, world: &Mat4) -> Result<(), SceneError> {
        let light = self
            .root
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .and_then(|l| l.lights.get(index))
            .ok_or_else(|| {
                malformed(format!("node {node} uses KHR_lights_punctual light {index}, which does not exist"))
            })?;
        let intensity = Vec3::from(light.color) * light.intensity;
        if !intensity.is_finite() || intensity.min_element() < 0.0 || intensity.max_element() > super::MAX_RADIANCE {
            return Err(malformed(format!(
                "KHR_lights_punctual light {index}: color x intensity must be finite, >= 0 and at most {:e}",
                super::MAX_RADIANCE
            )));
        }
        match light.type_ {
            Checked::Valid(LightType::Point) => {}
            Checked::Valid(LightType::Spot) => self.warnings.once("spot lights", || {
                "KHR_lights_punctual spot lights are treated as point lights (their cone is ignored)".into()
            }),
            Checked::Valid(LightType::Directional) => {
                self.warnings.once("directional lights", || {
                    "KHR_lights_punctual directional lights are not supported: they are ignored".into()
                });
                return Ok(());
            }
            Checked::Invalid => {
                return Err(malformed(format!("KHR_lights_punctual light {index} has an invalid type")))
            }
        }
        self.point_lights.push(PointLight { position: world.transform_point3(Vec3::ZERO), intensity });
        Ok(())
    }

    /// Appends a mesh instance's world-space triangles.
    fn instantiate(&mut self, mesh: usize, world: &Mat4) -> Result<(), SceneError> {
        let prims = self.mesh(mesh)?;
        let linear = Mat3::from_mat4(*world);
        let det = linear.determinant();
        if det == 0.0 {
            return Ok(()); // a zero scale hides the mesh: nothing to render
        }
        let normal_matrix = linear.inverse().transpose();
        let flip = det < 0.0;
        let added: usize = prims.iter().map(|p| p.triangles.len()).sum();
        if self.triangles.len().saturating_add(added) > MAX_TRIANGLES {
            return Err(SceneError::TooLarge(format!(
                "the scene has more than {MAX_TRIANGLES} triangles after instancing"
            )));
        }
        self.triangles.reserve(added);
        for prim in prims.iter() {
            for (t, tri) in prim.triangles.iter().enumerate() {
                let mut idx = *tri;
                if flip {
                    idx.swap(1, 2);
                }
                let fetch = |i: u32| prim.positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
                let positions = idx.map(|i| world.transform_point3(fetch(i)));
                if !positions.iter().all(|p| p.is_finite()) {
                    return Err(malformed(format!("mesh {mesh}: a vertex is not finite after its node transform")));
                }
                let flat = flat_normal(&positions);
                let normals = match &prim.normals {
                    Some(ns) => idx.map(|i| {
                        let n = ns.get(i as usize).copied().unwrap_or(Vec3::ZERO);
                        let n = (normal_matrix * n).normalize_or_zero();
                        if n == Vec3::ZERO {
                            flat
                        } else {
                            n
                        }
                    }),
                    None => [flat; 3],
                };
                let corner_uvs = |set: &Option<Vec<Vec2>>| match set {
                    Some(uv) => idx.map(|i| uv.get(i as usize).copied().unwrap_or(Vec2::ZERO)),
                    None => [Vec2::ZERO; 3],
                };
                let (uvs, uvs1) = (corner_uvs(&prim.uvs), corner_uvs(&prim.uvs1));
                let mut tangents = match &prim.tangents {
                    Some(ts) => ts.get(t).map_or([Vec4::ZERO; 3], |c| c.map(|c| world_tangent(&linear, c, flip))),
                    None => [Vec4::ZERO; 3],
                };
                if flip {
                    tangents.swap(1, 2);
                }
                self.triangles.push(Triangle { positions, normals, uvs, uvs1, tangents, material: prim.material });
            }
        }
        Ok(())
    }

    /// Decodes a mesh's primitives (once per mesh).
    fn mesh(&mut self, index: usize) -> Result<Rc<Vec<LocalPrimitive>>, SceneError> {
        if let Some(m) = self.meshes.get(&index) {
            return Ok(m.clone());
        }
        let mesh = self.root.meshes.get(index).ok_or_else(|| malformed(format!("mesh {index} does not exist")))?;
        warn_extensions(&mut self.warnings, mesh.extensions.as_ref().map(|e| &e.others));
        let mut prims = Vec::with_capacity(mesh.primitives.len());
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(local) = self.primitive(index, p, prim)? {
                prims.push(local);
            }
        }
        let prims = Rc::new(prims);
        self.meshes.insert(index, prims.clone());
        Ok(prims)
    }

    fn primitive(
        &mut self,
        m: usize,
        p: usize,
        prim: &gltf::json::mesh::Primitive,
    ) -> Result<Option<LocalPrimitive>, SceneError> {
        let what = format!("mesh {m} primitive {p}");
        let mode = match prim.mode {
            Checked::Valid(mode) => mode,
            Checked::Invalid => return Err(malformed(format!("{what}: invalid mode"))),
        };
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.warnings.once("non-triangle primitive modes", || {
                format!("primitive mode {mode:?} is not supported: only triangles (lists, strips, fans) are rendered; such primitives are skipped")
            });
            return Ok(None);
        }
        let ext = prim.extensions.as_ref().map(|e| &e.others);
        warn_extensions(&mut self.warnings, ext);
        let compressed = ext.is_some_and(|e| {
            e.contains_key("KHR_draco_mesh_compression")
                || e.contains_key("EXT_meshopt_compression")
                || e.contains_key("KHR_meshopt_compression")
        });
        if prim.targets.as_ref().is_some_and(|t| !t.is_empty()) {
            self.warnings.once("morph targets", || {
                "morph targets are not supported: meshes are rendered in their base shape".into()
            });
        }
        let mut position = None;
        let mut normal = None;
        let mut uv = None;
        let mut uv1 = None;
        let mut tangent = None;
        for (semantic, accessor) in &prim.attributes {
            match semantic {
                Checked::Valid(Semantic::Positions) => position = Some(accessor.value()),
                Checked::Valid(Semantic::Normals) => normal = Some(accessor.value()),
                Checked::Valid(Semantic::Tangents) => tangent = Some(accessor.value()),
                Checked::Valid(Semantic::TexCoords(0)) => uv = Some(accessor.value()),
                Checked::Valid(Semantic::TexCoords(1)) => uv1 = Some(accessor.value()),
                Checked::Valid(Semantic::Colors(0)) => self
                    .warnings
                    .once("COLOR_0", || "vertex colours (COLOR_0) are not supported: they are ignored".into()),
                _ => {}
            }
        }
        let Some(position) = position else {
            self.warnings.once("no POSITION", || "primitives without POSITION are skipped".into());
            return Ok(None);
        };
        if compressed
            && self.root.accessors.get(position).is_some_and(|a| a.buffer_view.is_none() && a.sparse.is_none())
        {
            // Compressed data only, no uncompressed fallback to read.
            return Ok(None);
        }
        let positions = to_vec3(self.buffers.read_f32(position, 3, &format!("{what} POSITION"))?);
        let vertex_count = positions.len();
        let normals = match normal {
            Some(a) => {
                let n = to_vec3(self.buffers.read_f32(a, 3, &format!("{what} NORMAL"))?);
                if n.len() != vertex_count {
                    return Err(malformed(format!("{what}: NORMAL has {} elements, POSITION {vertex_count}", n.len())));
                }
                Some(n)
            }
            None => None,
        };
        let uvs = self.texcoords(uv, 0, vertex_count, &what)?;
        let indices = match prim.indices {
            Some(a) => {
                let indices = self.buffers.read_indices(a.value(), &format!("{what} indices"))?;
                if let Some(bad) = indices.iter().find(|&&i| i as usize >= vertex_count) {
                    return Err(malformed(format!("{what}: index {bad} is out of range ({vertex_count} vertices)")));
                }
                indices
            }
            None => (0..vertex_count as u32).collect(),
        };
        let triangles = assemble(mode, &indices)
            .ok_or_else(|| malformed(format!("{what}: {} indices do not form whole triangles", indices.len())))?;
        let mut material = self.material(prim.material.map(|i| i.value()))?;
        let uses_set1 = self.materials.get(material as usize).is_some_and(texture_ref::uses_texcoord1);
        let uvs1 = match (uses_set1, uv1) {
            (true, Some(a)) => self.texcoords(Some(a), 1, vertex_count, &what)?,
            (true, None) => {
                material = self.material_without_texcoord1(material, &what);
                None
            }
            (false, _) => None,
        };
        let normal_mapped = self.materials.get(material as usize).is_some_and(|m| m.normal_texture.is_some());
        // MikkTSpace follows the UV set the normal map is read on.
        let normal_set = self.materials.get(material as usize).map_or(0, |m| m.texture_uvs[3].texcoord);
        let map_uvs = if normal_set == 1 { &uvs1 } else { &uvs };
        let tangents = match (normal_mapped, tangent, map_uvs) {
            (false, _, _) => None,
            (true, Some(a), _) => {
                let t = self.buffers.read_f32(a, 4, &format!("{what} TANGENT"))?;
                if t.len() != vertex_count * 4 {
                    return Err(malformed(format!(
                        "{what}: TANGENT has {} elements, POSITION {vertex_count}",
                        t.len() / 4
                    )));
                }
                let t: Vec<Vec4> =
                    t.chunks_exact(4).map(|c| super::tangents::unit_tangent(Vec4::from_slice(c))).collect();
                Some(triangles.iter().map(|tri| tri.map(|i| t[i as usize])).collect())
            }
            (true, None, Some(uvs)) => {
                super::tangents::mikktspace_tangents(&positions, normals.as_deref(), uvs, &triangles)
            }
            (true, None, None) => {
                self.warnings.once("normal map without TEXCOORD_0", || {
                    format!("{what}: a normal-mapped primitive has no TEXCOORD_0, so no tangents: its normal map is ignored")
                });
                None
            }
        };
        Ok(Some(LocalPrimitive { positions, normals, uvs, uvs1, triangles, tangents, material }))
    }
}

fn semantic_name(s: &Checked<Semantic>) -> String {
    match s {
        Checked::Valid(Semantic::Positions) => "POSITION".into(),
        Checked::Valid(Semantic::Normals) => "NORMAL".into(),
        Checked::Valid(Semantic::Tangents) => "TANGENT".into(),
        Checked::Valid(Semantic::TexCoords(n)) => format!("TEXCOORD_{n}"),
        Checked::Valid(Semantic::Colors(n)) => format!("COLOR_{n}"),
        Checked::Valid(Semantic::Joints(n)) => format!("JOINTS_{n}"),
        Checked::Valid(Semantic::Weights(n)) => format!("WEIGHTS_{n}"),
        Checked::Valid(other) => format!("{other:?}"),
        Checked::Invalid => "(invalid)".into(),
    }
}

/// A mesh-space tangent (xyz unit, w ±1) in world space under `linear`: tangents are carried
/// like positions (not like normals), and a mirroring transform flips their handedness.
fn world_tangent(linear: &Mat3, t: Vec4, flip: bool) -> Vec4 {
    match (*linear * t.truncate()).try_normalize() {
        Some(xyz) => xyz.extend(if flip { -t.w } else { t.w }),
        None => Vec4::ZERO,
    }
}

/// A node's local transform (matrix, or TRS with the rotation normalised).
fn node_matrix(node: &gltf::json::scene::Node, n: usize) -> Result<Mat4, SceneError> {
    if let Some(m) = node.matrix {
        let m = Mat4::from_cols_array(&m);
        if !m.is_finite() {
            return Err(malformed(format!("node {n}: matrix is not finite")));
        }
        return Ok(m);
    }
    let t = Vec3::from(node.translation.unwrap_or([0.0; 3]));
    let s = Vec3::from(node.scale.unwrap_or([1.0; 3]));
    let q = node.rotation.map_or(Quat::IDENTITY, |r| Quat::from_array(r.0));
    if !(t.is_finite() && s.is_finite() && q.is_finite()) {
        return Err(malformed(format!("node {n}: transform is not finite")));
    }
    let len = q.length();
    let q = if len > 0.0 { q / len } else { Quat::IDENTITY };
    Ok(Mat4::from_scale_rotation_translation(s, q, t))
}

/// Triangles from an index list in one of the triangle modes; `None` when a TRIANGLES list is
/// not a multiple of three.
fn assemble(mode: Mode, idx: &[u32]) -> Option<Vec<[u32; 3]>> {
    match mode {
        Mode::Triangles => {
            if !idx.len().is_multiple_of(3) {
                return None;
            }
            Some(idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
        }
        Mode::TriangleStrip => Some(
            idx.windows(3)
                .enumerate()
                .map(|(i, w)| if i % 2 == 0 { [w[0], w[1], w[2]] } else { [w[0], w[2], w[1]] })
                // Strips join with repeated indices; those triangles have no area.
                .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
                .collect(),
        ),
        Mode::TriangleFan => {
            let Some(&first) = idx.first() else {
                return Some(Vec::new());
            };
            Some(idx.get(1..).unwrap_or(&[]).windows(2).map(|w| [w[0], w[1], first]).collect())
        }
        _ => Some(Vec::new()),
    }
}

fn to_vec3(v: Vec<f32>) -> Vec<Vec3> {
    v.chunks_exact(3).map(Vec3::from_slice).collect()
}

fn to_vec2(v: Vec<f32>) -> Vec<Vec2> {
    v.chunks_exact(2).map(Vec2::from_slice).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans() {
        assert_eq!(assemble(Mode::TriangleStrip, &[0, 1, 2, 3]).unwrap(), vec![[0, 1, 2], [1, 3, 2]]);
        assert_eq!(assemble(Mode::TriangleFan, &[0, 1, 2, 3]).unwrap(), vec![[1, 2, 0], [2, 3, 0]]);
        assert!(assemble(Mode::Triangles, &[0, 1]).is_none());
        assert_eq!(assemble(Mode::TriangleFan, &[]).map(|v| v.len()), Some(0));
    }

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
