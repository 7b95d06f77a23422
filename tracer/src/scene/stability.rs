//! Small generated scenes, each built to make one sampling method fail (or to stress one piece
//! of numerics), for the stability suite (`tests/rendering/stability.rs`) and the charts.
//!
//! | scene | what it breaks |
//! |---|---|
//! | [`tiny_bright_light`] | BSDF sampling: a 3 cm light 200x brighter than the Cornell box's rarely gets hit (fireflies) |
//! | [`large_light_close`] | light sampling: a 2 m light 2 cm above the floor (1/r²) beside a wall it grazes (cosines) |
//! | [`sky_through_opening`] | sky sampling: a room lit by a uniform sky through a 20 cm hole (almost every sky sample is occluded) |
//! | [`degenerate_triangles`] | zero-area and sliver triangles, a zero-area emitter, in the Cornell box |
//! | [`camera_inside_geometry`] | a camera inside a closed box: the image must stay black |
//! | [`scaled`] | the Cornell box at 1e-3 and 1e4 m: self-intersection epsilons |
//! | [`light_under_glass`] | light sampling through a smooth surface: the light behind a glass pane no shadow ray passes |
//! | [`glass_cornell`] | every glass path: a delta lobe and its caustic, a rough lobe with light sampled through it, absorption |

use glam::Vec3;

use super::generate::{quad, v};
use super::{cornell_box, glass_cornell, Camera, Material, Scene, Sky, Triangle};

/// One stability scene with what it is built to break.
#[derive(Clone, Debug)]
pub struct StabilityCase {
    /// Short name (used in test messages and tables).
    pub name: &'static str,
    pub scene: Scene,
    /// The method or code path the scene is built to break, in words.
    pub breaks: &'static str,
    /// The expected image is all black (nothing to compare between strategies but zeros).
    pub black: bool,
}

/// Every stability scene, in the order of the module table.
pub fn stability_cases() -> Vec<StabilityCase> {
    let case = |name, scene, breaks| StabilityCase { name, scene, breaks, black: false };
    vec![
        case("tiny-bright-light", tiny_bright_light(), "BSDF sampling (fireflies)"),
        case("large-light-close", large_light_close(), "light sampling (1/r² and grazing cosines)"),
        case("sky-through-opening", sky_through_opening(), "sky sampling (occlusion)"),
        case("degenerate-triangles", degenerate_triangles(), "zero-area triangles and emitters"),
        StabilityCase {
            name: "camera-inside-geometry",
            scene: camera_inside_geometry(),
            breaks: "light leaking into a closed box",
            black: true,
        },
        case("cornell-1e-3", scaled(cornell_box(), 1e-3), "self-intersection at millimetre scale"),
        case("cornell-1e4", scaled(cornell_box(), 1e4), "self-intersection at 10 km scale"),
        case("light-under-glass", light_under_glass(), "light sampling through a smooth surface"),
        case("glass-cornell", glass_cornell(), "glass: delta and rough lobes, caustics, absorption"),
    ]
}

/// Emitted radiance of the Cornell box's light.
const CORNELL_LIGHT: Vec3 = Vec3::new(17.0, 12.0, 4.0);
/// Side of [`tiny_bright_light`]'s light, metres.
pub const TINY_LIGHT_SIDE: f32 = 0.03;

/// The Cornell box with its 0.47 x 0.38 m light replaced by a 3 cm square one emitting the same
/// power (about 200x the radiance). BSDF-sampled paths find it rarely and then with a huge
/// value: fireflies. Light sampling finds it every time. The camera looks a little lower than
/// the Cornell box's, so that the light itself is out of view: seen directly, it would make
/// every strategy's variance the same (that of camera rays landing on it or not).
pub fn tiny_bright_light() -> Scene {
    let mut scene = cornell_box();
    let light_material = scene.triangles.last().expect("the Cornell box has a light").material;
    scene.triangles.retain(|t| t.material != light_material);
    let area_ratio = (0.47 * 0.38) / (TINY_LIGHT_SIDE * TINY_LIGHT_SIDE);
    scene.materials[light_material as usize].emission = CORNELL_LIGHT * area_ratio;
    let (h, y) = (0.5 * TINY_LIGHT_SIDE, 1.98);
    quad(&mut scene.triangles, [v(-h, y, h), v(-h, y, -h), v(h, y, -h), v(h, y, h)], light_material);
    scene.camera = Camera::look_at(v(0.0, 1.0, 3.0), v(0.0, 0.5, 0.0), Vec3::Y, 0.6911);
    scene
}

