//! Scenes generated in code: the embedded Cornell box, small analytic test scenes and a large
//! benchmark scene.

use glam::{Vec2, Vec3};

use super::{flat_normal, Camera, Material, Scene, Texture, Triangle, Wrap};

/// Appends the two triangles of quad `q` (counter-clockwise seen from its front) with flat
/// normals and unit-square texture coordinates.
pub(crate) fn quad(out: &mut Vec<Triangle>, q: [Vec3; 4], material: u32) {
    let uv = [Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)];
    for [a, b, c] in [[0, 1, 2], [0, 2, 3]] {
        let positions = [q[a], q[b], q[c]];
        out.push(Triangle {
            positions,
            normals: [flat_normal(&positions); 3],
            uvs: [uv[a], uv[b], uv[c]],
            uvs1: Default::default(),
            tangents: Default::default(),
            material,
        });
    }
}

pub(crate) fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// The embedded default scene: the Cornell box as measured in McGuire's
/// `CornellBox-Original` (about 2 m wide, opening towards +Z): red left wall, green right wall,
/// white floor, ceiling and back wall, a short and a tall box, and a 0.47 x 0.38 m ceiling light
/// emitting radiance (17, 12, 4). 36 triangles, 8 materials, camera at (0, 1, 3) looking -Z
/// with a 39.6° vertical field of view.
///
/// Unlike the OBJ (whose box "bottom" faces repeat a side face), the boxes' bottoms here face
/// the floor; they are invisible either way.
pub fn cornell_box() -> Scene {
    let white = Vec3::new(0.725, 0.71, 0.68);
    let materials = vec![
        Material::diffuse("floor", white),
        Material::diffuse("ceiling", white),
        Material::diffuse("backWall", white),
        Material::diffuse("rightWall", Vec3::new(0.14, 0.45, 0.091)),
        Material::diffuse("leftWall", Vec3::new(0.63, 0.065, 0.05)),
        Material::diffuse("shortBox", white),
        Material::diffuse("tallBox", white),
        Material::emissive("light", Vec3::splat(0.78), Vec3::new(17.0, 12.0, 4.0)),
    ];
    let (floor, ceiling, back, right, left, short, tall, light) = (0, 1, 2, 3, 4, 5, 6, 7);
    let mut t = Vec::with_capacity(36);
    quad(&mut t, [v(-1.01, 0.0, 0.99), v(1.0, 0.0, 0.99), v(1.0, 0.0, -1.04), v(-0.99, 0.0, -1.04)], floor);
    quad(&mut t, [v(-1.02, 1.99, 0.99), v(-1.02, 1.99, -1.04), v(1.0, 1.99, -1.04), v(1.0, 1.99, 0.99)], ceiling);
    quad(&mut t, [v(-0.99, 0.0, -1.04), v(1.0, 0.0, -1.04), v(1.0, 1.99, -1.04), v(-1.02, 1.99, -1.04)], back);
    quad(&mut t, [v(1.0, 0.0, -1.04), v(1.0, 0.0, 0.99), v(1.0, 1.99, 0.99), v(1.0, 1.99, -1.04)], right);
    quad(&mut t, [v(-1.01, 0.0, 0.99), v(-0.99, 0.0, -1.04), v(-1.02, 1.99, -1.04), v(-1.02, 1.99, 0.99)], left);
    // Short box: footprint corners (x, z), height 0.6.
    let s = [(0.53, 0.75), (0.70, 0.17), (0.13, 0.00), (-0.05, 0.57)];
    prism(&mut t, s, 0.6, short);
    // Tall box, height 1.2.
    let h = [(-0.53, 0.09), (0.04, -0.09), (-0.14, -0.67), (-0.71, -0.49)];
    prism(&mut t, h, 1.2, tall);
    quad(&mut t, [v(-0.24, 1.98, 0.16), v(-0.24, 1.98, -0.22), v(0.23, 1.98, -0.22), v(0.23, 1.98, 0.16)], light);
    Scene {
        triangles: t,
        materials,
        camera: Camera::look_at(v(0.0, 1.0, 3.0), v(0.0, 1.0, 0.0), Vec3::Y, 0.6911),
        ..Scene::default()
    }
}

