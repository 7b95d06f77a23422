//! The fuzzers' findings, each refused with a clear error now (the inputs are in
//! `fuzz/regressions/`, which the smoke run and every fuzzing run also replay).

use std::path::Path;

use lightport_fuzz::{seeds, Target};
use tracer::scene::{self, LoadOptions, SceneError};

fn regression(target: Target, name: &str) -> Vec<u8> {
    std::fs::read(seeds::regressions_dir(target).join(name)).expect("the committed regression input")
}

/// A committed bundle carries the fingerprint of the kernel it was written by; every kernel
/// change alters it. The input is replayed against this build's kernel by rewriting that field
/// (the rest of the bundle, the finding itself, is unchanged).
fn for_this_kernel(mut bytes: Vec<u8>) -> Vec<u8> {
    if let Err(tracer::bundle::BundleError::OtherKernel { found, expected }) = tracer::bundle::decode(&bytes) {
        if let Some(i) = bytes.windows(4).position(|w| w == found.to_le_bytes()) {
            bytes[i..i + 4].copy_from_slice(&expected.to_le_bytes());
        }
    }
    bytes
}

/// A bundle whose `scene_scale` is NaN decoded, and the kernel then never finished a frame
/// (the CPU renderer hung; the page would have hung the GPU).
#[test]
fn a_bundle_with_a_nan_uniform_is_refused() {
    let input = for_this_kernel(regression(Target::Bundle, "nan-scene-scale-hang.lpb"));
    let err = tracer::bundle::decode(&input).unwrap_err();
    assert!(err.to_string().contains("scene_scale is NaN"), "{err}");
}

/// `Kd 0.5 0` in an MTL made tobj panic (caught, but reported as "the OBJ parser failed
/// unexpectedly"); now the line is named.
#[test]
fn an_mtl_colour_with_two_values_is_refused_with_its_line() {
    let input = regression(Target::Obj, "kd-two-values-panic.obj");
    let text = String::from_utf8(input).unwrap();
    let (obj, mtl) = text.split_once("#---mtl---\n").unwrap();
    let read = |p: &Path| -> Result<Vec<u8>, SceneError> {
        match p.to_str() {
            Some("a.mtl") => Ok(mtl.as_bytes().to_vec()),
            _ => Err(SceneError::Io { path: p.to_owned(), source: std::io::ErrorKind::NotFound.into() }),
        }
    };
    let err = scene::load_obj_slice(obj.as_bytes(), "kd.obj", &read, &LoadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("line 2: Kd needs three values (r g b), found 2"), "{err}");
}
