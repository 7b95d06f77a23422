//! The `lightport render` command line: forgiving loading, `--strict`, and the warning for a
//! scene that nothing lights.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::test_data;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightport-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `lightport render SCENE ARGS` at a tiny size, writing into `dir`; `scene` relative to
/// `tests/data/scenes/`.
fn render(scene: &str, args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightport"))
        .arg("render")
        .arg(test_data(&format!("scenes/{scene}")))
        .args(["--width", "8", "--height", "8", "--spp", "1", "--out"])
        .arg(dir.join("out.png"))
        .args(args)
        .output()
        .expect("run lightport")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_missing_texture_is_a_warning_and_strict_refuses_it() {
    let dir = scratch("missing-texture");
    // Two textured boxes; the second one's base colour image is not there.
    let scene = "missing-texture/MissingTexture.gltf";
    let lenient = render(scene, &[], &dir);
    let err = stderr(&lenient);
    assert!(lenient.status.success(), "{err}");
    let warned: Vec<&str> = err.lines().filter(|l| l.contains("Label_baseColor.png")).collect();
    assert!(warned.len() == 1 && warned[0].starts_with("warning: "), "{err}");
    assert!(dir.join("out.png").is_file());
    std::fs::remove_file(dir.join("out.png")).unwrap();

    let strict = render(scene, &["--strict"], &dir);
    let err = stderr(&strict);
    assert!(!strict.status.success(), "{err}");
    assert!(err.starts_with("error: ") && err.contains("Label_baseColor.png"), "{err}");
    assert!(!dir.join("out.png").exists(), "an image was written anyway");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn an_unlit_scene_is_warned_about_and_a_sky_lights_it() {
    let dir = scratch("unlit");
    // Khronos' Box: one material, which does not emit, and no sky.
    let unlit = "khronos/Box/glTF-Binary/Box.glb";
    let dark = render(unlit, &[], &dir);
    let err = stderr(&dark);
    assert!(dark.status.success(), "{err}");
    assert!(err.contains("warning: nothing lights the scene") && err.contains("--sky"), "{err}");
    let strict = render(unlit, &["--strict"], &dir);
    assert!(!strict.status.success() && stderr(&strict).contains("nothing lights the scene"), "{}", stderr(&strict));

    let sky = test_data("scenes/hdri/venice_sunset_1k.hdr");
    let lit = render(unlit, &["--strict", "--sky", sky.to_str().unwrap()], &dir);
    assert!(lit.status.success(), "{}", stderr(&lit));
    assert!(!stderr(&lit).contains("warning"), "{}", stderr(&lit));
    // The built-in Cornell box has its light.
    let cornell = Command::new(env!("CARGO_BIN_EXE_lightport"))
        .args(["render", "--strict", "--width", "8", "--height", "8", "--spp", "1", "--out"])
        .arg(dir.join("cornell.png"))
        .output()
        .unwrap();
    assert!(cornell.status.success() && !stderr(&cornell).contains("warning"), "{}", stderr(&cornell));
    std::fs::remove_dir_all(dir).ok();
}