/// A box standing on y = 0 with footprint `f` (corners in counter-clockwise order seen from
/// above) and height `h`: top, four sides and bottom, all facing outwards.
fn prism(out: &mut Vec<Triangle>, f: [(f32, f32); 4], h: f32, material: u32) {
    let lo = f.map(|(x, z)| v(x, 0.0, z));
    let hi = f.map(|(x, z)| v(x, h, z));
    quad(out, hi, material);
    for i in 0..4 {
        let j = (i + 1) % 4;
        quad(out, [lo[j], hi[j], hi[i], lo[i]], material);
    }
    quad(out, [lo[3], lo[2], lo[1], lo[0]], material);
}

/// A closed cube `[-1, 1]³` seen from the inside (normals point inwards), every surface with
/// diffuse albedo `albedo` and emitted radiance `emission`. The camera sits at the centre
/// looking -Z with a 60° field of view.
///
/// The white-furnace result: every pixel converges to `emission / (1 - albedo)` per channel
/// (for albedo < 1), whatever the path tracer's sampling, which tests energy conservation.
pub fn white_furnace(albedo: Vec3, emission: Vec3) -> Scene {
    let mut t = Vec::with_capacity(12);
    let c = |x: f32, y: f32, z: f32| v(x, y, z);
    // Counter-clockwise seen from inside the cube.
    let faces = [
        [c(-1., -1., -1.), c(1., -1., -1.), c(1., -1., 1.), c(-1., -1., 1.)], // floor, faces +Y
        [c(-1., 1., -1.), c(-1., 1., 1.), c(1., 1., 1.), c(1., 1., -1.)],     // ceiling, -Y
        [c(-1., -1., -1.), c(-1., 1., -1.), c(1., 1., -1.), c(1., -1., -1.)], // back, +Z
        [c(-1., -1., 1.), c(1., -1., 1.), c(1., 1., 1.), c(-1., 1., 1.)],     // front, -Z
        [c(-1., -1., -1.), c(-1., -1., 1.), c(-1., 1., 1.), c(-1., 1., -1.)], // left, +X
        [c(1., -1., -1.), c(1., 1., -1.), c(1., 1., 1.), c(1., -1., 1.)],     // right, -X
    ];
    for f in faces {
        // Reversed: the corners above wind outwards; emission is one-sided (front faces), so
        // the faces must face the inside of the furnace.
        quad(&mut t, [f[3], f[2], f[1], f[0]], 0);
    }
    Scene {
        triangles: t,
        materials: vec![Material::emissive("furnace", albedo, emission)],
        camera: Camera::look_at(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 60f32.to_radians()),
        ..Scene::default()
    }
}

/// A single square diffuse plane (y = 0, 20 x 20 m, facing +Y) with albedo `albedo`, and a
/// camera 1 m above looking straight down (60° field of view, so only the plane is in view).
///
/// Under a uniform sky of radiance `L` (see [`super::Sky::uniform`]) with nothing else in the
/// scene, every pixel converges to `albedo x L`.
pub fn diffuse_plane(albedo: Vec3) -> Scene {
    let mut t = Vec::with_capacity(2);
    let s = 10.0;
    quad(&mut t, [v(-s, 0.0, s), v(s, 0.0, s), v(s, 0.0, -s), v(-s, 0.0, -s)], 0);
    Scene {
        triangles: t,
        materials: vec![Material::diffuse("plane", albedo)],
        camera: Camera::look_at(v(0.0, 1.0, 0.0), Vec3::ZERO, Vec3::NEG_Z, 60f32.to_radians()),
        ..Scene::default()
    }
}

