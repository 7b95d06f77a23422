//! Wavefront OBJ (+ MTL) loading through `tobj`.
//!
//! MTL support: `Kd` (base colour, read as linear), `map_Kd` (sRGB texture), `Ke` (emitted
//! radiance), `map_Ke`. OBJ `vt` coordinates have v = 0 at the bottom of the image; they are
//! flipped to glTF's top-left convention. OBJ files have no camera: one framing the bounds is
//! generated.

use std::cell::RefCell;
use std::collections::HashMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::texture::{
    catch_decoder_panic, decode_textures_forgiving, is_texture_problem, material_label, probe_srgb, ImageHeader,
    ImageProblems, PendingTexture, Probed,
};
use super::util::read_file;
use super::{
    flat_normal, Camera, LoadOptions, Material, Scene, SceneError, Triangle, Warnings, Wrap, MAX_SCENE_TEXELS,
    MAX_TRIANGLES,
};

/// Base colour of materials without `Kd`, and of faces without a material.
const DEFAULT_ALBEDO: f32 = 0.8;

pub(crate) fn load_obj(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    let bytes = read_file(path)?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    load_obj_from(&bytes, path, &|name| read_file(&dir.join(name)), options)
}

/// Loads an OBJ from memory. `read` supplies the files it names (MTL libraries from `mtllib`,
/// texture maps from the MTL), given their path relative to the OBJ's folder as written in the
/// file (backslashes turned into slashes); return [`SceneError::Io`] for a missing file.
/// `name` names the OBJ in errors.
pub fn load_obj_slice(
    bytes: &[u8],
    name: &str,
    read: &dyn Fn(&Path) -> Result<Vec<u8>, SceneError>,
    options: &LoadOptions,
) -> Result<Scene, SceneError> {
    load_obj_from(bytes, Path::new(name), read, options)
}

fn load_obj_from(
    bytes: &[u8],
    path: &Path,
    read: &dyn Fn(&Path) -> Result<Vec<u8>, SceneError>,
    options: &LoadOptions,
) -> Result<Scene, SceneError> {
    let (models, mtl_materials) = parse_obj(bytes, path, read)?;
    let mut warnings = Warnings::default();
    let mut textures = Textures {
        read,
        strict: options.strict,
        images: Vec::new(),
        textures: Vec::new(),
        cache: HashMap::new(),
        problems: ImageProblems::default(),
    };
    let mut materials = Vec::with_capacity(mtl_materials.len() + 1);
    for m in &mtl_materials {
        let label = material_label(materials.len(), &m.name);
        materials.push(convert_material(m, &label, &mut textures, &mut warnings)?);
    }
    let mut default_material = None;

    let mut triangles = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let what = format!("object {:?}", model.name);
        let material = match mesh.material_id {
            Some(id) if id < materials.len() => id as u32,
            Some(id) => return Err(SceneError::Malformed(format!("{what} uses material {id}, which does not exist"))),
            None => *default_material.get_or_insert_with(|| {
                materials.push(Material::diffuse("default", Vec3::splat(DEFAULT_ALBEDO)));
                materials.len() as u32 - 1
            }),
        };
        append_triangles(mesh, &what, material, &mut triangles, &mut warnings)?;
    }
    if triangles.is_empty() {
        return Err(SceneError::NoTriangles(warnings.why_no_triangles(" (the OBJ has no faces)")));
    }
    let images: Vec<(&[u8], &ImageHeader)> = textures.images.iter().map(|(b, h)| (b.as_slice(), h)).collect();
    let mut problems = textures.problems;
    let textures =
        decode_textures_forgiving(&images, textures.textures, &mut materials, &mut problems, options.strict)?;
    problems.warn(&mut warnings);
    let mut scene = Scene {
        triangles,
        meshes: Vec::new(),
        instances: Vec::new(),
        materials,
        textures,
        point_lights: Vec::new(),
        camera: Camera::default(),
        sky: None,
        warnings: Vec::new(),
        motion: None,
    };
    scene.camera = Camera::framing(&scene.bounds());
    scene.warnings = warnings.into_vec();
    scene.validate()?;
    Ok(scene)
}

