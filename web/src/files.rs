//! Scenes dropped on the page: a `.glb`, or a `.gltf` with the files it references. There is no
//! file system in the browser, so each external URI of a `.gltf` (buffers, images) is replaced by
//! a `data:` URI of the dropped file it names, and the document goes through the loader's slice
//! API ([`tracer::scene::load_gltf_slice`]) unchanged: the browser loads, validates, builds the
//! BVH and packs exactly as the CLI does.

use base64::Engine;
use serde_json::Value;
use tracer::kernel::RenderSettings;
use tracer::pack::Packed;
use tracer::scene::{LoadOptions, Scene, SceneError};

/// One dropped file: its name (a relative path when a folder was dropped) and its bytes.
#[derive(Clone, Debug)]
pub struct DroppedFile {
    pub name: String,
    pub bytes: Vec<u8>,
}

/// Why dropped files cannot be rendered.
#[derive(Debug, thiserror::Error)]
pub enum DropError {
    #[error("no .glb or .gltf file among the dropped files ({0})")]
    NoScene(String),
    /// The browser build has no FBX parser (ufbx is C): the server converts FBX scenes.
    #[error(
        "{0}: FBX scenes are converted on the server side: run `lightport serve {0}` and pick it from the scene list"
    )]
    ServerSideFormat(String),
    #[error("drop one scene at a time: {0}")]
    SeveralScenes(String),
    #[error("{scene} references {uri:?}, which was not dropped with it (drop the .gltf together with its .bin and image files)")]
    MissingFile { scene: String, uri: String },
    #[error("{scene} is not valid glTF JSON: {message}")]
    Json { scene: String, message: String },
    #[error("{scene}: {source}")]
    Scene {
        scene: String,
        #[source]
        source: SceneError,
    },
    #[error("{scene}: building the BVH: {source}")]
    Bvh {
        scene: String,
        #[source]
        source: tracer::bvh::BvhError,
    },
    #[error("{scene}: packing: {source}")]
    Pack {
        scene: String,
        #[source]
        source: tracer::pack::PackError,
    },
}

fn extension(name: &str) -> String {
    name.rsplit_once('.').map(|(_, e)| e.to_ascii_lowercase()).unwrap_or_default()
}

fn base_name(path: &str) -> &str {
    path.rsplit(['/', '\\']).next().unwrap_or(path)
}

/// The dropped scene file: exactly one `.glb` or `.gltf`.
fn scene_file(files: &[DroppedFile]) -> Result<&DroppedFile, DropError> {
    let scenes: Vec<&DroppedFile> =
        files.iter().filter(|f| matches!(extension(&f.name).as_str(), "glb" | "gltf")).collect();
    match scenes.as_slice() {
        [one] => Ok(one),
        [] => {
            if let Some(fbx) = files.iter().find(|f| extension(&f.name) == "fbx") {
                return Err(DropError::ServerSideFormat(base_name(&fbx.name).to_owned()));
            }
            let names: Vec<&str> = files.iter().map(|f| f.name.as_str()).collect();
            Err(DropError::NoScene(if names.is_empty() { "nothing was dropped".into() } else { names.join(", ") }))
        }
        several => {
            Err(DropError::SeveralScenes(several.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(", ")))
        }
    }
}

/// The dropped file a glTF URI names: the same relative path (percent-decoded, without `./`),
/// else the same file name (files dropped without their folders).
fn find_file<'a>(files: &'a [DroppedFile], uri: &str) -> Option<&'a DroppedFile> {
    let decoded = percent_encoding::percent_decode_str(uri).decode_utf8_lossy();
    let wanted = decoded.trim_start_matches("./");
    files
        .iter()
        .find(|f| f.name == wanted || f.name.ends_with(&format!("/{wanted}")))
        .or_else(|| files.iter().find(|f| base_name(&f.name) == base_name(wanted)))
}

/// A `.gltf` document with every external buffer and image URI replaced by a data URI.
fn embed_external_files(scene: &DroppedFile, files: &[DroppedFile]) -> Result<Vec<u8>, DropError> {
    let json_error = |message: String| DropError::Json { scene: scene.name.clone(), message };
    let mut document: Value = serde_json::from_slice(&scene.bytes).map_err(|e| json_error(e.to_string()))?;
    for list in ["buffers", "images"] {
        let Some(entries) = document.get_mut(list).and_then(Value::as_array_mut) else { continue };
        for entry in entries {
            let Some(uri) = entry.get("uri").and_then(Value::as_str) else { continue };
            if uri.starts_with("data:") {
                continue;
            }
            let file = find_file(files, uri)
                .ok_or_else(|| DropError::MissingFile { scene: scene.name.clone(), uri: uri.to_owned() })?;
            let mime = match extension(&file.name).as_str() {
                "png" => "image/png",
                "jpg" | "jpeg" => "image/jpeg",
                _ => "application/octet-stream",
            };
            let data = base64::engine::general_purpose::STANDARD.encode(&file.bytes);
            entry["uri"] = Value::String(format!("data:{mime};base64,{data}"));
        }
    }
    serde_json::to_vec(&document).map_err(|e| json_error(e.to_string()))
}

