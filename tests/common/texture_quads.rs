//! Generated scenes for texture references (`KHR_texture_transform`, `TEXCOORD_1`): one
//! textured square under a far point light, its texture read through a transform and/or on
//! the second UV set, and the same square with the UVs those would give written into
//! `TEXCOORD_0` directly (no transform, set 0), which must render the same.

// Each test uses a different part of this module.
#![allow(dead_code)]

use glam::{Vec2, Vec3};
use tracer::scene::{Camera, Material, PointLight, Scene, Texture, Triangle, UvTransform, Wrap};

/// 8 x 8 texels, every one a different colour (so any misplaced lookup shows), repeating.
pub fn pattern_texture() -> Texture {
    let (w, h) = (8u32, 8u32);
    let texels: Vec<u32> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (r, g, b) = (20 + 30 * x, 20 + 30 * y, (37 * (x + 3 * y)) % 256);
            r | g << 8 | b << 16 | 0xff << 24
        })
        .collect();
    Texture { width: w, height: h, texels: texels.into(), wrap_s: Wrap::Repeat, wrap_t: Wrap::MirroredRepeat }
}

/// The square's corners (facing +Y, seen from above) and their UVs on `TEXCOORD_0`.
pub const CORNERS: [[f32; 3]; 4] = [[-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0], [-1.0, 0.0, -1.0]];
pub const UVS: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];

/// The square's two triangles, UV set 0 and 1 from `uv0` / `uv1` per corner.
pub fn square(uv0: impl Fn(usize) -> Vec2, uv1: impl Fn(usize) -> Vec2) -> Vec<Triangle> {
    [[0, 1, 2], [0, 2, 3]]
        .iter()
        .map(|&c: &[usize; 3]| Triangle {
            positions: c.map(|i| Vec3::from(CORNERS[i])),
            normals: [Vec3::Y; 3],
            uvs: c.map(&uv0),
            uvs1: c.map(&uv1),
            tangents: Default::default(),
            material: 0,
        })
        .collect()
}

/// The square with `material`'s textures all `pattern_texture`, lit by a far point light
/// and seen from straight above.
pub fn scene(triangles: Vec<Triangle>, material: Material) -> Scene {
    let scene = Scene {
        triangles,
        materials: vec![material],
        textures: vec![pattern_texture()],
        point_lights: vec![PointLight { position: Vec3::new(0.3, 20.0, 0.2), intensity: Vec3::splat(400.0) }],
        camera: Camera::look_at(Vec3::new(0.0, 4.0, 0.0), Vec3::ZERO, Vec3::NEG_Z, 0.45),
        ..Scene::default()
    };
    scene.validate().expect("valid scene");
    scene
}

/// A diffuse material with its base colour texture read through `uv`.
pub fn base_textured(uv: UvTransform) -> Material {
    let mut m = Material { base_color_texture: Some(0), ..Material::diffuse("base", Vec3::ONE) };
    m.texture_uvs[0] = uv;
    m
}

/// The transform of the tests: scale 2, an offset, a quarter turn.
pub fn quarter_turn() -> UvTransform {
    UvTransform {
        texcoord: 0,
        offset: Vec2::new(0.25, 0.375),
        rotation: std::f32::consts::FRAC_PI_2,
        scale: Vec2::new(2.0, 2.0),
    }
}

/// `quarter_turn` applied by hand, from the extension's example (rotation pi/2 maps
/// `(u, v)` to `(v, -u)` before the offset): written out here, not through `UvTransform`.
pub fn quarter_turn_by_hand(uv: Vec2) -> Vec2 {
    Vec2::new(2.0 * uv.y + 0.25, -2.0 * uv.x + 0.375)
}
