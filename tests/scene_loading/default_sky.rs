//! Which scenes get the default white sky (`Scene::light_if_unlit`): those that would render
//! black at exposure 0. Nothing lights them, or only emitters too weak to (LittlestTokyo's
//! lamps: 0.003 of a white sky's irradiance over its bounding box). A scene lit by its
//! emitters, or with a sky or point light of its own, is left as it is.

use glam::Vec3;
use tracer::scene::{self, PointLight, Sky, WEAK_EMITTERS};

/// The Cornell box with its light's radiance scaled by `k`.
fn cornell_lit_by(k: f32) -> scene::Scene {
    let mut s = scene::cornell_box();
    for m in &mut s.materials {
        m.emission *= k;
    }
    s
}

#[test]
fn a_scene_its_emitters_light_keeps_its_look() {
    let mut s = scene::cornell_box();
    assert!(!s.emitters_too_weak());
    assert_eq!(s.light_if_unlit(), None);
    assert!(s.sky.is_none(), "the built-in Cornell box keeps its look");
    // Its light gives 0.12 of a white sky's irradiance: ten times weaker is still lit.
    assert_eq!(cornell_lit_by(0.1).light_if_unlit(), None);
}

#[test]
fn emitters_too_weak_to_light_the_scene_get_the_default_sky_beside_them() {
    // 0.12 x 0.05 = 0.006 of a white sky: below WEAK_EMITTERS (0.01).
    let mut dim = cornell_lit_by(0.05);
    assert!(dim.emitters_too_weak() && WEAK_EMITTERS == 0.01);
    let warning = dim.light_if_unlit().expect("lit by the default sky");
    assert!(
        warning.contains("2 emissive triangles are too weak") && warning.contains("uniform white sky"),
        "{warning}"
    );
    assert_eq!(dim.sky, Some(Sky::default_white()));
    assert_eq!(dim.emissive_triangle_count(), 2, "the lamps keep glowing");
}

#[test]
fn a_scene_nothing_lights_gets_the_default_sky() {
    let mut dark = cornell_lit_by(0.0);
    let warning = dark.light_if_unlit().expect("lit by the default sky");
    assert!(warning.starts_with("nothing lights the scene"), "{warning}");
    assert!(dark.has_light());
    assert_eq!(dark.light_if_unlit(), None, "once lit, left alone");
}

#[test]
fn a_sky_or_point_light_of_its_own_is_never_replaced() {
    // Even a black one, or beside weak emitters: it was asked for.
    let mut black_sky = cornell_lit_by(0.0);
    black_sky.sky = Some(Sky::uniform(Vec3::ZERO));
    assert_eq!(black_sky.light_if_unlit(), None);
    assert_eq!(black_sky.sky, Some(Sky::uniform(Vec3::ZERO)));
    let mut lamp = cornell_lit_by(0.05);
    lamp.point_lights.push(PointLight { position: Vec3::new(0.0, 1.0, 0.0), intensity: Vec3::splat(0.1) });
    assert_eq!(lamp.light_if_unlit(), None);
    assert!(lamp.sky.is_none());
}
