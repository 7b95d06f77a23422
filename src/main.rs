//! The `lightport` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "lightport", version, about = "One path-tracing kernel for CPU, native GL, WebGL2 and WGSL")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Regenerate the GLSL ES 3.00 and WGSL of every kernel module into shaders-generated/
    /// (each file validated first) and print them.
    Shaders {
        /// Do not write: exit non-zero and print a diff when the committed files are stale.
        #[arg(long)]
        check: bool,
        /// Output directory.
        #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/shaders-generated"))]
        dir: PathBuf,
        /// Do not print the generated code.
        #[arg(long, short)]
        quiet: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Shaders { check, dir, quiet } => shaders(&dir, check, quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn shaders(dir: &Path, check: bool, quiet: bool) -> Result<()> {
    let files = tracer::kernel::generated_shaders()?;
    if check {
        let mut stale = Vec::new();
        for f in &files {
            let path = dir.join(&f.name);
            let committed = std::fs::read_to_string(&path).unwrap_or_default();
            if committed != f.source {
                let diff = similar::TextDiff::from_lines(&committed, &f.source);
                println!(
                    "{}",
                    diff.unified_diff().header(&format!("committed {}", f.name), &format!("generated {}", f.name))
                );
                stale.push(f.name.clone());
            }
        }
        let expected: Vec<&str> = files.iter().map(|f| f.name.as_str()).collect();
        for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
            let name = entry?.file_name().to_string_lossy().to_string();
            if (name.ends_with(".glsl") || name.ends_with(".wgsl")) && !expected.contains(&name.as_str()) {
                println!("{name}: no kernel module generates it any more");
                stale.push(name);
            }
        }
        if !stale.is_empty() {
            bail!(
                "shaders-generated/ is stale ({}): run `cargo run -- shaders` and commit the result",
                stale.join(", ")
            );
        }
        println!("shaders-generated/ is up to date ({} files)", files.len());
        return Ok(());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        let ext = path.extension().and_then(|e| e.to_str());
        if matches!(ext, Some("glsl" | "wgsl")) && !files.iter().any(|f| path.ends_with(&f.name)) {
            std::fs::remove_file(&path).with_context(|| format!("removing stale {}", path.display()))?;
        }
    }
    for f in &files {
        let path = dir.join(&f.name);
        std::fs::write(&path, &f.source).with_context(|| format!("writing {}", path.display()))?;
        if !quiet {
            println!("// ===== shaders-generated/{} =====\n{}", f.name, f.source);
        }
    }
    eprintln!("wrote {} validated files to {}", files.len(), dir.display());
    Ok(())
}
