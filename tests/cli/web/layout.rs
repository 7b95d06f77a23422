//! The page sized by its window, as a person opens it (the `layout` scenario of
//! `tests/web/layout.mjs`): the read-outs below the image change their text as it converges,
//! and the render size must not follow them back and forth.

use super::{browse, common, no_page_error, Server};

/// DamagedHelmet in the default 900x700 window, every setting the page's own: once its first
/// frame shows, the render size settles (the footer's lines may grow a couple of times, never
/// shrink back) and the accumulation goes on. Before the footer held its height, on WebGPU the
/// size went 450x200, 450x213, 450x200, ... for as long as one watched, each change a restart:
/// 11 restarts in 12 s and never more than 2 samples per pixel.
#[test]
fn the_image_converges_in_a_page_sized_by_its_window() {
    let helmet = common::test_data("scenes/khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
    let server = Server::start(&[&helmet.to_string_lossy()]);
    for api in ["webgl2", "webgpu"] {
        let report = browse(&server.url, "layout", &[("scene", "DamagedHelmet"), ("api", api), ("seconds", "12")]);
        no_page_error(&report);
        let sizes = report["sizes"].as_array().expect("the sizes seen");
        assert!(sizes.len() <= 3, "{api}: the render size settles after the first frame: {sizes:?}");
        let restarts = report["restarts"].as_u64().expect("restarts");
        assert!(restarts <= 2, "{api}: the accumulation restarted {restarts} times with nothing touched: {report}");
        let spp = report["spp"].as_u64().expect("spp");
        assert!(spp >= 3, "{api}: the accumulation goes on ({spp} spp after 12 s): {report}");
    }
}
