//! Memory is bounded by what a file backs: inputs that declare huge sizes (a 4 GiB buffer, a
//! 2^32-element accessor, an 8192 x 8192 image or sky in a few bytes, a bundle array of 2^40 elements)
//! are refused before anything that size is allocated. A counting allocator records the
//! largest single allocation and the peak of live bytes while each input loads.
//!
//! One test runs the cases one after another: the allocator's counters are process-wide.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use lightport_fuzz::glb;
use tracer::scene::{self, LoadOptions, SceneError};

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
        PEAK.fetch_max(live, Ordering::Relaxed);
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        System.alloc(layout)
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        System.dealloc(ptr, layout)
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The most any of these inputs may make the loader allocate: 16 MiB.
const BOUND: usize = 16 << 20;

/// Runs `load`, returning its error and the largest allocation and the peak growth of live
/// bytes during it.
fn measured<T>(load: impl FnOnce() -> Result<T, String>) -> (Option<String>, usize, usize) {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    LARGEST.store(0, Ordering::Relaxed);
    let error = load().err();
    (error, LARGEST.load(Ordering::Relaxed), PEAK.load(Ordering::Relaxed).saturating_sub(base))
}

fn gltf(bytes: &[u8]) -> Result<(), String> {
    scene::load_gltf_slice(bytes, None, &LoadOptions::default()).map(drop).map_err(|e| e.to_string())
}

/// A glTF whose one texture is refused: a forgiving load drops the image with a warning and
/// renders the material with its factors, so the refusal is seen as the error of a strict load
/// (the allocation bound applies either way).
fn gltf_texture(bytes: &[u8]) -> Result<(), String> {
    scene::load_gltf_slice(bytes, None, &LoadOptions { strict: true, ..Default::default() })
        .map(drop)
        .map_err(|e| e.to_string())
}

/// A triangle whose POSITION accessor has `count` elements in a buffer of `byte_length` bytes
/// given by a 36-byte data URI.
fn triangle_gltf(count: u64, byte_length: u64) -> Vec<u8> {
    let data = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"; // 36 bytes: 3 x VEC3
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{count},"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
"bufferViews":[{{"buffer":0,"byteLength":{byte_length}}}],
"buffers":[{{"byteLength":{byte_length},"uri":"data:application/octet-stream;base64,{data}"}}]}}"#
    )
    .into_bytes()
}

/// A PNG signature and IHDR chunk for a `width` x `height` RGBA8 image, then an IDAT of a few
/// bytes and IEND: a valid header whose pixels are not there.
fn png_header_only(width: u32, height: u32) -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let start = png.len();
        png.extend_from_slice(kind);
        png.extend_from_slice(data);
        let crc = crc32(&png[start..]);
        png.extend_from_slice(&crc.to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
    chunk(b"IEND", &[]);
    png
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

/// A baseline JPEG header (SOI, DQT, SOF0 for `width` x `height` grey, DHT, SOS) and EOI,
/// with no scan data.
fn jpeg_header_only(width: u16, height: u16) -> Vec<u8> {
    let mut j = vec![0xFF, 0xD8];
    j.extend_from_slice(&[0xFF, 0xDB, 0x00, 0x43, 0x00]);
    j.extend(std::iter::repeat_n(1u8, 64));
    j.extend_from_slice(&[0xFF, 0xC0, 0x00, 0x0B, 0x08]);
    j.extend_from_slice(&height.to_be_bytes());
    j.extend_from_slice(&width.to_be_bytes());
    j.extend_from_slice(&[0x01, 0x01, 0x11, 0x00]);
    // DC table 0 and AC table 0, one 1-bit code each.
    for class in [0x00u8, 0x10] {
        j.extend_from_slice(&[0xFF, 0xC4, 0x00, 0x14, class, 1]);
        j.extend(std::iter::repeat_n(0u8, 15));
        j.push(0);
    }
    j.extend_from_slice(&[0xFF, 0xDA, 0x00, 0x08, 0x01, 0x01, 0x00, 0x00, 0x3F, 0x00]);
    j.extend_from_slice(&[0x00, 0xFF, 0xD9]);
    j
}

fn bundle_with_count(count: u64) -> Vec<u8> {
    // A real bundle with its first entry's element count replaced.
    let packed = tracer::pack::build_and_pack(
        &scene::cornell_box(),
        &tracer::kernel::RenderSettings { width: 4, height: 4, ..Default::default() },
    )
    .expect("pack")
    .1;
    let mut bytes = tracer::bundle::encode(&packed);
    let name_len = bytes[24] as usize;
    let count_at = 24 + 1 + name_len + 4;
    bytes[count_at..count_at + 8].copy_from_slice(&count.to_le_bytes());
    bytes
}

/// One refusal check: loads a crafted input, `Err` says what went wrong.
type LoadCase = dyn Fn() -> Result<(), String>;

fn sky(bytes: &[u8], format: scene::SkyFormat) -> Result<(), String> {
    scene::load_sky_slice(bytes, format, "sky", 1.0, 0.0).map(drop).map_err(|e| e.to_string())
}

/// A Radiance HDR header declaring `width` x `height` texels, then one run-length scanline
/// start: a valid header whose pixels are not there.
fn hdr_header_only(width: u32, height: u32) -> Vec<u8> {
    let mut hdr = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n").into_bytes();
    hdr.extend_from_slice(&[2, 2, (width >> 8) as u8, width as u8, 0x81, 0x80, 0x81, 0x80]);
    hdr
}

/// A 4 x 4 RGB OpenEXR whose data and display windows are rewritten to `size` x `size`.
fn exr_header_only(size: i32) -> Vec<u8> {
    let image = image::Rgb32FImage::from_pixel(4, 4, image::Rgb([1.0, 0.5, 0.25]));
    let mut out = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb32F(image).write_to(&mut out, image::ImageFormat::OpenExr).expect("encode an EXR");
    let mut exr = out.into_inner();
    for attribute in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
        let at =
            exr.windows(attribute.len()).position(|w| w == attribute).expect("the window attribute") + attribute.len();
        // size (4 bytes), then xMin, yMin, xMax, yMax.
        exr[at + 12..at + 16].copy_from_slice(&(size - 1).to_le_bytes());
        exr[at + 16..at + 20].copy_from_slice(&(size - 1).to_le_bytes());
    }
    exr
}