/// The OBJ's models and its material libraries' materials, parsed by tobj (behind the checks
/// that keep tobj from panicking); a library that cannot be read is an error.
fn parse_obj(
    bytes: &[u8],
    path: &Path,
    read: &dyn Fn(&Path) -> Result<Vec<u8>, SceneError>,
) -> Result<(Vec<tobj::Model>, Vec<tobj::Material>), SceneError> {
    let obj_error = |message: String| SceneError::Obj { path: path.to_owned(), message };
    let mtl_failure: RefCell<Option<SceneError>> = RefCell::new(None);
    let parse_options =
        tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    check_face_indices(bytes).map_err(obj_error)?;
    let parsed = catch_decoder_panic(|| {
        tobj::load_obj_buf(&mut Cursor::new(bytes), &parse_options, |mtl| {
            let result = read(mtl).and_then(|b| {
                check_mtl_colours(&b).map_err(|message| SceneError::Obj { path: mtl.to_owned(), message })?;
                catch_decoder_panic(|| tobj::load_mtl_buf(&mut Cursor::new(b)))
                    .unwrap_or(Err(tobj::LoadError::GenericFailure))
                    .map_err(|e| SceneError::Obj { path: mtl.to_owned(), message: e.to_string() })
            });
            result.map_err(|e| {
                mtl_failure.borrow_mut().get_or_insert(e);
                tobj::LoadError::OpenFileFailed
            })
        })
    })
    .ok_or_else(|| obj_error("the OBJ parser failed unexpectedly".into()))?;
    let (models, materials) = parsed.map_err(|e| obj_error(e.to_string()))?;
    if let Some(e) = mtl_failure.into_inner() {
        return Err(e);
    }
    let mtl_materials = materials.map_err(|e| obj_error(format!("material library: {e}")))?;
    Ok((models, mtl_materials))
}

/// Appends `mesh`'s triangles (material `material`) to `triangles`: positions checked finite
/// and in range, degenerate triangles dropped (and counted in `warnings`), missing normals flat.
fn append_triangles(
    mesh: &tobj::Mesh,
    what: &str,
    material: u32,
    triangles: &mut Vec<Triangle>,
    warnings: &mut Warnings,
) -> Result<(), SceneError> {
    let vertex_count = mesh.positions.len() / 3;
    let positions: Vec<Vec3> = mesh.positions.chunks_exact(3).map(Vec3::from_slice).collect();
    if positions.iter().any(|p| !p.is_finite()) {
        return Err(SceneError::Malformed(format!("{what}: a vertex position is not finite")));
    }
    let normals: Option<Vec<Vec3>> = (mesh.normals.len() == mesh.positions.len())
        .then(|| mesh.normals.chunks_exact(3).map(Vec3::from_slice).collect());
    let uvs: Option<Vec<Vec2>> = (mesh.texcoords.len() / 2 == vertex_count && !mesh.texcoords.is_empty())
        .then(|| mesh.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], 1.0 - c[1])).collect());
    if normals.as_ref().is_some_and(|n| n.iter().any(|v| !v.is_finite()))
        || uvs.as_ref().is_some_and(|t| t.iter().any(|v| !v.is_finite()))
    {
        return Err(SceneError::Malformed(format!("{what}: a normal or texture coordinate is not finite")));
    }
    if !mesh.indices.len().is_multiple_of(3) {
        return Err(SceneError::Malformed(format!(
            "{what}: {} indices do not form whole triangles",
            mesh.indices.len()
        )));
    }
    if triangles.len() + mesh.indices.len() / 3 > MAX_TRIANGLES {
        return Err(SceneError::TooLarge(format!("the scene has more than {MAX_TRIANGLES} triangles")));
    }
    for face in mesh.indices.chunks_exact(3) {
        let idx = [face[0], face[1], face[2]].map(|i| i as usize);
        let mut p = [Vec3::ZERO; 3];
        for (k, &i) in idx.iter().enumerate() {
            p[k] = *positions.get(i).ok_or_else(|| {
                SceneError::Malformed(format!("{what}: vertex index {i} is out of range ({vertex_count} vertices)"))
            })?;
        }
        if !warnings.keep_triangle(&p) {
            continue;
        }
        let flat = flat_normal(&p);
        let normals = match &normals {
            Some(ns) => {
                idx.map(|i| ns.get(i).map(|n| n.normalize_or_zero()).filter(|n| *n != Vec3::ZERO).unwrap_or(flat))
            }
            None => [flat; 3],
        };
        let uvs = match &uvs {
            Some(t) => idx.map(|i| t.get(i).copied().unwrap_or(Vec2::ZERO)),
            None => [Vec2::ZERO; 3],
        };
        triangles.push(Triangle {
            positions: p,
            normals,
            uvs,
            uvs1: Default::default(),
            tangents: Default::default(),
            material,
        });
    }
    Ok(())
}