/// A large scene for benchmarks: a terrain heightfield (600 x 600 quads, 120 m across) with 500
/// UV spheres (32 x 16 quads, radius 0.3 to 2.3 m) scattered over it, 1,232,000 triangles
/// mixing a 2.5D surface with overlapping closed objects; one grey diffuse material under a
/// uniform sky, the camera 25 m up looking at the centre.
pub fn terrain_and_spheres() -> Scene {
    let mut t = Vec::with_capacity(1_232_000);
    let n = 600;
    let height = |x: f32, z: f32| 2.0 * (x * 0.05).sin() * (z * 0.07).cos() + 0.5 * (x * 0.31 + z * 0.17).sin();
    let p = |i: usize, j: usize| {
        let (x, z) = (i as f32 * 0.2 - 60.0, j as f32 * 0.2 - 60.0);
        v(x, height(x, z), z)
    };
    let flat = |positions: [Vec3; 3]| Triangle {
        positions,
        normals: [flat_normal(&positions); 3],
        uvs: [Vec2::ZERO; 3],
        uvs1: Default::default(),
        tangents: Default::default(),
        material: 0,
    };
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            t.push(flat([a, c, b]));
            t.push(flat([a, d, c]));
        }
    }
    // xorshift32: the same spheres on every run.
    let mut state = 0x1234_5678u32;
    let mut random = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        (state >> 8) as f32 / (1u32 << 24) as f32
    };
    for _ in 0..500 {
        let (x, z) = (random() * 110.0 - 55.0, random() * 110.0 - 55.0);
        let r = 0.3 + 2.0 * random();
        let center = v(x, height(x, z) + r * 0.5, z);
        let (segments, rings) = (32, 16);
        let at = |s: usize, k: usize| {
            let phi = s as f32 / segments as f32 * std::f32::consts::TAU;
            let theta = k as f32 / rings as f32 * std::f32::consts::PI;
            center + r * v(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin())
        };
        for s in 0..segments {
            for k in 0..rings {
                let (a, b, c, d) = (at(s, k), at(s + 1, k), at(s + 1, k + 1), at(s, k + 1));
                t.push(flat([a, b, c]));
                t.push(flat([a, c, d]));
            }
        }
    }
    Scene {
        triangles: t,
        materials: vec![Material::diffuse("ground", Vec3::splat(0.5))],
        sky: Some(super::Sky::uniform(Vec3::ONE)),
        camera: Camera::look_at(v(0.0, 25.0, 70.0), Vec3::ZERO, Vec3::Y, 50f32.to_radians()),
        ..Scene::default()
    }
}

/// Khronos' MetalRoughSpheres in code: a 5 x 5 grid of smooth spheres (radius 0.4 m, 1 m
/// apart, in the plane z = 0) of one copper-coloured base colour, metallic rising from 0 to 1
/// left to right, roughness from 0 (clamped to `kernel::metal_rough::MIN_ROUGHNESS`) at the
/// top to 1 at the bottom; lit by a 2 x 2 m area light above and left of the camera (radiance
/// 12) and a uniform sky (0.25). The camera at (0, 0, 7) looks at the grid's centre (40°).
/// 24,002 triangles.
pub fn metal_rough_spheres() -> Scene {
    const N: usize = 5;
    let base = Vec3::new(0.95, 0.64, 0.54);
    let mut materials = Vec::with_capacity(N * N + 1);
    let mut t = Vec::with_capacity(N * N * 512);
    for row in 0..N {
        for column in 0..N {
            let (metallic, roughness) = (column as f32 / (N - 1) as f32, row as f32 / (N - 1) as f32);
            let name = format!("metallic {metallic:.2} roughness {roughness:.2}");
            materials.push(Material::metal_rough(&name, base, metallic, roughness));
            let center = v(column as f32 - 2.0, 2.0 - row as f32, 0.0);
            sphere(&mut t, center, 0.4, (row * N + column) as u32);
        }
    }
    let light = materials.len() as u32;
    materials.push(Material::emissive("light", Vec3::ZERO, Vec3::splat(12.0)));
    // Facing the grid's centre from (-3, 4, 5).
    let c = v(-3.0, 4.0, 5.0);
    let n = (-c).normalize();
    let u = Vec3::Y.cross(n).normalize();
    let w = n.cross(u);
    quad(&mut t, [c - u - w, c + u - w, c + u + w, c - u + w], light);
    Scene {
        triangles: t,
        materials,
        sky: Some(super::Sky::uniform(Vec3::splat(0.25))),
        camera: Camera::look_at(v(0.0, 0.0, 7.0), Vec3::ZERO, Vec3::Y, 40f32.to_radians()),
        ..Scene::default()
    }
}

