//! What lights a scene: whether anything does, whether its emitters are bright enough to, and
//! the default white sky for one that nothing lights ([`Scene::light_if_unlit`]).

use glam::Vec3;

use super::{Material, Scene, Sky};

/// Below this fraction of a white sky's irradiance, a scene's emitters are too weak to light
/// it ([`Scene::emitters_too_weak`]).
pub const WEAK_EMITTERS: f32 = 0.01;

impl Scene {
    /// Whether anything lights the scene: an emissive triangle, a point light with power, or
    /// a sky that is not black. Without any, every image of it is black.
    pub fn has_light(&self) -> bool {
        let sky =
            self.sky.as_ref().is_some_and(|s| s.intensity > 0.0 && s.texels.iter().any(|t| t.max_element() > 0.0));
        sky || self.point_lights.iter().any(|l| l.intensity.max_element() > 0.0) || self.emissive_triangle_count() > 0
    }

    /// The warning for a scene that nothing lights ([`Scene::has_light`]), saying how to light it.
    pub fn unlit_warning(&self) -> Option<String> {
        (!self.has_light()).then(|| {
            "nothing lights the scene (no emissive material, no point light, no sky): it will render black; give it a \
             sky (`--sky FILE.hdr`, an equirectangular .hdr or .exr) or add emitters or lights to the file"
                .to_owned()
        })
    }

    /// Lights a scene with [`Sky::default_white`], as glTF viewers light a model with a default
    /// environment, where it would otherwise render black at exposure 0: it has no sky and no
    /// point light, and no emitter either, or emitters too weak to light it
    /// ([`Scene::emitters_too_weak`]: LittlestTokyo's 88 lamp triangles). A file carries no
    /// sky, and most carry no lights. Returns the warning that says so (each interface adds how
    /// to choose otherwise); `None` (nothing changed) for a scene its lights light, or one that
    /// has a sky or a point light of its own (even a black one: that was asked for).
    pub fn light_if_unlit(&mut self) -> Option<String> {
        let emitters = self.emissive_triangle_count();
        if self.sky.is_some() || !self.point_lights.is_empty() || (emitters > 0 && !self.emitters_too_weak()) {
            return None;
        }
        let why = if emitters > 0 {
            format!("the scene's {emitters} emissive triangles are too weak to light it (no sky, no point light)")
        } else {
            "nothing lights the scene (no emissive material, no point light, no sky)".to_owned()
        };
        self.sky = Some(Sky::default_white());
        Some(format!("{why}: lit by a uniform white sky"))
    }

    /// Whether the scene's emitters would leave it black at exposure 0: their power spread
    /// over its bounding box's surface gives under [`WEAK_EMITTERS`] of the irradiance the
    /// default white sky gives (π). (Such a surface of albedo 0.5 would show radiance under
    /// 0.005.) The Cornell box's light gives 0.12 of it, DamagedHelmet's (its emissive factor:
    /// textures are not counted, so a textured emitter errs towards lit) 0.80,
    /// LittlestTokyo's lamps 0.003. A scene with no extent (a point) is never too weak.
    pub fn emitters_too_weak(&self) -> bool {
        let d = self.bounds().diagonal();
        let area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
        self.emitted_power().max_element() < WEAK_EMITTERS * std::f32::consts::PI * area
    }

    /// Number of triangles whose material emits light.
    pub fn emissive_triangle_count(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| self.materials.get(t.material as usize).is_some_and(Material::is_emissive))
            .count()
    }

    /// Total emitted power of emissive triangles, per channel: `Σ emission x area x π`
    /// (one-sided Lambertian emitters; emissive textures are ignored). Handy to compare scenes.
    pub fn emitted_power(&self) -> Vec3 {
        self.triangles
            .iter()
            .filter_map(|t| {
                let m = self.materials.get(t.material as usize)?;
                let [a, b, c] = t.positions;
                let area = 0.5 * (b - a).cross(c - a).length();
                Some(m.emission * area * std::f32::consts::PI)
            })
            .sum()
    }
}
