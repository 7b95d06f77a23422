//! Tone mapping: the kernel's curves against the reference formulas, written again here in f64
//! with each matrix in its source's layout (GLSL's column-major `mat3(...)` for AgX, HLSL rows
//! for ACES), so that a transposed or mistyped matrix in the kernel fails.

use crate::common;

use common::TestRng;
use glam::Vec3;

mod tone_reference {
    pub type V = [f64; 3];

    /// `M * v` for a GLSL `mat3(c0, c1, c2)` given as its columns.
    pub fn mul_columns(m: [V; 3], v: V) -> V {
        std::array::from_fn(|i| m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2])
    }

    /// `mul(M, v)` for an HLSL `float3x3` given as its rows.
    pub fn mul_rows(m: [V; 3], v: V) -> V {
        std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
    }

    /// Khronos PBR Neutral, as the Khronos reference GLSL writes it.
    pub fn neutral(c: V) -> V {
        let start = 0.8 - 0.04;
        let desaturation = 0.15;
        let x = c[0].min(c[1]).min(c[2]);
        let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
        let c = c.map(|v| v - offset);
        let peak = c[0].max(c[1]).max(c[2]);
        if peak < start {
            return c;
        }
        let d = 1.0 - start;
        let new_peak = 1.0 - d * d / (peak + d - start);
        let c = c.map(|v| v * new_peak / peak);
        let g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
        c.map(|v| v * (1.0 - g) + new_peak * g)
    }

    /// Stephen Hill's fitted ACES (BakingLab's ACES.hlsl).
    pub fn aces(c: V) -> V {
        let input = [[0.59719, 0.35458, 0.04823], [0.07600, 0.90834, 0.01566], [0.02840, 0.13383, 0.83777]];
        let output = [[1.60475, -0.53108, -0.07367], [-0.10208, 1.10813, -0.00605], [-0.00327, -0.07276, 1.07602]];
        let v = mul_rows(input, c)
            .map(|v| (v * (v + 0.0245786) - 0.000090537) / (v * (0.983729 * v + 0.4329510) + 0.238081));
        mul_rows(output, v).map(|v| v.clamp(0.0, 1.0))
    }

    /// Minimal AgX (Benjamin Wrensch), default look, with its 2.2 display EOTF.
    pub fn agx(c: V) -> V {
        let agx_mat = [
            [0.842479062253094, 0.0423282422610123, 0.0423756549057051],
            [0.0784335999999992, 0.878468636469772, 0.0784336],
            [0.0792237451477643, 0.0791661274605434, 0.879142973793104],
        ];
        let agx_mat_inv = [
            [1.19687900512017, -0.0528968517574562, -0.0529716355144438],
            [-0.0980208811401368, 1.15190312990417, -0.0980434501171241],
            [-0.0990297440797205, -0.0989611768448433, 1.15107367264116],
        ];
        let (min_ev, max_ev) = (-12.47393, 4.026069);
        let v =
            mul_columns(agx_mat, c).map(|v| (v.max(1e-10).log2().clamp(min_ev, max_ev) - min_ev) / (max_ev - min_ev));
        let v = v.map(|x| {
            let (x2, x4) = (x * x, x * x * x * x);
            15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x - 0.00232
        });
        mul_columns(agx_mat_inv, v).map(|v| v.clamp(0.0, 1.0).powf(2.2))
    }
}

