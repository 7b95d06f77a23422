//! Embeds the web page into the `lightport` binary, so that `serve` and `export` work from an
//! installed binary (`cargo install --path .`) far from this repository: every file of `web/www/`
//! (served at `/`) and of `web/pkg/` (the wasm build, at `/pkg/`), if `scripts/build-web.sh` has
//! built it, as `include_bytes!` in `$OUT_DIR/embedded_web.rs`. Without `web/pkg/` the binary
//! carries the page without its wasm, and says so (a cargo warning now; `serve`/`export` at run
//! time name the commands to run). Same file rules as `--web DIR` (src/site.rs).

use std::path::{Path, PathBuf};

fn collect(dir: &Path, route: &str, out: &mut Vec<(String, PathBuf)>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let mut entries: Vec<_> = entries.filter_map(Result::ok).collect();
    entries.sort_by_key(|e| e.file_name());
    for entry in entries {
        let name = entry.file_name().to_string_lossy().to_string();
        let safe = !name.starts_with('.') && name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
        let Ok(kind) = entry.file_type() else { continue };
        if !safe || kind.is_symlink() {
            continue;
        }
        if kind.is_dir() {
            collect(&entry.path(), &format!("{route}{name}/"), out);
        } else if kind.is_file() {
            out.push((format!("{route}{name}"), entry.path()));
        }
    }
}

fn main() {
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("web");
    // A directory is scanned whole for changes; a missing one would rerun this at every build,
    // so without web/pkg/ watch web/ (where build-web.sh creates it).
    for dir in [web.join("www"), web.join("pkg")] {
        let watched = if dir.is_dir() { dir } else { web.clone() };
        println!("cargo:rerun-if-changed={}", watched.display());
    }
    let mut files = Vec::new();
    collect(&web.join("www"), "/", &mut files);
    collect(&web.join("pkg"), "/pkg/", &mut files);
    let has_wasm = files.iter().any(|(route, _)| route == "/pkg/lightport_web_bg.wasm");
    if !has_wasm {
        println!(
            "cargo:warning=web/pkg/ is not built: this lightport binary carries the page without its wasm. Run `bash scripts/build-web.sh`, then build lightport again"
        );
    }
    let mut code = String::from(
        "/// The page's files built into the binary: (route, bytes).\npub static FILES: &[(&str, &[u8])] = &[\n",
    );
    for (route, path) in &files {
        code.push_str(&format!("    ({route:?}, include_bytes!({:?})),\n", path.display().to_string()));
    }
    code.push_str("];\n");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR")).join("embedded_web.rs");
    std::fs::write(out, code).expect("writing embedded_web.rs");
}