/// A 2 x 2 m light (radiance 1) 2 cm above a 4 x 4 m floor, facing it, with a wall along the
/// light's back edge that its light grazes; the camera looks into the gap at a low angle.
/// Light sampling picks points uniformly on the light although the integrand is 1/r² peaked
/// under each floor point, and wall points see the light at cosines near zero; BSDF sampling
/// hits the light with almost every ray. Nothing else is in the scene (escaping rays are black).
pub fn large_light_close() -> Scene {
    let materials = vec![
        Material::diffuse("floor", Vec3::splat(0.5)),
        Material::diffuse("wall", Vec3::new(0.6, 0.5, 0.4)),
        Material::emissive("light", Vec3::splat(0.5), Vec3::ONE),
    ];
    let mut t = Vec::new();
    quad(&mut t, [v(-2.0, 0.0, 2.0), v(2.0, 0.0, 2.0), v(2.0, 0.0, -2.0), v(-2.0, 0.0, -2.0)], 0);
    // The wall at z = -1 faces +Z, from the floor to 1 m.
    quad(&mut t, [v(-2.0, 0.0, -1.0), v(2.0, 0.0, -1.0), v(2.0, 1.0, -1.0), v(-2.0, 1.0, -1.0)], 1);
    let y = 0.02;
    quad(&mut t, [v(-1.0, y, 1.0), v(-1.0, y, -1.0), v(1.0, y, -1.0), v(1.0, y, 1.0)], 2);
    Scene {
        triangles: t,
        materials,
        camera: Camera::look_at(v(0.0, 0.3, 2.5), v(0.0, 0.02, -0.6), Vec3::Y, 40f32.to_radians()),
        ..Scene::default()
    }
}

/// Side of the hole in [`sky_through_opening`]'s ceiling, metres.
pub const OPENING_SIDE: f32 = 0.2;

/// A closed 2 x 2 x 2 m room whose only opening is a 20 cm square hole in the ceiling, under a
/// uniform sky of radiance 5. Sky sampling picks directions over the whole sphere and nearly
/// all are occluded (from the floor, the hole covers about 0.3% of the hemisphere); BSDF
/// sampling finds the hole no better. Both are poor; MIS must not be worse than either.
pub fn sky_through_opening() -> Scene {
    let materials = vec![Material::diffuse("room", Vec3::splat(0.7))];
    let mut t = Vec::new();
    let (lo, hi, top) = (-1.0f32, 1.0f32, 2.0f32);
    // Floor and walls, facing inwards (as in the Cornell box).
    quad(&mut t, [v(lo, 0.0, hi), v(hi, 0.0, hi), v(hi, 0.0, lo), v(lo, 0.0, lo)], 0);
    quad(&mut t, [v(lo, 0.0, lo), v(hi, 0.0, lo), v(hi, top, lo), v(lo, top, lo)], 0);
    quad(&mut t, [v(hi, 0.0, hi), v(lo, 0.0, hi), v(lo, top, hi), v(hi, top, hi)], 0);
    quad(&mut t, [v(hi, 0.0, lo), v(hi, 0.0, hi), v(hi, top, hi), v(hi, top, lo)], 0);
    quad(&mut t, [v(lo, 0.0, hi), v(lo, 0.0, lo), v(lo, top, lo), v(lo, top, hi)], 0);
    // The ceiling, facing down, as four panels around the hole [-s, s]².
    let s = 0.5 * OPENING_SIDE;
    let ceiling = |t: &mut Vec<Triangle>, x0: f32, x1: f32, z0: f32, z1: f32| {
        quad(t, [v(x0, top, z1), v(x0, top, z0), v(x1, top, z0), v(x1, top, z1)], 0)
    };
    ceiling(&mut t, lo, hi, lo, -s);
    ceiling(&mut t, lo, hi, s, hi);
    ceiling(&mut t, lo, -s, -s, s);
    ceiling(&mut t, s, hi, -s, s);
    Scene {
        triangles: t,
        materials,
        camera: Camera::look_at(v(0.0, 1.0, 0.95), v(0.0, 0.2, -0.3), Vec3::Y, 70f32.to_radians()),
        sky: Some(Sky::uniform(Vec3::splat(5.0))),
        ..Scene::default()
    }
}

/// Height of [`light_under_glass`]'s pane, metres (the light is at 1.98).
pub const GLASS_PANE_HEIGHT: f32 = 1.9;

/// The Cornell box with a smooth, thin-walled glass pane (index 1.5) under its light, wider
/// than the light so that no straight line from the room below the pane reaches it. A shadow
/// ray stops at glass, so light sampling sees the light from nowhere but the top 8 cm of the
/// walls; the room is lit by paths that pass through the pane's delta lobe, which BSDF
/// sampling alone finds (and which count in full under every strategy: a delta bounce has no
/// light-sampling counterpart to weigh against). Every strategy becomes BSDF sampling.
pub fn light_under_glass() -> Scene {
    let mut scene = cornell_box();
    let pane = scene.materials.len() as u32;
    scene.materials.push(Material::glass("pane", Vec3::ONE, 1.5, false));
    let y = GLASS_PANE_HEIGHT;
    quad(&mut scene.triangles, [v(-0.3, y, 0.25), v(-0.3, y, -0.3), v(0.3, y, -0.3), v(0.3, y, 0.25)], pane);
    scene
}