/// A white texture of `n x n` texels whose alpha is a checker: 255 where `x + y` is even
/// (opaque under any cutoff in (0, 1]), 0 where it is odd (a hole under any cutoff above 0).
pub fn alpha_checker(n: u32) -> Texture {
    let texels: Vec<u32> =
        (0..n * n).map(|i| if (i % n + i / n).is_multiple_of(2) { 0xffff_ffff } else { 0x00ff_ffff }).collect();
    Texture { width: n, height: n, texels: texels.into(), wrap_s: Wrap::ClampToEdge, wrap_t: Wrap::ClampToEdge }
}

/// A 2 x 2 m floor whose base colour is an 8 x 8 checker of light (sRGB 204: albedo 0.60) and
/// dark (sRGB 51: 0.033) squares, 8 x 8 texels each (so that filtering blurs only their edges),
/// under a uniform white sky, seen from (0, 1.6, 1.6) at 45°: a texture whose edges a denoiser
/// must keep (the contrast between the squares).
pub fn checker_floor() -> Scene {
    let n = 64u32;
    let light = |i: u32| ((i % n) / 8 + (i / n) / 8).is_multiple_of(2);
    let texels: Vec<u32> = (0..n * n).map(|i| if light(i) { 0xffcc_cccc } else { 0xff33_3333 }).collect();
    let checker =
        Texture { width: n, height: n, texels: texels.into(), wrap_s: Wrap::ClampToEdge, wrap_t: Wrap::ClampToEdge };
    let floor = Material { base_color_texture: Some(0), ..Material::diffuse("checker", Vec3::ONE) };
    let mut t = Vec::with_capacity(2);
    quad(&mut t, [v(-1.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), v(-1.0, 0.0, -1.0)], 0);
    Scene {
        triangles: t,
        materials: vec![floor],
        textures: vec![checker],
        sky: Some(super::Sky::uniform(Vec3::ONE)),
        camera: Camera::look_at(v(0.0, 1.6, 1.6), Vec3::ZERO, Vec3::Y, 45f32.to_radians()),
        ..Scene::default()
    }
}

/// Alpha cut-outs (glTF `alphaMode` MASK) in code: a 2 x 2 m white floor, above it (y = 0.8) a
/// 1 x 1 m green screen whose base colour texture is an 8 x 8 alpha checker (cutoff 0.5, half
/// of it holes), above that (y = 1.6) a 0.8 x 0.8 m light facing down (radiance 8) cut by a
/// 2 x 2 alpha checker, so half of it emits, and a grey back wall. The camera at (0, 1.2, 2.2)
/// looks at (0, 0.4, 0) (45°), seeing the screen from above, the floor through its holes
/// and the light from below. 8 triangles; every kind of ray meets a hole: camera rays, bounces,
/// shadow rays, and light samples on the emitter.
pub fn alpha_masked_screen() -> Scene {
    let masked =
        |m: Material, texture: u32| Material { base_color_texture: Some(texture), alpha_cutoff: Some(0.5), ..m };
    let materials = vec![
        Material::diffuse("floor", Vec3::splat(0.8)),
        masked(Material::diffuse("screen", Vec3::new(0.2, 0.7, 0.3)), 0),
        masked(Material::emissive("light", Vec3::ZERO, Vec3::splat(8.0)), 1),
        Material::diffuse("wall", Vec3::splat(0.5)),
    ];
    let mut t = Vec::with_capacity(8);
    quad(&mut t, [v(-1.0, 0.0, 1.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), v(-1.0, 0.0, -1.0)], 0);
    quad(&mut t, [v(-0.5, 0.8, 0.5), v(0.5, 0.8, 0.5), v(0.5, 0.8, -0.5), v(-0.5, 0.8, -0.5)], 1);
    quad(&mut t, [v(-0.4, 1.6, -0.4), v(0.4, 1.6, -0.4), v(0.4, 1.6, 0.4), v(-0.4, 1.6, 0.4)], 2);
    quad(&mut t, [v(-1.0, 0.0, -1.0), v(1.0, 0.0, -1.0), v(1.0, 2.0, -1.0), v(-1.0, 2.0, -1.0)], 3);
    Scene {
        triangles: t,
        materials,
        textures: vec![alpha_checker(8), alpha_checker(2)],
        camera: Camera::look_at(v(0.0, 1.2, 2.2), v(0.0, 0.4, 0.0), Vec3::Y, 45f32.to_radians()),
        ..Scene::default()
    }
}

