//! Load on `lightport serve` over loopback (what it measures: `lightport::load`).
//!
//! ```sh
//! cargo build --release && cargo run --release --example load -- [--clients 64] [--seconds 20] [--slow 16]
//! ```

use std::path::{Path, PathBuf};

use lightport::load::{print, run, Options};

fn main() -> anyhow::Result<()> {
    let mut options = Options {
        exe: Path::new(env!("CARGO_MANIFEST_DIR")).join("target/release/lightport"),
        clients: 64,
        seconds: 20.0,
        slow: 16,
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let value = pair.get(1).ok_or_else(|| anyhow::anyhow!("{} needs a value", pair[0]))?;
        match pair[0].as_str() {
            "--clients" => options.clients = value.parse()?,
            "--seconds" => options.seconds = value.parse()?,
            "--slow" => options.slow = value.parse()?,
            "--lightport" => options.exe = PathBuf::from(value),
            other => anyhow::bail!("unknown option {other} (--clients N --seconds S --slow N --lightport PATH)"),
        }
    }
    anyhow::ensure!(
        options.exe.is_file(),
        "{} is missing: cargo build --release (or --lightport PATH)",
        options.exe.display()
    );
    let report = run(&options)?;
    print(&report, &options);
    Ok(())
}
