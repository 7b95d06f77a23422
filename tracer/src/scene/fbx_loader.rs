//! Autodesk FBX loading (binary and ASCII, FBX 6.1 to 7.7) through `ufbx`, the Rust bindings
//! of the ufbx C library (single file, heavily fuzzed, MIT or public domain).
//!
//! ufbx converts the file's axis system and unit scale to glTF's (+Y up, right-handed,
//! metres) by a transform on the root node, so every node's world matrix carries the
//! conversion; geometric (pivot) transforms are part of each mesh node's geometry-to-world
//! matrix. Cameras are converted to look down their local -Z with +Y up, as glTF's do.
//!
//! What is read: polygon meshes of visible nodes (triangulated by ufbx, mirrored instances get
//! their winding flipped), normals as the file has them (flat when absent), the first UV set
//! (v flipped: FBX's v = 0 is the bottom of an image), per-face materials, point lights
//! (spot lights as points, like the glTF loader), and the first perspective camera.
//!
//! Materials map onto [`Material`] as it is today (a diffuse, possibly emissive surface):
//! ufbx's PBR view of every shading model (FBX Lambert/Phong, 3ds Max PBR, Stingray, ...)
//! gives the base colour (`base_color x base_factor`) and the emission (`emission_color x
//! emission_factor`). A texture connected to a colour replaces the constant colour (as Maya,
//! 3ds Max and Blender treat it: Blender's exporter writes black emission under an emission
//! texture); the factor still multiplies it. Metalness, roughness, specular, opacity, normal and bump maps are warned
//! about and ignored. Textures are embedded in the file or external: a relative path is resolved
//! next to the FBX file; when it is not there, the absolute path (if it exists on this
//! machine), then the bare file name next to the FBX (absolute Windows paths from the exporting
//! machine end up here).
//!
//! Point lights get radiant intensity `color x intensity` (ufbx reads FBX's percent, 100 = 1.0),
//! the unit glTF's candela get here. FBX leaves the unit to the exporting application (Blender's
//! exporter writes its lamp power: a 1000 W lamp reads as 1000), so an FBX light may need its
//! intensity adjusted to match the same scene exported as glTF.
//!
//! Skinning, blend shapes, animation, NURBS, line curves, subdivision levels and lights other
//! than point and spot lights are warned about by name; the meshes render in the pose the file
//! stores (the bind pose for a skinned character).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};

use super::texture::{
    catch_decoder_panic, decode_textures_forgiving, is_texture_problem, material_label, probe_srgb, ImageHeader,
    ImageProblems, PendingTexture, Probed,
};
use super::util::read_file;
use super::{
    flat_normal, Camera, FoundCamera, LoadOptions, Material, PointLight, Scene, SceneError, Triangle, Warnings, Wrap,
    MAX_FILE_BYTES, MAX_RADIANCE, MAX_SCENE_TEXELS, MAX_TRIANGLES,
};

/// Base colour of faces without a material (FBX's default diffuse colour).
const DEFAULT_ALBEDO: f32 = 0.8;

/// Most memory ufbx may allocate for the parsed scene, and separately for temporaries.
const PARSER_MEMORY_LIMIT: u64 = 8 << 30;

/// Loads an `.fbx` file. External textures are resolved next to it.
pub(crate) fn load_fbx(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    let bytes = read_file(path)?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    let fbx_error = |message: String| SceneError::Fbx { path: path.to_owned(), message };
    let root = catch_decoder_panic(|| parse(&bytes))
        .ok_or_else(|| fbx_error("the FBX parser failed unexpectedly".into()))?
        .map_err(fbx_error)?;
    let loader = Loader {
        fbx: &root,
        dir: &dir,
        options,
        warnings: Warnings::default(),
        triangles: Vec::new(),
        materials: Vec::new(),
        material_map: HashMap::new(),
        default_material: None,
        images: Vec::new(),
        image_map: HashMap::new(),
        problems: ImageProblems::default(),
        textures: Vec::new(),
        texture_map: HashMap::new(),
        point_lights: Vec::new(),
        camera: None,
    };
    loader.run()
}

