//! glTF `alphaMode` and `alphaCutoff` of a material ([`super::Material::alpha`],
//! [`super::Material::alpha_cutoff`]): OPAQUE ignores alpha; MASK cuts out where the coverage
//! (`baseColorFactor.a` x the base colour texture's alpha) is below `alphaCutoff` (default 0.5);
//! BLEND is rendered as MASK at 0.5, with a warning (a path tracer without transparency has no
//! blending). A cutoff the specification does not allow is a warning, never a panic.

use gltf::json::material::AlphaMode;
use gltf::json::validation::Checked;

use super::{SceneError, Warnings};

/// The alpha a material's coverage starts from and its cutoff (`None`: opaque). `what` names
/// the material in messages.
pub(super) fn material_alpha(
    m: &gltf::json::Material,
    what: &str,
    warnings: &mut Warnings,
) -> Result<(f32, Option<f32>), SceneError> {
    let alpha = m.pbr_metallic_roughness.base_color_factor.0[3];
    if !alpha.is_finite() {
        return Err(SceneError::Malformed(format!("{what}: baseColorFactor alpha is not finite")));
    }
    let alpha = alpha.clamp(0.0, 1.0);
    let cutoff = match m.alpha_mode {
        Checked::Valid(AlphaMode::Opaque) => None,
        Checked::Valid(AlphaMode::Mask) => Some(cutoff(m.alpha_cutoff.map(|c| c.0), what, warnings)),
        Checked::Valid(AlphaMode::Blend) => {
            warnings.once("alphaMode BLEND", || {
                format!(
                    "{what}: alphaMode BLEND is rendered as MASK with alphaCutoff 0.5 (no partial transparency): \
                     texels with alpha below 0.5 are holes"
                )
            });
            Some(0.5)
        }
        Checked::Invalid => {
            warnings.once("alphaMode invalid", || {
                format!("{what}: alphaMode is not OPAQUE, MASK or BLEND: rendered opaque")
            });
            None
        }
    };
    Ok((alpha, cutoff))
}

/// `alphaCutoff` (default 0.5): the specification asks for a number >= 0; a negative one is
/// taken as 0 (nothing cut out) and a non-finite one (JSON overflowing f32) as the default,
/// each with a warning; above 1 every texel is a hole, which is legal but worth saying.
fn cutoff(value: Option<f32>, what: &str, warnings: &mut Warnings) -> f32 {
    let Some(c) = value else {
        return 0.5;
    };
    if !c.is_finite() {
        warnings.once("alphaCutoff not finite", || {
            format!("{what}: alphaCutoff {c} is not a finite number: the default 0.5 is used")
        });
        0.5
    } else if c < 0.0 {
        warnings.once("alphaCutoff negative", || {
            format!("{what}: alphaCutoff {c} is below 0 (the specification's minimum): 0 is used, nothing is cut out")
        });
        0.0
    } else {
        if c > 1.0 {
            warnings.once("alphaCutoff above 1", || {
                format!("{what}: alphaCutoff {c} is above 1: every texel's alpha is below it, the surface is invisible")
            });
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn warned(value: Option<f32>) -> (f32, Vec<String>) {
        let mut w = Warnings::default();
        let c = cutoff(value, "material 0", &mut w);
        (c, w.into_vec())
    }

    #[test]
    fn cutoffs_out_of_range_are_warned_and_replaced() {
        assert_eq!(warned(None), (0.5, vec![]));
        assert_eq!(warned(Some(0.25)), (0.25, vec![]));
        assert_eq!(warned(Some(1.0)), (1.0, vec![]));
        for (v, expect) in [(f32::NAN, 0.5), (f32::INFINITY, 0.5), (f32::NEG_INFINITY, 0.5), (-0.1, 0.0), (1.5, 1.5)] {
            let (c, w) = warned(Some(v));
            assert_eq!(c.to_bits(), f32::to_bits(expect), "{v}");
            assert_eq!(w.len(), 1, "{v}: {w:?}");
            assert!(w[0].contains("alphaCutoff") && w[0].contains("material 0"), "{w:?}");
        }
    }
}