/// The Cornell box plus triangles with no area: three collinear vertices, three equal
/// vertices, an emitter with collinear vertices (radiance 50) and an emitting sliver of
/// 5e-7 m². None of them may hit, emit or poison the light selection: the image estimates
/// the plain Cornell box (the sliver emits about 8e-5 W per channel against the box light's 2 to 10 W).
pub fn degenerate_triangles() -> Scene {
    let mut scene = cornell_box();
    let white = 0;
    let emitter = scene.materials.len() as u32;
    scene.materials.push(Material::emissive("degenerateLight", Vec3::splat(0.5), Vec3::splat(50.0)));
    let tri = |positions: [Vec3; 3], material: u32| Triangle {
        positions,
        normals: [super::flat_normal(&positions); 3],
        uvs: Default::default(),
        uvs1: Default::default(),
        tangents: Default::default(),
        material,
    };
    scene.triangles.extend([
        tri([v(-0.5, 1.0, 0.0), v(0.0, 1.0, 0.0), v(0.5, 1.0, 0.0)], white),
        tri([v(0.2, 0.5, 0.3); 3], white),
        tri([v(-0.3, 1.9, 0.0), v(0.0, 1.9, 0.0), v(0.3, 1.9, 0.0)], emitter),
        tri([v(0.0, 1.97, 0.5), v(0.25, 1.97, 0.5 + 2e-6), v(0.5, 1.97, 0.5)], emitter),
    ]);
    scene
}

/// The Cornell box seen from inside its tall box (closed on all six sides): no light reaches
/// the camera, so every pixel must stay exactly black. Light leaking through the box's edges
/// or through self-intersection would show.
pub fn camera_inside_geometry() -> Scene {
    let mut scene = cornell_box();
    // The tall box's footprint centre is about (-0.335, -0.29); it is 1.2 m tall.
    scene.camera = Camera::look_at(v(-0.335, 0.6, -0.29), v(-0.335, 0.6, -1.0), Vec3::Y, 90f32.to_radians());
    scene
}

/// `scene` scaled by `factor` about the origin: positions, camera, lens and point lights.
/// Radiance does not depend on scale, so the image estimates the same as the unscaled scene's
/// (point-light intensities scale by factor² to keep their irradiance).
pub fn scaled(mut scene: Scene, factor: f32) -> Scene {
    for t in &mut scene.triangles {
        t.positions = t.positions.map(|p| p * factor);
    }
    for l in &mut scene.point_lights {
        l.position *= factor;
        l.intensity *= factor * factor;
    }
    let c = &mut scene.camera;
    c.position *= factor;
    c.target *= factor;
    c.focus_distance *= factor;
    c.aperture_radius *= factor;
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_case_is_valid() {
        for case in stability_cases() {
            case.scene.validate().unwrap_or_else(|e| panic!("{}: {e}", case.name));
        }
    }

    #[test]
    fn the_tiny_light_keeps_the_cornell_power_and_faces_down() {
        let tiny = tiny_bright_light();
        let (a, b) = (tiny.emitted_power(), cornell_box().emitted_power());
        assert!((a - b).abs().max_element() < 1e-3 * b.max_element(), "{a} vs {b}");
        let light = tiny.triangles.last().unwrap();
        assert!(light.normals[0].y < -0.99);
        assert_eq!(tiny.emissive_triangle_count(), 2);
    }

    #[test]
    fn lights_and_surfaces_face_where_the_docs_say() {
        let close = large_light_close();
        assert!(close.triangles[0].normals[0].y > 0.99, "floor faces up");
        assert!(close.triangles[2].normals[0].z > 0.99, "wall faces +Z");
        assert!(close.triangles[4].normals[0].y < -0.99, "light faces the floor");
        let room = sky_through_opening();
        let centre = v(0.0, 1.0, 0.0);
        for t in &room.triangles {
            let centroid = (t.positions[0] + t.positions[1] + t.positions[2]) / 3.0;
            assert!(t.normals[0].dot(centre - centroid) > 0.0, "room faces inwards: {t:?}");
        }
        // The ceiling has exactly the hole's area missing.
        let ceiling_area: f32 = room
            .triangles
            .iter()
            .filter(|t| t.positions.iter().all(|p| p.y == 2.0))
            .map(|t| 0.5 * (t.positions[1] - t.positions[0]).cross(t.positions[2] - t.positions[0]).length())
            .sum();
        assert!((ceiling_area - (4.0 - OPENING_SIDE * OPENING_SIDE)).abs() < 1e-5, "{ceiling_area}");
    }

    #[test]
    fn scaling_scales_geometry_and_camera() {
        let s = scaled(cornell_box(), 1e4);
        let b = s.bounds();
        assert!((b.max.y - 1.99e4).abs() < 1.0, "{b:?}");
        assert_eq!(s.camera.position, v(0.0, 1.0, 3.0) * 1e4);
        assert_eq!(s.materials, cornell_box().materials);
    }
}