#[test]
fn tone_curves_match_the_reference_formulas() {
    use tracer::kernel::tonemap::{self, TONEMAP_ACES, TONEMAP_AGX, TONEMAP_NEUTRAL, TONEMAP_NONE};
    let mut r = TestRng::new(31);
    let mut worst = [0.0f64; 3];
    for i in 0..20_000 {
        let c = if i % 4 == 0 {
            Vec3::splat(r.range(-12.0, 12.0).exp2())
        } else {
            Vec3::new(r.range(-12.0, 12.0).exp2(), r.range(-12.0, 12.0).exp2(), r.range(-12.0, 12.0).exp2())
        };
        let v = c.as_dvec3().to_array();
        let cases = [
            (tonemap::tone_map(c, TONEMAP_NEUTRAL, 1.0), tone_reference::neutral(v).map(|x| x.clamp(0.0, 1.0))),
            (tonemap::tone_map(c, TONEMAP_ACES, 1.0), tone_reference::aces(v)),
            (tonemap::tone_map(c, TONEMAP_AGX, 1.0), tone_reference::agx(v)),
        ];
        for (k, (got, want)) in cases.iter().enumerate() {
            for (g, w) in got.to_array().iter().zip(want) {
                assert!((0.0..=1.0).contains(g), "{c}: operator {k} gave {got}");
                worst[k] = worst[k].max((*g as f64 - w).abs());
            }
        }
    }
    println!("largest difference from the f64 references (neutral, ACES, AgX): {worst:?}");
    assert!(worst.iter().all(|&w| w < 2e-5), "{worst:?}");

    // Hand-checked values. Neutral: grey below the knee only loses the 0.04 toe offset; a
    // 10 x brighter grey rolls off to 1 - 0.24² / 9.44.
    let neutral = |c: f32| tonemap::tone_map(Vec3::splat(c), TONEMAP_NEUTRAL, 1.0).x;
    assert!((neutral(0.5) - 0.46).abs() < 1e-6 && (neutral(0.05) - 0.015625).abs() < 1e-6);
    assert!((neutral(10.0) - (1.0 - 0.0576 / 9.44)).abs() < 1e-6, "{}", neutral(10.0));
    // ACES: black stays (nearly) black, very bright saturates to white.
    let aces = |c: f32| tonemap::tone_map(Vec3::splat(c), TONEMAP_ACES, 1.0);
    assert!(aces(0.0).max_element() < 1e-3 && aces(1e4).min_element() > 0.99, "{} {}", aces(0.0), aces(1e4));
    // AgX maps middle grey 0.18 near the middle of the display range, white-balanced.
    let agx_grey = tonemap::tone_map(Vec3::splat(0.18), TONEMAP_AGX, 1.0);
    assert!((agx_grey.x - agx_grey.z).abs() < 1e-3 && agx_grey.x > 0.1 && agx_grey.x < 0.3, "{agx_grey}");
    // None clamps; exposure scales before the curve (+1 EV: twice the radiance).
    assert_eq!(tonemap::tone_map(Vec3::new(0.25, 2.0, -1.0), TONEMAP_NONE, 1.0), Vec3::new(0.25, 1.0, 0.0));
    assert_eq!(tonemap::tone_map(Vec3::splat(0.2), TONEMAP_NONE, 2.0), Vec3::splat(0.4));
    assert_eq!(
        tonemap::tone_map(Vec3::splat(0.3), TONEMAP_NEUTRAL, 2.0),
        tonemap::tone_map(Vec3::splat(0.6), TONEMAP_NEUTRAL, 1.0)
    );
    // Non-finite and negative radiance displays black with every operator.
    for op in [TONEMAP_NONE, TONEMAP_NEUTRAL, TONEMAP_ACES, TONEMAP_AGX] {
        let v = tonemap::display_srgb(Vec3::new(f32::NAN, f32::INFINITY, -3.0), op, 1.0);
        assert!(v.is_finite() && v.max_element() < 0.02, "operator {op}: {v}");
    }
    // sRGB encoding: the two pieces meet at 0.0031308; 1 stays 1.
    assert!((tonemap::linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
    assert!((tonemap::linear_to_srgb(0.0031308) - 0.0031308 * 12.92).abs() < 1e-6);
    assert!((tonemap::linear_to_srgb(0.18) - 0.4614).abs() < 1e-3);
}

#[test]
fn png_output_keeps_the_old_clamp_as_none_and_tone_maps_by_default() {
    use tracer::backend::Image;
    use tracer::output::{to_display_srgb8, to_srgb8, Display, ToneMap};
    let image =
        Image { width: 3, height: 1, pixels: vec![Vec3::splat(0.5), Vec3::splat(4.0), Vec3::new(f32::NAN, 0.0, 1.0)] };
    let clamped = to_srgb8(&image);
    assert_eq!(clamped, [188, 188, 188, 255, 255, 255, 0, 0, 255]);
    assert_eq!(to_display_srgb8(&image, &Display::CLAMP), clamped);
    let neutral = to_display_srgb8(&image, &Display::default());
    assert_eq!(Display::default().tone_map, ToneMap::Neutral);
    // Neutral keeps a 4.0 highlight below white and darkens 0.5 only by its toe offset.
    assert!(neutral[3] < 255 && neutral[3] > 240 && neutral[0] < 188 && neutral[0] > 175, "{neutral:?}");
    let brighter = to_display_srgb8(&image, &Display { tone_map: ToneMap::Neutral, exposure: 1.0 });
    assert!(brighter[0] > neutral[0], "{brighter:?}");
}