/// Parses FBX bytes with the conversions of the module docs, or says why ufbx refused them.
fn parse(bytes: &[u8]) -> Result<ufbx::SceneRoot, String> {
    let limit = usize::try_from(PARSER_MEMORY_LIMIT.max(MAX_FILE_BYTES)).unwrap_or(usize::MAX);
    let mut opts = ufbx::LoadOpts {
        target_axes: ufbx::CoordinateAxes::right_handed_y_up(),
        target_unit_meters: 1.0,
        space_conversion: ufbx::SpaceConversion::TransformRoot,
        target_camera_axes: ufbx::CoordinateAxes::right_handed_y_up(),
        target_light_axes: ufbx::CoordinateAxes::right_handed_y_up(),
        // Textures are read here, with the loaders' own limits and path rules.
        load_external_files: false,
        // ufbx also reads OBJ: a `.fbx` file is parsed as FBX or refused.
        file_format: ufbx::FileFormat::Fbx,
        ..Default::default()
    };
    opts.temp_allocator.memory_limit = limit;
    opts.result_allocator.memory_limit = limit;
    ufbx::load_memory(bytes, opts).map_err(|e| {
        let info = catch_decoder_panic(|| e.info().to_owned()).unwrap_or_default();
        if info.is_empty() {
            e.description.to_string()
        } else {
            format!("{}: {info}", &*e.description)
        }
    })
}

fn malformed(m: String) -> SceneError {
    SceneError::Malformed(m)
}

/// A ufbx matrix (column-major 3x4, affine) as a glam matrix.
fn dmat4(m: &ufbx::Matrix) -> DMat4 {
    DMat4::from_cols_array(&[
        m.m00, m.m10, m.m20, 0.0, m.m01, m.m11, m.m21, 0.0, m.m02, m.m12, m.m22, 0.0, m.m03, m.m13, m.m23, 1.0,
    ])
}

fn dvec3(v: ufbx::Vec3) -> DVec3 {
    DVec3::new(v.x, v.y, v.z)
}

/// A colour and the texture on it: the texture when one is connected (it replaces the constant
/// colour, as in Maya, 3ds Max and Blender, whose exporters leave an unused default there),
/// else the constant colour (its first three components); either way times the factor map's
/// value (1 when the file sets none).
fn mapped_color<'a>(color: &'a ufbx::MaterialMap, factor: &ufbx::MaterialMap) -> (Vec3, Option<&'a ufbx::Texture>) {
    let f = if factor.has_value { factor.value_vec4.x } else { 1.0 };
    match &color.texture {
        Some(t) if color.texture_enabled => (DVec3::splat(f).as_vec3(), Some(&**t)),
        _ => {
            let c = color.value_vec4;
            ((DVec3::new(c.x, c.y, c.z) * f).as_vec3(), None)
        }
    }
}

/// One mesh instance's vertex data in world space, for [`Loader::instance`].
struct WorldMesh<'a> {
    mesh: &'a ufbx::Mesh,
    to_world: DMat4,
    normal_matrix: DMat3,
    flip: bool,
    what: String,
}

struct Loader<'a> {
    fbx: &'a ufbx::Scene,
    dir: &'a Path,
    options: &'a LoadOptions,
    warnings: Warnings,
    triangles: Vec<Triangle>,
    materials: Vec<Material>,
    /// ufbx material element id → index in `materials`.
    material_map: HashMap<u32, u32>,
    default_material: Option<u32>,
    /// Probed images with their bytes.
    images: Vec<(Vec<u8>, ImageHeader)>,
    /// Where an image came from (a path, or an embedded texture's element id) → index in
    /// `images`, `None` when its format is unsupported, `Err` when it could not be read or
    /// probed (its entry in `problems`).
    image_map: HashMap<String, Result<Option<usize>, usize>>,
    /// Texture images that could not be used (a forgiving load: see [`LoadOptions::strict`]).
    problems: ImageProblems,
    textures: Vec<PendingTexture>,
    /// (image, wrap u, wrap v) → index in `textures`.
    texture_map: HashMap<(usize, Wrap, Wrap), u32>,
    point_lights: Vec<PointLight>,
    camera: Option<FoundCamera>,
}

