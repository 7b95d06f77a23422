//! The page in headless Chromium: one scenario of `tests/web/run.mjs` (node + npm
//! `playwright-core`, Debian's `/usr/bin/chromium`), its JSON report back. Shared by
//! tests/cli/web.rs (`lightport serve`) and tests/cli/export.rs (an export behind nginx).

use std::path::Path;
use std::process::Command;
use std::sync::Mutex;

use serde_json::Value;

/// One browser at a time: Chromium on SwiftShader takes the machine's cores.
static BROWSER: Mutex<()> = Mutex::new(());

/// Runs `scenario` against the page at `url`; never skipped: a missing driver or browser fails
/// with the command that installs it.
pub fn browse(url: &str, scenario: &str, options: &[(&str, &str)]) -> Value {
    let web_tests = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web");
    assert!(
        web_tests.join("node_modules/playwright-core").is_dir(),
        "tests/web/node_modules is missing: run `npm ci` in tests/web (scripts/test.sh does)"
    );
    assert!(Path::new("/usr/bin/chromium").is_file(), "Chromium is missing: apt-get install chromium");
    let out = std::env::temp_dir().join(format!("lightport-web-{scenario}-{}.json", std::process::id()));
    let _guard = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let mut command = Command::new("node");
    command.current_dir(&web_tests).arg("run.mjs").arg(scenario).args(["--url", url]);
    command.arg("--out").arg(&out).arg("--exit-on-stdin-eof");
    for (k, v) in options {
        command.arg(format!("--{k}")).arg(v);
    }
    let status = lightport::serve_child::run_tied(&mut command).expect("node runs (apt-get install nodejs npm)");
    assert!(status.success(), "tests/web/run.mjs {scenario} failed ({status}); see its output above");
    let text = std::fs::read_to_string(&out).expect("the scenario's report");
    let _ = std::fs::remove_file(&out);
    serde_json::from_str(&text).expect("a JSON report")
}

pub fn no_page_error(report: &Value) {
    assert!(report["error"].is_null(), "the page reported an error: {}", report["error"]);
}