#[test]
fn inputs_declaring_huge_sizes_are_refused_before_allocating_them() {
    let four_gib = 4u64 << 30;
    let mut glb_huge_chunk = glb::build(b"{\"asset\":{\"version\":\"2.0\"}}", None);
    glb_huge_chunk[12..16].copy_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
    let mut glb_huge_total = glb::build(b"{}", None);
    glb_huge_total[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    let huge_bundle_array = bundle_with_count(1 << 40);
    let huge_bundle_total = {
        let mut b = bundle_with_count(1);
        b[16..24].copy_from_slice(&four_gib.to_le_bytes());
        b
    };
    let cases: Vec<(&str, Box<LoadCase>)> = vec![
        ("a 4 GiB buffer backed by 36 bytes", Box::new(move || gltf(&triangle_gltf(3, four_gib)))),
        ("a 2^32-element accessor", Box::new(|| gltf(&triangle_gltf(u32::MAX as u64 + 1, 36)))),
        ("a 2^26-element accessor in 36 bytes", Box::new(|| gltf(&triangle_gltf(1 << 26, 36)))),
        ("a GLB whose JSON chunk declares 4 GiB", Box::new(move || gltf(&glb_huge_chunk))),
        ("a GLB whose header declares 4 GiB", Box::new(move || gltf(&glb_huge_total))),
        (
            "an 8192 x 8192 PNG header without pixels",
            Box::new(|| gltf_texture(&glb::textured_quad(&png_header_only(8192, 8192)))),
        ),
        ("a 65535 x 65535 PNG header", Box::new(|| gltf_texture(&glb::textured_quad(&png_header_only(65535, 65535))))),
        (
            "an 8192 x 8192 JPEG header without pixels",
            Box::new(|| gltf_texture(&glb::textured_quad(&jpeg_header_only(8192, 8192)))),
        ),
        (
            "a bundle array of 2^40 elements",
            Box::new(move || tracer::bundle::decode(&huge_bundle_array).map(drop).map_err(|e| e.to_string())),
        ),
        (
            "a bundle declaring 4 GiB",
            Box::new(move || tracer::bundle::decode(&huge_bundle_total).map(drop).map_err(|e| e.to_string())),
        ),
        (
            "an 8192 x 8192 HDR sky header without pixels",
            Box::new(|| sky(&hdr_header_only(8192, 8192), scene::SkyFormat::Hdr)),
        ),
        (
            "an 8192 x 8192 EXR sky header without pixels",
            Box::new(|| sky(&exr_header_only(8192), scene::SkyFormat::Exr)),
        ),
        (
            "an OBJ face with vertex index 2^32 - 1",
            Box::new(|| {
                let read = |p: &std::path::Path| -> Result<Vec<u8>, SceneError> {
                    Err(SceneError::Io { path: p.to_owned(), error: std::io::ErrorKind::NotFound.into() })
                };
                scene::load_obj_slice(
                    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4294967295\n",
                    "big.obj",
                    &read,
                    &LoadOptions::default(),
                )
                .map(drop)
                .map_err(|e| e.to_string())
            }),
        ),
    ];
    let mut problems = Vec::new();
    for (what, load) in &cases {
        let (error, largest, peak) = measured(load);
        eprintln!("{what}: largest allocation {largest} bytes, peak {peak} bytes: {error:?}");
        match error {
            None => problems.push(format!("{what}: loaded")),
            Some(_) if largest > BOUND || peak > BOUND => {
                problems.push(format!("{what}: refused, but allocated {largest} bytes at once ({peak} bytes live)"))
            }
            Some(_) => {}
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