impl Loader<'_> {
    fn run(mut self) -> Result<Scene, SceneError> {
        self.warn_about_unsupported_content();
        let fbx = self.fbx;
        for node in &fbx.nodes {
            if !node.visible {
                if node.mesh.is_some() {
                    self.warnings.once("hidden nodes", || "hidden FBX nodes are not rendered".into());
                }
                continue;
            }
            if let Some(mesh) = &node.mesh {
                self.instance(node, mesh)?;
            }
            if let Some(light) = &node.light {
                self.light(node, light)?;
            }
            if let Some(camera) = &node.camera {
                self.camera(node, camera)?;
            }
        }
        if self.triangles.is_empty() {
            return Err(SceneError::NoTriangles(
                self.warnings.why_no_triangles(" (the FBX file has no visible polygon meshes)"),
            ));
        }
        let images: Vec<(&[u8], &ImageHeader)> = self.images.iter().map(|(b, h)| (b.as_slice(), h)).collect();
        let textures = decode_textures_forgiving(
            &images,
            self.textures,
            &mut self.materials,
            &mut self.problems,
            self.options.strict,
        )?;
        self.problems.warn(&mut self.warnings);
        let mut scene = Scene {
            triangles: self.triangles,
            meshes: Vec::new(),
            instances: Vec::new(),
            materials: self.materials,
            textures,
            point_lights: self.point_lights,
            camera: Camera::default(),
            sky: None,
            warnings: Vec::new(),
            motion: None,
        };
        let bounds = scene.bounds();
        scene.camera = match self.camera {
            Some(c) => c.finish(&bounds),
            None => Camera::framing(&bounds),
        };
        scene.warnings = self.warnings.into_vec();
        scene.validate()?;
        Ok(scene)
    }

    /// Names, once each, what the file holds that Lightport does not render.
    fn warn_about_unsupported_content(&mut self) {
        let fbx = self.fbx;
        let w = &mut self.warnings;
        if !fbx.skin_deformers.is_empty() {
            w.once("skinning", || {
                "FBX skinning is not supported: skinned meshes are rendered in their bind pose".into()
            });
        }
        if !fbx.blend_deformers.is_empty() {
            w.once("blend shapes", || "FBX blend shapes are not supported: meshes are rendered without them".into());
        }
        if !fbx.cache_deformers.is_empty() {
            w.once("geometry caches", || "FBX geometry caches are not supported: they are ignored".into());
        }
        if !fbx.anim_curves.is_empty() {
            w.once("animation", || "FBX animation is not supported: the scene is rendered in its stored pose".into());
        }
        if !fbx.nurbs_curves.is_empty() || !fbx.nurbs_surfaces.is_empty() || !fbx.nurbs_trim_surfaces.is_empty() {
            w.once("NURBS", || "FBX NURBS curves and surfaces are not supported: they are ignored".into());
        }
        if !fbx.line_curves.is_empty() {
            w.once("line curves", || "FBX line curves are not supported: they are ignored".into());
        }
        if !fbx.procedural_geometries.is_empty() {
            w.once("procedural geometry", || "FBX procedural geometry is not supported: it is ignored".into());
        }
        for warning in &fbx.metadata.warnings {
            let what = warning.description.to_string();
            let count = warning.count;
            w.once(&format!("ufbx {what}"), || format!("the FBX file has problems ufbx repaired: {what} ({count}x)"));
        }
    }

    /// Appends a mesh node's world-space triangles.
    fn instance(&mut self, node: &ufbx::Node, mesh: &ufbx::Mesh) -> Result<(), SceneError> {
        let what = format!("FBX mesh {:?}", &*mesh.element.name);
        self.warn_about_mesh(mesh);
        let to_world = dmat4(&node.geometry_to_world);
        let linear = DMat3::from_mat4(to_world);
        let det = linear.determinant();
        if det == 0.0 || !det.is_finite() {
            return Ok(()); // a zero scale hides the mesh: nothing to render
        }
        if self.triangles.len().saturating_add(mesh.num_triangles) > MAX_TRIANGLES {
            return Err(SceneError::TooLarge(format!("the scene has more than {MAX_TRIANGLES} triangles")));
        }
        let materials: Vec<Option<u32>> = (0..mesh.materials.len().max(1))
            .map(|i| node.materials.get(i).or_else(|| mesh.materials.get(i)).map(|m| self.material(m)).transpose())
            .collect::<Result<_, _>>()?;
        let world = WorldMesh { mesh, to_world, normal_matrix: linear.inverse().transpose(), flip: det < 0.0, what };
        let mut corners = vec![0u32; mesh.max_face_triangles.saturating_mul(3)];
        self.triangles.reserve(mesh.num_triangles);
        for (f, face) in mesh.faces.iter().enumerate() {
            if face.num_indices < 3 {
                self.warnings.once("points and lines", || "FBX point and line faces are not rendered".into());
                continue;
            }
            let material = match materials.get(mesh.face_material.get(f).copied().unwrap_or(0) as usize) {
                Some(Some(m)) => *m,
                _ => self.default_material(),
            };
            let count = mesh.triangulate_face(&mut corners, *face) as usize;
            for tri in corners.get(..count * 3).unwrap_or(&[]).chunks_exact(3) {
                let triangle = world.triangle([tri[0], tri[1], tri[2]], material)?;
                if self.warnings.keep_triangle(&triangle.positions) {
                    self.triangles.push(triangle);
                }
            }
        }
        Ok(())
    }

    fn warn_about_mesh(&mut self, mesh: &ufbx::Mesh) {
        if mesh.vertex_color.exists {
            self.warnings.once("vertex colours", || "FBX vertex colours are not supported: they are ignored".into());
        }
        if mesh.uv_sets.len() > 1 {
            self.warnings.once("uv sets", || {
                "FBX meshes with several UV sets: only the first is used (textures on others are mapped with it)".into()
            });
        }
        if mesh.subdivision_display_mode != ufbx::SubdivisionDisplayMode::Disabled {
            self.warnings.once("subdivision", || {
                "FBX subdivision surfaces are not supported: their control meshes are rendered".into()
            });
        }
    }

    fn default_material(&mut self) -> u32 {
        *self.default_material.get_or_insert_with(|| {
            self.materials.push(Material::diffuse("default", Vec3::splat(DEFAULT_ALBEDO)));
            self.materials.len() as u32 - 1
        })
    }

    /// The scene material of a ufbx material (converted once).
    fn material(&mut self, m: &ufbx::Material) -> Result<u32, SceneError> {
        if let Some(&index) = self.material_map.get(&m.element.element_id) {
            return Ok(index);
        }
        let name = m.element.name.to_string();
        let what = format!("FBX material {name:?}");
        let (base_color, base_map) = mapped_color(&m.pbr.base_color, &m.pbr.base_factor);
        let (emission, emission_map) = mapped_color(&m.pbr.emission_color, &m.pbr.emission_factor);
        if !base_color.is_finite() || !emission.is_finite() || emission.min_element() < 0.0 {
            return Err(malformed(format!("{what}: colours must be finite (and emission >= 0)")));
        }
        if emission.max_element() > MAX_RADIANCE {
            return Err(malformed(format!(
                "{what}: emission {emission} is above the largest radiance Lightport accepts ({MAX_RADIANCE:e})"
            )));
        }
        self.warn_about_material(m);
        let label = material_label(self.materials.len(), &name);
        let base_color_texture = match base_map {
            Some(t) => self.texture(t, &label)?,
            None => None,
        };
        let emissive_texture = match emission_map {
            Some(t) if emission.max_element() > 0.0 => self.texture(t, &label)?,
            _ => None,
        };
        let material = Material {
            name,
            base_color: base_color.clamp(Vec3::ZERO, Vec3::ONE),
            base_color_texture,
            emission,
            emissive_texture,
            ..Material::diffuse("", Vec3::ZERO)
        };
        self.materials.push(material);
        let index = self.materials.len() as u32 - 1;
        self.material_map.insert(m.element.element_id, index);
        Ok(index)
    }

    fn warn_about_material(&mut self, m: &ufbx::Material) {
        let pbr = &m.pbr;
        let used = |map: &ufbx::MaterialMap| map.texture.is_some() && map.texture_enabled;
        if (pbr.metalness.has_value && pbr.metalness.value_vec4.x > 0.0) || used(&pbr.metalness) || used(&pbr.roughness)
        {
            self.warnings.once("metal-roughness", || {
                "FBX metalness and roughness are not supported yet: surfaces are rendered diffuse".into()
            });
        }
        if used(&m.fbx.specular_color) || used(&pbr.specular_color) {
            self.warnings.once("specular maps", || "FBX specular maps are not supported: they are ignored".into());
        }
        if used(&pbr.normal_map) || used(&m.fbx.normal_map) || used(&m.fbx.bump) {
            self.warnings.once("normal maps", || "FBX normal and bump maps are not supported: they are ignored".into());
        }
        let transparent = (pbr.opacity.has_value && pbr.opacity.value_vec4.x < 1.0) || used(&pbr.opacity);
        if transparent {
            self.warnings.once("opacity", || "FBX transparency is not supported: surfaces are rendered opaque".into());
        }
        if used(&m.pbr.base_factor) || used(&m.pbr.emission_factor) {
            self.warnings.once("factor maps", || {
                "FBX textures on colour factors (not on the colours) are not supported: they are ignored".into()
            });
        }
    }

    /// The scene texture of a ufbx texture: its image (embedded or a file) and wrap modes.
    /// `label`: how warnings name the material that uses it.
    fn texture(&mut self, t: &ufbx::Texture, label: &str) -> Result<Option<u32>, SceneError> {
        let file = match t.type_ {
            ufbx::TextureType::File => t,
            _ => {
                let Some(first) = t.file_textures.first() else {
                    self.warnings.once("procedural textures", || {
                        "FBX procedural and shader textures are not supported: they are ignored".into()
                    });
                    return Ok(None);
                };
                self.warnings.once("layered textures", || {
                    "FBX layered textures are not supported: only their first file texture is used".into()
                });
                &**first
            }
        };
        if file.has_uv_transform {
            self.warnings.once("uv transforms", || "FBX texture UV transforms are not supported: ignored".into());
        }
        let Some(image) = self.image(file, label)? else { return Ok(None) };
        let wrap = |mode: ufbx::WrapMode| match mode {
            ufbx::WrapMode::Repeat => Wrap::Repeat,
            ufbx::WrapMode::Clamp => Wrap::ClampToEdge,
        };
        let key = (image, wrap(file.wrap_u), wrap(file.wrap_v));
        if let Some(&index) = self.texture_map.get(&key) {
            return Ok(Some(index));
        }
        self.textures.push(PendingTexture { image, wrap_s: key.1, wrap_t: key.2 });
        let index = self.textures.len() as u32 - 1;
        self.texture_map.insert(key, index);
        Ok(Some(index))
    }

    /// A file texture's image, probed once per source. A missing, unreadable or unprobeable
    /// image is `None` (recorded in `problems` for `label`) unless loading is strict.
    fn image(&mut self, t: &ufbx::Texture, label: &str) -> Result<Option<usize>, SceneError> {
        let embedded = if !t.content.is_empty() {
            Some(&*t.content)
        } else {
            t.video.as_ref().map(|v| &*v.content).filter(|c| !c.is_empty())
        };
        let (key, name) = match embedded {
            Some(_) => {
                (format!("embedded {}", t.element.element_id), format!("embedded texture {:?}", &*t.element.name))
            }
            None => {
                let path = self.texture_path(t).display().to_string();
                (path.clone(), format!("image {path}"))
            }
        };
        match self.image_map.get(&key) {
            Some(Ok(image)) => return Ok(*image),
            Some(&Err(problem)) => {
                self.problems.used_by(problem, label);
                return Ok(None);
            }
            None => {}
        }
        let probed = match embedded {
            Some(content) => self.probe(content.to_vec(), &name),
            None => read_file(Path::new(&key)).and_then(|bytes| self.probe(bytes, &key)),
        };
        let result = match probed {
            Err(e) if !self.options.strict && is_texture_problem(&e) => {
                let problem = self.problems.add(name, &e);
                self.problems.used_by(problem, label);
                Err(problem)
            }
            other => Ok(other?),
        };
        self.image_map.insert(key, result);
        Ok(result.unwrap_or(None))
    }

    /// Probes an image's header within the scene's texel budget (see [`Loader::image`]).
    fn probe(&mut self, bytes: Vec<u8>, name: &str) -> Result<Option<usize>, SceneError> {
        let used: u64 = self.images.iter().map(|(_, header)| header.texels()).sum();
        let budget = MAX_SCENE_TEXELS.saturating_sub(used);
        if budget == 0 {
            return Err(SceneError::TooLarge(format!("the scene's textures have more than {MAX_SCENE_TEXELS} texels")));
        }
        Ok(match probe_srgb(&bytes, name, budget)? {
            Probed::Image(header) => {
                self.images.push((bytes, header));
                Some(self.images.len() - 1)
            }
            Probed::Unsupported(format) => {
                self.warnings.once(&format!("image format {format}"), || {
                    format!(
                        "image format {format} is not supported (PNG, JPEG and WebP are): textures using it are dropped"
                    )
                });
                None
            }
        })
    }

    /// Where an external texture's file is (see the module docs): the first candidate that
    /// exists, else the relative path (whose read error then names it).
    fn texture_path(&self, t: &ufbx::Texture) -> PathBuf {
        let native = |s: &str| s.replace('\\', "/");
        let relative = native(&t.relative_filename);
        let absolute = native(&t.absolute_filename);
        let is_windows_absolute = |s: &str| s.as_bytes().get(1) == Some(&b':') || s.starts_with("//");
        let mut candidates = Vec::new();
        if !relative.is_empty() {
            candidates.push(self.dir.join(&relative));
        }
        if !absolute.is_empty() && Path::new(&absolute).is_absolute() && !is_windows_absolute(absolute.as_str()) {
            candidates.push(PathBuf::from(&absolute));
        }
        for name in [&relative, &absolute] {
            if let Some(base) = name.rsplit('/').next().filter(|b| !b.is_empty()) {
                candidates.push(self.dir.join(base));
            }
        }
        candidates.iter().find(|p| p.is_file()).or(candidates.first()).cloned().unwrap_or_else(|| {
            // No file name at all: a path that names the texture in the error.
            self.dir.join(format!("(texture {:?} has no file name)", &*t.element.name))
        })
    }

    fn light(&mut self, node: &ufbx::Node, light: &ufbx::Light) -> Result<(), SceneError> {
        let name = &*light.element.name;
        let intensity = (dvec3(light.color) * light.intensity).as_vec3();
        if !intensity.is_finite() || intensity.min_element() < 0.0 || intensity.max_element() > MAX_RADIANCE {
            return Err(malformed(format!(
                "FBX light {name:?}: colour x intensity must be finite, >= 0 and at most {MAX_RADIANCE:e}"
            )));
        }
        match light.type_ {
            ufbx::LightType::Point => {}
            ufbx::LightType::Spot => self
                .warnings
                .once("spot lights", || "FBX spot lights are treated as point lights (their cone is ignored)".into()),
            other => {
                self.warnings.once(&format!("{other:?} lights"), || {
                    format!("FBX {} lights are not supported: they are ignored", format!("{other:?}").to_lowercase())
                });
                return Ok(());
            }
        }
        if light.decay != ufbx::LightDecay::Quadratic {
            self.warnings.once("light decay", || {
                "FBX lights without quadratic decay are rendered with physical (inverse-square) falloff".into()
            });
        }
        let position = dmat4(&node.node_to_world).transform_point3(DVec3::ZERO).as_vec3();
        if !position.is_finite() {
            return Err(malformed(format!("FBX light {name:?}: its position is not finite")));
        }
        self.point_lights.push(PointLight { position, intensity });
        Ok(())
    }

    fn camera(&mut self, node: &ufbx::Node, camera: &ufbx::Camera) -> Result<(), SceneError> {
        if self.camera.is_some() {
            return Ok(());
        }
        if camera.projection_mode != ufbx::ProjectionMode::Perspective {
            self.warnings.once("orthographic camera", || {
                "FBX orthographic cameras are not supported: the first perspective camera (or a framing one) is used"
                    .into()
            });
            return Ok(());
        }
        let yfov = camera.field_of_view_deg.y.to_radians() as f32;
        if !(yfov > 0.0 && yfov < std::f32::consts::PI) {
            return Err(malformed(format!(
                "FBX camera {:?}: vertical field of view {}° is not in (0°, 180°)",
                &*camera.element.name, camera.field_of_view_deg.y
            )));
        }
        let world = dmat4(&node.node_to_world);
        let forward = world.transform_vector3(DVec3::NEG_Z).as_vec3().normalize_or_zero();
        let up = world.transform_vector3(DVec3::Y).as_vec3().normalize_or_zero();
        let position = world.transform_point3(DVec3::ZERO).as_vec3();
        if forward == Vec3::ZERO || up == Vec3::ZERO || !position.is_finite() {
            self.warnings
                .once("degenerate camera", || "an FBX camera has a degenerate transform: it is ignored".into());
            return Ok(());
        }
        self.camera = Some(FoundCamera { position, forward, up, yfov });
        Ok(())
    }
}