/// The Cornell box in glass: its short box replaced by a smooth glass sphere (index 1.5, a solid
/// that refracts) resting on the floor, its tall box by a rough glass block (roughness 0.3,
/// index 1.5) that absorbs red and green (Beer–Lambert: 60 % of blue-green light left after
/// 0.4 m). Every glass path at once: the delta lobe and its caustic on the floor, the rough
/// lobe with light sampled through it, refraction in and out of volumes, absorption inside.
pub fn glass_cornell() -> Scene {
    let mut scene = cornell_box();
    let (short, tall) = (5u32, 6u32);
    scene.materials[short as usize] = Material::glass("smoothGlass", Vec3::ONE, 1.5, true);
    scene.materials[tall as usize] = Material {
        roughness: 0.3,
        attenuation_color: Vec3::new(0.6, 0.8, 0.95),
        attenuation_distance: 0.4,
        ..Material::glass("roughTintedGlass", Vec3::ONE, 1.5, true)
    };
    scene.triangles.retain(|t| t.material != short && t.material != tall);
    // Both lifted 1 mm off the floor: a glass bottom face on the floor's plane would leave which
    // surface a ray meets there to rounding.
    sphere(&mut scene.triangles, v(0.33, 0.301, 0.37), 0.3, short);
    let first = scene.triangles.len();
    let h = [(-0.53, 0.09), (0.04, -0.09), (-0.14, -0.67), (-0.71, -0.49)];
    prism(&mut scene.triangles, h, 1.2, tall);
    for t in &mut scene.triangles[first..] {
        t.positions = t.positions.map(|p| p + Vec3::Y * 0.001);
    }
    scene
}

/// Appends a UV sphere (32 segments x 16 rings, outward-facing, smooth normals) to `out`.
pub(crate) fn sphere(out: &mut Vec<Triangle>, center: Vec3, radius: f32, material: u32) {
    uv_sphere(out, center, radius, material, (32, 16));
}

/// Appends a UV sphere of `(segments, rings)` (`2 * segments * (rings - 1)` triangles).
fn uv_sphere(out: &mut Vec<Triangle>, center: Vec3, radius: f32, material: u32, (segments, rings): (usize, usize)) {
    let dir = |s: usize, k: usize| {
        let phi = s as f32 / segments as f32 * std::f32::consts::TAU;
        let theta = k as f32 / rings as f32 * std::f32::consts::PI;
        v(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin())
    };
    let uv = |s: usize, k: usize| Vec2::new(s as f32 / segments as f32, k as f32 / rings as f32);
    for s in 0..segments {
        for k in 0..rings {
            let corners = [(s, k), (s, k + 1), (s + 1, k + 1), (s + 1, k)];
            for (half, [a, b, c]) in [[0, 1, 2], [0, 2, 3]].into_iter().enumerate() {
                // The pole quads are triangles: their other half would be degenerate.
                if (k == 0 && half == 1) || (k == rings - 1 && half == 0) {
                    continue;
                }
                let normals = [corners[a], corners[b], corners[c]].map(|(s, k)| dir(s, k));
                let positions = normals.map(|n| center + radius * n);
                let uvs = [corners[a], corners[b], corners[c]].map(|(s, k)| uv(s, k));
                out.push(Triangle {
                    positions,
                    normals,
                    uvs,
                    uvs1: Default::default(),
                    tangents: Default::default(),
                    material,
                });
            }
        }
    }
}