/// Loads the scene among `files` (a `.glb`, or a `.gltf` and what it references).
/// Returns the scene file's name and the scene.
pub fn load_dropped(files: &[DroppedFile]) -> Result<(String, Scene), DropError> {
    let file = scene_file(files)?;
    let bytes = if extension(&file.name) == "gltf" {
        std::borrow::Cow::Owned(embed_external_files(file, files)?)
    } else {
        std::borrow::Cow::Borrowed(file.bytes.as_slice())
    };
    // An animated scene keeps its motion: the page plays it (`crate::playback`).
    let options = LoadOptions { keep_motion: true, ..Default::default() };
    let scene = tracer::scene::load_gltf_slice(&bytes, None, &options)
        .map_err(|source| DropError::Scene { scene: file.name.clone(), source })?;
    Ok((file.name.clone(), scene))
}

/// BVH build and packing, as for a served bundle.
pub fn prepare(name: &str, scene: &Scene, settings: &RenderSettings) -> Result<Packed, DropError> {
    let bvh = tracer::pack::static_bvh(scene).map_err(|source| DropError::Bvh { scene: name.into(), source })?;
    tracer::pack::pack(scene, &bvh, settings).map_err(|source| DropError::Pack { scene: name.into(), source })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// A scene vendored for the tests (`tests/data/scenes/`, each with its licence).
    fn test_scene(path: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/scenes").join(path)
    }

    fn dropped(path: &str, name: &str) -> DroppedFile {
        let bytes = std::fs::read(test_scene(path)).unwrap_or_else(|e| panic!("{path}: {e}"));
        DroppedFile { name: name.into(), bytes }
    }

    /// A `.gltf` with an external `.bin` and a PNG loads from memory as from disk.
    #[test]
    fn a_gltf_with_its_files_loads_like_the_file_on_disk() {
        let dir = "khronos/BoxTextured/glTF";
        let files = vec![
            dropped(&format!("{dir}/BoxTextured.gltf"), "BoxTextured.gltf"),
            dropped(&format!("{dir}/BoxTextured0.bin"), "BoxTextured0.bin"),
            dropped(&format!("{dir}/CesiumLogoFlat.png"), "textures/CesiumLogoFlat.png"),
        ];
        let (name, scene) = load_dropped(&files).expect("loads");
        let on_disk = tracer::scene::load(&test_scene(&format!("{dir}/BoxTextured.gltf"))).expect("on disk");
        assert_eq!(name, "BoxTextured.gltf");
        assert_eq!(scene.triangles, on_disk.triangles);
        assert_eq!(scene.textures, on_disk.textures);
        assert_eq!(scene.textures.len(), 1);
        prepare(&name, &scene, &RenderSettings::default()).expect("packs");
    }

    #[test]
    fn a_glb_loads() {
        let files = vec![dropped("khronos/Box/glTF-Binary/Box.glb", "Box.glb")];
        let (_, scene) = load_dropped(&files).expect("loads");
        assert_eq!(scene.triangles.len(), 12);
    }

    #[test]
    fn missing_and_wrong_files_are_clear_errors() {
        let dir = "khronos/BoxTextured/glTF";
        let gltf = dropped(&format!("{dir}/BoxTextured.gltf"), "BoxTextured.gltf");
        let err = load_dropped(std::slice::from_ref(&gltf)).expect_err("no .bin");
        assert!(matches!(&err, DropError::MissingFile { uri, .. } if uri == "BoxTextured0.bin"), "{err}");

        let png = dropped(&format!("{dir}/CesiumLogoFlat.png"), "CesiumLogoFlat.png");
        let err = load_dropped(std::slice::from_ref(&png)).expect_err("no scene");
        assert!(err.to_string().contains("CesiumLogoFlat.png"), "{err}");
        let err = load_dropped(&[gltf.clone(), gltf]).expect_err("two scenes");
        assert!(matches!(err, DropError::SeveralScenes(_)), "{err}");

        let fbx = DroppedFile { name: "models/scene.fbx".into(), bytes: b"Kaydara FBX Binary  \0".to_vec() };
        let err = load_dropped(&[fbx]).expect_err("FBX is converted by the server");
        assert!(err.to_string().contains("lightport serve scene.fbx"), "{err}");

        let garbage = DroppedFile { name: "broken.glb".into(), bytes: b"glTF\x02\0\0\0garbage".to_vec() };
        let err = load_dropped(&[garbage]).expect_err("not glTF");
        assert!(matches!(err, DropError::Scene { .. }), "{err}");
        let garbage = DroppedFile { name: "broken.gltf".into(), bytes: b"{ not json".to_vec() };
        assert!(matches!(load_dropped(&[garbage]), Err(DropError::Json { .. })));
    }
}