impl WorldMesh<'_> {
    /// The world-space triangle of three face corners (ufbx mesh indices).
    fn triangle(&self, mut corners: [u32; 3], material: u32) -> Result<Triangle, SceneError> {
        if self.flip {
            corners.swap(1, 2);
        }
        let mesh = self.mesh;
        let mut positions = [Vec3::ZERO; 3];
        for (p, &c) in positions.iter_mut().zip(&corners) {
            let local = corner_value(&mesh.vertex_position, c)
                .ok_or_else(|| malformed(format!("{}: a face corner has no position", self.what)))?;
            *p = self.to_world.transform_point3(local).as_vec3();
        }
        if !positions.iter().all(|p| p.is_finite()) {
            return Err(malformed(format!("{}: a vertex is not finite in world space", self.what)));
        }
        let flat = flat_normal(&positions);
        let normals = if mesh.vertex_normal.exists {
            corners.map(|c| {
                corner_value(&mesh.vertex_normal, c)
                    .map(|n| (self.normal_matrix * n).as_vec3().normalize_or_zero())
                    .filter(|n| *n != Vec3::ZERO && n.is_finite())
                    .unwrap_or(flat)
            })
        } else {
            [flat; 3]
        };
        let uv = &mesh.vertex_uv;
        let uvs = if uv.exists {
            corners.map(|c| {
                let i = uv.indices.get(c as usize).copied().unwrap_or(u32::MAX) as usize;
                uv.values.get(i).map_or(Vec2::ZERO, |v| Vec2::new(v.x as f32, (1.0 - v.y) as f32))
            })
        } else {
            [Vec2::ZERO; 3]
        };
        if !uvs.iter().all(|t| t.is_finite()) {
            return Err(malformed(format!("{}: a texture coordinate is not finite", self.what)));
        }
        Ok(Triangle { positions, normals, uvs, uvs1: Default::default(), tangents: Default::default(), material })
    }
}

/// A vertex attribute's value at a face corner (a ufbx mesh index), `None` when out of range.
fn corner_value(attribute: &ufbx::VertexVec3, corner: u32) -> Option<DVec3> {
    let i = *attribute.indices.get(corner as usize)? as usize;
    attribute.values.get(i).map(|v| dvec3(*v))
}