/// The stress scene of two levels: a 10,240-triangle sphere placed `side` x `side` times
/// (100 x 100: 102 million triangles placed, 10,242 stored) over a static floor, under a sky.
pub fn instanced_field(side: usize) -> Scene {
    use glam::{Mat4, Quat};
    let mut mesh = Vec::new();
    uv_sphere(&mut mesh, Vec3::ZERO, 0.4, 0, (128, 41));
    let half = side as f32 * 0.5;
    let mut floor = Vec::new();
    quad(&mut floor, [v(-half, -0.4, half), v(half, -0.4, half), v(half, -0.4, -half), v(-half, -0.4, -half)], 1);
    let instances = (0..side * side)
        .map(|k| {
            let (i, j) = (k % side, k / side);
            let at = v(i as f32 + 0.5 - half, 0.0, j as f32 + 0.5 - half);
            let scale = v(1.0, 0.6 + 0.4 * (k as f32 * 0.37).sin().abs(), 1.0);
            let transform = Mat4::from_scale_rotation_translation(scale, Quat::from_rotation_y(k as f32), at);
            super::Instance { mesh: 0, transform }
        })
        .collect();
    Scene {
        triangles: floor,
        meshes: vec![super::Mesh { triangles: mesh }],
        instances,
        materials: vec![
            Material::diffuse("spheres", Vec3::new(0.6, 0.5, 0.4)),
            Material::diffuse("floor", Vec3::splat(0.5)),
        ],
        sky: Some(super::Sky::uniform(Vec3::ONE)),
        camera: Camera::look_at(v(0.0, 6.0, half + 4.0), v(0.0, 0.0, half - 12.0), Vec3::Y, 0.9),
        ..Scene::default()
    }
}

/// A two-level test scene: a static floor and area light, and one mesh (a smooth sphere with a
/// box stuck to its +x side, so that mirroring shows) placed `grid` x `grid` times by
/// instances, rotated, scaled non-uniformly and, every third one, mirrored. Lit by the light
/// and a dim sky. `Scene::bake_instances` gives the same scene flattened.
pub fn instanced_shapes(grid: usize) -> Scene {
    use glam::{Mat4, Quat};
    let materials = vec![
        Material::diffuse("floor", Vec3::splat(0.6)),
        Material::diffuse("shape", Vec3::new(0.7, 0.4, 0.2)),
        Material::emissive("light", Vec3::ZERO, Vec3::splat(8.0)),
    ];
    let mut shape = Vec::new();
    sphere(&mut shape, v(0.0, 0.0, 0.0), 0.3, 1);
    prism(&mut shape, [(0.25, 0.1), (0.5, 0.1), (0.5, -0.1), (0.25, -0.1)].map(|(x, z)| (x, -z)), 0.2, 1);
    let half = grid as f32 * 0.5;
    let mut floor = Vec::new();
    quad(&mut floor, [v(-half, -0.35, half), v(half, -0.35, half), v(half, -0.35, -half), v(-half, -0.35, -half)], 0);
    let l = half * 0.4;
    let h = 2.5;
    quad(&mut floor, [v(-l, h, -l), v(l, h, -l), v(l, h, l), v(-l, h, l)], 2);
    let mut instances = Vec::with_capacity(grid * grid);
    for i in 0..grid {
        for j in 0..grid {
            let k = (i * grid + j) as f32;
            let at = v(i as f32 + 0.5 - half, 0.0, j as f32 + 0.5 - half);
            let mut scale = v(1.0, 0.7 + 0.3 * (k * 0.7).sin().abs(), 1.2 - 0.4 * (k * 1.3).cos().abs());
            if (i * grid + j) % 3 == 1 {
                scale.x = -scale.x;
            }
            let rotation = Quat::from_rotation_y(k * 0.9) * Quat::from_rotation_x(0.3 * (k * 0.5).sin());
            let transform = Mat4::from_scale_rotation_translation(scale, rotation, at);
            instances.push(super::Instance { mesh: 0, transform });
        }
    }
    Scene {
        triangles: floor,
        meshes: vec![super::Mesh { triangles: shape }],
        instances,
        materials,
        sky: Some(super::Sky::uniform(Vec3::splat(0.2))),
        camera: Camera::look_at(v(0.0, half * 1.2 + 1.0, half * 1.6 + 1.0), v(0.0, -0.3, 0.0), Vec3::Y, 0.8),
        ..Scene::default()
    }
}

