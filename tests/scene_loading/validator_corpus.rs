//! The Khronos glTF-Validator corpus (`tests/data/gltf-validator-tests/`, 372 mostly invalid
//! files): every file loads or is refused with an error; none panics, none hangs. Files the
//! validator reports as error-free and that contain triangles must load.

use crate::common;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use tracer::scene::{self, SceneError};

fn corpus_dir() -> PathBuf {
    common::test_data("gltf-validator-tests")
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect(&path, out);
        } else if matches!(path.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
            out.push(path);
        }
    }
}

/// A number field of the validator's report beside the file (`"name": 12`), if present.
fn report_number(path: &Path, field: &str) -> Option<u64> {
    let mut report = path.as_os_str().to_owned();
    report.push(".report.json");
    let text = std::fs::read_to_string(report).ok()?;
    let key = format!("\"{field}\":");
    let start = text.find(&key)? + key.len();
    let digits: String = text[start..].trim_start().chars().take_while(|c| c.is_ascii_digit()).collect();
    digits.parse().ok()
}

#[test]
fn every_corpus_file_loads_or_is_refused_without_panicking() {
    let mut files = Vec::new();
    collect(&corpus_dir(), &mut files);
    files.sort();
    assert_eq!(files.len(), 372, "corpus not found or changed at {}", corpus_dir().display());

    let start = Instant::now();
    let (mut loaded, mut refused) = (Vec::new(), Vec::new());
    let mut panicked = Vec::new();
    let mut valid_but_refused = Vec::new();
    let mut slowest = (Duration::ZERO, PathBuf::new());
    for path in &files {
        let rel = path.strip_prefix(corpus_dir()).unwrap_or(path).display().to_string();
        let t0 = Instant::now();
        let result = catch_unwind(AssertUnwindSafe(|| scene::load(path)));
        let took = t0.elapsed();
        if took > slowest.0 {
            slowest = (took, path.clone());
        }
        let errors = report_number(path, "numErrors");
        let triangles = report_number(path, "totalTriangleCount");
        match result {
            Err(_) => panicked.push(rel),
            Ok(Ok(s)) => loaded.push((rel, s.triangles.len(), errors)),
            Ok(Err(e)) => {
                // A valid file may still hold nothing to render (meshes that no scene node
                // uses) or reference data it does not contain (a GLB-chunk buffer in a .gltf).
                let nothing_to_render = matches!(e, SceneError::NoTriangles(_));
                let data_absent = e.to_string().contains("no GLB binary chunk");
                if errors == Some(0) && triangles.unwrap_or(0) > 0 && !nothing_to_render && !data_absent {
                    valid_but_refused.push(format!("{rel}: {e}"));
                }
                refused.push(format!("{rel}: {e}"));
            }
        }
    }
    let total = start.elapsed();

    println!("refused:");
    for r in &refused {
        println!("  {r}");
    }
    println!("loaded:");
    for (rel, tris, errors) in &loaded {
        println!("  {rel}: {tris} triangles (validator errors: {})", errors.map_or("?".into(), |e| e.to_string()));
    }
    println!(
        "{} files: {} loaded, {} refused, {} panicked; {:.2?} in all, slowest {:.2?} ({})",
        files.len(),
        loaded.len(),
        refused.len(),
        panicked.len(),
        total,
        slowest.0,
        slowest.1.display()
    );
    assert!(panicked.is_empty(), "panicked on {} files: {panicked:#?}", panicked.len());
    assert!(valid_but_refused.is_empty(), "valid files refused: {valid_but_refused:#?}");
    assert!(slowest.0 < Duration::from_secs(5), "{} took {:?}", slowest.1.display(), slowest.0);
    assert!(total < Duration::from_secs(30), "the corpus took {total:?}");
}
