//! Where a kernel module's source is, as generated shaders and errors name it.

use std::path::Path;

/// The source file as `<package>/<path in the package>` (`lightport-tracer/src/kernel/rng.rs`),
/// so generated shaders and errors name it the same on every machine and in every checkout:
/// rustc names the file relative to the workspace root for a workspace member but by its
/// absolute build path for a dependency. Falls back to rustc's name when Cargo's variables are
/// absent (a build outside Cargo) or the file lies outside the package (an `include!`).
pub(crate) fn crate_relative(rustc_name: &str) -> String {
    let package = std::env::var("CARGO_PKG_NAME").ok();
    let manifest_dir = std::env::var("CARGO_MANIFEST_DIR").ok();
    let cwd = std::env::current_dir().ok();
    match (package, manifest_dir) {
        (Some(package), Some(dir)) => source_tag(rustc_name, &package, Path::new(&dir), cwd.as_deref()),
        _ => rustc_name.replace('\\', "/"),
    }
}

/// [`crate_relative`] without the environment: a relative `rustc_name` is relative to `cwd`,
/// rustc's working directory (which Cargo chooses differently for members and dependencies).
fn source_tag(rustc_name: &str, package: &str, manifest_dir: &Path, cwd: Option<&Path>) -> String {
    let named = Path::new(rustc_name);
    let absolute = match cwd {
        Some(cwd) if named.is_relative() => cwd.join(named),
        _ => named.to_path_buf(),
    };
    let inside = absolute.strip_prefix(manifest_dir).map(Path::to_path_buf).or_else(|_| {
        // Symlinked checkouts: compare the resolved paths.
        let (file, dir) = (absolute.canonicalize().map_err(drop)?, manifest_dir.canonicalize().map_err(drop)?);
        file.strip_prefix(dir).map(Path::to_path_buf).map_err(drop)
    });
    match inside {
        Ok(path) => {
            let parts: Vec<String> = path.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
            format!("{package}/{}", parts.join("/"))
        }
        Err(()) => rustc_name.replace('\\', "/"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_workspace_member_is_named_from_its_package() {
        // rustc runs in the workspace root and names a member's file relative to it.
        let tag =
            source_tag("tracer/src/kernel/rng.rs", "lightport-tracer", Path::new("/w/tracer"), Some(Path::new("/w")));
        assert_eq!(tag, "lightport-tracer/src/kernel/rng.rs");
    }

    #[test]
    fn a_dependency_is_named_without_its_build_path() {
        // A path or registry dependency is named by its absolute path, different on every machine.
        let tag = source_tag(
            "/home/someone/checkouts/lightport/tracer/src/kernel/rng.rs",
            "lightport-tracer",
            Path::new("/home/someone/checkouts/lightport/tracer"),
            Some(Path::new("/home/someone/my-crate")),
        );
        assert_eq!(tag, "lightport-tracer/src/kernel/rng.rs");
    }

    #[test]
    fn a_file_outside_the_package_keeps_rustc_name() {
        let tag = source_tag("/elsewhere/generated.rs", "mine", Path::new("/w/mine"), Some(Path::new("/w")));
        assert_eq!(tag, "/elsewhere/generated.rs");
    }

    #[test]
    fn the_expanding_crate_names_its_own_files() {
        // This test runs with Cargo's variables for this package, as the macro does.
        let own = concat!(env!("CARGO_MANIFEST_DIR"), "/src/source_tag.rs");
        assert_eq!(crate_relative(own), format!("{}/src/source_tag.rs", env!("CARGO_PKG_NAME")));
    }
}