/// A two-level scene of alpha cut-outs: one mesh of masked "leaves" (two coincident quads
/// with different checkers, 8 x 8 and 2 x 2, so that their holes overlap at the same distance,
/// and a crossing quad), an opaque triangle coincident with half of the first quad (an
/// unmasked and a masked hit at the same distance) and a small opaque ball, placed `grid` x
/// `grid` times (rotated, scaled non-uniformly, every third mirrored), the first two
/// placements twice (the same triangle at the same distance in two instances); a static
/// floor and a static masked wall. Every tie `traverse_masked::is_next_candidate` orders and
/// every kind of hole: what one traversal per ray must find as searching again behind each hole
/// did.
pub fn instanced_masked_leaves(grid: usize) -> Scene {
    use glam::{Mat4, Quat};
    let masked =
        |m: Material, texture: u32| Material { base_color_texture: Some(texture), alpha_cutoff: Some(0.5), ..m };
    let materials = vec![
        Material::diffuse("floor", Vec3::splat(0.6)),
        masked(Material::diffuse("leaves8", Vec3::new(0.2, 0.6, 0.2)), 0),
        masked(Material::diffuse("leaves2", Vec3::new(0.5, 0.6, 0.1)), 1),
        Material::diffuse("trunk", Vec3::new(0.4, 0.3, 0.2)),
    ];
    let mut leaves = Vec::new();
    let a = [v(-0.4, -0.3, 0.0), v(0.4, -0.3, 0.0), v(0.4, 0.5, 0.0), v(-0.4, 0.5, 0.0)];
    quad(&mut leaves, a, 1);
    quad(&mut leaves, a, 2);
    quad(&mut leaves, [v(0.1, -0.3, -0.4), v(0.1, -0.3, 0.4), v(0.1, 0.5, 0.4), v(0.1, 0.5, -0.4)], 1);
    // The opaque twin of the first quad's first triangle (the same vertices in the same order).
    let twin = Triangle { material: 3, ..leaves[0] };
    leaves.push(twin);
    uv_sphere(&mut leaves, v(0.0, -0.15, 0.2), 0.12, 3, (8, 5));
    let half = grid as f32 * 0.5;
    let mut statics = Vec::new();
    quad(&mut statics, [v(-half, -0.35, half), v(half, -0.35, half), v(half, -0.35, -half), v(-half, -0.35, -half)], 0);
    quad(&mut statics, [v(-half, -0.35, -half), v(half, -0.35, -half), v(half, 1.0, -half), v(-half, 1.0, -half)], 2);
    let mut instances = Vec::with_capacity(grid * grid + 2);
    for i in 0..grid {
        for j in 0..grid {
            let k = (i * grid + j) as f32;
            let at = v(i as f32 + 0.5 - half, 0.0, j as f32 + 0.5 - half);
            let mut scale = v(1.0, 0.7 + 0.3 * (k * 0.7).sin().abs(), 1.2 - 0.4 * (k * 1.3).cos().abs());
            if (i * grid + j) % 3 == 1 {
                scale.x = -scale.x;
            }
            let rotation = Quat::from_rotation_y(k * 0.9) * Quat::from_rotation_x(0.3 * (k * 0.5).sin());
            let transform = Mat4::from_scale_rotation_translation(scale, rotation, at);
            instances.push(super::Instance { mesh: 0, transform });
        }
    }
    let twins = instances[..2.min(instances.len())].to_vec();
    instances.extend(twins);
    Scene {
        triangles: statics,
        meshes: vec![super::Mesh { triangles: leaves }],
        instances,
        materials,
        textures: vec![alpha_checker(8), alpha_checker(2)],
        sky: Some(super::Sky::uniform(Vec3::splat(0.5))),
        camera: Camera::look_at(v(0.0, half * 1.2 + 1.0, half * 1.6 + 1.0), v(0.0, -0.3, 0.0), Vec3::Y, 0.8),
        ..Scene::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_benchmark_scene_is_valid_and_as_large_as_documented() {
        let s = terrain_and_spheres();
        s.validate().unwrap();
        assert_eq!(s.triangles.len(), 1_232_000);
        assert!(s.sky.is_some() && s.emissive_triangle_count() == 0);
    }

    #[test]
    fn cornell_box_is_valid_and_closed_towards_the_camera() {
        let s = cornell_box();
        s.validate().unwrap();
        assert_eq!(s.triangles.len(), 36);
        assert_eq!(s.emissive_triangle_count(), 2);
        // Walls, floor and ceiling face the inside of the box.
        let center = v(0.0, 1.0, 0.0);
        for t in &s.triangles[..10] {
            let centroid = (t.positions[0] + t.positions[1] + t.positions[2]) / 3.0;
            assert!(t.normals[0].dot(center - centroid) > 0.0, "{t:?}");
        }
        // Box faces point away from their box's axis; the light faces down.
        assert!(s.triangles[34].normals[0].y < -0.99);
    }

    #[test]
    fn analytic_scenes_face_the_right_way() {
        let f = white_furnace(Vec3::splat(0.5), Vec3::ONE);
        f.validate().unwrap();
        for t in &f.triangles {
            let centroid = (t.positions[0] + t.positions[1] + t.positions[2]) / 3.0;
            assert!(t.normals[0].dot(-centroid) > 0.0);
        }
        let p = diffuse_plane(Vec3::splat(0.5));
        p.validate().unwrap();
        assert!(p.triangles.iter().all(|t| t.normals[0] == Vec3::Y));
    }

    #[test]
    fn metal_rough_spheres_face_outwards_over_the_whole_grid() {
        let s = metal_rough_spheres();
        s.validate().unwrap();
        assert_eq!(s.emissive_triangle_count(), 2);
        for t in s.triangles.iter().filter(|t| t.material < 25) {
            let (row, column) = (t.material / 5, t.material % 5);
            let center = v(column as f32 - 2.0, 2.0 - row as f32, 0.0);
            let centroid = (t.positions[0] + t.positions[1] + t.positions[2]) / 3.0;
            let face = (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]);
            assert!(face.dot(centroid - center) > 0.0, "front faces point outwards: {t:?}");
            assert!(t.normals.iter().all(|n| n.dot(face) > 0.0), "normals agree with the winding: {t:?}");
        }
        let m = &s.materials;
        assert!(m[..25].iter().all(|m| m.uses_metal_rough() || (m.metallic == 0.0 && m.roughness == 1.0)));
        assert_eq!((m[0].metallic, m[0].roughness, m[4].metallic, m[24].roughness), (0.0, 0.0, 1.0, 1.0));
        // The light faces the grid.
        let light = s.triangles.iter().find(|t| t.material == 25).unwrap();
        assert!(light.normals[0].dot(-light.positions[0]) > 0.0);
    }
}
