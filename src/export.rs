//! `lightport export SCENE... --out DIR`: the site `lightport serve` answers, as files that any
//! static host or CDN serves as they are: the page (`index.html`, its scripts), its wasm build
//! (`pkg/`), `scenes.json` and one `bundles/<sha256>.lpb` per scene. The same table as the server's
//! ([`crate::site::Site`]), written out: one route, one file. With `--precompress`, each file
//! that compresses gets `.gz` and `.br` siblings for hosts that serve precompressed files
//! (nginx `gzip_static`, `brotli_static`; object stores with `Content-Encoding` metadata). The
//! headers a host should send are in docs/deploy.md.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};

use crate::site::{Site, SiteArgs};

#[derive(clap::Args)]
pub struct ExportArgs {
    #[command(flatten)]
    site: SiteArgs,
    /// Directory to write the site to (created; it must be empty if it exists).
    #[arg(long)]
    out: PathBuf,
    /// Also write `.gz` and `.br` beside each file that compresses (for hosts that serve
    /// precompressed files).
    #[arg(long)]
    precompress: bool,
}

pub fn export(args: &ExportArgs) -> Result<()> {
    if args.out.exists() {
        let mut entries = std::fs::read_dir(&args.out)
            .with_context(|| format!("--out {} exists and is not a readable directory", args.out.display()))?;
        if entries.next().is_some() {
            bail!("--out {} is not empty: export into a new or empty directory", args.out.display());
        }
    }
    let site = Site::build(&args.site)?;
    site.print_reports();
    for required in ["/index.html", "/pkg/lightport_web_bg.wasm", "/pkg/lightport_web.js"] {
        if !site.routes.contains_key(required) {
            match &args.site.web {
                Some(dir) => bail!(
                    "the page is incomplete: {required} is missing under --web {} (run `bash scripts/build-web.sh`, which builds web/pkg)",
                    dir.display()
                ),
                None => bail!(
                    "the page is incomplete: {required} is missing from the page built into this binary: run `bash scripts/build-web.sh`, then rebuild lightport (`cargo build`, or `cargo install --path .`)"
                ),
            }
        }
    }
    let t0 = Instant::now();
    let (mut files, mut bytes) = (0usize, 0u64);
    for (route, resource) in &site.routes {
        // `/` is `/index.html` again: a static host answers it with the index file.
        let Some(relative) = route.strip_prefix('/').filter(|r| !r.is_empty()) else { continue };
        let path = args.out.join(relative);
        write(&path, &resource.identity)?;
        (files, bytes) = (files + 1, bytes + resource.identity.len() as u64);
        if args.precompress {
            if let Some(gzip) = &resource.gzip {
                write(&with_suffix(&path, "gz"), gzip)?;
                let br = brotli(&resource.identity)?;
                // Only where it helps; a host falls back to the plain file.
                if br.len() < resource.identity.len() {
                    write(&with_suffix(&path, "br"), &br)?;
                }
                (files, bytes) = (files + 2, bytes + gzip.len() as u64 + br.len() as u64);
            }
        }
    }
    println!(
        "exported {} scene(s) to {}: {files} files, {bytes} bytes ({:.1} s writing{})",
        site.reports.len(),
        args.out.display(),
        t0.elapsed().as_secs_f64(),
        if args.precompress { " and compressing" } else { "" }
    );
    Ok(())
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".");
    name.push(suffix);
    PathBuf::from(name)
}

/// Brotli at quality 9 (of 11), a 4 MiB window: near the best ratio at a few MB/s; 10 and 11
/// are many times slower for a few percent.
fn brotli(bytes: &[u8]) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(bytes.len() / 3);
    {
        let mut writer = brotli::CompressorWriter::new(&mut out, 1 << 16, 9, 22);
        writer.write_all(bytes)?;
        writer.flush()?;
    }
    Ok(out)
}