/// Refuses MTL colour statements with fewer than three values (`Kd 0.5 0`), on which tobj
/// 4 panics (`parse_float3` unwraps); found by fuzzing. Other lines are tobj's to judge.
fn check_mtl_colours(mtl: &[u8]) -> Result<(), String> {
    for (n, line) in String::from_utf8_lossy(mtl).lines().enumerate() {
        let mut words = line.split_whitespace();
        if let Some(key @ ("Ka" | "Kd" | "Ks" | "Ke")) = words.next() {
            let values = words.count();
            if values < 3 {
                return Err(format!("line {}: {key} needs three values (r g b), found {values}", n + 1));
            }
        }
    }
    Ok(())
}

/// The largest positive face index accepted (no OBJ within the loader's limits has more vertices).
const MAX_FACE_INDEX: i64 = 1 << 32;

/// Refuses face (and line) indices that tobj 4 would overflow on: a relative index reaching
/// before the first vertex, texture coordinate or normal wraps to a huge `usize`, which tobj
/// then multiplies by 2 or 3 (`lib.rs:852/860`: a panic in debug builds, a wrapped bounds check
/// in release ones); found by fuzzing. The counts are tobj's own at that line (one per `v`,
/// `vt` or `vn` statement). Indices that are not integers are tobj's to refuse.
fn check_face_indices(obj: &[u8]) -> Result<(), String> {
    const KINDS: [(&str, &str); 3] = [("vertex", "v"), ("texture coordinate", "vt"), ("normal", "vn")];
    let mut counts = [0u64; 3];
    for (n, line) in obj.split(|&b| b == b'\n').enumerate() {
        let Ok(line) = std::str::from_utf8(line) else { continue };
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("f" | "l") => {
                for corner in words {
                    for (k, index) in corner.split('/').enumerate().take(3) {
                        let Ok(i) = index.parse::<i64>() else { continue };
                        let (kind, keyword) = KINDS[k];
                        if i > MAX_FACE_INDEX {
                            return Err(format!("line {}: {kind} index {i} is above {MAX_FACE_INDEX}", n + 1));
                        }
                        if i < 0 && i.unsigned_abs() > counts[k] {
                            return Err(format!(
                                "line {}: relative {kind} index {i} reaches before the first `{keyword}` ({} so far)",
                                n + 1,
                                counts[k]
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// The MTL textures, probed (each image is one texture), decoded once the materials are read.
struct Textures<'r> {
    /// Reads a file named relative to the OBJ's folder (see [`load_obj_slice`]).
    read: &'r dyn Fn(&Path) -> Result<Vec<u8>, SceneError>,
    /// [`LoadOptions::strict`].
    strict: bool,
    images: Vec<(Vec<u8>, ImageHeader)>,
    textures: Vec<PendingTexture>,
    /// Map file name -> its texture (`Err`: its entry in `problems`).
    cache: HashMap<String, Result<Option<u32>, usize>>,
    problems: ImageProblems,
}

/// `label`: how warnings name the material.
fn convert_material(
    m: &tobj::Material,
    label: &str,
    textures: &mut Textures,
    warnings: &mut Warnings,
) -> Result<Material, SceneError> {
    let what = format!("MTL material {:?}", m.name);
    let color = |c: Option<[f32; 3]>, default: f32, name: &str| -> Result<Vec3, SceneError> {
        let v = c.map_or(Vec3::splat(default), Vec3::from);
        if v.is_finite() && v.min_element() >= 0.0 {
            Ok(v)
        } else {
            Err(SceneError::Malformed(format!("{what}: {name} must be finite and >= 0")))
        }
    };
    let base_color = color(m.diffuse, DEFAULT_ALBEDO, "Kd")?.min(Vec3::ONE);
    let emission = color(m.emissive, 0.0, "Ke")?;
    if emission.max_element() > super::MAX_RADIANCE {
        return Err(SceneError::Malformed(format!(
            "{what}: Ke {emission} is above the largest radiance Lightport accepts ({:e})",
            super::MAX_RADIANCE
        )));
    }
    if m.specular.is_some_and(|ks| ks.iter().any(|&k| k > 0.0)) {
        warnings
            .once("MTL Ks", || "MTL specular reflection (Ks) is not supported: surfaces are rendered diffuse".into());
    }
    if m.dissolve.is_some_and(|d| d < 1.0) || m.unknown_param.contains_key("Tr") {
        warnings.once("MTL d", || "MTL transparency (d, Tr) is not supported: surfaces are rendered opaque".into());
    }
    if m.normal_texture.is_some() || m.unknown_param.contains_key("map_Bump") {
        warnings.once("MTL bump", || "MTL bump and normal maps are not supported: they are ignored".into());
    }
    let base_color_texture = match &m.diffuse_texture {
        Some(t) => textures.texture(t, label, warnings)?,
        None => None,
    };
    let emissive_texture = match m.unknown_param.get("map_Ke") {
        Some(t) if emission.max_element() > 0.0 => textures.texture(t, label, warnings)?,
        _ => None,
    };
    Ok(Material {
        name: m.name.clone(),
        base_color,
        base_color_texture,
        emission,
        emissive_texture,
        ..Material::diffuse("", Vec3::ZERO)
    })
}

impl Textures<'_> {
    /// Loads an MTL texture map (relative to the OBJ's folder) for material `label`. Map
    /// options (`-bm 1 ...`) are skipped with a warning; the file name is the last word. A
    /// missing, unreadable or undecodable image is `None` (recorded in `problems`) unless
    /// loading is strict.
    fn texture(&mut self, spec: &str, label: &str, warnings: &mut Warnings) -> Result<Option<u32>, SceneError> {
        let file = if spec.starts_with('-') {
            warnings.once("MTL map options", || {
                "MTL texture map options (-bm, -s, ...) are not supported: they are ignored".into()
            });
            spec.split_whitespace().last().unwrap_or(spec)
        } else {
            spec
        };
        match self.cache.get(file) {
            Some(Ok(t)) => return Ok(*t),
            Some(&Err(problem)) => {
                self.problems.used_by(problem, label);
                return Ok(None);
            }
            None => {}
        }
        let path = PathBuf::from(file.replace('\\', "/"));
        let result = match self.probe(&path, warnings) {
            Err(e) if !self.strict && is_texture_problem(&e) => {
                let problem = self.problems.add(format!("image {}", path.display()), &e);
                self.problems.used_by(problem, label);
                Err(problem)
            }
            other => Ok(other?),
        };
        self.cache.insert(file.to_owned(), result);
        Ok(result.unwrap_or(None))
    }

    /// Reads and probes the image at `path` (see [`Textures::texture`]).
    fn probe(&mut self, path: &Path, warnings: &mut Warnings) -> Result<Option<u32>, SceneError> {
        let bytes = (self.read)(path)?;
        let used: u64 = self.images.iter().map(|(_, header)| header.texels()).sum();
        let budget = MAX_SCENE_TEXELS.saturating_sub(used);
        if budget == 0 {
            return Err(SceneError::TooLarge(format!("the scene's textures have more than {MAX_SCENE_TEXELS} texels")));
        }
        Ok(match probe_srgb(&bytes, &path.display().to_string(), budget)? {
            Probed::Image(header) => {
                self.images.push((bytes, header));
                let image = self.images.len() - 1;
                self.textures.push(PendingTexture { image, wrap_s: Wrap::Repeat, wrap_t: Wrap::Repeat });
                Some(self.textures.len() as u32 - 1)
            }
            Probed::Unsupported(format) => {
                let key = format!("image format {format}");
                warnings.once(&key, || {
                    format!(
                        "image format {format} is not supported (PNG, JPEG and WebP are): textures using it are dropped"
                    )
                });
                None
            }
        })
    }
}
